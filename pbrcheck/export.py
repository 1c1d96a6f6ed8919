"""Export a pbrcheck scene for any renderer: glTF 2.0, the environment, and a scenario with the
output contract (``pbrcheck export SCENE --out DIR``; docs/renderers.md).

API
---
- :func:`export_scene` -- write ``scene.gltf``, ``scene.bin``, ``environment.exr``,
  ``environment.hdr`` and ``scenario.json`` into a folder; returns an :class:`Export`. An asset's
  material extensions pbrcheck does not model are removed from ``scene.gltf`` unless
  ``keep_unmodelled`` (:mod:`pbrcheck.unmodelled`; :attr:`Export.unmodelled` names them).
- :func:`keeping_unmodelled` -- a context in which every :func:`export_scene` whose caller did not
  say (``keep_unmodelled=None``, as the external engines' export in :func:`clients.run.render_external`)
  keeps the unmodelled extensions: an explicit, run-wide choice (``pbrcheck report --keep-unmodelled``)
  to see the engines' own form of a feature pbrcheck does not model (the transmission extensions are
  modelled since issue 37 and always kept); :func:`keeps_unmodelled` -- whether it is in force.
- :func:`gltf_document` -- the glTF JSON and its binary buffer (no file written).
- :func:`sphere_segments` -- the tessellation rule: segments around a sphere for a silhouette error
  below :data:`SILHOUETTE_TOLERANCE_PX` at the scene's resolution.
- :func:`uv_sphere` -- the unit sphere mesh (positions = analytic normals, triangle indices);
  :func:`sphere_tangents` -- the reference's sphere tangent, written as ``TANGENT`` for the objects
  whose material has ``KHR_materials_anisotropy`` (a plane's: its ``plane_frame`` tangent).
- :func:`ior_from_f0` -- ``KHR_materials_ior``'s ior for a dielectric F0.
- An analytic material's lobe fields (``clearcoat``, ``sheen_color``, ...) are written as their
  extensions (``KHR_materials_clearcoat``, ...: :func:`pbrcheck.lobe_params.scene_extensions`);
  until pbrcheck models them they are removed like an asset's unmodelled extensions unless
  ``keep_unmodelled``.
- :func:`equirect_image` -- the environment resampled into the exported orientation
  (:data:`ENVIRONMENT_ORIENTATION`).
- :func:`scenario` -- the ``scenario.json`` content (and the model-viewer render-fidelity scenario).
- :data:`OUTPUT_FORMATS` -- what a renderer may write (``exr``, ``hdr``, ``pfm``, ``png-srgb``).

Conventions (docs/renderers.md has the table): world axes are glTF's (+Y up, right-handed, metres
= scene units); object ``k`` (index after sphere grids are expanded, the ``object`` AOV) is the
node named ``object_<k>_<name>`` with ``extras.pbrcheck_object = k``; roughness is perceptual
(glTF's ``roughnessFactor``, alpha = roughness^2, as both); point, spot and directional lights
are ``KHR_lights_punctual`` with 1 cd taken as 1 W/sr and 1 lux as 1 W/m^2 (radiometric, RGB
split into a colour with max 1 times a scalar; the node's -Z is the light's ``direction``; in an
asset scene the scene file's lights follow the asset's own, on root nodes ``light_<k>``); planes
are one-sided quads (front = the scene's normal;
``doubleSided`` false; the reference's BSDFs are black from behind).

References: glTF 2.0 specification (Khronos, 2021), sections 3.10 (cameras), 3.9 (materials);
``KHR_lights_punctual`` and ``KHR_materials_ior`` extension specifications; three.js ``equirectUv``
(``src/renderers/shaders/ShaderChunk/common.glsl.js``) for the environment orientation.
"""

from __future__ import annotations

import contextlib
import copy
import math
import threading
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import __version__
from .atomic import staged_folder, write_bytes_atomic
from .camera import camera_frame, tan_half_fov
from .environment import EnvMap, load_environment, scene_hash
from .errors import PbrcheckError
from .exr import Image, write_exr
from .hdrimage import write_hdr
from .jsonio import dump_json, write_json_atomic
from .gltf import SUPPORTED_EXTENSIONS
from .scene import Plane, Scene, Sphere, plane_frame
from .lobe_params import ANISOTROPY, scene_extensions, scene_features
from .transmission_params import scene_extensions as transmission_extensions
from .unmodelled import strip_unmodelled

#: scenario.json's words on the metallic blend (its ``metallic_blend`` table).
METALLIC_BLEND_NOTE = ("f0: pbrcheck's F0 mix (the diffuse under 1 - F of mix(specular, base_color, metallic)); "
                       "gltf: glTF 2.0 Appendix B, mix(dielectric_brdf, metal_brdf, metallic) (the diffuse under "
                       "1 - F of the dielectric's F0). They agree at metallic 0 and 1; set [brdf] metallic_blend = "
                       "\"gltf\" to judge a glTF engine against its own blend.")
