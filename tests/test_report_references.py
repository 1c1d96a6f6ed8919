"""The report's "both references" section (compare/report/references.py): every external renderer
against the single-scattering and the random-walk reference. A fake engine (tests/test_clients.py)
plays the renderer and a fake reference plays Mitsuba (fast); one real three.js run is marked slow."""

from __future__ import annotations

import json
import shutil
from dataclasses import replace

import numpy as np
import pytest

import compare.renderers as renderers
from compare.report.references import (RANDOM_WALK_MAX_SPP, measure_references, random_walk_scene,
                                       references_sections, single_scattering_scene)
from pbrcheck.scene import dump_toml, scene_from_dict
from tests.test_clients import FAKE, SCENE, fake  # noqa: F401  (the fake engine fixture)
from tests.test_compare_report import fake_reference

SPP_SEEN: list = []


def two_references(scene, **kw):
    """Single scattering loses energy (0.6 on the sphere), the walk keeps it (1.0): the fake engine,
    which renders 1.0 everywhere (a compensating engine), differs from the first only."""
    SPP_SEEN.append((scene.brdf.multiscatter, kw.get("spp")))
    img = fake_reference(scene, **kw)
    ids = np.rint(img.channels["object"])
    val = 1.0 if scene.brdf.multiscatter == "random_walk" else 0.6
    for c in "RGB":
        img.channels[c] = np.where(ids >= 0, val, 1.0).astype(np.float32)
    return img


@pytest.fixture
def compensating(fake, monkeypatch):  # noqa: F811
    (fake / "fake.py").write_text(FAKE.replace("img = np.full((H, W, 3), 0.5, np.float32)",
                                               "img = np.full((H, W, 3), 1.0, np.float32)"))
    monkeypatch.setattr(renderers, "render_reference", two_references)
    SPP_SEEN.clear()
    return fake


def test_random_walk_scene_needs_the_correlated_geometry():
    s = scene_from_dict(SCENE)
    rw, why = random_walk_scene(s)
    assert rw.brdf.multiscatter == "random_walk" and why == ""
    assert single_scattering_scene(rw).brdf.multiscatter == "none" and single_scattering_scene(s) is s
    none, why = random_walk_scene(replace(s, brdf=replace(s.brdf, geometry="smith_ggx")))
    assert none is None and "smith_ggx_correlated" in why
    none, why = random_walk_scene(replace(s, brdf=replace(s.brdf, ndf="blinn_phong")))
    assert none is None and "blinn_phong" in why


def test_an_asset_scene_has_a_random_walk(tmp_path):
    # the textured material of glTF assets walks per shading point since issue 40 (tests/test_asset_walk.py)
    from gltf_build import quad_asset, quad_scene
    from pbrcheck.scene import load_scene
    asset = quad_asset(tmp_path / "q.gltf", {"pbrMetallicRoughness": {"metallicFactor": 1.0, "roughnessFactor": 0.8}})
    s = load_scene(quad_scene(tmp_path, asset, size=(8, 8)))
    assert s.assets and s.brdf.ndf == "ggx"
    rw, why = random_walk_scene(s)
    assert rw.brdf.multiscatter == "random_walk" and why == ""


def test_a_compensating_engine_is_right_against_the_walk(compensating):
    s = scene_from_dict(SCENE)
    [p] = measure_references(s, [renderers.RendererSpec.parse("ext:pfm")], 512)
    assert p.vs_single["relmse"] > 0.1                     # 1.0 against 0.6
    assert p.vs_random_walk["relmse"] < 1e-3 and p.share > 0.99
    assert p.spp_single == 512 and p.spp_random_walk == RANDOM_WALK_MAX_SPP
    assert ("none", 512) in SPP_SEEN and ("random_walk", RANDOM_WALK_MAX_SPP) in SPP_SEEN
    d = p.to_dict()
    assert d["share_of_error_from_reference"] == p.share and d["vs_random_walk"]["relmse"] == p.vs_random_walk["relmse"]


def test_a_scene_without_a_walk_says_why(compensating):
    s = scene_from_dict({**SCENE, "brdf": {"ndf": "blinn_phong", "geometry": "smith_ggx"}})
    [p] = measure_references(s, [renderers.RendererSpec.parse("ext:pfm")], 8)
    assert p.vs_random_walk is None and p.share is None and "blinn_phong" in p.note
    assert all(m == "none" for m, _ in SPP_SEEN)


@pytest.mark.parametrize("lobe,walks", [({"clearcoat": 1.0, "sheen_color": [0.5, 0.5, 0.5]}, True),
                                        ({"anisotropy_strength": 0.5}, False)])
