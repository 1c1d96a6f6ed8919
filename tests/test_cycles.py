"""The Blender Cycles client (``ext:cycles``, clients/cycles/render.py), for real: Blender's glTF
importer and CPU Cycles from the ``bpy`` wheel in ``clients/cycles/.venv`` (``make client-packages``
runs tools/ensure-cycles.sh). The render tests skip where that environment is absent.

- without bpy: the built-in configuration (pinned by requirements.txt) and the usage errors;
- the orientation probe (``probe_scene`` of tests/test_threejs.py): markers of radiance 8 land in the
  reference's pixels in the background and in a mirror sphere, with their radiance (linear float
  output: Standard view transform not applied to the EXR, no clamp);
- exposure: a 10 cd point light on a Lambertian sphere gives the reference's radiance (the
  importer's COMPAT light mode: 1 cd = 1 W/sr; its default SPEC mode would be 683x darker);
- where Cycles' Principled BSDF and glTF's BRDF agree (metallic 0 and 1, smooth enough that
  Cycles' multiple-scattering GGX adds little), a sphere's mean radiance matches the reference.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import compare.renderers as renderers
from clients import config as C
from pbrcheck.scene import scene_from_dict
from tests.test_threejs import assert_one_candela_is_one_watt_per_steradian, centroids, probe_scene

ROOT = Path(__file__).resolve().parents[1]
CLIENT = ROOT / "clients" / "cycles"
VENV_PY = CLIENT / ".venv" / "bin" / "python"
#: The bpy release requirements.txt pins (the version line starts with it).
BPY_VERSION = "4.5.4"
#: Marker centroids against the reference's, in pixels: background (large markers) and mirror sphere
#: (8 to 13 px markers). Measured 0.07 px and 0.8 px at most (16 spp both).
BACKGROUND_TOLERANCE_PX = 1.0
MIRROR_TOLERANCE_PX = 1.5
#: A sphere's mean radiance against the reference's where the models agree (constant environment,
#: roughness 0.3). Measured (64 spp both, 48 x 32): metallic 0: Cycles/reference 0.966 / 0.961 / 0.968
#: (R / G / B; Cycles' Principled dielectric scales its diffuse by the specular layer's albedo and uses
#: the exact dielectric Fresnel, glTF's by 1 - F Schlick); metallic 1: 1.013 / 0.989 / 0.977.
SPHERE_MEAN_REL_TOLERANCE = 0.05


def _skip_without_bpy() -> None:
    if not VENV_PY.is_file():
        pytest.skip("clients/cycles/.venv is absent: make client-packages (tools/ensure-cycles.sh) installs bpy")
    if subprocess.run([str(VENV_PY), "-c", "import bpy"], capture_output=True).returncode != 0:
        pytest.skip("bpy does not import in clients/cycles/.venv: rerun tools/ensure-cycles.sh")


def test_builtin_config_is_registered_and_pinned():
    cfg = C.get_renderer("ext:cycles")
    assert cfg.builtin and cfg.output == "exr" and cfg.lockfile_path() == CLIENT / "requirements.txt"
    assert cfg.lockfile_hash() not in (None, "missing")
    argv = C.expand(cfg, cfg.command, scenario="/s/scenario.json", out="/o/x.exr", dir="/s", width=1, height=1)
    assert Path(argv[0]) == VENV_PY and Path(argv[1]) == CLIENT / "render.py"
    assert argv[2:4] == ["/s/scenario.json", "/o/x.exr"] and argv[argv.index("--spp") + 1] == "64"
    assert (CLIENT / "requirements.txt").read_text().split() == [f"bpy=={BPY_VERSION}"]


@pytest.mark.parametrize("args", [["only-one.json"], ["a.json", "b.exr", "--spp", "0"], ["a.json", "b.exr", "--threads", "-1"]])
def test_usage_errors_exit_2_before_blender_starts(args):
    # argparse rejects the arguments before bpy is imported: any Python runs this.
    r = subprocess.run([sys.executable, str(CLIENT / "render.py"), *args], capture_output=True, text=True)
    assert r.returncode == 2 and "usage: render.py" in r.stderr


def test_a_missing_scenario_is_one_line_exit_1(tmp_path):
    r = subprocess.run([sys.executable, str(CLIENT / "render.py"), str(tmp_path / "none.json"), str(tmp_path / "o.exr")],
                       capture_output=True, text=True)
    assert r.returncode == 1 and r.stderr.count("\n") == 1 and "cycles client: FileNotFoundError" in r.stderr
    assert not (tmp_path / "o.exr").exists()


def _marker_offsets(img, ref, region: np.ndarray, min_pixels: int) -> tuple[set, set, float]:
    """The markers (colours) seen in ``region`` of each image, with at least ``min_pixels`` pixels, and
    the largest distance in pixels (row or column) between the two images' centroids of one marker."""
    seen = []
    for rgb in (img.rgb, ref.rgb):
        found = centroids(np.where(region[..., None], rgb, 0.0))
        seen.append({c: v for c, v in found.items() if v is not None and v[2] >= min_pixels})
    a, b = seen
    both = set(a) & set(b)
    worst = max((max(abs(a[c][0] - b[c][0]), abs(a[c][1] - b[c][1])) for c in both), default=np.inf)
    return set(a), set(b), float(worst)


