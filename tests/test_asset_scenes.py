"""glTF asset scenes everywhere an analytic scene goes (issue 23, sections 3 and 4): ``gate``,
``report``, ``sweep``, ``corpus``, ``diagnose`` and ``explain`` on a small asset the test builds
(:func:`pbrcheck.gltf_build.panel_asset`), with the real raster pipeline and the real reference;
and the gate's committed asset is what its builder writes.

Cheap: 16 x 12 images, references of 8..16 spp, and the real-time ``default`` preset replaced for
the test by the same preset with small bakes (cube 16, 64 prefilter samples, 16^2 LUT): the
plumbing is under test here, not the accuracy (the gate's ``panel-default`` check measures that).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pbrcheck_cli import main
from pbrcheck.errors import PbrcheckError
from pbrcheck.gltf import load_asset
from pbrcheck.gltf_build import panel_asset
from pbrcheck.exr import Image, write_exr

ROOT = Path(__file__).resolve().parents[1]
#: The default preset with small bakes (module docstring).
CHEAP = {"cube_size": 16, "prefilter_levels": 4, "prefilter_samples": 64, "irradiance_size": 8,
         "irradiance_source_size": 16, "lut_size": 16, "lut_samples": 64, "supersample": 2}
SCENE = """name = "panel_tiny"
[camera]
origin = [0.0, 0.35, 3.1]
target = [0.0, 0.0, 0.45]
fov = 44.0
width = 16
height = 12
[environment]
type = "{env}"
{env_fields}
[[lights]]
type = "point"
position = [-2.0, 2.0, 3.0]
intensity = [6.0, 6.0, 6.0]
[[objects]]
type = "gltf"
path = "panel.glb"
"""


def scene_text(env: str = "constant", env_fields: str = "radiance = [0.8, 0.9, 1.0]") -> str:
    return SCENE.format(env=env, env_fields=env_fields)


@pytest.fixture
def asset_dir(tmp_path, monkeypatch, tmp_cache):
    from realtime.presets import PRESETS

    monkeypatch.setitem(PRESETS, "default", {**PRESETS["default"], **CHEAP})
    panel_asset(tmp_path / "panel.glb")
    (tmp_path / "scene.toml").write_text(scene_text())
    return tmp_path


def test_committed_gate_asset_is_what_the_builder_writes(tmp_path):
    """compare/budgets/assets/panel.glb decodes to what pbrcheck.gltf_build.panel_asset builds now
    (content, not bytes: another zlib may compress the PNGs differently)."""
    a = load_asset(ROOT / "compare/budgets/assets/panel.glb")
    b = load_asset(panel_asset(tmp_path / "panel.glb"))
    assert len(a.images) == len(b.images) == 3
    for x, y in zip(a.images, b.images):
        assert np.array_equal(x.pixels, y.pixels)
    for p, q in zip(a.primitives, b.primitives):
        assert np.array_equal(p.positions, q.positions) and np.array_equal(p.indices, q.indices)
        assert np.array_equal(p.texcoords[0], q.texcoords[0]) and np.array_equal(p.tangents, q.tangents)
    assert a.materials == b.materials


def test_gate_on_an_asset_scene_accepts_then_passes(asset_dir, capsys):
    (asset_dir / "b.toml").write_text("""require_baselines = true
