"""Render Fidelity scenarios as RF reads them (pbrcheck/scenario_import.py, ``import-scenario``): the
generator's defaults merged per component, a whole config.json to one scene per scenario, ``exclude``
kept, LDR lighting sRGB-decoded, paths relative to the config, radius 0 (the camera at the target, drawn by `default`); RF's own config for the
shared assets (skipped when ../shared is absent)."""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from pbrcheck_cli import main
from pbrcheck.environment import load_environment
from pbrcheck.gltf import srgb_to_linear
from pbrcheck.scenario_import import RF_DEFAULTS, ScenarioError, config_scenes, scenario_scene
from pbrcheck.errors import SceneError
from pbrcheck.scene import load_scene
from pbrcheck.untrusted import allowed_dirs
from tests.gltf_build import quad_asset

SHARED_RF = Path(__file__).resolve().parents[1].parent / "shared" / "rf" / "config.json"


@pytest.fixture
def quad(tmp_path):
    """A quad asset [-1, 1]^2 at z = 0 in ``tmp_path/assets``."""
    (tmp_path / "assets").mkdir()
    return quad_asset(tmp_path / "assets" / "q.gltf", {"name": "matte"})


def write(p: Path, obj) -> Path:
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(json.dumps(obj))
    return p


def test_generator_defaults(tmp_path, quad):
    # config-reader.ts: 768 x 768, target (0, 0, 0), orbit theta 0 / phi 90 / radius 1, vertical fov 45
    assert RF_DEFAULTS["dimensions"] == {"width": 768, "height": 768} and RF_DEFAULTS["verticalFoV"] == 45.0
    t = scenario_scene(write(tmp_path / "s.json", {"model": "assets/q.gltf", "lighting": "neutral"}))
    c = t["camera"]
    assert (c["width"], c["height"]) == (768, 768) and c["target"] == [0.0, 0.0, 0.0]
    np.testing.assert_allclose(c["origin"], [0.0, 0.0, 1.0], atol=1e-12)
    assert c["fov"] == pytest.approx(45.0, abs=1e-12)          # square: horizontal = vertical
    assert "renderSkybox false" in t["description"] and t["name"] == "q"


def test_partial_fields_merge_per_component(tmp_path, quad):
    t = scenario_scene(write(tmp_path / "s.json", {
        "model": "assets/q.gltf", "lighting": "neutral", "dimensions": {"width": 1200}, "target": {"y": 0.5},
        "orbit": {"radius": 3, "theta": 90}, "verticalFoV": 30, "renderSkybox": True}))
    c = t["camera"]
    assert (c["width"], c["height"]) == (1200, 768) and c["target"] == [0.0, 0.5, 0.0]
    np.testing.assert_allclose(c["origin"], [3.0, 0.5, 0.0], atol=1e-12)   # theta 90: on +X, phi 90: level
    assert c["fov"] == pytest.approx(math.degrees(2 * math.atan(math.tan(math.radians(15)) * 1200 / 768)))
    assert "renderSkybox" not in t["description"]


def _rf_grid_scenario(tmp_path) -> Path:
    """RF's MetalRoughSpheresNoTextures shape: a millimetre-scale asset (a quad [-4, 4] mm at z = 0)
    and a radius-0 orbit whose target lies 10 mm in front of it."""
    (tmp_path / "assets").mkdir()
    quad_asset(tmp_path / "assets" / "q.gltf", {"name": "matte"}, scale=0.004)
    return write(tmp_path / "s.json", {"model": "assets/q.gltf", "lighting": "neutral", "dimensions": {"width": 16, "height": 16},
                                       "target": {"x": 0.0, "y": 0.0, "z": 0.01}, "orbit": {"radius": 0}})


