"""The web engines render the lobe extensions pbrcheck exports (issue 36 item 4).

Each client loads the exported glTF with its engine's own loader, which enables the
``KHR_materials_*`` lobe extensions by default (three.js's GLTFLoader registers them, Babylon.js's
``@babylonjs/loaders/glTF`` import registers its extensions, PlayCanvas's container parser and
Filament's gltfio read them; docs/renderers.md section 11). Here: a one-sphere scene with
``clearcoat = 1`` exported with the extension kept (``keep_unmodelled``: until both of pbrcheck's
renderers model a lobe the engines' default export removes it) renders differently from the same
scene with ``clearcoat = 0``: the engine shades the coat. Slow (a browser per render); skipped
where node, Chromium or the client's ``node_modules`` are absent.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from pbrcheck.export import export_scene
from pbrcheck.hdrimage import read_pfm
from pbrcheck.scene import scene_from_dict

ROOT = Path(__file__).resolve().parents[1]
#: engine -> (client folder, the npm package whose presence means it is installed)
ENGINES = {"threejs": ("threejs", "three"), "sample-viewer": ("gltf-sample-viewer", "@khronosgroup/gltf-viewer"),
           "filament": ("filament", "filament"), "babylon": ("babylon", "@babylonjs/loaders"),
           "playcanvas": ("playcanvas", "playcanvas")}
#: The suite runs the two fastest clients (measured, both renders: Filament 10 s, three.js 16 s;
#: the Sample Viewer 16 s, PlayCanvas 22 s, Babylon.js 62 s); the others on request:
#: ``PBRCHECK_LOBE_CLIENTS_ALL=1`` runs all five (docs/renderers.md section 11 has what each rendered).
IN_SUITE = ("threejs", "filament")
ALL_ENGINES_ENV = "PBRCHECK_LOBE_CLIENTS_ALL"
#: Least relative change of the sphere centre's mean radiance a clearcoat of 1 makes under the sky
#: (the coat adds the sky's sharp reflection, weight 0.04 head-on to 1 at grazing, over a rough red
#: base). Measured: three.js +6.2 %, Sample Viewer +5.2 %, Filament +6.7 %, Babylon.js +6.8 %,
#: PlayCanvas +1.4 % (the smallest: its coat's image-based reflection): 1 % separates a coat from
#: none with every engine.
MIN_COAT_CHANGE = 0.01
SIZE = 32


def _scene(clearcoat: float):
    return scene_from_dict({
        "name": f"coat{clearcoat}", "camera": {"origin": [0, 0, 4], "fov": 40, "width": SIZE, "height": SIZE},
        "environment": {"type": "sky", "sun_direction": [0.4, 0.6, 0.7], "sun_angular_diameter": 8.0,
                        "sun_radiance": [60, 55, 48], "sky_radiance": [0.25, 0.4, 0.8],
                        "horizon_radiance": [0.9, 0.85, 0.8], "ground_radiance": [0.25, 0.2, 0.15],
                        "resolution": [128, 64]},
        "objects": [{"type": "sphere", "center": [0, 0, 0], "radius": 1.0,
                     "material": {"base_color": [0.8, 0.1, 0.1], "roughness": 0.6, "clearcoat": clearcoat,
                                  "clearcoat_roughness": 0.0}}]})


def _render(engine: str, scene, folder: Path) -> np.ndarray:
    exp = export_scene(scene, folder, output="pfm", keep_unmodelled=True)
    client = ROOT / "clients" / ENGINES[engine][0]
    out = folder / "out.pfm"
    r = subprocess.run(["node", str(client / "render.mjs"), str(exp.out_dir / "scenario.json"), str(out), "--ss", "1"],
                       capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-2000:]
    return read_pfm(out)


@pytest.mark.slow
@pytest.mark.parametrize("engine", list(ENGINES) if os.environ.get(ALL_ENGINES_ENV) == "1" else list(IN_SUITE))
def test_an_engine_renders_the_clearcoat_it_is_given(engine, tmp_path, tmp_cache):
    folder, pkg = ENGINES[engine]
    if shutil.which("node") is None:
        pytest.skip("node is absent (make setup installs Debian's nodejs)")
    if not (ROOT / "clients" / folder / "node_modules" / pkg / "package.json").is_file():
        pytest.skip(f"{pkg} is not installed: run npm ci in clients/{folder}")
    if not any(shutil.which(c) for c in ("chromium", "chromium-browser")):
        pytest.skip("Chromium is absent (make setup installs Debian's chromium)")
    coat = _render(engine, _scene(1.0), tmp_path / "coat")
    doc = json.loads((tmp_path / "coat" / "scene.gltf").read_text())
    assert doc["materials"][0]["extensions"]["KHR_materials_clearcoat"]["clearcoatFactor"] == 1.0
    plain = _render(engine, _scene(0.0), tmp_path / "plain")
    assert "KHR_materials_clearcoat" not in json.loads((tmp_path / "plain" / "scene.gltf").read_text()).get(
        "extensionsUsed", [])
    yy, xx = np.mgrid[0:SIZE, 0:SIZE]
    disc = (xx - SIZE / 2 + 0.5) ** 2 + (yy - SIZE / 2 + 0.5) ** 2 < (0.3 * SIZE) ** 2   # well inside the sphere
    a, b = float(coat[disc].mean()), float(plain[disc].mean())
    assert np.isfinite(a) and np.isfinite(b) and b > 0
    assert abs(a - b) / b > MIN_COAT_CHANGE, (engine, a, b)
    # the background (the sky) is the same in both: the difference is the coat's
    corner = (xx < 3) & (yy < 3)
    assert np.allclose(coat[corner], plain[corner], rtol=1e-3, atol=1e-5)
