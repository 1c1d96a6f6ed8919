"""Issue 34, the gate's side: names from budgets and scenes reach the gate's outputs escaped for
each format (JUnit XML stays well-formed, the Markdown summary holds no raw HTML and no broken
table, terminal lines carry no control character), and ``gate --accept`` switches the baselines
and the history line together: a stop at any point leaves the old set or the new one, never a mix."""

from __future__ import annotations

import io
import os
import shutil
import tomllib
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from compare.baseline import BASELINE_DIR, load_baseline
from compare.gate import load_budget, run_gate
from compare.maps import safe_name
from pbrcheck.errors import Terminated
from pbrcheck.exr import Image, read_exr, write_exr

H, W = 16, 16
#: A check name holding what broke each output: ESC (an ANSI colour), 0x01 and backspace (XML 1.0
#: forbids them), a newline and a carriage return (forge a line), HTML and the table's column bar.
HOSTILE = "evil\x1b[31mred\x01\x08<script>alert(1)</script><img src=x onerror=alert(2)>|col\nFAKE pass\rx"


def _toml_str(s: str) -> str:
    return '"' + "".join(c if c.isalnum() or c in " <>()=/|[]" else f"\\u{ord(c):04x}" for c in s) + '"'


def _image(v: float) -> Image:
    return Image.from_rgb(np.full((H, W, 3), v, np.float32), object=np.zeros((H, W), np.float32),
                          coverage=np.ones((H, W), np.float32))


@pytest.fixture
def hostile_dir(tmp_path):
    """A budget whose one check (named :data:`HOSTILE`) breaks its relmse budget."""
    write_exr(tmp_path / "ref.exr", _image(0.5))
    write_exr(tmp_path / "test.exr", _image(0.6))
    (tmp_path / "b.toml").write_text(f'[[check]]\nname = {_toml_str(HOSTILE)}\ntest = "test.exr"\n'
                                     'reference = "ref.exr"\n[check.max]\nrelmse = 1e-6\n', encoding="utf-8")
    assert load_budget(tmp_path / "b.toml").checks[0].name == HOSTILE
    return tmp_path


def _gate(d, **kw) -> tuple[int, str]:
    out = io.StringIO()
    rc = run_gate(d / "b.toml", progress=False, stream=out, maps_dir=str(d / "maps"), **kw)
    return rc, out.getvalue()


def test_junit_is_well_formed_whatever_the_names_hold(hostile_dir):
    rc, _ = _gate(hostile_dir, junit=str(hostile_dir / "j.xml"))
    assert rc == 1
    root = ET.parse(hostile_dir / "j.xml").getroot()  # raises on a control character
    tc = root.find("testsuite").find("testcase")
    assert tc.get("name").startswith("evil\\x1b[31mred\\x01\\x08<script>")
    assert "\x1b" not in (hostile_dir / "j.xml").read_text(encoding="utf-8")
    assert tc.find("failure").get("message").startswith("FAIL evil\\x1b")


def test_markdown_summary_escapes_names(hostile_dir):
    _gate(hostile_dir, summary=str(hostile_dir / "s.md"))
    md = (hostile_dir / "s.md").read_text(encoding="utf-8")
    assert "<script>" not in md and "<img" not in md and "\x1b" not in md
    assert "&lt;script&gt;" in md and "&lt;img src=x onerror=alert(2)&gt;" in md
    rows = [l for l in md.splitlines() if l.startswith("| evil")]
    assert len(rows) == 1  # the newline did not start a row of its own
    # 5 columns: 6 unescaped bars; the name's bar is escaped as \|
    assert rows[0].count("|") - rows[0].count("\\|") == 6 and "\\|col\\\\nFAKE pass\\\\rx" in rows[0]
    assert not any(l.startswith("FAKE pass") for l in md.splitlines())


def test_terminal_lines_escape_control_characters(hostile_dir):
    rc, out = _gate(hostile_dir)
    assert rc == 1
    assert "\x1b" not in out and "\r" not in out and "\x08" not in out and "\x01" not in out
    assert not any(l.startswith("FAKE pass") for l in out.splitlines())
    assert "FAIL evil\\x1b[31mred\\x01\\x08<script>" in out


