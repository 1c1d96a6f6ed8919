"""The Babylon.js, PlayCanvas and Filament clients (``ext:babylon``, ``ext:playcanvas``,
``ext:filament``), for real: headless
Chromium (WebGL2 on SwiftShader) renders an exported scene with each engine's own loaders,
prefiltering and shaders. The render tests skip where node, Chromium or the client's
``node_modules`` are absent (``make setup`` installs them); on a machine set up by ``make setup``
they run. One small render per client (the orientation probe, 160 x 100), the rest is measured by
the report and gated by ``compare/budgets/clients.toml``.

- without a browser: each built-in configuration (pinned by its lockfile, the shared runner) and
  the runner's usage errors;
- the orientation probe: markers of radiance 8 in the environment (rotated 30 degrees) land in the
  reference's pixels in the background and in a mirror sphere (each engine's panorama lookup is a
  quarter turn off the export's; the client turns it back: docs/renderers.md; Filament's cube is
  built by the page in GL's cube convention), and keep their
  radiance (linear float output: no tone map, no gamma, no clamp at 1).
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import compare.renderers as renderers
from clients import config as C
from tests.test_threejs import centroids, probe_scene

ROOT = Path(__file__).resolve().parents[1]
#: client name -> (folder, {npm package: version pinned by the lockfile}, runner label)
CLIENTS = {
    "babylon": ("babylon", {"@babylonjs/core": "9.28.0", "@babylonjs/loaders": "9.28.0"}, "babylon client"),
    "playcanvas": ("playcanvas", {"playcanvas": "2.23.3", "draco3d": "1.5.7"}, "playcanvas client"),
    "filament": ("filament", {"filament": "1.53.4"}, "filament client"),
}
#: Pixels a marker's centroid may lie from the reference's: in the background (large markers) and in
#: the mirror sphere (markers of 8 to 13 pixels, their reflection magnified towards the rim).
BACKGROUND_TOLERANCE_PX = 1.0
MIRROR_TOLERANCE_PX = 2.0
#: Babylon.js's panorama-to-cube conversion reads the nearest texel at round(u W) (not floor): half a
#: texel of the probe's 256-wide panorama, which the mirror sphere's rim magnifies (measured: 2.1 and
#: 2.6 px for the green marker against two 16-spp references, whose own centroid moved by 0.5 px;
#: every other marker within 1.4).
MIRROR_TOLERANCE_PX_BABYLON = 3.0


def _skip_without(name: str, chromium: bool = True) -> None:
    folder, pins, _ = CLIENTS[name]
    if shutil.which("node") is None:
        pytest.skip("node is absent (make setup installs Debian's nodejs)")
    for pkg in pins:
        if not (ROOT / "clients" / folder / "node_modules" / pkg / "package.json").is_file():
            pytest.skip(f"{pkg} is not installed: run npm ci in clients/{folder}")
    if chromium and not any(shutil.which(c) for c in ("chromium", "chromium-browser")):
        pytest.skip("Chromium is absent (make setup installs Debian's chromium)")


@pytest.mark.parametrize("name", sorted(CLIENTS))
def test_builtin_config_is_registered_and_pinned(name):
    folder, pins, _ = CLIENTS[name]
    client = ROOT / "clients" / folder
    cfg = C.get_renderer(f"ext:{name}")
    assert cfg.builtin and cfg.output == "pfm" and cfg.lockfile_path() == client / "package-lock.json"
    assert cfg.lockfile_hash() not in (None, "missing")
    argv = C.expand(cfg, cfg.command, scenario="/s/scenario.json", out="/o/x.pfm", dir="/s", width=1, height=1)
    assert argv[0] == "node" and Path(argv[1]) == client / "render.mjs" and argv[2:4] == ["/s/scenario.json", "/o/x.pfm"]
    inputs = {Path(C.expand(cfg, [p], scenario="", out="", dir="", width=1, height=1)[0]).name for p in cfg.inputs}
    assert {"render.mjs", "page.js", "page.html", "headless.mjs", "page-common.js", "runner.mjs"} <= inputs
    lock = json.loads((client / "package-lock.json").read_text())
    deps = json.loads((client / "package.json").read_text())["dependencies"]
    for pkg, version in pins.items():
        assert lock["packages"][f"node_modules/{pkg}"]["version"] == version == deps[pkg]


@pytest.mark.parametrize("name", sorted(CLIENTS))
@pytest.mark.parametrize("args", [["only-one.json"], ["a.json", "b.pfm", "--ss", "0"], ["a.json", "b.pfm", "--timeout", "-1"]])
def test_runner_usage_errors_are_one_line_exit_1(name, args):
    _skip_without(name, chromium=False)
    folder, _, label = CLIENTS[name]
    r = subprocess.run(["node", str(ROOT / "clients" / folder / "render.mjs"), *args], capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and r.stdout == ""
    assert r.stderr.startswith(f"{label}: usage") and r.stderr.count("\n") == 1


@pytest.mark.parametrize("name", sorted(CLIENTS))
def test_version_line_names_the_pinned_packages(name):
    _skip_without(name, chromium=False)
    folder, pins, _ = CLIENTS[name]
    r = subprocess.run(["node", str(ROOT / "clients" / folder / "render.mjs"), "--version"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stdout.startswith(", ".join(f"{p} {v}" for p, v in pins.items()) + "; ")


def _centroids_in(rgb: np.ndarray, mask: np.ndarray, min_pixels: int) -> dict:
    out = centroids(np.where(mask[..., None], rgb, 0.0))
    return {c: v for c, v in out.items() if v is not None and v[2] >= min_pixels}


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(CLIENTS))
def test_orientation_probe_markers_land_in_the_same_pixels_with_linear_hdr_radiance(name, tmp_cache, tmp_path):
    _skip_without(name)
    scene = probe_scene(tmp_path)
    img = renderers.render_under_test(scene, renderers.RendererSpec.parse(f"ext:{name}"))
    ref = renderers.render_reference(scene, spp=16, use_cache=False)
    assert img.meta["version"].startswith(", ".join(f"{p} {v}" for p, v in CLIENTS[name][1].items()))
    ids = img.channels["object"]
    mirror_tol = MIRROR_TOLERANCE_PX_BABYLON if name == "babylon" else MIRROR_TOLERANCE_PX
    for mask, tol, min_px, at_least in ((ids < 0, BACKGROUND_TOLERANCE_PX, 50, 2), (ids >= 0, mirror_tol, 4, 4)):
        a, b = _centroids_in(img.rgb, mask, min_px), _centroids_in(ref.rgb, mask, min_px)
        assert set(a) == set(b) and len(b) >= at_least, (a, b)
        for c in b:
            assert abs(a[c][0] - b[c][0]) < tol and abs(a[c][1] - b[c][1]) < tol, (c, a[c], b[c])
    # Linear float output: the blue marker's core in the background is radiance 8, the 0.05 stays 0.05.
    bg = ids < 0
    blue = (img.rgb[..., 2] > 1.0) & (img.rgb[..., 0] < 0.5) & (img.rgb[..., 1] < 0.5) & bg
    assert blue.sum() > 100 and np.median(img.rgb[blue, 2]) == pytest.approx(8.0, rel=0.03)
    dim = np.all(img.rgb < 0.2, axis=-1) & bg
    assert np.median(img.rgb[dim]) == pytest.approx(0.05, rel=0.05)


#: The shared Draco-compressed asset (KHR_draco_mesh_compression; RF's BoxTextured).
DRACO_ASSET = ROOT.parent / "shared" / "assets" / "BoxTextured.glb"
#: How far an engine's mean radiance over the box may lie from the `default` preset's (per channel;
#: measured 0.003 to 0.02 in a white furnace; a box not drawn reads the background, 1.0).
DRACO_MEAN_TOLERANCE = 0.05


@pytest.mark.slow
@pytest.mark.parametrize("name", ["babylon", "playcanvas"])
@pytest.mark.skipif(not DRACO_ASSET.is_file(), reason=f"{DRACO_ASSET} is absent (the shared assets)")
def test_draco_compressed_asset_renders_offline(name, tmp_cache, tmp_path):
    # issue 38: Babylon.js fetched its Draco decoder from its CDN (no network: an error row) and
    # PlayCanvas had no decoder wasm (it fetched its 404 page as WebAssembly); both are now served
    # from the clients' own npm packages
    _skip_without(name)
    from pbrcheck.scene import scene_from_dict
    from pbrcheck.untrusted import allowed_dirs

    table = {"camera": {"origin": [1.2, 1.0, 2.0], "target": [0.0, 0.0, 0.0], "fov": 40, "width": 32, "height": 32},
             "environment": {"type": "constant", "radiance": [1.0, 1.0, 1.0]},
             "objects": [{"type": "gltf", "path": str(DRACO_ASSET)}]}
    with allowed_dirs(DRACO_ASSET.parent):
        scene = scene_from_dict(table, file=str(tmp_path / "s.toml"), base_dir=tmp_path, contained=True)
        img = renderers.render_under_test(scene, renderers.RendererSpec.parse(f"ext:{name}"))
        ref = renderers.render_under_test(scene, renderers.RendererSpec.parse("default"))
    box = img.channels["object"] >= 0
    assert box.sum() > 200   # the box covers ~half the image
    rgb, want = (np.stack([x.channels[c] for c in "RGB"], -1)[box].mean(axis=0) for x in (img, ref))
    assert want.max() < 0.7   # the textured box is darker than the white background
    np.testing.assert_allclose(rgb, want, atol=DRACO_MEAN_TOLERANCE)