@pytest.mark.slow
def test_orientation_probe_and_linear_radiance(tmp_cache, tmp_path):
    _skip_without_bpy()
    scene = probe_scene(tmp_path)
    img = renderers.render_under_test(scene, renderers.RendererSpec.parse("ext:cycles"))
    ref = renderers.render_reference(scene, spp=16, use_cache=False)
    assert img.meta["version"].startswith(f"bpy {BPY_VERSION}")
    ids = img.channels["object"]
    cycles_bg, ref_bg, off_bg = _marker_offsets(img, ref, ids < 0, 50)
    cycles_mirror, ref_mirror, off_mirror = _marker_offsets(img, ref, ids >= 0, 4)
    assert cycles_bg == ref_bg and len(ref_bg) == 2 and off_bg < BACKGROUND_TOLERANCE_PX
    assert cycles_mirror == ref_mirror and len(ref_mirror) == 5 and off_mirror < MIRROR_TOLERANCE_PX
    bg = ids < 0
    blue = (img.rgb[..., 2] > 1.0) & (img.rgb[..., 0] < 0.5) & (img.rgb[..., 1] < 0.5) & bg
    assert blue.sum() > 100 and np.median(img.rgb[blue, 2]) == pytest.approx(8.0, rel=0.01)
    dim = np.all(img.rgb < 0.2, axis=-1) & bg
    assert np.median(img.rgb[dim]) == pytest.approx(0.05, rel=0.01)


@pytest.mark.slow
def test_point_light_one_candela_is_one_watt_per_steradian(tmp_cache):
    _skip_without_bpy()
    assert_one_candela_is_one_watt_per_steradian("ext:cycles")


@pytest.mark.slow
def test_spheres_match_where_the_models_agree(tmp_cache, tmp_path):
    """Metallic 0 and 1 at roughness 0.3 under a constant environment of radiance 1: each sphere's
    mean radiance within SPHERE_MEAN_REL_TOLERANCE of the reference's."""
    _skip_without_bpy()
    spheres = [{"type": "sphere", "center": [x, 0.0, -4.0], "radius": 0.9,
                "material": {"base_color": [0.9, 0.6, 0.3], "metallic": m, "roughness": 0.3}}
               for x, m in ((-1.0, 0.0), (1.0, 1.0))]
    scene = scene_from_dict({
        "name": "two", "camera": {"origin": [0, 0, 0.0], "target": [0, 0, -1], "fov": 60.0, "width": 48, "height": 32},
        "environment": {"type": "constant", "radiance": [1.0, 1.0, 1.0]},
        "objects": spheres}, file=str(tmp_path / "two.toml"), base_dir=tmp_path)
    img = renderers.render_under_test(scene, renderers.RendererSpec.parse("ext:cycles"))
    ref = renderers.render_reference(scene, spp=64, use_cache=False)
    ids = img.channels["object"]
    for k in (0, 1):
        m = ids == k
        a, b = img.rgb[m].mean(axis=0), ref.rgb[m].mean(axis=0)
        assert np.allclose(a, b, rtol=SPHERE_MEAN_REL_TOLERANCE), (k, a, b)