def test_a_lobe_scene_is_set_against_the_walk(compensating, lobe, walks):
    """The walk under the lobes (reference/lobe_bsdf.py, issue 40): a clearcoat + sheen sphere gets the
    random-walk reference; anisotropy (no walk) says why."""
    obj = {**SCENE["objects"][0], "material": {**SCENE["objects"][0]["material"], **lobe}}
    s = scene_from_dict({**SCENE, "objects": [obj]})
    [p] = measure_references(s, [renderers.RendererSpec.parse("ext:pfm")], 8)
    if walks:
        assert p.vs_random_walk["relmse"] < 1e-3 and p.note == "" and ("random_walk", 8) in SPP_SEEN
    else:
        assert p.vs_random_walk is None and "anisotropy" in p.note
        assert all(m == "none" for m, _ in SPP_SEEN)


def test_no_external_renderer_no_section(tmp_path):
    assert references_sections([], [], [renderers.RendererSpec.parse(p) for p in ("default", "filament")],
                               tmp_path) == []


def test_report_shows_both_references_for_every_external_renderer(compensating, tmp_path):
    from compare.report.build import ReportConfig, build_report

    (tmp_path / "tiny.toml").write_text(dump_toml(SCENE))
    index = build_report([str(tmp_path / "tiny.toml")], tmp_path / "r",
                         ReportConfig(presets=["ext:pfm", "ext:exr"], spp=4, convergence=False, sweep=False,
                                      furnace=False, progress=False))
    html = index.read_text()
    sec = html[html.index('id="references"'):]
    assert "External renderers against both references" in sec
    assert "ext:pfm" in sec and "ext:exr" in sec and "relmse vs random walk" in sec and "100 %" in sec
    rows = json.loads((tmp_path / "r" / "tiny" / "references.json").read_text())
    assert [r["renderer"] for r in rows] == ["ext:pfm", "ext:exr"]
    assert all(r["share_of_error_from_reference"] > 0.99 for r in rows)


def _threejs_ready() -> bool:
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    return bool(shutil.which("node")) and (root / "clients/threejs/node_modules/three").is_dir() and bool(
        shutil.which("chromium") or shutil.which("chromium-browser"))


@pytest.mark.slow
@pytest.mark.skipif(not _threejs_ready(), reason="three.js client not installed (node, npm ci, chromium)")
def test_threejs_furnace_is_explained_by_the_random_walk(tmp_cache):
    """three.js r187 in a small white furnace: its error against the single-scattering reference is
    the reference's missing multiple scattering (most of it goes away against the walk)."""
    from pbrcheck.scene import load_scene

    s = load_scene("furnace").with_camera(width=96, height=24)
    [p] = measure_references(s, [renderers.RendererSpec.parse("ext:threejs")], 32)
    assert p.vs_single["relmse"] > 0.05
    assert p.share > 0.9, p.to_dict()


# --- the model-matched truth: report --reference-mode path (issue 40) ------------------------------

MODES_SEEN: list = []


def matched_references(scene, **kw):
    """The plain truth (single scattering, local) 0.6 on the sphere; the walk in path mode, the
    model-matched truth, 1.0 (what the compensating fake engine renders); any other 0.8."""
    mode = kw.get("mode", "local")
    MODES_SEEN.append((scene.brdf.multiscatter, mode))
    img = fake_reference(scene, **{k: v for k, v in kw.items() if k != "mode"})
    ids = np.rint(img.channels["object"])
    walk = scene.brdf.multiscatter == "random_walk"
    val = 1.0 if (walk and mode == "path") else (0.6 if (not walk and mode == "local") else 0.8)
    for c in "RGB":
        img.channels[c] = np.where(ids >= 0, val, 1.0).astype(np.float32)
    img.meta["mode"] = mode
    return img


@pytest.fixture
def matched(compensating, monkeypatch):
    monkeypatch.setattr(renderers, "render_reference", matched_references)
    MODES_SEEN.clear()
    return compensating


def test_path_mode_sets_the_engine_against_the_model_matched_truth_per_material(matched):
    s = scene_from_dict(SCENE)
    [p] = measure_references(s, [renderers.RendererSpec.parse("ext:pfm")], 64, mode="path")
    assert p.physics == ["multiple scattering (random walk)", "visibility and interreflection (path)"]  # metallic 1
    assert ("none", "local") in MODES_SEEN and ("random_walk", "path") in MODES_SEEN
    assert p.vs_single["relmse"] > 0.1 and p.share > 0.99
    [m] = p.materials                                       # one sphere: one row
    assert m["relmse_plain"] == pytest.approx(p.vs_single["relmse"]) and m["share"] > 0.99
    # local mode: the walk alone (as before the option), its share and per-object rows too
    MODES_SEEN.clear()
    [q] = measure_references(s, [renderers.RendererSpec.parse("ext:pfm")], 64)
    assert q.physics == ["multiple scattering (random walk)"] and set(MODES_SEEN) == {("none", "local"),
                                                                                      ("random_walk", "local")}
    assert q.share == pytest.approx(1 - (0.2 ** 2 / 0.65) / (0.4 ** 2 / 0.37), abs=1e-3)   # 0.8 vs 0.6: part of it


