"""glTF assets in pbrcheck scenes: the ``[[objects]] type = "gltf"`` entry and scenes made from an asset
file alone (``pbrcheck COMMAND asset.glb --env FILE --size WxH``).

API
---
- :class:`AssetInstance` -- one ``gltf`` object of a scene: the file, its placement, the loaded asset.
- :class:`Mesh` -- one (node, primitive) of an instance as a scene object (id, ``node/mesh/primitive``).
- :func:`expand_gltf_object` -- a scene file's ``gltf`` table -> (instance, meshes, point lights).
- :func:`asset_scene` -- a :class:`~pbrcheck.scene.Scene` from an asset file (camera, environment, size).
- :func:`set_asset_options` / :func:`asset_options` -- ``--env`` and ``--size`` for asset paths (the CLI).
- :func:`framing_camera` -- model-viewer's default framing of a bounding box.
- :func:`is_asset_path`, :func:`scene_has_assets`, :func:`material_summary`.

Placement convention: ``matrix = T(translation) * R * S(scale)`` applied to the asset's world (its
node hierarchy resolved), with ``R = Rz(rz) * Ry(ry) * Rx(rx)`` for ``rotation = [rx, ry, rz]`` in
degrees (rotate about X first, then Y, then Z; right-handed, counter-clockwise looking down each
axis toward the origin); ``scale`` a number or three.

Framing (model-viewer's defaults, ``camera-orbit = "0deg 75deg 105%"``, ``field-of-view = 45deg``): the
target is the bounding box's centre, the bounding sphere's radius ``r`` is half the box's diagonal,
the camera sits at ``1.05 * r / sin(fov / 2)`` (``fov`` the smaller of the vertical and the
horizontal field of view) on the orbit ``theta = 0`` (azimuth from +Z about +Y), ``phi = 75 deg``
(from +Y).

Lights: ``KHR_lights_punctual`` point lights become scene point lights (1 cd taken as 1 W/sr, the
export's convention, times ``color``); spot and directional lights are refused (:class:`AssetError`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .gltf import Asset, AssetError, load_asset
from .scene import Camera, Environment, Material, PointLight, Scene, SceneError

#: model-viewer's default vertical field of view (degrees), orbit (degrees) and radius factor.
FRAMING_FOV_DEG = 45.0
FRAMING_THETA_DEG = 0.0
FRAMING_PHI_DEG = 75.0
FRAMING_RADIUS_FACTOR = 1.05
#: Image size of an asset scene without ``--size`` (width, height).
DEFAULT_ASSET_SIZE = (512, 512)
#: The neutral built-in environment of an asset scene without ``--env``: constant radiance 1.
NEUTRAL_ENVIRONMENT = Environment(type="constant", radiance=(1.0, 1.0, 1.0))
ASSET_SUFFIXES = (".gltf", ".glb")

_OPTIONS: dict = {"env": None, "size": None}


def set_asset_options(env: str | None = None, size: tuple[int, int] | None = None) -> None:
    """Environment file and image size for scenes made from an asset path (set by the CLI)."""
    _OPTIONS["env"], _OPTIONS["size"] = env, size


def asset_options() -> dict:
    return dict(_OPTIONS)


def parse_size(s: str) -> tuple[int, int]:
    """``"WxH"`` -> (W, H); raises ValueError."""
    w, sep, h = s.lower().partition("x")
    if not sep:
        raise ValueError(f"expected WxH, found {s!r}")
    W, H = int(w), int(h)
    if not (1 <= W <= 16384 and 1 <= H <= 16384):
        raise ValueError(f"expected sides in [1, 16384], found {s!r}")
    return W, H


def is_asset_path(s: str | Path) -> bool:
    return Path(str(s)).suffix.lower() in ASSET_SUFFIXES


@dataclass(frozen=True)
class AssetInstance:
    """A ``gltf`` object: the file, the glTF scene, the placement; ``asset`` is the loaded content."""
    path: str
    translation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    scene: int | None = None
    content_hash: str = ""
    first_id: int = 0
    asset: Asset | None = field(default=None, compare=False, repr=False)

    def matrix(self) -> np.ndarray:
        """4x4 placement (module docstring)."""
        rx, ry, rz = (math.radians(a) for a in self.rotation)

        def rot(axis, a):
            c, s = math.cos(a), math.sin(a)
            m = np.eye(3)
            i, j = [(1, 2), (2, 0), (0, 1)][axis]
            m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
            return m

        m = np.eye(4)
        m[:3, :3] = rot(2, rz) @ rot(1, ry) @ rot(0, rx) @ np.diag(self.scale)
        m[:3, 3] = self.translation
        return m

    def is_identity(self) -> bool:
        return bool(np.allclose(self.matrix(), np.eye(4), atol=0, rtol=0))

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """World (min, max) after placement."""
        lo, hi = self.asset.bounds()
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        m = self.matrix()
        w = corners @ m[:3, :3].T + m[:3, 3]
        return w.min(axis=0), w.max(axis=0)

    def to_dict(self) -> dict:
        return {"type": "gltf", "path": self.path, "translation": list(self.translation),
                "rotation": list(self.rotation), "scale": list(self.scale),
                **({"scene": self.scene} if self.scene is not None else {}), "content_hash": self.content_hash}


@dataclass(frozen=True)
class Mesh:
    """One (node, primitive) of an asset instance: ``name`` is ``node/mesh/primitive``; ``material``
    is the glTF material's factors as a :class:`~pbrcheck.scene.Material` (for summaries; the
    reference reads the glTF material itself: ``instance``'s ``asset.materials[gltf_material]``)."""
    id: int
    name: str
    instance: int           # index into Scene.assets
    primitive: int          # index into the asset's primitives
    gltf_material: int      # -1: the default material
    material: Material
    triangles: int = 0
    type: str = "mesh"