def test_error_lines_escape_control_characters(hostile_dir):
    (hostile_dir / "test.exr").unlink()
    rc, out = _gate(hostile_dir, junit=str(hostile_dir / "j.xml"))
    assert rc == 2 and out.startswith("ERROR evil\\x1b[31m") and "\x1b" not in out
    assert ET.parse(hostile_dir / "j.xml").getroot().find("testsuite").get("errors") == "1"


# --- gate --accept: one switch ------------------------------------------------------------------

BUDGET = """[[check]]
name = "a"
test = "a.exr"
reference = "ref.exr"
[check.max]
relmse = 1

[[check]]
name = "b"
test = "b.exr"
reference = "ref.exr"
[check.max]
relmse = 1
"""


def _state(d) -> tuple[int, tuple[float, ...]]:
    """(number of history entries, the value each check's baseline holds), read as the gate does."""
    budget = load_budget(d / "b.toml")  # completes a committed accept, as every gate run does
    hist = tomllib.loads((d / "b.toml").read_text(encoding="utf-8")).get("history", [])
    vals = tuple(float(load_baseline(d, safe_name(c.name)).image.rgb[0, 0, 0]) for c in budget.checks)
    return len(hist), vals


@pytest.fixture
def accepted(tmp_path):
    """Two checks accepted once at 0.5 and 0.6 (history: 1 entry); the renders are now 0.55, 0.65."""
    d = tmp_path / "old"
    d.mkdir()
    write_exr(d / "ref.exr", _image(0.5))
    write_exr(d / "a.exr", _image(0.5))
    write_exr(d / "b.exr", _image(0.6))
    (d / "b.toml").write_text(BUDGET, encoding="utf-8")
    assert run_gate(d / "b.toml", accept_reason="old", progress=False, stream=io.StringIO()) == 0
    write_exr(d / "a.exr", _image(0.55))
    write_exr(d / "b.exr", _image(0.65))
    assert _state(d) == (1, (0.5, pytest.approx(0.6)))
    return d


OLD, NEW = (1, (0.5, pytest.approx(0.6))), (2, (pytest.approx(0.55), pytest.approx(0.65)))


def test_accept_stopped_at_any_rename_leaves_the_old_set_or_the_new(accepted, tmp_path, monkeypatch):
    """A SIGTERM (the CLI raises :class:`Terminated`) at the k-th rename of the accept, for every k
    until the accept completes: the set read afterwards is wholly old or wholly new."""
    real = os.replace
    seen = []
    for k in range(100):
        d = tmp_path / f"run{k}"
        shutil.copytree(accepted, d)
        calls = []

        def stop_at_k(src, dst, _calls=calls, _k=k):
            if len(_calls) == _k:
                raise Terminated(15)
            _calls.append(dst)
            return real(src, dst)

        monkeypatch.setattr(os, "replace", stop_at_k)
        try:
            run_gate(d / "b.toml", accept_reason="new", progress=False, stream=io.StringIO())
            done = True
        except Terminated:
            done = False
        monkeypatch.setattr(os, "replace", real)
        state = _state(d)
        assert state in (OLD, NEW), (k, calls, state)
        seen.append(state == NEW)
        assert not list((d / BASELINE_DIR).glob(".*")), k  # no staging or commit folder left after a read
        if done:
            break
    assert done and seen[0] is False and seen[-1] is True
    # the stop after the commit but before every file moved: the next read completed it
    assert any(seen[:-1]), seen


def test_accept_keeps_the_baselines_layout(accepted):
    """The staged accept keeps the committed layout (``baselines/<check>.exr`` + ``.json``, nothing
    else once done), readable by a plain EXR reader."""
    assert run_gate(accepted / "b.toml", accept_reason="new", progress=False, stream=io.StringIO()) == 0
    assert sorted(p.name for p in (accepted / BASELINE_DIR).iterdir()) == ["a.exr", "a.json", "b.exr", "b.json"]
    assert float(read_exr(accepted / BASELINE_DIR / "b.exr").rgb[0, 0, 0]) == pytest.approx(0.65)
