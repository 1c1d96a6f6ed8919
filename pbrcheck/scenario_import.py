"""Khronos glTF Render Fidelity (RF) scenarios as pbrcheck scenes, read as RF reads them
(``pbrcheck import-scenario``).

Inputs: a whole RF ``config.json`` (``{"renderers": [...], "scenarios": [...]}``: one scene per
scenario, :func:`config_scenes`); one scenario entry (a JSON object with ``model``); the
``{"scenario", "outputFile"}`` file the RF tools hand each renderer (its ``scenario``); the
``scenario.json`` of ``pbrcheck export`` (its ``model_viewer`` part).

A scenario names ``model`` (a .gltf/.glb, relative to the file read), ``lighting`` (an environment
file relative to the file read: .hdr / .exr, or an LDR .jpg / .png, which the scene loader
sRGB-decodes to linear radiance in [0, 1] (:func:`pbrcheck.environment.read_image_file`; the scene's
description says so); ``"neutral"``: pbrcheck's neutral constant environment of radiance 1),
``dimensions`` ``{width, height}``, ``target`` ``{x, y, z}``, ``orbit`` ``{theta, phi, radius}``
(model-viewer's camera-orbit: degrees, degrees, scene units; ``theta`` the azimuth about +Y from +Z
towards +X, ``phi`` the polar angle from +Y), ``verticalFoV`` (degrees), ``renderSkybox`` and
``exclude`` (the RF renderers that skip it). Absent fields take the RF generator's defaults
(:data:`RF_DEFAULTS`, from ``src/config-reader.ts`` of KhronosGroup/glTF-Render-Fidelity-Generator,
whose ``scenarioConfig`` merges ``dimensions``, ``target`` and ``orbit`` per component): 768 x 768,
target (0, 0, 0), orbit theta 0 / phi 90 / radius 1, vertical field of view 45 degrees, no skybox,
and the lighting ``../../../environments/lightroom_14b.hdr`` (relative to the file; an error naming
it where that file is absent). ``renderSkybox = false`` (RF captures with a transparent background):
pbrcheck's images show the environment anyway and its metrics exclude background pixels; the
description says so. ``exclude`` is kept as metadata for the engines: a comment in the scene TOML
and the ``exclude`` of the index ``scenarios.json`` that :func:`import_to_folder` writes.

``orbit.radius`` 0 (RF's own MetalRoughSpheresNoTextures scenario, target (0.003, 0.003, 0.01) in
front of a 7.5 mm grid of spheres at z <= 0.00035) puts the camera at the target, oriented by
``theta`` / ``phi`` (model-viewer orients its camera from the orbit's angles, not by a look-at, and
RF's three-gpu-pathtracer client puts the camera at the target): the camera looks along the orbit's
inward direction from the target. The scene's camera ``target`` (a look-at point) is then placed
along that direction at :func:`look_distance` (the distance to the asset's bounding-box centre; only
its direction matters to a pinhole camera, its length becomes the exported scenario's orbit radius).
An earlier rule framed the asset's bounding sphere about the target instead: with RF's target
0.01 in front of the grid the spheres came out ~1 pixel wide at 64 x 64 and no pixel was fully
covered (the ``default`` row's "no valid pixel"). The description says which rule applied.

Importing does not otherwise load the asset (RF's framing needs no bounds): an asset pbrcheck
refuses (a required extension it does not implement) imports, and is refused where the scene is used.

API: :func:`scenario_scene` (one scenario file -> the scene TOML's table), :func:`scenario_table`
(one scenario entry -> the table), :func:`config_scenes` (a file -> [(name, table, metadata)]),
:func:`import_scenario` (one scenario file -> TOML text), :func:`import_to_folder` (every scenario
of a file -> ``DIR/<name>.toml`` and ``DIR/scenarios.json``), :func:`scenario_toml`,
:func:`look_distance`, :data:`RF_DEFAULTS`, :data:`LIGHTING_SUFFIXES`, :class:`ScenarioError`.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np

from .atomic import staged_folder, write_text_atomic
from .errors import SceneError
from .fmt import terminal_safe
from .gltf import load_asset
from .gltf_objects import is_asset_path
from .jsonio import dump_json
from .scene import CAMERA_UP_PARALLEL_SINE, LDR_ENVIRONMENT_SUFFIXES as LDR_SUFFIXES, MAX_IMAGE_SIDE, dump_toml

KEYS = ("name", "model", "lighting", "dimensions", "target", "orbit", "verticalFoV", "renderSkybox", "exclude")
#: The RF generator's scenario defaults (``src/config-reader.ts``, ``defaultScenario``; checked
#: against KhronosGroup/glTF-Render-Fidelity-Generator at commit deaaba0b, 2026-11-26).
RF_DEFAULTS = {"lighting": "../../../environments/lightroom_14b.hdr", "dimensions": {"width": 768, "height": 768},
               "target": {"x": 0.0, "y": 0.0, "z": 0.0}, "orbit": {"theta": 0.0, "phi": 90.0, "radius": 1.0},
               "verticalFoV": 45.0, "renderSkybox": False}
#: Environment files a scenario's ``lighting`` may name (HDR, or LDR read as sRGB).
LIGHTING_SUFFIXES = (".hdr", ".exr") + LDR_SUFFIXES
#: Smallest look-at distance :func:`look_distance` returns (an asset centred on the target: 1 micrometre;
#: a camera's origin and target must differ).
MIN_LOOK_DISTANCE = 1e-6
#: The index :func:`import_to_folder` writes beside the scenes.
INDEX = "scenarios.json"


class ScenarioError(SceneError):
    """A scenario that cannot become a scene: names the file and the field."""


def _num(v, file, fieldname):
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ScenarioError(file, fieldname, "a finite number", v)
    return float(v)


def _merged(data: dict, key: str, file: str) -> dict:
    """``RF_DEFAULTS[key]`` updated per component by the scenario's (config-reader's Object.assign)."""
    v = data.get(key, {})
    if not isinstance(v, dict):
        raise ScenarioError(file, key, "{" + ", ".join(RF_DEFAULTS[key]) + "}", v)
    for k in v:
        if k not in RF_DEFAULTS[key]:
            raise ScenarioError(file, f"{key}.{k}", "one of " + ", ".join(RF_DEFAULTS[key]), k)
    return {**RF_DEFAULTS[key], **v}


def _read(p: Path):
    try:
        return json.loads(p.read_text(encoding="utf-8"))
    except OSError as e:
        raise ScenarioError(str(p), None, "a readable file", message=f"{p}: cannot read: {e.strerror}") from None
    except UnicodeDecodeError:
        raise ScenarioError(str(p), None, "JSON", message=f"{p}: not a UTF-8 JSON file") from None
    except json.JSONDecodeError as e:
        raise ScenarioError(str(p), None, "JSON", message=f"{p}: invalid JSON: {e}") from None


def scenario_table(data, base: Path, file: str, where: str = "") -> tuple[dict, dict]:
    """One scenario entry ``data`` (paths relative to ``base``) -> (the scene table, the metadata
    ``{"name", "exclude", "renderSkybox"}``); ``where`` prefixes the fields in errors."""
    w = (lambda k: f"{where}.{k}" if where else k)
    if not isinstance(data, dict):
        raise ScenarioError(file, where or None, "a JSON object", type(data).__name__)
    for k in data:
        if k not in KEYS:
            raise ScenarioError(file, w(k), "one of the keys " + ", ".join(KEYS), f"unknown key {k!r}")
    model = data.get("model")
    if not isinstance(model, str) or not is_asset_path(model):
        raise ScenarioError(file, w("model"), "the path of a .gltf or .glb file", model)
    model_path = (base / model).resolve()
    if not model_path.is_file():
        raise ScenarioError(file, w("model"), "an existing file", str(model_path))
    light = data.get("lighting", RF_DEFAULTS["lighting"])
    if not isinstance(light, str):
        raise ScenarioError(file, w("lighting"), "a path of an environment file, or \"neutral\"", light)
    note = ""
    if light == "neutral":
        env = {"type": "constant", "radiance": [1.0, 1.0, 1.0]}
    else:
        lp = (base / light).resolve()
        if lp.suffix.lower() not in LIGHTING_SUFFIXES:
            raise ScenarioError(file, w("lighting"), "an " + ", ".join(LIGHTING_SUFFIXES) + " file", str(lp))
        if not lp.is_file():
            default = "" if "lighting" in data else " (the RF generator's default lighting: name one)"
            raise ScenarioError(file, w("lighting"), "an existing file" + default, str(lp))
        env = {"type": "file", "path": str(lp)}
        if lp.suffix.lower() in LDR_SUFFIXES:
            note = f"; lighting {lp.name} is LDR: sRGB-decoded to linear radiance in [0, 1]"
    dims = _merged(data, "dimensions", file)
    try:
        if any(isinstance(dims[k], bool) or float(dims[k]) != int(dims[k]) for k in ("width", "height")):
            raise ValueError
        W, H = int(dims["width"]), int(dims["height"])
    except (TypeError, ValueError, OverflowError):
        raise ScenarioError(file, w("dimensions"), "{width, height} integers", data.get("dimensions")) from None
    if not (1 <= W <= MAX_IMAGE_SIDE and 1 <= H <= MAX_IMAGE_SIDE):
        raise ScenarioError(file, w("dimensions"), f"sides in [1, {MAX_IMAGE_SIDE}]", dims)
    yfov = _num(data.get("verticalFoV", RF_DEFAULTS["verticalFoV"]), file, w("verticalFoV"))
    if not 0 < yfov < 179:
        raise ScenarioError(file, w("verticalFoV"), "degrees in (0, 179)", yfov)
    sky = data.get("renderSkybox", RF_DEFAULTS["renderSkybox"])
    if not isinstance(sky, bool):
        raise ScenarioError(file, w("renderSkybox"), "true or false", sky)
    exclude = data.get("exclude", [])
    if not isinstance(exclude, list) or not all(isinstance(x, str) for x in exclude):
        raise ScenarioError(file, w("exclude"), "a list of renderer names", exclude)
    name = data.get("name", model_path.stem)
    if not isinstance(name, str) or not name.strip():
        raise ScenarioError(file, w("name"), "a non-empty string", name)
    t = _merged(data, "target", file)
    target = [_num(t[a], file, w(f"target.{a}")) for a in "xyz"]
    o = _merged(data, "orbit", file)
    th, ph = (math.radians(_num(o[k], file, w(f"orbit.{k}"))) for k in ("theta", "phi"))
    rad = _num(o["radius"], file, w("orbit.radius"))
    if rad < 0:
        raise ScenarioError(file, w("orbit.radius"), "a distance >= 0", rad)
    tx = math.tan(math.radians(yfov) / 2) * W / H
    if abs(math.sin(ph)) < CAMERA_UP_PARALLEL_SINE:  # the camera's up is +Y: it cannot look straight down
        raise ScenarioError(file, w("orbit.phi"), "a polar angle away from 0 and 180 degrees", o["phi"])
    d = (math.sin(ph) * math.sin(th), math.cos(ph), math.sin(ph) * math.cos(th))
    radius_note = ""
    if rad == 0:  # the camera at the target, looking along -d (module docstring); look-at point ahead of it
        origin = list(target)
        ahead = look_distance(model_path, target)
        target = [c - ahead * x for c, x in zip(origin, d)]
        radius_note = (f"; orbit radius 0 in the scenario: the camera at the target, looking along the orbit's "
                       f"direction (look-at point {ahead:.6g} ahead)")
    else:
        origin = [c + rad * x for c, x in zip(target, d)]
    sky_note = "" if sky else "; renderSkybox false: pbrcheck's background still shows the environment"
    table = {"name": name,
             "description": f"Render Fidelity scenario {name} ({Path(file).name}){sky_note}{note}{radius_note}",
             "camera": {"origin": origin, "target": target, "up": [0.0, 1.0, 0.0],
                        "fov": math.degrees(2 * math.atan(tx)), "width": W, "height": H},
             "environment": env, "objects": [{"type": "gltf", "path": str(model_path)}]}
    return table, {"name": name, "exclude": list(exclude), "renderSkybox": sky}


def look_distance(model_path: Path, point) -> float:
    """The distance from ``point`` to the centre of the asset's bounding box (at least
    :data:`MIN_LOOK_DISTANCE`): where a radius-0 scenario's look-at point goes (module docstring)."""
    lo, hi = load_asset(model_path).bounds()
    centre = 0.5 * (np.asarray(lo, float) + np.asarray(hi, float))
    return max(float(np.linalg.norm(centre - np.asarray(point, float))), MIN_LOOK_DISTANCE)