#: Largest distance, in pixels, between a tessellated sphere's silhouette and the true one.
SILHOUETTE_TOLERANCE_PX = 0.25
#: Below this length the sphere tangent's (-n.y, n.x) is a pole on the z axis: +X there (as
#: realtime.lobes.sphere_tangent, whose 1e-6 it is).
TANGENT_POLE_EPS = 1e-6
#: Fewest and most segments around a sphere (the rings are half as many).
MIN_SPHERE_SEGMENTS = 16
MAX_SPHERE_SEGMENTS = 1024
#: glTF's dielectric F0 without KHR_materials_ior (ior 1.5): ((1.5 - 1) / (1.5 + 1))^2.
GLTF_DEFAULT_F0 = 0.04
#: |specular - 0.04| below which no KHR_materials_ior is written.
F0_MATCH_TOLERANCE = 1e-9
#: The exported environment's width is twice the source's (bilinear resampling keeps its detail),
#: clamped to this range; the height is half the width.
ENV_MIN_WIDTH = 64
ENV_MAX_WIDTH = 4096
#: The formats a renderer's output may take (``output`` in renderers.toml, ``output.format`` here).
OUTPUT_FORMATS = ("exr", "hdr", "pfm", "png-srgb")
OUTPUT_SUFFIX = {"exr": ".exr", "hdr": ".hdr", "pfm": ".pfm", "png-srgb": ".png"}
#: Bumped whenever the exported files change for the same scene (part of the client cache key).
EXPORT_FORMAT_VERSION = 2  # 2: an asset scene's scene-file lights are exported
#: The files :func:`export_scene` writes.
FILES = ("scene.gltf", "scene.bin", "environment.exr", "environment.hdr", "scenario.json")
#: The buffer of analytic objects exported beside an asset (the asset keeps its own buffers).
OBJECTS_BIN = "pbrcheck_objects.bin"

ENVIRONMENT_ORIENTATION = (
    "equirectangular, +Y up, row 0 at the top: pixel (row k, column c) of an H x W image holds the "
    "radiance arriving from direction d = (cos a cos e, sin e, sin a cos e) with "
    "a = 2 pi ((c + 0.5)/W - 0.5), e = pi (0.5 - (k + 0.5)/H); this is three.js's equirectUv "
    "(u = atan2(d.z, d.x)/2pi + 0.5, v = asin(d.y)/pi + 0.5) read with flipY off; Mitsuba's envmap "
    "u is this u - 0.25 (docs/renderers.md maps other conventions); the scene's scale and rotation "
    "are baked in")


class ExportError(PbrcheckError):
    """The scene cannot be exported (names the scene file and the field)."""


@dataclass
class Export:
    """What :func:`export_scene` wrote: the folder, the files, the scenario and the tessellation."""
    out_dir: Path
    files: dict[str, Path]
    scenario: dict
    segments: dict[int, int] = field(default_factory=dict)   # object id -> segments around
    triangles: int = 0
    # the asset's unmodelled material extensions: [(feature, material names)], removed from scene.gltf
    # unless kept (keep_unmodelled): pbrcheck.unmodelled.strip_unmodelled
    unmodelled: list = field(default_factory=list)
    kept_unmodelled: bool = False


# ------------------------------------------------------------------------------------------------
# Geometry
# ------------------------------------------------------------------------------------------------

def pixels_per_unit(scene: Scene, center, radius: float) -> float:
    """An upper bound of the screen magnification (pixels per scene unit) on a sphere's surface.

    A pinhole camera maps a length l at depth z, at angle t off axis, to at most
    ``l f / z (1 + tan^2 t)`` pixels, ``f = (W/2) / tan(fov_x/2)``; the nearest point of the sphere
    has ``z >= |c - o| - r`` and the image corner has the largest ``tan^2 t = tan_x^2 + tan_y^2``.
    """
    cam = scene.camera
    tx, ty = tan_half_fov(cam)
    f = (cam.width / 2) / tx
    dist = float(np.linalg.norm(np.asarray(center, float) - np.asarray(cam.origin, float)))
    near = max(dist - radius, 1e-3 * radius)
    return f / near * (1.0 + tx * tx + ty * ty)


def sphere_segments(scene: Scene, sphere: Sphere) -> int:
    """Segments around the sphere so that its silhouette deviates less than
    :data:`SILHOUETTE_TOLERANCE_PX` pixels at the scene's resolution.

    A UV sphere of ``n`` segments and ``n/2`` rings has cells of ``2 pi / n`` by ``2 pi / n``
    radians (at most); each flat triangle lies inside the sphere by at most the sagitta of its
    circumscribed cap, ``r (1 - cos(rho))`` with ``rho <= sqrt(2) pi / n`` (half the cell's
    diagonal). With ``s`` pixels per unit (:func:`pixels_per_unit`):
    ``s r (1 - cos(sqrt(2) pi / n)) <= 0.25`` gives ``n >= sqrt(2) pi / acos(1 - 0.25 / (s r))``,
    rounded up to a multiple of 4 and clamped to [:data:`MIN_SPHERE_SEGMENTS`,
    :data:`MAX_SPHERE_SEGMENTS`].
    """
    r_px = pixels_per_unit(scene, sphere.center, sphere.radius) * sphere.radius
    x = 1.0 - SILHOUETTE_TOLERANCE_PX / r_px
    n = MIN_SPHERE_SEGMENTS if x <= 0 else math.sqrt(2.0) * math.pi / math.acos(x)
    n = int(math.ceil(n / 4.0) * 4)
    return int(min(max(n, MIN_SPHERE_SEGMENTS), MAX_SPHERE_SEGMENTS))