def test_radius_zero_puts_the_camera_at_the_target_looking_along_the_orbit(tmp_path):
    t = scenario_scene(_rf_grid_scenario(tmp_path))
    c = t["camera"]
    # the camera at RF's target, looking along -Z (theta 0, phi 90); the look-at point at the asset's
    # bounding-box centre distance (10 mm): the quad's centre
    np.testing.assert_allclose(c["origin"], [0.0, 0.0, 0.01], atol=1e-15)
    np.testing.assert_allclose(c["target"], [0.0, 0.0, 0.0], atol=1e-15)
    assert "orbit radius 0" in t["description"] and "camera at the target" in t["description"]


def test_radius_zero_scene_is_drawn_by_the_default_preset(tmp_path):
    # issue 38: the old rule framed the bounding sphere about the target (radius 0.0115 / sin 22.5 deg:
    # the quad 0.24 of the width, ~6 % of the pixels); from the target the 8 mm quad at 10 mm fills
    # 0.004 / (0.01 tan 22.5 deg) = 0.97 of each side: 15.5 of 16 pixels, the 14 x 14 inner ones fully
    # covered (0.766 of the image)
    from compare.renderers import RendererSpec, render_under_test

    with allowed_dirs(tmp_path):
        scene = load_scene_of(tmp_path, scenario_scene(_rf_grid_scenario(tmp_path)))
        img = render_under_test(scene, RendererSpec.parse("default"), use_cache=False)
    full = float(np.mean(img.channels["coverage"] >= 1.0))
    assert full == pytest.approx(14 * 14 / 256), full


def load_scene_of(tmp_path: Path, table: dict):
    from pbrcheck.scene import scene_from_dict

    return scene_from_dict(table, file=str(tmp_path / "s.json"), base_dir=tmp_path, contained=True)


@pytest.mark.slow
@pytest.mark.skipif(not SHARED_RF.is_file(), reason=f"{SHARED_RF} is absent (RF's scenarios for ../shared/assets)")
def test_rf_metal_rough_spheres_is_drawn_by_the_default_preset():
    # the scenario whose `default` row was "no valid pixel" in reports/fidelity (orbit radius 0)
    from compare.fidelity import load_scenarios
    from compare.renderers import RendererSpec, render_under_test

    with allowed_dirs(SHARED_RF.parent.parent):
        sc, = load_scenarios(SHARED_RF, 64, ("khronos-MetalRoughSpheresNoTextures",))
        assert sc.scene is not None, sc.problem
        img = render_under_test(sc.scene, RendererSpec.parse("default"), use_cache=False)
    # 7 x 7 spheres fill the frame: 0.29 of the pixels fully covered at 64 x 64 (0 before the fix)
    assert float(np.mean(img.channels["coverage"] >= 1.0)) > 0.2