def config_scenes(path: str | Path) -> list[tuple[str, dict, dict]]:
    """Every scenario of file ``path`` as (name, scene table, metadata): a whole RF config gives one
    per ``scenarios`` entry (names unique), any other accepted file one."""
    p = Path(path)
    f = str(p)
    data = _read(p)
    if isinstance(data, dict) and "scenarios" in data and "model" not in data:  # a whole RF config.json
        extra = set(data) - {"renderers", "scenarios"}
        if extra:
            raise ScenarioError(f, sorted(extra)[0], "renderers and scenarios (an RF config.json)", sorted(extra)[0])
        lst = data["scenarios"]
        if not isinstance(lst, list) or not lst:
            raise ScenarioError(f, "scenarios", "a non-empty list of scenarios", lst)
        out, seen = [], {}
        for i, s in enumerate(lst):
            table, meta = scenario_table(s, p.parent, f, f"scenarios[{i}]")
            key = _file_name(meta["name"])
            if key in seen:
                raise ScenarioError(f, f"scenarios[{i}].name", f"a name unique in the config (as a file name: "
                                    f"scenarios[{seen[key]}] is also {key})", meta["name"])
            seen[key] = i
            out.append((meta["name"], table, meta))
        return out
    if isinstance(data, dict) and "model_viewer" in data and "model" not in data:  # pbrcheck's own scenario.json
        data = data["model_viewer"]
    elif isinstance(data, dict) and "scenario" in data and "model" not in data:
        data = data["scenario"]   # the file RF's tools hand each renderer: {"scenario": {...}, "outputFile": PNG}
    table, meta = scenario_table(data, p.parent, f)
    return [(meta["name"], table, meta)]