def uv_sphere(segments: int) -> tuple[np.ndarray, np.ndarray]:
    """The unit UV sphere of ``segments`` around and ``segments/2`` rings: (positions (V, 3) float32,
    which are also the analytic normals, and indices (T, 3) uint32, counter-clockwise seen from
    outside). Pole rows are single vertices."""
    rings = segments // 2
    theta = np.pi * np.arange(1, rings) / rings                  # interior rings
    phi = 2 * np.pi * np.arange(segments) / segments
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    ring = np.stack([st * np.sin(phi), ct * np.ones_like(phi), st * np.cos(phi)], axis=-1).reshape(-1, 3)
    pos = np.concatenate([[[0.0, 1.0, 0.0]], ring, [[0.0, -1.0, 0.0]]]).astype(np.float64)
    pos /= np.linalg.norm(pos, axis=1, keepdims=True)
    top, bottom = 0, len(pos) - 1

    def vid(i, j):  # interior ring i (0 = nearest +Y), segment j
        return 1 + i * segments + (j % segments)

    tris = []
    for j in range(segments):
        tris.append((top, vid(0, j), vid(0, j + 1)))
        tris.append((bottom, vid(rings - 2, j + 1), vid(rings - 2, j)))
    for i in range(rings - 2):
        for j in range(segments):
            a, b, c, d = vid(i, j), vid(i, j + 1), vid(i + 1, j), vid(i + 1, j + 1)
            tris.append((a, c, b))
            tris.append((b, c, d))
    return pos.astype(np.float32), np.asarray(tris, dtype=np.uint32)


def sphere_tangents(normals: np.ndarray) -> np.ndarray:
    """The reference's tangent of a sphere at unit ``normals`` (V, 3): Mitsuba's sphere dp/du direction
    ``normalize(-n.y, n.x, 0)`` (the sphere's frame is the world's: the export's nodes translate and
    scale, never rotate), +X where that vanishes (the points on the z axis); the bitangent is
    ``n x t`` (sign +1). Written for the spheres whose material has ``KHR_materials_anisotropy``: its
    direction is in this frame, and an engine without a TANGENT attribute makes up its own."""
    n = np.asarray(normals, np.float64)
    t = np.stack([-n[:, 1], n[:, 0], np.zeros(len(n))], axis=1)
    ln = np.linalg.norm(t, axis=1, keepdims=True)
    return np.where(ln > TANGENT_POLE_EPS, t / np.maximum(ln, TANGENT_POLE_EPS), np.array([1.0, 0.0, 0.0]))