def test_an_asset_scene_is_matched_by_walk_visibility_and_blend_in_path_mode(tmp_path):
    from gltf_build import quad_asset, quad_scene
    from compare.report.references import matched_scene
    from pbrcheck.scene import load_scene
    asset = quad_asset(tmp_path / "q.gltf", {"pbrMetallicRoughness": {"metallicFactor": 1.0, "roughnessFactor": 0.8}})
    s = load_scene(quad_scene(tmp_path, asset, size=(8, 8)))
    assert s.brdf.metallic_blend == "gltf"   # an asset scene's default (pbrcheck.gltf_objects.ASSET_METALLIC_BLEND)
    got, physics, why = matched_scene(s, "local")
    assert physics == ["multiple scattering (random walk)"] and got.brdf.metallic_blend == "gltf"
    got, physics, why = matched_scene(s, "path")
    assert physics == ["multiple scattering (random walk)", "visibility and interreflection (path)"]
    assert got.brdf.metallic_blend == "gltf" and got.brdf.multiscatter == "random_walk"
    f0 = replace(s, brdf=replace(s.brdf, metallic_blend="f0"))   # a scene file that keeps the seeds' mix
    got, physics, why = matched_scene(f0, "path")
    assert physics[-1] == "glTF's metallic blend" and got.brdf.metallic_blend == "gltf"
    half = scene_from_dict({**SCENE, "objects": [{"type": "sphere", "radius": 1.0,
                                                  "material": {"metallic": 0.5, "roughness": 0.5}}]})
    assert matched_scene(half, "path")[0].brdf.metallic_blend == "gltf"
    assert matched_scene(half, "local")[0].brdf.metallic_blend == "f0"   # local: the figures as they were


def test_report_states_the_reference_mode_and_the_share_per_material(matched, tmp_path):
    from compare.report.build import ReportConfig, build_report

    (tmp_path / "tiny.toml").write_text(dump_toml(SCENE))
    index = build_report([str(tmp_path / "tiny.toml")], tmp_path / "r",
                         ReportConfig(presets=["ext:pfm"], spp=4, convergence=False, sweep=False,
                                      furnace=False, progress=False, reference_mode="path"))
    html = index.read_text()
    assert "set against the reference in mode <code>path</code>" in html and "visibility (shadows)" in html
    assert ("none", "path") in MODES_SEEN          # the scene's own reference: path
    sec = html[html.index('id="references"'):]
    assert "model-matched (walk, path, blend)" in sec and "Per material" in sec and "100 %" in sec
    rows = json.loads((tmp_path / "r" / "tiny" / "references.json").read_text())
    assert rows[0]["materials"][0]["share"] > 0.99 and "visibility" in rows[0]["model_matched_physics"][-1]
    with pytest.raises(Exception, match="reference-mode"):
        build_report([str(tmp_path / "tiny.toml")], tmp_path / "r2", ReportConfig(presets=["ext:pfm"],
                                                                                  reference_mode="walk"))


def test_the_share_is_also_given_less_each_references_own_noise():
    """A noisy model-matched truth (a path reference: noisier than a local one at the same spp) would
    count its noise against itself; less each reference's noise the share is the physics'."""
    from compare.metrics import compare_images
    from compare.report.references import _per_material, reference_noise_relmse
    from pbrcheck.exr import Image
    rng = np.random.default_rng(9)
    h, w, sigma = 32, 48, 0.1
    obj = np.zeros((h, w), np.float32)
    var = {c: np.full((h, w), sigma ** 2, np.float32) for c in ("variance.R", "variance.G", "variance.B")}
    truth = np.full((h, w, 3), 1.0, np.float32)
    plain = Image.from_rgb(np.full((h, w, 3), 0.6, np.float32), object=obj,
                           **{c: np.zeros((h, w), np.float32) for c in var})
    matched = Image.from_rgb((truth + sigma * rng.standard_normal(truth.shape)).astype(np.float32), object=obj, **var)
    engine = Image.from_rgb(truth, object=obj)   # renders exactly the matched truth's mean
    c1, c2 = compare_images(plain, engine, flip=False, itp=False), compare_images(matched, engine, flip=False, itp=False)
    assert reference_noise_relmse(matched, c2) == pytest.approx(sigma ** 2 / 1.01, rel=0.05)
    assert reference_noise_relmse(plain, c1) == 0.0
    [m] = _per_material(c1, c2, plain, matched)
    assert m["relmse_matched"] > 0.009                       # the matched truth's own noise, raw
    assert m["relmse_matched_corrected"] == pytest.approx(0.0, abs=1e-3)
    assert m["share_corrected"] == pytest.approx(1.0, abs=0.01) and m["share"] < 0.985   # raw: 1 - 0.0099 / 0.432