def _one(path: str | Path) -> tuple[str, dict, dict]:
    scenes = config_scenes(path)
    if len(scenes) != 1:
        raise ScenarioError(str(path), "scenarios", "one scenario (a config of several: import it with --out DIR)",
                            f"{len(scenes)} scenarios")
    return scenes[0]


def scenario_scene(path: str | Path) -> dict:
    """The scene table (``pbrcheck.scene`` TOML fields, paths absolute) of one-scenario file ``path``."""
    return _one(path)[1]


def scenario_toml(table: dict, meta: dict, source: str | Path) -> str:
    """The scene TOML of one scenario, headed by comments naming its source and its RF metadata
    (names from the file shown with their control characters escaped: a comment stays one line)."""
    head = [f"# Render Fidelity scenario {terminal_safe(meta['name'])} of {terminal_safe(str(source))}"]
    if meta["exclude"]:
        head.append(f"# exclude (RF renderers that skip it): {', '.join(map(terminal_safe, meta['exclude']))}")
    return "\n".join(head) + "\n" + dump_toml(table)


def import_scenario(path: str | Path) -> str:
    """The scene TOML text of one-scenario file ``path``."""
    _, table, meta = _one(path)
    return scenario_toml(table, meta, path)


def _file_name(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]", "_", name).lstrip(".") or "scenario"


def import_to_folder(path: str | Path, out_dir: str | Path) -> list[Path]:
    """Every scenario of ``path`` as ``out_dir/<name>.toml`` (characters other than letters, digits and
    ``._-`` as ``_``) and the index ``out_dir/scenarios.json`` (the config's renderers, and per
    scenario its scene file, ``exclude`` and ``renderSkybox``), all written or none. Returns the
    scene files."""
    src = Path(path)
    scenes = config_scenes(src)
    data = _read(src)
    renderers = data.get("renderers", []) if isinstance(data, dict) and "scenarios" in data else []
    index = {"source": str(src.resolve()), "renderers": renderers, "scenarios": []}
    files = []
    out = Path(out_dir)
    with staged_folder(out) as stage:
        for name, table, meta in scenes:
            fn = _file_name(name) + ".toml"
            write_text_atomic(stage / fn, scenario_toml(table, meta, src))
            files.append(out / fn)
            index["scenarios"].append({"name": name, "scene": fn, "exclude": meta["exclude"],
                                       "renderSkybox": meta["renderSkybox"]})
        write_text_atomic(stage / INDEX, dump_json(index, indent=2) + "\n")
    return files