def material_summary(asset: Asset, index: int) -> Material:
    m = asset.material(index)
    return Material(base_color=tuple(float(c) for c in m.base_color[:3]), metallic=m.metallic,
                    roughness=m.roughness, specular=m.specular)


def _vec3(ctx, t, key, where, default):
    from .scene import _vec3 as v3
    return v3(ctx, t, key, where, default)


def expand_gltf_object(ctx, t: dict, where: str, first_id: int, instance_index: int):
    """A scene file's ``gltf`` table -> (AssetInstance, [Mesh], [PointLight]); ``ctx`` is the scene
    loader's context (file, base directory)."""
    from .scene import _check_keys, _num

    _check_keys(ctx, t, {"type", "name", "path", "translation", "rotation", "scale", "scene", "content_hash"}, where)
    p = t.get("path")
    if not isinstance(p, str) or not p:
        raise ctx.err(f"{where}.path", "the path of a .gltf or .glb file (required)", p)
    path = Path(p)
    if not path.is_absolute():
        path = (ctx.base_dir or Path.cwd()) / path
    if not path.is_file():
        raise ctx.err(f"{where}.path", "an existing .gltf or .glb file", str(path))
    if not is_asset_path(path):
        raise ctx.err(f"{where}.path", "a .gltf or .glb file", str(path))
    sc = t.get("scale", 1.0)
    if isinstance(sc, (int, float)) and not isinstance(sc, bool):
        sc = [sc, sc, sc]
    if (not isinstance(sc, list) or len(sc) != 3
            or any(isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x) or x == 0 for x in sc)):
        raise ctx.err(f"{where}.scale", "a non-zero number or 3 non-zero numbers", t.get("scale"))
    scene_i = _num(ctx, t, "scene", where, -1, lo=0, integer=True) if "scene" in t else None
    asset = load_asset(path, scene=scene_i)
    inst = AssetInstance(path=str(path.resolve()), translation=_vec3(ctx, t, "translation", where, (0.0, 0.0, 0.0)),
                         rotation=_vec3(ctx, t, "rotation", where, (0.0, 0.0, 0.0)),
                         scale=tuple(float(x) for x in sc), scene=scene_i, content_hash=asset.content_hash,
                         first_id=first_id, asset=asset)
    meshes = [Mesh(id=first_id + k, name=prim.name, instance=instance_index, primitive=k,
                   gltf_material=prim.material, material=material_summary(asset, prim.material),
                   triangles=prim.triangles)
              for k, prim in enumerate(asset.primitives)]
    lights = []
    m = inst.matrix()
    for L in asset.lights:
        if L.type != "point":
            raise AssetError(asset.path, "/extensions/KHR_lights_punctual/lights",
                             f"{L.type} light {L.name!r}: only point lights are supported (spot and directional: not yet)")
        pos = np.asarray(L.position) @ m[:3, :3].T + m[:3, 3]
        lights.append(PointLight(position=tuple(float(x) for x in pos),
                                 intensity=tuple(float(c) * L.intensity for c in L.color)))
    return inst, meshes, lights