def test_absent_lighting_is_the_generators_default_and_named(tmp_path, quad, capsys):
    p = write(tmp_path / "s.json", {"model": "assets/q.gltf"})
    with pytest.raises(ScenarioError, match="the RF generator.s default lighting"):
        scenario_scene(p)
    assert main(["import-scenario", str(p)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "RF generator's default lighting" in err and "lightroom_14b.hdr" in err


def test_whole_config_imports_one_scene_per_scenario(tmp_path, quad, capsys):
    from PIL import Image as PILImage

    # an LDR environment beside the config (a sub-folder: paths are relative to the config, not the cwd)
    cfg_dir = tmp_path / "rf"
    (cfg_dir / "env").mkdir(parents=True)
    PILImage.fromarray(np.full((8, 16, 3), 128, np.uint8)).save(cfg_dir / "env" / "grey.png")
    PILImage.fromarray(np.full((8, 16, 3), 64, np.uint8)).save(cfg_dir / "env" / "dark.jpg", quality=100)
    cfg = write(cfg_dir / "config.json", {
        "renderers": [{"name": "three", "description": "three.js"}, {"name": "vray", "description": "V-Ray"}],
        "scenarios": [
            {"name": "a/one", "model": "../assets/q.gltf", "lighting": "env/grey.png", "exclude": ["vray"]},
            {"name": "two", "model": "../assets/q.gltf", "lighting": "env/dark.jpg", "orbit": {"radius": 4},
             "renderSkybox": True}]})
    out = tmp_path / "scenes"
    assert main(["import-scenario", str(cfg), "--out", str(out)]) == 0
    assert "2 scene(s)" in capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == ["a_one.toml", "scenarios.json", "two.toml"]
    index = json.loads((out / "scenarios.json").read_text())
    assert [s["name"] for s in index["scenarios"]] == ["a/one", "two"]
    assert [s["exclude"] for s in index["scenarios"]] == [["vray"], []]
    assert [s["renderSkybox"] for s in index["scenarios"]] == [False, True]
    assert [r["name"] for r in index["renderers"]] == ["three", "vray"]
    text = (out / "a_one.toml").read_text()
    assert "# exclude (RF renderers that skip it): vray" in text
    # the scenes name files outside their folder: refused (docs/security.md) unless the user allows them
    with pytest.raises(SceneError, match="--allow-dir"):
        load_scene(out / "a_one.toml")
    with allowed_dirs(tmp_path):
        one, two = load_scene(out / "a_one.toml"), load_scene(out / "two.toml")
    assert main(["check-scene", str(out / "two.toml"), "--allow-dir", str(tmp_path)]) == 0
    assert "grey.png is LDR: sRGB-decoded to linear" in one.description
    assert np.allclose(two.camera.origin, [0.0, 0.0, 4.0], atol=1e-12)
    # the LDR environments: sRGB-decoded 128 and (JPEG, within a code value) 64
    assert load_environment(one).data[..., :3] == pytest.approx(float(srgb_to_linear(np.float32(128 / 255))), abs=1e-6)
    dark = load_environment(two).data[..., :3]
    assert float(srgb_to_linear(np.float32(63 / 255))) <= dark.min() <= dark.max() <= float(
        srgb_to_linear(np.float32(65 / 255)))


def test_config_with_duplicate_names_or_one_bad_scenario_writes_nothing(tmp_path, quad, capsys):
    cfg = write(tmp_path / "c.json", {"renderers": [], "scenarios": [
        {"name": "x", "model": "assets/q.gltf", "lighting": "neutral"},
        {"name": "x", "model": "assets/q.gltf", "lighting": "neutral"}]})
    with pytest.raises(ScenarioError, match=r"scenarios\[1\]\.name"):
        config_scenes(cfg)
    write(cfg, {"renderers": [], "scenarios": [{"name": "x", "model": "assets/q.gltf", "lighting": "neutral"},
                                                {"name": "y", "model": "assets/q.gltf", "orbit": {"phi": 0},
                                                 "lighting": "neutral"}]})
    assert main(["import-scenario", str(cfg), "--out", str(tmp_path / "o")]) == 2
    assert "scenarios[1].orbit.phi" in capsys.readouterr().err and not (tmp_path / "o").exists()


@pytest.mark.skipif(not SHARED_RF.is_file(), reason=f"{SHARED_RF} is absent (RF's scenarios for ../shared/assets)")
def test_rf_config_of_the_shared_assets_imports_whole(tmp_path):
    cfg = json.loads(SHARED_RF.read_text())
    out = tmp_path / "rf"
    assert main(["import-scenario", str(SHARED_RF), "--out", str(out)]) == 0
    index = json.loads((out / "scenarios.json").read_text())
    assert [s["name"] for s in index["scenarios"]] == [s["name"] for s in cfg["scenarios"]]
    for s, entry in zip(index["scenarios"], cfg["scenarios"]):
        t = tomllib.loads((out / s["scene"]).read_text())
        assert s["exclude"] == entry.get("exclude", [])
        want = {**RF_DEFAULTS["dimensions"], **entry.get("dimensions", {})}
        assert (t["camera"]["width"], t["camera"]["height"]) == (want["width"], want["height"])
        assert Path(t["objects"][0]["path"]) == (SHARED_RF.parent / entry["model"]).resolve()
