"""The Khronos glTF Sample Viewer client (``ext:sample-viewer``), for real: headless Chromium
(WebGL2 on SwiftShader) renders exported scenes with ``@khronosgroup/gltf-viewer`` 1.1.0. The
render tests skip where node, Chromium or ``clients/gltf-sample-viewer/node_modules`` are absent
(``make setup`` installs them); on a machine set up by ``make setup`` they run.

- the white furnace: the Sample Viewer's multiple-scattering term keeps a white metal at 1.0 at
  every roughness, while the single-scattering reference loses energy as roughness grows;
- the orientation probe: coloured markers of radiance 8 in the environment (rotated 30 degrees)
  land in the same pixels as in the reference in a mirror sphere's reflection (environmentRotation
  0 is the exported orientation), and where its skybox projection puts them in the background;
  they keep their radiance (linear float output: no tone map, no clamp at 1, no gamma);
- a point, a spot and a directional light on a diffuse sphere, each on pixels of its own: 1 cd =
  1 W/sr, 1 lux = 1 W/m^2, and the spot's penumbra is the specification's squared ramp (as the
  reference's), not three.js's smoothstep;
- ``diagnose`` on its spheres_ci image names multiple scattering (a model difference), and every
  convention hypothesis makes the error worse;
- without a browser: the built-in configuration, the runner's usage errors, and the engine
  constants the ``--ibl`` profiles replace (each present exactly once in the pinned package).
"""

from __future__ import annotations

import dataclasses
import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import compare.renderers as renderers
from clients import config as C
from pbrcheck.camera import primary_rays
from pbrcheck.environment import load_environment
from pbrcheck.exr import read_exr
from pbrcheck.scene import load_scene
from tests.test_threejs import centroids, probe_scene

ROOT = Path(__file__).resolve().parents[1]
CLIENT = ROOT / "clients" / "gltf-sample-viewer"
MODULE = CLIENT / "node_modules" / "@khronosgroup" / "gltf-viewer" / "dist" / "gltf-viewer.module.js"
RUNNER = CLIENT / "render.mjs"
#: The version the lockfile pins (and the version line must report).
PINNED = "1.1.0"


def _skip_without(node: bool = True, package: bool = True, chromium: bool = True) -> None:
    if node and shutil.which("node") is None:
        pytest.skip("node is absent (make setup installs Debian's nodejs)")
    if package and not MODULE.is_file():
        pytest.skip(f"@khronosgroup/gltf-viewer is not installed: run npm ci in {CLIENT}")
    if chromium and not any(shutil.which(c) for c in ("chromium", "chromium-browser")):
        pytest.skip("Chromium is absent (make setup installs Debian's chromium)")


@pytest.fixture
def sample_viewer(tmp_cache):
    _skip_without()


# ------------------------------------------------------------------------------------------------
# Without a browser
# ------------------------------------------------------------------------------------------------

def test_builtin_config_is_registered_and_pinned():
    cfg = C.get_renderer("ext:sample-viewer")
    assert cfg.builtin and cfg.output == "pfm" and cfg.lockfile_path() == CLIENT / "package-lock.json"
    assert cfg.lockfile_hash() not in (None, "missing")
    argv = C.expand(cfg, cfg.command, scenario="/s/scenario.json", out="/o/x.pfm", dir="/s", width=1, height=1)
    assert argv[0] == "node" and Path(argv[1]) == RUNNER and argv[2:4] == ["/s/scenario.json", "/o/x.pfm"]
    assert argv[argv.index("--ibl") + 1] == "fast"
    lock = json.loads((CLIENT / "package-lock.json").read_text())
    assert lock["packages"]["node_modules/@khronosgroup/gltf-viewer"]["version"] == PINNED
    assert json.loads((CLIENT / "package.json").read_text())["dependencies"]["@khronosgroup/gltf-viewer"] == PINNED