def plane_quad(plane: Plane) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(positions (4, 3), normals (4, 3), indices (2, 3)) of a plane: counter-clockwise seen from
    the side its normal points to (the front face)."""
    t, b, n = (np.asarray(v, float) for v in plane_frame(plane.normal))
    c = np.asarray(plane.center, float)
    hx, hy = plane.size[0] / 2, plane.size[1] / 2
    pos = np.array([c - hx * t - hy * b, c + hx * t - hy * b, c + hx * t + hy * b, c - hx * t + hy * b])
    nrm = np.repeat(n[None], 4, axis=0)
    idx = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
    if np.dot(np.cross(pos[1] - pos[0], pos[2] - pos[0]), n) < 0:   # t x b = n, but be sure
        idx = idx[:, ::-1].copy()
    return pos.astype(np.float32), nrm.astype(np.float32), idx


# ------------------------------------------------------------------------------------------------
# Materials, lights, camera
# ------------------------------------------------------------------------------------------------

def ior_from_f0(f0: float) -> float:
    """``KHR_materials_ior``: F0 = ((ior - 1) / (ior + 1))^2, so ior = (1 + sqrt(F0)) / (1 - sqrt(F0)).

    F0 = 0 gives ior 1; F0 = 1 has no finite ior: the extension's special value 0 gives
    ((0 - 1)/(0 + 1))^2 = 1.
    """
    s = math.sqrt(max(0.0, min(1.0, f0)))
    if s >= 1.0:
        return 0.0
    return (1.0 + s) / (1.0 - s)


def _material(obj) -> dict:
    m = obj.material
    d = {"name": f"material_{obj.id}",
         "pbrMetallicRoughness": {"baseColorFactor": [float(c) for c in m.base_color] + [1.0],
                                  "metallicFactor": float(m.metallic),
                                  "roughnessFactor": float(m.roughness)},
         "doubleSided": False}
    if abs(m.specular - GLTF_DEFAULT_F0) > F0_MATCH_TOLERANCE:
        d["extensions"] = {"KHR_materials_ior": {"ior": ior_from_f0(m.specular)}}
    lobes = scene_extensions(m)   # the lobes' extensions (pbrcheck.lobe_params), where set
    lobes.update(transmission_extensions(m))   # transmission, volume, ... (pbrcheck.transmission_params)
    if lobes:
        d.setdefault("extensions", {}).update(lobes)
    return d


def _materials_extensions(materials) -> set[str]:
    """The extensions the exported analytic materials use (for ``extensionsUsed``)."""
    return {e for m in materials for e in m.get("extensions", {})}


def _light(light) -> dict:
    """``KHR_lights_punctual`` light of a :mod:`pbrcheck.lights` light: RGB split into ``color``
    (max 1) times ``intensity`` (cd = W/sr; lux = W/m^2 for a directional light); no ``range``."""
    i = [float(x) for x in light.intensity]
    peak = max(i)
    color = [x / peak for x in i] if peak > 0 else [1.0, 1.0, 1.0]
    d = {"type": light.type, "color": color, "intensity": peak}
    if light.type == "spot":
        d["spot"] = {"innerConeAngle": float(light.inner_cone_angle), "outerConeAngle": float(light.outer_cone_angle)}
    return d


def _light_node(k: int, light) -> dict:
    """The node of light ``k``: translation (point, spot), rotation taking the node's -Z to the
    light's ``direction`` (spot, directional)."""
    node: dict = {"name": f"light_{k}"}
    if light.type != "directional":
        node["translation"] = [float(c) for c in light.position]
    if light.type != "point":
        z = -np.asarray(light.direction, float)
        hint = np.array([0.0, 1.0, 0.0]) if abs(z[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
        x = np.cross(hint, z)
        x /= np.linalg.norm(x)
        node["rotation"] = _quaternion(np.stack([x, np.cross(z, x), z], axis=1))
    node["extensions"] = {"KHR_lights_punctual": {"light": k}}
    return node


def _scenario_light(k: int | None, light) -> dict:
    """``scenario.json``'s entry of the scene file's light ``k`` (pbrcheck's units, its node named),
    or with ``k`` None of a light an exported asset carries itself (``"source": "asset"``, no node
    of pbrcheck's)."""
    d: dict = {"type": light.type, **({"gltf_node": f"light_{k}"} if k is not None else {"source": "asset"})}
    if light.type != "directional":
        d["position"] = list(light.position)
    if light.type != "point":
        d["direction"] = list(light.direction)
    if light.type == "spot":
        d["inner_cone_angle_rad"] = light.inner_cone_angle
        d["outer_cone_angle_rad"] = light.outer_cone_angle
    key = "irradiance_w_per_m2" if light.type == "directional" else "intensity_w_per_sr"
    return {**d, key: list(light.intensity)}


def _quaternion(m: np.ndarray) -> list[float]:
    """Unit quaternion [x, y, z, w] of a rotation matrix (Shepperd's method)."""
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    if tr > 0:
        s = 2.0 * math.sqrt(tr + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [s / 4, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, s / 4, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, s / 4, (m[1, 0] - m[0, 1]) / s]
    n = math.sqrt(sum(x * x for x in q))
    return [float(x / n) for x in q]


def camera_yfov(scene: Scene) -> float:
    """glTF's vertical field of view (radians) from the scene's horizontal ``fov`` and aspect:
    ``yfov = 2 atan(tan(fov_x / 2) H / W)``."""
    _, ty = tan_half_fov(scene.camera)
    return 2.0 * math.atan(ty)


def _znear(scene: Scene) -> float:
    o = np.asarray(scene.camera.origin, float)
    gaps = []
    for obj in scene.objects:
        if isinstance(obj, Sphere):
            gaps.append(np.linalg.norm(np.asarray(obj.center) - o) - obj.radius)
    for inst in getattr(scene, "assets", ()):
        lo, hi = inst.bounds()
        gaps.append(np.linalg.norm(0.5 * (lo + hi) - o) - 0.5 * np.linalg.norm(hi - lo))
    near = 0.5 * min([g for g in gaps if g > 0], default=0.1)
    return float(max(min(near, 0.1), 1e-4))


# ------------------------------------------------------------------------------------------------
# glTF
# ------------------------------------------------------------------------------------------------

class _Buffer:
    """The one binary buffer: 4-byte aligned buffer views and their accessors."""

    def __init__(self):
        self.data = bytearray()
        self.views: list[dict] = []
        self.accessors: list[dict] = []

    def add(self, array: np.ndarray, *, target: int, component: int, type_: str, minmax: bool = False) -> int:
        while len(self.data) % 4:
            self.data.append(0)
        raw = np.ascontiguousarray(array).tobytes()
        self.views.append({"buffer": 0, "byteOffset": len(self.data), "byteLength": len(raw), "target": target})
        self.data += raw
        acc = {"bufferView": len(self.views) - 1, "componentType": component,
               "count": int(array.shape[0]) if type_ != "SCALAR" else int(array.size), "type": type_}
        if minmax:
            acc["min"] = [float(x) for x in array.min(axis=0)]
            acc["max"] = [float(x) for x in array.max(axis=0)]
        self.accessors.append(acc)
        return len(self.accessors) - 1

    def vertices(self, pos: np.ndarray, nrm: np.ndarray) -> tuple[int, int]:
        return (self.add(pos.astype(np.float32), target=34962, component=5126, type_="VEC3", minmax=True),
                self.add(nrm.astype(np.float32), target=34962, component=5126, type_="VEC3"))

    def tangents(self, tan: np.ndarray) -> int:
        """A ``TANGENT`` accessor: xyz and the bitangent sign w = +1 (glTF: b = cross(n, t) w)."""
        t4 = np.concatenate([tan, np.ones((len(tan), 1))], axis=1)
        return self.add(t4.astype(np.float32), target=34962, component=5126, type_="VEC4")

    def indices(self, idx: np.ndarray, n_vertices: int) -> int:
        flat = idx.reshape(-1)
        if n_vertices < 65536:
            return self.add(flat.astype(np.uint16), target=34963, component=5123, type_="SCALAR")
        return self.add(flat.astype(np.uint32), target=34963, component=5125, type_="SCALAR")


def _camera(scene: Scene) -> tuple[dict, dict]:
    """(camera node, glTF camera) of the scene's camera."""
    cam = scene.camera
    r, u, f = camera_frame(cam)
    rot = np.stack([r, u, -f], axis=1)           # camera looks down its local -Z, +Y up
    node = {"name": "camera", "camera": 0, "translation": [float(c) for c in cam.origin],
            "rotation": _quaternion(rot)}
    return node, {"name": "camera", "type": "perspective",
                  "perspective": {"yfov": camera_yfov(scene), "aspectRatio": cam.width / cam.height,
                                  "znear": _znear(scene)}}


def _add_lights(doc: dict, lights) -> list[int]:
    """Append ``lights`` to ``doc``'s ``KHR_lights_punctual`` lights (after any the document has)
    and one node each (``light_<k>``, :func:`_light_node`) to ``doc["nodes"]``; returns the new
    nodes' indices (for the scene's root nodes)."""
    if not lights:
        return []
    table = doc.setdefault("extensions", {}).setdefault("KHR_lights_punctual", {}).setdefault("lights", [])
    used = doc.setdefault("extensionsUsed", [])
    if "KHR_lights_punctual" not in used:
        used.append("KHR_lights_punctual")
    nodes = doc.setdefault("nodes", [])
    first_node = len(nodes)
    for k, light in enumerate(lights):
        node = _light_node(k, light)
        node["extensions"]["KHR_lights_punctual"]["light"] = len(table)
        table.append(_light(light) | {"name": f"light_{k}"})
        nodes.append(node)
    return list(range(first_node, len(nodes)))


def _asset_document(scene: Scene, bin_name: str):
    """The asset's own document (:func:`pbrcheck.gltf_export.asset_document`) with the scene file's
    lights on extra root nodes ``light_<k>`` beside ``pbrcheck_root`` (world space: the placement
    does not move them), their ``KHR_lights_punctual`` entries after the asset's own, and the
    analytic objects beside it."""
    from .gltf_export import asset_document

    node, cam = _camera(scene)
    # the export's own files (and the objects' buffer) are never an asset resource's name
    reserved = tuple(f for f in FILES if f != bin_name) + (OBJECTS_BIN,)
    doc, files = asset_document(scene, node, cam, bin_name, reserved=reserved)
    doc["scenes"][0]["nodes"].extend(_add_lights(doc, scene.own_lights()))
    triangles = sum(o.triangles for o in scene.objects if o.type == "mesh")
    analytic = [o for o in scene.objects if o.type != "mesh"]
    if not analytic:
        return doc, files, {}, triangles
    # analytic objects beside the asset: tessellated as in an analytic scene, in a buffer of their own
    buf = _Buffer()
    meshes, nodes, materials, segments, ntri = _analytic_objects(scene, analytic, buf)
    m0, me0, a0, v0 = (len(doc.setdefault(k, [])) for k in ("materials", "meshes", "accessors", "bufferViews"))
    for view in buf.views:
        view["buffer"] = len(doc.setdefault("buffers", []))
    for acc in buf.accessors:
        acc["bufferView"] += v0
    for mesh in meshes:
        for prim in mesh["primitives"]:
            prim["attributes"] = {k: a + a0 for k, a in prim["attributes"].items()}
            prim["indices"] += a0
            prim["material"] += m0
    for n in nodes:
        n["mesh"] += me0
    while len(buf.data) % 4:
        buf.data.append(0)
    doc["buffers"].append({"uri": OBJECTS_BIN, "byteLength": len(buf.data)})
    files[OBJECTS_BIN] = bytes(buf.data)
    doc["materials"] += materials
    doc["meshes"] += meshes
    doc["accessors"] += buf.accessors
    doc["bufferViews"] += buf.views
    first = len(doc["nodes"])
    doc["nodes"] += nodes
    doc["scenes"][0]["nodes"] += list(range(first, len(doc["nodes"])))
    if any("extensions" in m for m in materials):
        doc["extensionsUsed"] = sorted(set(doc.get("extensionsUsed", [])) | _materials_extensions(materials))
    return doc, files, segments, triangles + ntri


def _analytic_objects(scene: Scene, objects, buf: "_Buffer"):
    """(meshes, nodes, materials, segments around each sphere, triangles) of analytic ``objects``
    tessellated into ``buf``; each primitive's material and node's mesh index the returned lists."""
    meshes, nodes, materials = [], [], []
    sphere_geo: dict[int, tuple[int, int, int]] = {}
    segments: dict[int, int] = {}
    triangles = 0
    sphere_tan: dict[int, int] = {}
    for obj in objects:
        materials.append(_material(obj))
        node = {"name": f"object_{obj.id}_{obj.name}", "mesh": len(meshes), "extras": {"pbrcheck_object": obj.id}}
        # anisotropy's direction is in the tangent frame: its objects carry the reference's (only they:
        # every other export stays byte for byte as it was)
        aniso = ANISOTROPY in scene_features(obj.material)
        tan = None
        if isinstance(obj, Sphere):
            n = sphere_segments(scene, obj)
            segments[obj.id] = n
            if n not in sphere_geo:
                pos, idx = uv_sphere(n)
                p, nr = buf.vertices(pos, pos)
                sphere_geo[n] = (p, nr, buf.indices(idx, len(pos)), len(idx))
            p, nr, ix, ntri = sphere_geo[n]
            if aniso:
                if n not in sphere_tan:
                    sphere_tan[n] = buf.tangents(sphere_tangents(uv_sphere(n)[0]))
                tan = sphere_tan[n]
            node["translation"] = [float(c) for c in obj.center]
            node["scale"] = [float(obj.radius)] * 3
        elif isinstance(obj, Plane):
            pos, nrm, idx = plane_quad(obj)
            p, nr = buf.vertices(pos, nrm)
            ix, ntri = buf.indices(idx, 4), 2
            if aniso:   # plane_frame's tangent, its bitangent n x t (a right-handed frame)
                tan = buf.tangents(np.repeat(np.asarray(plane_frame(obj.normal)[0], float)[None, :], 4, axis=0))
        else:  # pragma: no cover - the loader expands grids
            raise ExportError(f"{scene.source}: objects[{obj.id}]: cannot export type {type(obj).__name__}")
        triangles += ntri
        attrs = {"POSITION": p, "NORMAL": nr, **({"TANGENT": tan} if tan is not None else {})}
        meshes.append({"name": f"mesh_{obj.id}", "primitives": [
            {"attributes": attrs, "indices": ix, "material": len(materials) - 1, "mode": 4}]})
        nodes.append(node)
    return meshes, nodes, materials, segments, triangles


def gltf_document(scene: Scene, bin_name: str = "scene.bin") -> tuple[dict, bytes, dict[int, int], int]:
    """The glTF 2.0 JSON of ``scene`` and its binary buffer.

    Returns
    -------
    (dict, bytes, dict, int)
        The glTF JSON, the buffer bytes (``buffers[0].uri = bin_name``; for a scene holding an
        asset, ``{relative path: bytes}`` of the files beside the JSON), segments around each
        sphere (object id -> n) and the number of triangles.
    """
    if getattr(scene, "assets", ()):  # the user's asset itself (pbrcheck.gltf_export), analytic objects beside
        return _asset_document(scene, bin_name)
    buf = _Buffer()
    meshes, nodes, materials, segments, triangles = _analytic_objects(scene, scene.objects, buf)

    cam_node, cam_dict = _camera(scene)
    nodes.append(cam_node)
    cameras = [cam_dict]
    while len(buf.data) % 4:
        buf.data.append(0)
    doc = {
        "asset": {"version": "2.0", "generator": f"pbrcheck {__version__} export"},
        "scene": 0,
        "scenes": [{"name": scene.name, "nodes": list(range(len(nodes)))}],
        "nodes": nodes, "meshes": meshes, "materials": materials, "cameras": cameras,
        "accessors": buf.accessors, "bufferViews": buf.views,
        "buffers": [{"uri": bin_name, "byteLength": len(buf.data)}],
    }
    if any("extensions" in m for m in materials):
        doc["extensionsUsed"] = sorted(_materials_extensions(materials))
    doc["scenes"][0]["nodes"].extend(_add_lights(doc, scene.lights))
    if "extensionsUsed" in doc:
        doc["extensionsUsed"].sort()
    return doc, bytes(buf.data), segments, triangles


# ------------------------------------------------------------------------------------------------
# Environment
# ------------------------------------------------------------------------------------------------

def export_directions(width: int, height: int) -> np.ndarray:
    """(H, W, 3) world directions of the exported environment's pixel centres
    (:data:`ENVIRONMENT_ORIENTATION`)."""
    a = 2 * np.pi * ((np.arange(width) + 0.5) / width - 0.5)
    e = np.pi * (0.5 - (np.arange(height) + 0.5) / height)
    aa, ee = np.meshgrid(a, e)
    return np.stack([np.cos(aa) * np.cos(ee), np.sin(ee), np.sin(aa) * np.cos(ee)], axis=-1)


def export_width(source_width: int) -> int:
    """The exported environment's width: twice the source's, clamped to [:data:`ENV_MIN_WIDTH`,
    :data:`ENV_MAX_WIDTH`] (the height is half of it)."""
    return int(min(max(2 * source_width, ENV_MIN_WIDTH), ENV_MAX_WIDTH))


def equirect_image(env: EnvMap, width: int | None = None) -> np.ndarray:
    """The environment (scale and rotation included) resampled at the exported orientation's pixel
    centres, (H, W, 3) float32 with ``W = 2 H``; ``width`` defaults to twice the source's, clamped
    to [:data:`ENV_MIN_WIDTH`, :data:`ENV_MAX_WIDTH`]."""
    if width is None:
        width = export_width(env.width)
    height = max(width // 2, 1)
    return env.radiance(export_directions(width, height)).astype(np.float32)


# ------------------------------------------------------------------------------------------------
# Scenario
# ------------------------------------------------------------------------------------------------

def model_viewer_scenario(scene: Scene) -> dict | None:
    """The scene as a scenario of the Khronos/model-viewer render-fidelity tools, or None when the
    camera does not fit its fields (an orbit needs up = +Y).

    Orbit: ``theta`` is the azimuth about +Y from +Z, ``phi`` the polar angle from +Y (degrees),
    ``radius`` the distance to ``target``; ``verticalFoV`` in degrees."""
    cam = scene.camera
    up = np.asarray(cam.up, float) / np.linalg.norm(cam.up)
    if np.linalg.norm(up - np.array([0.0, 1.0, 0.0])) > 1e-6:
        return None
    d = np.asarray(cam.origin, float) - np.asarray(cam.target, float)
    radius = float(np.linalg.norm(d))
    phi = math.degrees(math.acos(max(-1.0, min(1.0, d[1] / radius))))
    theta = math.degrees(math.atan2(d[0], d[2]))
    return {"name": f"pbrcheck-{scene.name}", "model": "scene.gltf", "lighting": "environment.hdr",
            "dimensions": {"width": cam.width, "height": cam.height},
            "target": {"x": float(cam.target[0]), "y": float(cam.target[1]), "z": float(cam.target[2])},
            "orbit": {"theta": round(theta, 6), "phi": round(phi, 6), "radius": round(radius, 6)},
            "verticalFoV": round(math.degrees(camera_yfov(scene)), 6), "renderSkybox": True}


def scenario(scene: Scene, env: EnvMap, env_shape: tuple[int, int], *, output: str = "exr",
             segments: dict[int, int] | None = None, triangles: int = 0) -> dict:
    """The ``scenario.json`` content: what a renderer needs besides the glTF, and the contract its
    output must meet."""
    if output not in OUTPUT_FORMATS:
        raise ExportError(f"output: expected one of {', '.join(OUTPUT_FORMATS)}, found {output!r}")
    cam = scene.camera
    r, u, f = camera_frame(cam)
    own = scene.own_lights()
    d = {
        "pbrcheck": __version__, "export_format": EXPORT_FORMAT_VERSION,
        "scene": scene.name, "scene_hash": scene_hash(scene, env.content_hash),
        "size": {"width": cam.width, "height": cam.height},
        "gltf": "scene.gltf",
        "camera": {"origin": list(cam.origin), "target": list(cam.target), "up": list(cam.up),
                   "right": r.tolist(), "true_up": u.tolist(), "forward": f.tolist(),
                   "fov_x_deg": cam.fov, "yfov_rad": camera_yfov(scene), "aspect": cam.width / cam.height,
                   "znear": _znear(scene), "gltf_node": "camera",
                   "pixel_centres": "pixel (row i, column j) looks through x_ndc = 2 (j + 0.5)/W - 1, "
                                    "y_ndc = 1 - 2 (i + 0.5)/H; row 0 at the top"},
        "environment": {"exr": "environment.exr", "hdr": "environment.hdr",
                        "width": env_shape[1], "height": env_shape[0],
                        "orientation": ENVIRONMENT_ORIENTATION, "as_background": True},
        "lights": [_scenario_light(k if k < len(own) else None, l) for k, l in enumerate(scene.lights)],
        # the reference's metallic blend ([brdf] metallic_blend): a glTF engine renders glTF's (Appendix B)
        # whatever it says; the two differ only on partially metallic surfaces (docs/renderers.md)
        "metallic_blend": {"reference": scene.brdf.metallic_blend, "gltf_engines": "gltf",
                           "partially_metallic_objects": sum(0.0 < o.material.metallic < 1.0 for o in scene.objects),
                           "note": METALLIC_BLEND_NOTE},
        "units": "point and spot light intensity: 1 cd is taken as 1 W/sr (radiometric); directional light: "
                 "1 lux as 1 W/m^2; radiance in W/(sr m^2), linear Rec.709 primaries; light directions: "
                 "where the light shines (the glTF node's -Z)",
        "objects": [{"id": o.id, "name": o.name, "type": o.type,
                     **({"gltf_node": f"object_{o.id}_{o.name}"} if o.type != "mesh" else
                        {"gltf_node_index": scene.assets[o.instance].asset.primitives[o.primitive].node,
                         "gltf_primitive": scene.assets[o.instance].asset.primitives[o.primitive].primitive}),
                     **({"segments": segments[o.id]} if segments and o.id in segments else {})}
                    for o in scene.objects],
        "tessellation": {"silhouette_tolerance_px": SILHOUETTE_TOLERANCE_PX, "triangles": triangles,
                         "rule": "UV sphere, n segments and n/2 rings, n >= sqrt(2) pi / acos(1 - 0.25 / "
                                 "(s r)) with s the largest pixels per unit on the sphere"},
        "output": {"format": output, "suffix": OUTPUT_SUFFIX[output], "width": cam.width, "height": cam.height,
                   "contract": "linear radiance (no tone mapping, no exposure), float, row 0 at the top, "
                               "background = the environment seen through each pixel"
                               if output != "png-srgb" else
                               "8-bit sRGB: clamp to [0, 1] then the sRGB transfer; compared in display space"},
    }
    mv = model_viewer_scenario(scene)
    if mv is not None:
        d["model_viewer"] = mv
    return d


# ------------------------------------------------------------------------------------------------
# Export
# ------------------------------------------------------------------------------------------------



#: The run-wide default of :func:`export_scene`'s ``keep_unmodelled`` (:func:`keeping_unmodelled`);
#: a count, so that nested or concurrent contexts (the report's background engine threads) compose.
_KEEP_UNMODELLED = [0]
_KEEP_LOCK = threading.Lock()


@contextlib.contextmanager
def keeping_unmodelled():
    """Within this context an :func:`export_scene` called without ``keep_unmodelled`` keeps the
    unmodelled material extensions (process-wide: the report's prefetch threads see it). Whoever
    enters it says so in its output; the external engines' render cache is not read or written for
    such renders (:func:`compare.renderers.render_under_test`), since its key names the stripped export."""
    with _KEEP_LOCK:
        _KEEP_UNMODELLED[0] += 1
    try:
        yield
    finally:
        with _KEEP_LOCK:
            _KEEP_UNMODELLED[0] -= 1


def keeps_unmodelled() -> bool:
    """Whether a :func:`keeping_unmodelled` context is in force."""
    return _KEEP_UNMODELLED[0] > 0


def export_scene(scene: Scene, out_dir: str | Path, *, output: str = "exr", env: EnvMap | None = None,
                 keep_unmodelled: bool | None = None) -> Export:
    """Write the scene's files (:data:`FILES`) into ``out_dir`` (created).

    Everything is computed before the first write (a bad scene or environment writes nothing); the
    files are written into a sibling temporary folder and moved into ``out_dir`` together
    (:func:`pbrcheck.atomic.staged_folder`): all of them appear, or none.

    Parameters
    ----------
    scene : Scene
        The scene.
    out_dir : str or Path
        The folder.
    output : str, optional
        The output format the renderer will write (:data:`OUTPUT_FORMATS`), stated in the scenario.
    env : EnvMap, optional
        The loaded environment (loaded from the scene when not given).
    keep_unmodelled : bool, optional
        Keep the asset's material extensions pbrcheck does not model (default: removed, so that an
        engine is measured on what the reference models; :mod:`pbrcheck.unmodelled`); None (the
        default): kept only inside :func:`keeping_unmodelled`.

    Returns
    -------
    Export

    Raises
    ------
    ExportError, EnvironmentMapError, ImageIOError
    """
    if keep_unmodelled is None:
        keep_unmodelled = keeps_unmodelled()
    env = env if env is not None else load_environment(scene)
    doc, blob, segments, triangles = gltf_document(scene)
    # the unmodelled material extensions: removed from what the engine gets, or (kept) only named
    unmodelled = strip_unmodelled(copy.deepcopy(doc) if keep_unmodelled else doc, SUPPORTED_EXTENSIONS)
    eq = equirect_image(env)
    sc = scenario(scene, env, eq.shape[:2], output=output, segments=segments, triangles=triangles)
    out = Path(out_dir)
    files = {name: out / name for name in FILES}
    with staged_folder(out) as stage:
        staged = {name: stage / name for name in FILES}
        if isinstance(blob, dict):  # an asset: its own resources under their relative paths
            files.pop("scene.bin")
            for rel, data in blob.items():
                files[rel] = out / rel
                (stage / rel).parent.mkdir(parents=True, exist_ok=True)
                write_bytes_atomic(stage / rel, data)
        else:
            write_bytes_atomic(staged["scene.bin"], blob)
        write_bytes_atomic(staged["scene.gltf"], (dump_json(doc) + "\n").encode())
        write_exr(staged["environment.exr"], Image.from_rgb(eq, {"orientation": ENVIRONMENT_ORIENTATION}))
        write_hdr(staged["environment.hdr"], eq)
        write_json_atomic(staged["scenario.json"], sc)
    return Export(out, files, sc, segments, triangles, unmodelled, keep_unmodelled)

