"""Khronos glTF Render Fidelity / model-viewer scenarios as pbrcheck scenes (``pbrcheck import-scenario``).

A scenario (render-fidelity-tools' ``config.json`` entries, the ``scenario`` part of the
``{"scenario", "outputFile"}`` file those tools hand each renderer, and the ``model_viewer`` part of
``pbrcheck export``'s ``scenario.json``) names ``model`` (a .gltf/.glb, relative to the scenario
file), ``lighting`` (an .hdr/.exr, relative; absent or ``"neutral"``: pbrcheck's neutral constant
environment), ``dimensions`` ``{width, height}``, ``target`` ``{x, y, z}``, ``orbit`` ``{theta, phi,
radius}`` (degrees, degrees, scene units: ``theta`` the azimuth about +Y from +Z, ``phi`` the polar
angle from +Y), ``verticalFoV`` (degrees) and ``renderSkybox``. Absent fields take model-viewer's
defaults: the target is the bounding box's centre, the orbit and field of view are
:func:`pbrcheck.gltf_scene.framing_camera`'s. ``renderSkybox = false``: the background shows the
environment anyway (pbrcheck's images always see it; its metrics exclude background pixels); the
scene's description says so.

API: :func:`scenario_scene` (a scenario file -> the scene TOML's table), :func:`import_scenario`
(-> the TOML text), :class:`ScenarioError`.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from .errors import SceneError
from .gltf_objects import DEFAULT_ASSET_SIZE, FRAMING_FOV_DEG, is_asset_path
from .gltf_scene import framing_camera
from .scene import dump_toml, scene_from_dict

KEYS = ("name", "model", "lighting", "dimensions", "target", "orbit", "verticalFoV", "renderSkybox")


class ScenarioError(SceneError):
    """A scenario that cannot become a scene: names the file and the field."""


def _num(v, file, fieldname):
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ScenarioError(file, fieldname, "a finite number", v)
    return float(v)


def scenario_scene(path: str | Path) -> dict:
    """The scene table (``pbrcheck.scene`` TOML fields, paths absolute) of scenario file ``path``."""
    p = Path(path)
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except OSError as e:
        raise ScenarioError(str(p), None, "a readable file", message=f"{p}: cannot read: {e.strerror}") from None
    except json.JSONDecodeError as e:
        raise ScenarioError(str(p), None, "JSON", message=f"{p}: invalid JSON: {e}") from None
    if isinstance(data, dict) and "model_viewer" in data and "model" not in data:  # pbrcheck's own scenario.json
        data = data["model_viewer"]
    elif isinstance(data, dict) and "scenario" in data and "model" not in data:
        # the file render-fidelity-tools hands each renderer: {"scenario": {...}, "outputFile": PNG}
        data = data["scenario"]
    if not isinstance(data, dict):
        raise ScenarioError(str(p), None, "a JSON object", type(data).__name__)
    f = str(p)
    for k in data:
        if k not in KEYS:
            raise ScenarioError(f, k, "one of the keys " + ", ".join(KEYS), f"unknown key {k!r}")
    model = data.get("model")
    if not isinstance(model, str) or not is_asset_path(model):
        raise ScenarioError(f, "model", "the path of a .gltf or .glb file", model)
    model_path = (p.parent / model).resolve()
    if not model_path.is_file():
        raise ScenarioError(f, "model", "an existing file", str(model_path))
    light = data.get("lighting", "neutral")
    if not isinstance(light, str):
        raise ScenarioError(f, "lighting", "a path of an .hdr or .exr file, or \"neutral\"", light)
    if light == "neutral":
        env = {"type": "constant", "radiance": [1.0, 1.0, 1.0]}
    else:
        lp = (p.parent / light).resolve()
        if lp.suffix.lower() not in (".hdr", ".exr") or not lp.is_file():
            raise ScenarioError(f, "lighting", "an existing .hdr or .exr file", str(lp))
        env = {"type": "file", "path": str(lp)}
    dims = data.get("dimensions", {"width": DEFAULT_ASSET_SIZE[0], "height": DEFAULT_ASSET_SIZE[1]})
    try:
        W, H = int(dims["width"]), int(dims["height"])
    except (TypeError, KeyError, ValueError):
        raise ScenarioError(f, "dimensions", "{width, height} integers", dims) from None
    if not (1 <= W <= 16384 and 1 <= H <= 16384):
        raise ScenarioError(f, "dimensions", "sides in [1, 16384]", dims)
    yfov = _num(data.get("verticalFoV", FRAMING_FOV_DEG), f, "verticalFoV")
    if not 0 < yfov < 179:
        raise ScenarioError(f, "verticalFoV", "degrees in (0, 179)", yfov)
    sky = data.get("renderSkybox", True)
    if not isinstance(sky, bool):
        raise ScenarioError(f, "renderSkybox", "true or false", sky)
    table = {"name": str(data.get("name", model_path.stem)),
             "description": f"Render Fidelity scenario {p.name}" + ("" if sky else
                            " (renderSkybox false: pbrcheck's background still shows the environment)"),
             "environment": env, "objects": [{"type": "gltf", "path": str(model_path)}]}
    # the asset's bounds, for the defaults (model-viewer frames the model's bounding box)
    sc = scene_from_dict(table, file=f, base_dir=p.parent)
    lo, hi = sc.assets[0].bounds()
    frame = framing_camera(lo, hi, W, H)
    target = np.asarray(frame.target)
    if "target" in data:
        t = data["target"]
        if not isinstance(t, dict):
            raise ScenarioError(f, "target", "{x, y, z}", t)
        target = np.array([_num(t.get(a, c), f, f"target.{a}") for a, c in zip("xyz", target)])
    d0 = np.asarray(frame.origin) - np.asarray(frame.target)
    r0 = float(np.linalg.norm(d0))
    theta0, phi0 = math.degrees(math.atan2(d0[0], d0[2])), math.degrees(math.acos(d0[1] / r0))
    orbit = data.get("orbit", {})
    if not isinstance(orbit, dict):
        raise ScenarioError(f, "orbit", "{theta, phi, radius}", orbit)
    th = math.radians(_num(orbit.get("theta", theta0), f, "orbit.theta"))
    ph = math.radians(_num(orbit.get("phi", phi0), f, "orbit.phi"))
    rad = _num(orbit.get("radius", r0), f, "orbit.radius")
    if rad <= 0:
        raise ScenarioError(f, "orbit.radius", "a positive distance", rad)
    origin = target + rad * np.array([math.sin(ph) * math.sin(th), math.cos(ph), math.sin(ph) * math.cos(th)])
    tx = math.tan(math.radians(yfov) / 2) * W / H
    table["camera"] = {"origin": [float(x) for x in origin], "target": [float(x) for x in target],
                       "up": [0.0, 1.0, 0.0], "fov": math.degrees(2 * math.atan(tx)), "width": W, "height": H}
    scene_from_dict(table, file=f, base_dir=p.parent)  # validates the camera (e.g. phi 0: up parallel)
    return table


def import_scenario(path: str | Path) -> str:
    """The scene TOML text of scenario file ``path``."""
    return dump_toml(scenario_scene(path))