@pytest.mark.parametrize("args, msg", [
    (["only-one.json"], "usage"),
    (["a.json", "b.pfm", "--ibl", "medium"], "usage"),
    (["a.json", "b.pfm", "--ss", "0"], "usage"),
])
def test_runner_usage_errors_are_one_line_exit_1(args, msg):
    _skip_without(package=False, chromium=False)
    r = subprocess.run(["node", str(RUNNER), *args], capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and r.stdout == ""
    assert r.stderr.startswith("gltf-sample-viewer client: ") and msg in r.stderr and r.stderr.count("\n") == 1


def test_ibl_profile_constants_are_found_once_in_the_pinned_engine():
    """Each constant the runner replaces is in the installed module exactly once with the package's
    value (the runner refuses to run otherwise: a new version must be looked at again)."""
    _skip_without(node=False, chromium=False)
    full = re.search(r"full: \{([^}]*)\}", RUNNER.read_text()).group(1)
    consts = dict((k, v) for k, v in re.findall(r"(\w+): (\d+)", full))
    assert set(consts) == {"textureSize", "ggxSampleCount", "lambertianSampleCount", "sheenSamplCount", "lutResolution"}
    text = MODULE.read_text()
    for k, v in consts.items():
        assert text.count(f"this.{k} = {v};") == 1, k


def test_version_line_names_the_pinned_package():
    _skip_without(chromium=False)
    r = subprocess.run(["node", str(RUNNER), "--version"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stdout.startswith(f"@khronosgroup/gltf-viewer {PINNED}; ")


# ------------------------------------------------------------------------------------------------
# Real renders (headless Chromium)
# ------------------------------------------------------------------------------------------------

@pytest.mark.slow
def test_white_furnace_sample_viewer_keeps_energy_reference_loses_it(sample_viewer):
    scene = load_scene(str(ROOT / "compare" / "budgets" / "furnace_ci.toml"))
    img = renderers.render_under_test(scene, renderers.RendererSpec.parse("ext:sample-viewer"))
    ref = read_exr(ROOT / "compare" / "budgets" / "refs" / "furnace_ci.exr")
    assert img.meta["version"].startswith(f"@khronosgroup/gltf-viewer {PINNED}")
    stdout = json.loads(img.meta["renderer_stdout"])
    assert stdout["ibl"]["profile"] == "fast" and stdout["ibl_format"] == "FLOAT"
    ids = img.channels["object"]
    viewer, mitsuba = [], []
    for k in range(5):                                   # roughness 0, 0.25, 0.5, 0.75, 1
        m = (ids == k) & (ref.channels["coverage"] >= 0.999)
        viewer.append(float(img.rgb[m].mean()))
        mitsuba.append(float(ref.rgb[m].mean()))
    assert np.allclose(viewer, 1.0, atol=0.01), viewer  # multiple scattering compensated
    assert mitsuba[0] == pytest.approx(1.0, abs=0.01)
    assert mitsuba[4] < 0.9 and viewer[4] - mitsuba[4] > 0.1, (viewer, mitsuba)


#: The Sample Viewer's skybox vertex shader replaces its view-projection matrix's last column by
#: (0, 0, 0, 0.1): gl_Position.w = -z_view + 0.1 for the unit cube around the camera. Where the
#: camera looks down a cube axis (z_view = -1 on that face) the background is the environment seen
#: with tan(fov / 2) this much larger (a 2-degree shift at 35 degrees off-axis in this probe); the
#: metrics exclude background pixels, so only the picture shows it (docs/renderers.md).
SKYBOX_TAN_SCALE = 1.1


def _centroids_in(rgb: np.ndarray, mask: np.ndarray, min_pixels: int = 4) -> dict:
    out = centroids(np.where(mask[..., None], rgb, 0.0))
    return {c: v for c, v in out.items() if v is not None and v[2] >= min_pixels}


@pytest.mark.slow
def test_orientation_probe_markers_land_in_the_same_pixels_with_linear_hdr_radiance(sample_viewer, tmp_path):
    scene = probe_scene(tmp_path)
    viewer = renderers.render_under_test(scene, renderers.RendererSpec.parse("ext:sample-viewer"))
    # 64 spp: at 16 a marker's thresholded centroid moved up to 1.7 px with the sampler's noise alone
    # (measured: the green marker at y 70.8 with qmc, 70.3 independent, 70.0 / 69.1 at 64 spp).
    ref = renderers.render_reference(scene, spp=64, use_cache=False)
    ids = viewer.channels["object"]

    # In the mirror sphere (the image-based lighting): every marker the reference shows, in the
    # same pixels (the yellow and cyan ones are behind the camera).
    a, b = _centroids_in(viewer.rgb, ids >= 0), _centroids_in(ref.rgb, ids >= 0)
    assert set(a) == set(b) and len(b) >= 4, (a, b)
    for c in b:
        assert abs(a[c][0] - b[c][0]) < 1.5 and abs(a[c][1] - b[c][1]) < 1.5, (c, a[c], b[c])

    # In the background: the environment through the skybox's projection (SKYBOX_TAN_SCALE).
    cam = scene.camera
    wide = dataclasses.replace(cam, fov=2 * np.degrees(np.arctan(SKYBOX_TAN_SCALE * np.tan(np.radians(cam.fov) / 2))))
    expect = load_environment(scene).radiance(primary_rays(wide)[1])
    plain = load_environment(scene).radiance(primary_rays(cam)[1])
    bg = ids < 0
    a, e, p = (_centroids_in(x, bg, 50) for x in (viewer.rgb, expect, plain))
    assert set(a) == set(e) and len(e) >= 2, (a, e)
    for c in e:
        assert abs(a[c][0] - e[c][0]) < 1.0 and abs(a[c][1] - e[c][1]) < 1.0, (c, a[c], e[c])
    assert max(abs(p[c][1] - a[c][1]) for c in e) > 3.0   # the skybox projection is really there

    # Linear float output: the blue marker's core in the background is radiance 8 (an 8-bit,
    # tone-mapped or gamma-encoded canvas could not hold it), and the dim 0.05 stays 0.05.
    blue = (viewer.rgb[..., 2] > 1.0) & (viewer.rgb[..., 0] < 0.5) & (viewer.rgb[..., 1] < 0.5) & bg
    assert blue.sum() > 100 and np.median(viewer.rgb[blue, 2]) == pytest.approx(8.0, rel=0.05)
    dim = np.all(viewer.rgb < 0.2, axis=-1) & bg
    assert np.median(viewer.rgb[dim]) == pytest.approx(0.05, rel=0.05)


#: The engines' model tolerance under punctual lights: a crop's mean radiance against the
#: reference's (the point light's 10 %, tests/test_threejs.py).
LIGHT_RTOL = 0.1
#: Lights of the one Sample Viewer light render: a spot from the camera whose penumbra (inner 0.05,
#: outer 0.15 rad) lies on the sphere's front, a directional light from -X (the left limb), a point
#: light at +X (the right limb); each reaches pixels the others do not.
LIT_SPOT = {"type": "spot", "position": [0.0, 0.0, 5.0], "direction": [0.0, 0.0, -1.0],
            "intensity": [10.0, 10.0, 10.0], "inner_cone_angle": 0.05, "outer_cone_angle": 0.15}
LIT_LIGHTS = [LIT_SPOT, {"type": "directional", "direction": [1.0, 0.0, 0.0], "intensity": [2.0, 2.0, 2.0]},
              {"type": "point", "position": [5.0, 0.0, 0.0], "intensity": [10.0, 10.0, 10.0]}]
LAMBERT_ALBEDO = 0.8
#: The reference's crop means against Lambert at the pixel centres: the pixel footprint's
#: integration of a curved radiance (16 spp), no model difference.
ANALYTIC_RTOL = 0.05


def _lambert_at_pixel_centres(scene, falloff):
    """Per light, the radiance of the Lambertian unit sphere at each pixel centre's hit ((H, W) per
    light, NaN off the sphere), the spot's penumbra by ``falloff(cd, cos_outer, cos_inner)``, and
    n.v at the hits."""
    o, d = primary_rays(scene.camera)
    b = d @ o
    disc = b * b - (o @ o - 1.0)
    t = -b - np.sqrt(np.where(disc > 0, disc, np.nan))
    p = o + t[..., None] * d                                    # the hit = its normal
    out = []
    for L in scene.lights:
        if L.type == "directional":
            l, e = -np.asarray(L.direction), L.intensity[0]
            out.append(LAMBERT_ALBEDO / np.pi * e * np.clip(p @ l, 0, None))
            continue
        v = np.asarray(L.position) - p
        dist = np.linalg.norm(v, axis=-1)
        l = v / dist[..., None]
        a = 1.0
        if L.type == "spot":
            a = falloff(-(l @ np.asarray(L.direction)), np.cos(L.outer_cone_angle), np.cos(L.inner_cone_angle))
        out.append(LAMBERT_ALBEDO / np.pi * L.intensity[0] * a * np.clip(np.sum(p * l, -1), 0, None) / dist ** 2)
    return out, -np.sum(p * d, -1)


@pytest.mark.slow
def test_point_spot_and_directional_lights_match_the_reference(sample_viewer):
    """One exported scene, three lights, each alone on its pixels (n.v > 0.5): the Sample Viewer's
    point light (1 cd = 1 W/sr), directional light (1 lux = 1 W/m^2) and spot penumbra agree with
    the reference within :data:`LIGHT_RTOL`. Its penumbra is the specification's squared ramp in
    cos (``getSpotAttenuation``), as the reference's: on the same pixels three.js's smoothstep
    would be off by more than the tolerance."""
    from pbrcheck.lights import spot_attenuation
    from pbrcheck.scene import scene_from_dict

    scene = scene_from_dict({
        "name": "three-lights", "camera": {"origin": [0, 0, 5.0], "fov": 30.0, "width": 48, "height": 48},
        "environment": {"type": "none"}, "lights": LIT_LIGHTS,
        "objects": [{"type": "sphere", "radius": 1.0, "material": {
            "base_color": [LAMBERT_ALBEDO] * 3, "metallic": 0.0, "roughness": 1.0}}]})
    engine = renderers.render_under_test(scene, renderers.RendererSpec.parse("ext:sample-viewer"))
    ref = renderers.render_reference(scene, spp=16, use_cache=False)
    (spot, sun, lamp), nv = _lambert_at_pixel_centres(scene, spot_attenuation)

    def smooth(cd, lo, hi):
        x = np.clip((cd - lo) / (hi - lo), 0.0, 1.0)
        return x * x * (3 - 2 * x)

    (smooth_spot, _, _), _ = _lambert_at_pixel_centres(scene, smooth)
    alone = [(f > 0) & np.all([g == 0 for g in others], axis=0) & (nv > 0.5)
             for f, others in ((spot, (sun, lamp)), (sun, (spot, lamp)), (lamp, (spot, sun)))]
    full = spot >= LAMBERT_ALBEDO / np.pi * 10.0 / 16.0 * 0.9 * nv
    penumbra = alone[0] & ~full & (spot > 0.01)
    for name, m in (("spot inside", alone[0] & full), ("spot penumbra", penumbra), ("directional", alone[1]),
                    ("point", alone[2])):
        assert m.sum() >= 8, name
        r = float(ref.rgb[m].mean())
        assert float(engine.rgb[m].mean()) == pytest.approx(r, rel=LIGHT_RTOL), name
        # the reference itself: Lambert with 1 cd = 1 W/sr and 1 lux = 1 W/m^2 at the pixel centres
        want = {"spot inside": spot, "spot penumbra": spot, "directional": sun, "point": lamp}[name]
        assert r == pytest.approx(float(want[m].mean()), rel=ANALYTIC_RTOL), name
    assert abs(smooth_spot[penumbra].mean() / spot[penumbra].mean() - 1) > LIGHT_RTOL


@pytest.mark.slow
def test_diagnose_names_a_model_difference_not_a_convention(sample_viewer):
    """``pbrcheck diagnose`` on the Sample Viewer's spheres_ci image: every convention hypothesis
    (flips, sRGB, R/B, environment turns, roughness, diffuse and light units) makes the error worse
    or leaves it; undoing multiple scattering removes most of it (docs/renderers.md)."""
    from compare.research import diagnose as dg

    scene = load_scene(str(ROOT / "compare" / "budgets" / "spheres_ci.toml"))
    ref = read_exr(ROOT / "compare" / "budgets" / "refs" / "spheres_ci.exr")
    img = renderers.render_under_test(scene, renderers.RendererSpec.parse("ext:sample-viewer"))
    d = dg.diagnose(ref, img, scene, spp=32)
    # the Sample Viewer mixes two BRDFs (glTF's metallic blend) and compensates multiple scattering: both
    # are model differences of the engine, each explaining about half the error here
    assert d.likely in ("multiple_scattering", "metallic_blend") and "a model difference" in d.line, dg.table_markdown(d)
    rows = {r.hypothesis: r for r in d.rows if r.skipped is None}
    assert rows["multiple_scattering"].reduction > 0.4 and rows["metallic_blend"].reduction > 0.4, dg.table_markdown(d)
    for name in ("flip_vertical", "flip_horizontal", "srgb_as_linear", "linear_as_srgb", "swap_rb",
                 "env_rotate_90", "env_rotate_180", "env_rotate_270", "env_mirror_u", "roughness_as_alpha"):
        assert rows[name].reduction < 0.0, (name, dg.table_markdown(d))


@pytest.mark.slow
def test_draco_asset_is_decoded_and_drawn(sample_viewer):
    """A Draco-compressed asset (``../shared/assets/BoxTextured.glb``) through the Sample Viewer:
    its meshes decoded by the Draco decoder the three.js package vendors (clients/gltf-sample-viewer
    page.js) and drawn where the reference sees the box: on the box's pixels the image is much
    closer to the reference than the environment behind the box is."""
    from pbrcheck.scene import asset_scene
    from reference.render import render_reference

    box = ROOT.parent / "shared" / "assets" / "BoxTextured.glb"
    env = ROOT.parent / "shared" / "envmaps" / "royal_esplanade_1k.hdr"
    if not box.is_file() or not env.is_file():
        pytest.skip("../shared/assets/BoxTextured.glb or ../shared/envmaps/royal_esplanade_1k.hdr absent")
    if not (ROOT / "clients" / "threejs" / "node_modules" / "three").is_dir():
        pytest.skip("the three.js client (its vendored Draco decoder) is not installed: npm ci in clients/threejs")
    scene = asset_scene(box, size=(32, 24), env=str(env))
    img = renderers.render_under_test(scene, renderers.RendererSpec.parse("ext:sample-viewer"))
    ref = render_reference(scene, spp=16, progress=False)
    bg = render_reference(dataclasses.replace(scene, objects=(), assets=()), spp=2, progress=False)
    box_px = ref.channels["coverage"] == 1
    assert box_px.mean() > 0.2
    err = lambda a: float(np.abs(a.rgb - ref.rgb)[box_px].mean())
    assert err(img) < 0.5 * err(bg), (err(img), err(bg))
