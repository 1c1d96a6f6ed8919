"""The gate's accepted baselines (compare/baseline.py, compare/gate.py) on small synthetic images:
accept and history, the four verdicts and their exit codes, the noise of a change (the reference's
variance, the renderer's spread), JUnit / Markdown / HTML outputs, and budget validation."""

from __future__ import annotations

import math
import tomllib
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from compare.baseline import (BIAS_FLOOR, Baseline, compare_to_baseline, load_baseline, region_masks, sensitivity,
                              spread_of)
from compare.gate import BudgetError, Check, CheckResult, Verdict, budget_noise, load_budget, noise_note
from pbrcheck.cli import main
from pbrcheck.exr import Image, write_exr

H, W = 64, 64
#: The reference's per-pixel variance: a change within it is neither better nor worse.
VAR = 0.05


def ref_image(var=VAR):
    """Two objects (left half id 0, right half id 1), radiance 0.5, with variance channels."""
    obj = np.zeros((H, W), np.float32)
    obj[:, W // 2:] = 1
    rgb = np.full((H, W, 3), 0.5, np.float32)
    v = np.full((H, W), var, np.float32)
    return Image.from_rgb(rgb, object=obj, coverage=np.ones((H, W), np.float32),
                          **{"variance.R": v, "variance.G": v, "variance.B": v})


def under_test(left=1.05, right=1.0):
    """The renderer under test: object 0 ``left`` x the reference, object 1 ``right`` x."""
    r = ref_image()
    rgb = r.rgb.copy()
    rgb[:, : W // 2] *= left
    rgb[:, W // 2:] *= right
    return Image.from_rgb(rgb, object=r.channels["object"], coverage=r.channels["coverage"])


BUDGET = """{top}
[[check]]
name = "synthetic"
test = "test.exr"
reference = "ref.exr"
{extra}
[check.max]
relmse = 1
"""


@pytest.fixture
def gate_dir(tmp_path):
    write_exr(tmp_path / "ref.exr", ref_image())
    write_exr(tmp_path / "test.exr", under_test())
    (tmp_path / "b.toml").write_text(BUDGET.format(top="", extra=""))
    return tmp_path


def gate(d, *extra, budget="b.toml"):
    return main(["gate", str(d / budget), "--quiet", "--maps", str(d / "maps"), *extra])


def accept(d, reason="first"):
    return gate(d, "--accept", "--reason", reason)


def test_accept_writes_baseline_and_history_then_unchanged_passes(gate_dir, capsys):
    assert gate(gate_dir) == 0
    assert "no accepted baseline" in capsys.readouterr().out
    assert accept(gate_dir, 'the "first" one') == 0
    out = capsys.readouterr().out
    assert "accepted synthetic: new" in out
    base = load_baseline(gate_dir, "synthetic")
    assert base is not None and base.record["reason"] == 'the "first" one' and base.record["bit_exact"]
    assert np.array_equal(base.image.rgb, under_test().rgb)
    hist = tomllib.loads((gate_dir / "b.toml").read_text())["history"]
    assert len(hist) == 1 and hist[0]["reason"] == 'the "first" one' and "synthetic" in hist[0]["figures"][0]
    load_budget(gate_dir / "b.toml")  # still a valid budget
    assert gate(gate_dir) == 0
    out = capsys.readouterr().out
    assert out.startswith("pass synthetic") and "baseline: pass" in out and "sensitivity: brightness +-0.01%" in out
    assert accept(gate_dir, "second") == 0
    assert len(tomllib.loads((gate_dir / "b.toml").read_text())["history"]) == 2
    assert not list((gate_dir / "baselines").glob(".staging-*"))


@pytest.mark.parametrize("left, right, verdict, rc", [
    (1.06, 1.0, "REGRESSED", 1),        # object 0 further from the reference
    (1.04, 1.0, "IMPROVED", 0),         # object 0 closer, nothing worse
    (1.05, 1.001, "CHANGED", 1),        # object 1: 0.1 % brighter, within the reference's noise
    (1.05, 1.0 + BIAS_FLOOR / 2, "pass", 0),  # below the floor of a bit-exact renderer
])
def test_verdicts_and_exit_codes(gate_dir, capsys, left, right, verdict, rc):
    assert accept(gate_dir) == 0
    capsys.readouterr()
    write_exr(gate_dir / "test.exr", under_test(left, right))
    assert gate(gate_dir) == rc
    out = capsys.readouterr().out
    assert out.startswith(verdict)
    if verdict == "REGRESSED":
        assert "object #0: relmse" in out.splitlines()[1] and "sigma" in out
    if verdict == "IMPROVED":
        assert "--accept --reason" in out
    if verdict == "CHANGED":
        assert "object #1" in out


def test_on_change_pass_allows_a_change(gate_dir, capsys):
    assert accept(gate_dir) == 0
    write_exr(gate_dir / "test.exr", under_test(1.05, 1.001))
    (gate_dir / "b.toml").write_text(BUDGET.format(top='on_change = "pass"', extra=""))
    assert gate(gate_dir) == 0
    assert 'allowed by on_change = "pass"' in capsys.readouterr().out
    (gate_dir / "b.toml").write_text(BUDGET.format(top="", extra='on_change = "fail"'))
    assert gate(gate_dir) == 1


def test_change_noise_reference_variance_and_renderer_spread():
    ref = ref_image()
    t0, t1 = under_test(1.05, 1.0), under_test(1.06, 1.0)
    base = Baseline(t0, np.zeros((H, W, 3)), {}, None)
    ch = compare_to_baseline(ref, base, t1)
    worse = {r.name for r in ch.by_state("worse")}
    assert ch.verdict == "regressed" and "object #0" in worse and "object #1" not in worse
    # sigma_d = 2 sqrt(sum d^2 v w^2) / n on object 0 (d = 0.005, w = 1 / 0.26)
    r0 = next(r for r in ch.regions if r.name == "object #0")
    n = H * W // 2 * 3
    assert r0.sigma_d == pytest.approx(2 * math.sqrt(n * 0.005 ** 2 * VAR / 0.26 ** 2) / n, rel=1e-3)
    assert r0.bias == pytest.approx(0.01 / 1.05, rel=1e-4)
    # a renderer whose run-to-run spread explains the change: no change at all
    noisy = Baseline(t0, np.full((H, W, 3), 0.05), {}, None)
    assert compare_to_baseline(ref, noisy, t1).verdict == "pass"
    # a noise-free reference: the same change is far beyond its noise
    assert compare_to_baseline(ref_image(0.0), base, t1).verdict == "regressed"


def test_regions_objects_and_tiles():
    valid = np.ones((H, W), bool)
    ids = np.zeros((H, W), np.int64)
    names = [n for n, _ in region_masks(valid, ids, {0: "ball"})]
    assert names[0] == "object ball" and len(names) == 1 + (H // 16) * (W // 16)
    assert "tile x16-31,y48-63" in names


def test_spread_and_sensitivity():
    a = np.zeros((4, 4, 3))
    assert not spread_of([a, a, a]).any() and spread_of([a, a + 1]).max() == pytest.approx(math.sqrt(0.5))
    base = Baseline(under_test(), np.zeros((H, W, 3)), {}, None)
    s = sensitivity(ref_image(), base)
    assert s["brightness"] == pytest.approx(BIAS_FLOOR) and s["lod"] is None and not s["lod_probed"]


def test_junit_summary_html(gate_dir):
    assert accept(gate_dir) == 0
    write_exr(gate_dir / "test.exr", under_test(1.06, 1.0))
    assert gate(gate_dir, "--junit", str(gate_dir / "j.xml"), "--summary", str(gate_dir / "s.md"),
                "--html", str(gate_dir / "html")) == 1
    suite = ET.parse(gate_dir / "j.xml").getroot().find("testsuite")
    names = [tc.get("name") for tc in suite.iter("testcase")]
    assert names[0] == "synthetic" and "synthetic/object #0" in names
    assert all(tc.find("failure") is not None for tc in suite.iter("testcase"))
    assert int(suite.get("tests")) == len(names) and int(suite.get("failures")) == len(names)
    md = (gate_dir / "s.md").read_text()
    assert "## synthetic: regressed" in md and "| #0 | worse |" in md
    for k in ("before", "after", "diff"):
        assert f"s-img/synthetic-{k}.png" in md and (gate_dir / "s-img" / f"synthetic-{k}.png").stat().st_size > 0
    page = (gate_dir / "html" / "index.html").read_text()
    assert 'type="range"' in page and "synthetic-after.png" in page and (gate_dir / "html" / "synthetic-diff.png").is_file()


def test_accept_refused_when_a_check_errors_and_needs_reason(gate_dir, capsys):
    (gate_dir / "test.exr").unlink()
    before = (gate_dir / "b.toml").read_text()
    assert accept(gate_dir) == 2
    assert "nothing accepted" in capsys.readouterr().out
    assert (gate_dir / "b.toml").read_text() == before and not (gate_dir / "baselines").exists()
    write_exr(gate_dir / "test.exr", under_test())
    assert gate(gate_dir, "--accept") == 2
    assert "--reason" in capsys.readouterr().err
    assert not (gate_dir / "baselines").exists()


def test_require_baselines(gate_dir, capsys):
    (gate_dir / "b.toml").write_text(BUDGET.format(top="require_baselines = true", extra=""))
    assert gate(gate_dir) == 2
    assert "no accepted baseline" in capsys.readouterr().out
    assert accept(gate_dir) == 0 and gate(gate_dir) == 0


def test_check_runs_and_accepts_only_the_named_check(gate_dir, capsys):
    """--check NAME: only that check runs; with --accept only its baseline and figures are written;
    an unknown name is bad input (exit 2) before anything runs."""
    write_exr(gate_dir / "test2.exr", under_test(left=1.0))
    second = BUDGET.format(top="", extra="").replace('"synthetic"', '"second"').replace("test.exr", "test2.exr")
    (gate_dir / "b.toml").write_text(BUDGET.format(top="", extra="") + second)
    assert gate(gate_dir, "--accept", "--reason", "only one", "--check", "second") == 0
    out = capsys.readouterr().out
    assert "accepted second: new" in out and "synthetic" not in out
    assert load_baseline(gate_dir, "second") is not None and load_baseline(gate_dir, "synthetic") is None
    hist = tomllib.loads((gate_dir / "b.toml").read_text())["history"]
    assert len(hist) == 1 and len(hist[0]["figures"]) == 1 and hist[0]["figures"][0].startswith("second: new")
    before = (gate_dir / "b.toml").read_text()
    assert gate(gate_dir, "--check", "nope") == 2
    assert "--check 'nope': no such check" in capsys.readouterr().err
    assert (gate_dir / "b.toml").read_text() == before


@pytest.mark.parametrize("bound, msg", [("-1", "a finite number >= 0"), ("inf", "a finite number >= 0"),
                                        ("nan", "a finite number >= 0")])
def test_budget_bounds_finite_and_non_negative(tmp_path, bound, msg):
    p = tmp_path / "b.toml"
    p.write_text(BUDGET.format(top="", extra="").replace("relmse = 1", f"relmse = {bound}"))
    with pytest.raises(BudgetError, match=msg):
        load_budget(p)
    p.write_text(BUDGET.format(top='on_change = "maybe"', extra=""))
    with pytest.raises(BudgetError, match="on_change"):
        load_budget(p)


def test_zero_budget_noise_note_does_not_crash():
    c = Check(name="z", max={"relmse": 0.0}, min={}, reference="r.exr")
    r = CheckResult(c, Verdict.PASS, budget_noise=budget_noise(c, {"simulated": {"relmse": 1e-4}}, 64))
    assert math.isinf(r.budget_noise[0]["spp_needed"])
    assert "a budget of 0" in noise_note(r)


def test_a_change_names_a_different_renderer_version(gate_dir, capsys):
    import json

    t = under_test()
    t.meta["version"] = "engine 1.0"
    write_exr(gate_dir / "test.exr", t)
    assert accept(gate_dir) == 0
    rec = json.loads((gate_dir / "baselines" / "synthetic.json").read_text())
    assert rec["version"] == "engine 1.0"
    t = under_test(1.06, 1.0)
    t.meta["version"] = "engine 2.0"
    write_exr(gate_dir / "test.exr", t)
    capsys.readouterr()
    assert gate(gate_dir) == 1
    assert "baseline was made with renderer version 'engine 1.0', this run used 'engine 2.0'" in capsys.readouterr().out


@pytest.mark.parametrize("budget", ["ci.toml", "clients.toml"])
def test_shipped_budgets_require_and_have_baselines(budget):
    from pathlib import Path

    from compare.maps import safe_name as _safe

    path = Path(__file__).resolve().parents[1] / "compare" / "budgets" / budget
    budget = load_budget(path)
    assert budget.require_baselines
    for c in budget.checks:
        b = load_baseline(budget.base, _safe(c.name))
        assert b is not None, c.name
        assert b.record["check"] == c.name and b.record["bit_exact"] and b.record["runs"] >= 3


def test_likely_term_from_which_objects_changed():
    from compare.baseline import RegionChange, Change, likely_term

    def reg(name, bias):
        return RegionChange(name, 10, bias, 1e-4, 0.0, 1e-6, 0.0, 0.0, 0.0, 1.0, abs(bias) > 1e-4, "changed")

    mats = {"object d": {"metallic": 0.0}, "object m": {"metallic": 1.0}, "object d2": {"metallic": 0.0}}
    assert "uniform factor x0.99" in likely_term(Change("changed", [reg("object d", -0.01), reg("object m", -0.01),
                                                                    reg("object d2", -0.01)]), mats)
    assert "diffuse term" in likely_term(Change("changed", [reg("object d", -0.01), reg("object m", 0.0),
                                                            reg("object d2", -0.01)]), mats)
    assert "specular term" in likely_term(Change("changed", [reg("object d", -0.0001), reg("object m", -0.01),
                                                             reg("object d2", -0.0002)]), mats)