def scene_has_assets(scene: Scene) -> bool:
    return bool(getattr(scene, "assets", ()))


def framing_camera(lo, hi, width: int, height: int) -> Camera:
    """model-viewer's default framing of the box [lo, hi] (module docstring)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    c = 0.5 * (lo + hi)
    r = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-6)
    ty = math.tan(math.radians(FRAMING_FOV_DEG) / 2)
    tx = ty * width / height
    half = min(math.atan(tx), math.atan(ty))
    dist = FRAMING_RADIUS_FACTOR * r / math.sin(half)
    th, ph = math.radians(FRAMING_THETA_DEG), math.radians(FRAMING_PHI_DEG)
    d = np.array([math.sin(ph) * math.sin(th), math.cos(ph), math.sin(ph) * math.cos(th)])
    return Camera(origin=tuple(float(x) for x in c + dist * d), target=tuple(float(x) for x in c),
                  up=(0.0, 1.0, 0.0), fov=math.degrees(2 * math.atan(tx)), width=width, height=height)


def asset_scene(path: str | Path, *, env: str | None = None, size: tuple[int, int] | None = None) -> Scene:
    """A scene of one asset: its first camera or model-viewer's framing, ``env`` (an .hdr/.exr file)
    or :data:`NEUTRAL_ENVIRONMENT`, ``size`` (W, H; default :data:`DEFAULT_ASSET_SIZE`, or the
    camera's aspect ratio at that height)."""
    from .scene import scene_from_dict

    p = Path(path)
    opts = asset_options()
    env = env if env is not None else opts["env"]
    size = size if size is not None else opts["size"]
    data: dict = {"name": p.stem, "description": f"glTF asset {p.name}",
                  "objects": [{"type": "gltf", "path": str(p.resolve())}]}
    if env is not None:
        data["environment"] = {"type": "file", "path": str(Path(env).resolve())}
    else:
        data["environment"] = {"type": "constant", "radiance": list(NEUTRAL_ENVIRONMENT.radiance)}
    scene = scene_from_dict(data, file=str(p), base_dir=p.parent)
    asset = scene.assets[0].asset
    if asset.cameras:
        cam = asset.cameras[0]
        if size is None:
            H = DEFAULT_ASSET_SIZE[1]
            W = int(round(H * cam.aspect)) if cam.aspect else DEFAULT_ASSET_SIZE[0]
        else:
            W, H = size
        tx = math.tan(cam.yfov / 2) * W / H
        o = np.asarray(cam.origin)
        camera = Camera(origin=cam.origin, target=tuple(float(x) for x in o + np.asarray(cam.forward)),
                        up=cam.up, fov=math.degrees(2 * math.atan(tx)), width=W, height=H)
    else:
        W, H = size if size is not None else DEFAULT_ASSET_SIZE
        lo, hi = scene.assets[0].bounds()
        camera = framing_camera(lo, hi, W, H)
    from dataclasses import replace
    return replace(scene, camera=camera)


def describe(scene: Scene) -> list[str]:
    """``check-scene``'s lines for the scene's assets: meshes, triangles, materials, textures (size,
    colour space, slot), lights, camera, extensions used and ignored."""
    from .gltf import SRGB_SLOTS

    out: list[str] = []
    for k, inst in enumerate(scene.assets):
        a = inst.asset
        out.append(f"# asset {k}: {inst.path} (glTF scene {a.scene}; translation {list(inst.translation)}, "
                   f"rotation {list(inst.rotation)} deg XYZ, scale {list(inst.scale)})")
        out.append(f"#   {len(a.primitives)} primitive(s), {a.triangles} triangles; objects (node/mesh/primitive):")
        for o in scene.objects:
            if isinstance(o, Mesh) and o.instance == k:
                p = a.primitives[o.primitive]
                extra = [s for s, on in (("flat normals", p.flat_normals), ("generated tangents", p.generated_tangents),
                                         ("TANGENT", p.tangents is not None and not p.generated_tangents),
                                         ("TEXCOORD_1", p.texcoords[1] is not None), ("COLOR_0", p.color is not None)) if on]
                out.append(f"#     object {o.id} {o.name}: {p.triangles} triangles, material "
                           f"{a.material(p.material).name!r}" + (f" ({', '.join(extra)})" if extra else ""))
        out.append(f"#   {len(a.materials)} material(s):")
        for i, m in enumerate(a.materials):
            tex = ", ".join(f"{s}=image{t.image}/uv{t.texcoord}" + (" +transform" if t.transform else "")
                            for s, t in m.textures().items())
            out.append(f"#     {i} {m.name!r}: baseColor {list(m.base_color)}, metallic {m.metallic}, roughness "
                       f"{m.roughness}, emissive {list(m.emissive)}, ior {m.ior}, alpha {m.alpha_mode}"
                       + (f" (cutoff {m.alpha_cutoff})" if m.alpha_mode == "MASK" else "")
                       + (", double-sided" if m.double_sided else "") + (f"; textures {tex}" if tex else ""))
        slots = a.texture_slots()
        out.append(f"#   {len(a.images)} texture image(s):")
        for i, im in enumerate(a.images):
            used = slots.get(i, [])
            srgb = any(u.split(":")[-1] in SRGB_SLOTS for u in used)
            lin = any(u.split(":")[-1] not in SRGB_SLOTS for u in used)
            space = "sRGB and linear" if srgb and lin else "sRGB" if srgb else "linear" if lin else "unused"
            out.append(f"#     image{i} {im.source} ({im.mime}): {im.size[0]}x{im.size[1]}, {im.pixels.shape[2] if im.pixels.ndim == 3 else 1} "
                       f"channel(s), {space}; slots {', '.join(used) or 'none'}")
        out.append(f"#   lights: {len(a.lights)}" + "".join(f"; {L.name} {L.type} {L.intensity} x {list(L.color)}" for L in a.lights))
        out.append(f"#   cameras: {len(a.cameras)}" + (f" (the first, {a.cameras[0].name!r}, is the scene's camera "
                                                       "when the asset is the scene)" if a.cameras else ""))
        out.append(f"#   extensions used: {', '.join(a.extensions_used) or 'none'}; ignored: "
                   f"{', '.join(a.extensions_ignored) or 'none'}")
    c = scene.camera
    out.append(f"# camera: origin {[round(x, 6) for x in c.origin]}, target {[round(x, 6) for x in c.target]}, "
               f"horizontal fov {c.fov:.4g} deg, {c.width}x{c.height}")
    return out


#: The one-line reason a real-time preset cannot render an asset scene (until it rasterizes meshes).
RASTER_MISSING = ("the real-time renderer ray-casts analytic spheres and planes; its mesh raster pipeline for "
                  "glTF assets does not exist yet (use ext:threejs or ext:sample-viewer)")


class UnsupportedSceneError(AssetError):
    """A renderer that cannot render a scene holding glTF assets."""


def require_analytic(scene: Scene, renderer: str) -> None:
    """Raise :class:`UnsupportedSceneError` when ``scene`` holds glTF assets (``renderer`` names who asks)."""
    if scene_has_assets(scene):
        raise UnsupportedSceneError(scene.source, "", f"{renderer}: {RASTER_MISSING}")


def split_presets(scene: Scene, presets) -> tuple[list[str], list[str]]:
    """(usable, skipped) presets for ``scene``: real-time presets are skipped on asset scenes."""
    if not scene_has_assets(scene):
        return list(presets), []
    use = [p for p in presets if str(p).startswith("ext:")]
    return use, [p for p in presets if p not in use]