[[check]]
name = "panel"
scene = "scene.toml"
preset = "default"
reference = "auto"
spp = 8
spp_cap = 8
[check.max]
relmse = 10
""")
    assert main(["gate", str(asset_dir / "b.toml"), "--quiet", "--accept", "--reason", "first"]) == 0
    assert (asset_dir / "baselines" / "panel.exr").is_file()
    capsys.readouterr()
    assert main(["gate", str(asset_dir / "b.toml"), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "pass panel" in out and "skip" not in out


def test_report_sweep_and_diagnose_on_an_asset_scene(asset_dir, capsys):
    scene = str(asset_dir / "scene.toml")
    out = asset_dir / "report"
    assert main(["report", scene, "--presets", "default", "--out", str(out), "--spp", "8", "--spp-cap", "8",
                 "--quiet", "--no-convergence", "--no-furnace", "--vary", "supersample=1,2"]) == 0
    metrics = json.loads((out / "panel_tiny" / "metrics.json").read_text())
    assert set(metrics["presets"]) == {"default"}
    assert [r["options"] for r in metrics["sweep"]] == [{"supersample": 1}, {"supersample": 2}]
    assert metrics["presets"]["default"]["materials"], "per-material metrics of the asset"
    assert "presets skipped" not in (out / "index.html").read_text()
    # diagnose on the asset: the test is the reference with its rows flipped (found), and the
    # scene-space hypotheses that need analytic materials say why they are not tried.
    from pbrcheck.scene import load_scene
    from reference.render import render_reference

    r = render_reference(load_scene(scene), spp=8, use_cache=True, progress=False)
    write_exr(asset_dir / "ref.exr", r)
    write_exr(asset_dir / "test.exr", Image.from_rgb(r.rgb[::-1].copy(), coverage=r.channels["coverage"][::-1].copy()))
    capsys.readouterr()
    assert main(["diagnose", str(asset_dir / "ref.exr"), str(asset_dir / "test.exr"), "--scene", scene,
                 "--spp", "8", "--json", str(asset_dir / "d.json"), "--quiet"]) == 0
    d = json.loads((asset_dir / "d.json").read_text())
    assert d["likely"] == "flip_vertical", d["likely"]
    skipped = {h["hypothesis"]: h["skipped"] for h in d["rows"]}
    assert "glTF asset materials" in (skipped["roughness_as_alpha"] or "")
    # the scene file's point light is one: its units are tried; the constant environment is not rotated
    assert skipped["light_units_4pi"] is None and skipped["light_units_over_4pi"] is None
    assert all("constant" in (skipped[f"env_rotate_{a}"] or "") for a in (90, 180, 270))
    assert "point lights" not in capsys.readouterr().out


def test_corpus_of_environments_on_an_asset_scene(asset_dir, capsys):
    envs = asset_dir / "envs"
    envs.mkdir()
    for i in range(2):
        a = np.full((8, 16, 3), 0.5, np.float32)
        a[2, 3 + 4 * i] = 40.0
        write_exr(envs / f"env{i}.exr", Image.from_rgb(a))
    out = asset_dir / "corpus"
    assert main(["corpus", str(envs), "--scene", str(asset_dir / "scene.toml"), "--presets", "default",
                 "--spp", "4", "--out", str(out), "--scheduler", "serial", "--quiet"]) == 0
    rows = json.loads((out / "corpus.json").read_text())["rows"]
    assert len(rows) == 2 and all(r["status"] == "ok" for r in rows), rows
    assert "skipping" not in capsys.readouterr().err


def test_explain_on_an_asset_decomposes_the_asset_approximations(asset_dir):
    from compare.research.explain import ASSET_SOURCES, run_explain, table_markdown
    from pbrcheck.scene import load_scene

    (asset_dir / "sky.toml").write_text(scene_text("sky", 'sun_direction = [0.4, 0.6, 0.7]\nsun_angular_diameter = 8.0\n'
                                                   'sun_radiance = [60.0, 55.0, 48.0]\nresolution = [64, 32]'))
    res = run_explain(load_scene(str(asset_dir / "sky.toml")), options=CHEAP, spp=8, spp_cap=8, cube_max=16,
                      samples_scale=0.05, only=tuple(ASSET_SOURCES))
    rows = {r.source: r for r in res.sources}
    assert list(rows) == list(ASSET_SOURCES)
    b = res.baseline["relmse"]
    for name in ASSET_SOURCES:
        r = rows[name]
        assert r.error is None and np.isfinite(r.metrics["relmse"]) and r.contribution == b - r.metrics["relmse"]
    # every asset source changes the image here (measured, not assumed): mip-filtered textures and
    # normals differ from level 0 at this density, and the occlusion texture darkens the grooves
    assert all(abs(rows[n].contribution) > 1e-7 for n in ASSET_SOURCES), {n: rows[n].contribution for n in ASSET_SOURCES}
    for k, v in ASSET_SOURCES.items():
        assert all(res.all_exact.options[o] == x for o, x in v.items())
    (occ,) = res.path_truth
    assert occ.source == "occlusion" and occ.spp == res.spp
    assert occ.contribution == occ.baseline["relmse"] - occ.metrics["relmse"]
    assert occ.baseline["relmse"] != b  # measured against the path reference, not the local one
    with pytest.raises(PbrcheckError, match="unknown source.*texture_filtering"):
        run_explain(load_scene("spheres"), options=CHEAP, size=8, spp=4, spp_cap=4, only=("texture_filtering",))
    text = table_markdown(res)
    assert "| texture_filtering |" in text and "path reference" in text and "horizon" in text


def test_raster_times_texture_upload_and_mips_apart(asset_dir):
    """``bench realtime``'s asset figures: the upload and the mip generation are separate passes."""
    from realtime.render import render_realtime
    from pbrcheck.scene import load_scene

    img = render_realtime(load_scene(str(asset_dir / "scene.toml")), "default", {"texture_sampling": "lod0"},
                          progress=False)
    t = json.loads(img.meta["timings"])
    assert t["texture_upload"] > 0 and t["texture_mips"] > 0 and "textures" not in t
