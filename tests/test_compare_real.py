"""The comparator against the real renderers (Mitsuba reference, GL real time) on a tiny scene.

The renderers and their backends are part of the product's set-up (`make test` installs them), so a
missing one fails these tests rather than skipping them.
"""

from __future__ import annotations

import json

import pytest

from pbrcheck_cli import main
from pbrcheck.exr import write_exr
from pbrcheck.scene import load_scene

from test_compare_report import SCENE, check_offline_html

# Renders, fits or quadratures of seconds each: `make test-fast` skips them, `make test` runs them.
pytestmark = pytest.mark.slow

# The fastest real-time preset: runtime importance sampling has no prefilter pass.
FAST_PRESET = "runtime_is20"


@pytest.fixture
def scene_file(tmp_path):
    p = tmp_path / "tiny.toml"
    p.write_text(SCENE)
    return p


@pytest.fixture
def renderers(tmp_cache):
    import realtime.render as rt
    import reference.render as ref

    return ref, rt


def _reference(ref_mod, scene, **kw):
    return ref_mod.render_reference(scene, progress=False, **kw)


def _realtime(rt_mod, scene, preset):
    return rt_mod.render_realtime(scene, preset, progress=False)


def test_independent_reference_renders_are_within_noise(renderers, scene_file):
    from compare.metrics import compare_images

    ref_mod, _ = renderers
    scene = load_scene(scene_file)
    a = _reference(ref_mod, scene, spp=16, seed=0)
    b = _reference(ref_mod, scene, spp=16, seed=1)
    c = compare_images(a, b, scene=scene)
    assert c.summary["pixels"]["valid"] > 100 and c.summary["pixels"]["edge"] > 0
    flags = c.summary["noise"]["within_noise"]
    assert all(flags.values()), flags
    assert {o["material"]["roughness"] for o in c.summary["objects"]} == {0.0, 0.5, 1.0}


def test_gate_with_real_renderers(renderers, scene_file, tmp_path, capsys):
    ref_mod, rt_mod = renderers
    scene = load_scene(scene_file)
    write_exr(tmp_path / "refs" / "tiny.exr", _reference(ref_mod, scene, spp=16))
    budget = tmp_path / "budget.toml"
    budget.write_text(f"""
[[check]]
name = "stored"
scene = "tiny.toml"
preset = "{FAST_PRESET}"
reference = "refs/tiny.exr"
[check.max]
relmse = 1.0
flip_mean = 0.5
[[check]]
name = "auto-tight"
scene = "tiny.toml"
preset = "{FAST_PRESET}"
reference = "auto"
spp = 16
[check.max]
flip_mean = 1e-4
""")
    rc = main(["gate", str(budget), "--quiet", "--maps", str(tmp_path / "maps"), "--junit", str(tmp_path / "j.xml")])
    out = capsys.readouterr().out
    assert rc == 1, out
    assert "pass stored" in out and "FAIL auto-tight: flip_mean" in out
    assert (tmp_path / "maps" / "auto-tight" / "flip.png").is_file()


def test_report_and_sweep_with_real_renderers(renderers, scene_file, tmp_path):
    ref_mod, rt_mod = renderers
    _realtime(rt_mod, load_scene(scene_file), FAST_PRESET)
    out = tmp_path / "report"
    assert main(["report", str(scene_file), "--presets", FAST_PRESET, "--out", str(out), "--spp", "8",
                 "--spp-cap", "8", "--vary", "runtime_samples=4,16", "--quiet"]) == 0
    check_offline_html(out / "index.html")
    data = json.loads((out / "tiny" / "metrics.json").read_text())
    assert data["presets"][FAST_PRESET]["timings"]["frame"] > 0
    assert [c["spp"] for c in data["convergence"]] == [2, 4]
    rule = data["reference_spp"]  # the cap holds the reference at 8 spp; the rule's figures are real
    assert rule["spp"] == 8 and rule["cap"] == 8 and rule["noise_floor"] > 0
    assert rule["noise_limited"] == (rule["ratio"] is not None and rule["ratio"] < 10)
    assert len(data["sweep"]) == 2 and all(r["frame_s"] is not None for r in data["sweep"])


def test_gate_refuses_a_stored_reference_of_another_scene(renderers, scene_file, tmp_path, capsys):
    """An edited scene with a stale stored reference is an error (exit 2), never a pass or a fail."""
    ref_mod, _ = renderers
    scene = load_scene(scene_file)
    write_exr(tmp_path / "refs" / "tiny.exr", _reference(ref_mod, scene, spp=4))
    scene_file.write_text(SCENE.replace("base_color = [0.8, 0.5, 0.3]", "base_color = [0.8, 0.5, 0.4]"))
    budget = tmp_path / "budget.toml"
    budget.write_text(f"""
[[check]]
name = "stale"
scene = "tiny.toml"
preset = "{FAST_PRESET}"
reference = "refs/tiny.exr"
[check.max]
relmse = 100.0
""")
    rc = main(["gate", str(budget), "--quiet"])
    out = capsys.readouterr()
    assert rc == 2, out
    assert "re-render it" in out.out + out.err
