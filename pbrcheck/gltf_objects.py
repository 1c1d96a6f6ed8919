"""glTF assets as scene objects: the ``[[objects]] type = "gltf"`` entry and the defaults of scenes made
from an asset file alone (``pbrcheck COMMAND asset.glb --env FILE --size WxH``;
:func:`pbrcheck.scene.asset_scene`). Below :mod:`pbrcheck.scene` (it imports nothing of it: the scene
loader passes its context and classes in).

API
---
- :class:`AssetInstance` -- one ``gltf`` object of a scene: the file, its placement, the loaded asset.
- :class:`Mesh` -- one (node, primitive) of an instance as a scene object (id, ``node/mesh/primitive``).
- :func:`expand_gltf_object` -- a scene file's ``gltf`` table -> (instance, meshes, lights).
- :class:`AssetOptions` -- ``--env``, ``--size WxH`` and ``--variant NAME`` of a scene made from an asset path alone, an
  explicit argument of :func:`pbrcheck.scene.load_scene` (no module state); :func:`add_asset_arguments`
  gives a command that takes a SCENE the three options (listed in its ``--help``), :func:`asset_options_of`
  reads them back from the parsed arguments.
- :func:`framing` -- model-viewer's default framing of a bounding box (origin, target, horizontal fov).
- :func:`is_asset_path`, :func:`parse_size`.
- :data:`ASSET_METALLIC_BLEND` -- the ``[brdf] metallic_blend`` of a scene that holds an asset and sets none.

Placement convention: ``matrix = T(translation) * R * S(scale)`` applied to the asset's world (its
node hierarchy resolved), with ``R = Rz(rz) * Ry(ry) * Rx(rx)`` for ``rotation = [rx, ry, rz]`` in
degrees (rotate about X first, then Y, then Z; right-handed, counter-clockwise looking down each
axis toward the origin); ``scale`` a number or three.

Framing (model-viewer's defaults, ``camera-orbit = "0deg 75deg 105%"``, ``field-of-view = 45deg``): the
target is the bounding box's centre, the bounding sphere's radius ``r`` is half the box's diagonal,
the camera sits at ``1.05 * r / sin(fov / 2)`` (``fov`` the smaller of the vertical and the
horizontal field of view) on the orbit ``theta = 0`` (azimuth from +Z about +Y), ``phi = 75 deg``
(from +Y).

Lights: ``KHR_lights_punctual`` point, spot and directional lights become scene lights
(:mod:`pbrcheck.lights`: 1 cd taken as 1 W/sr and 1 lux as 1 W/m^2, the export's convention, times
``color``; position and direction, the node's -Z, through the node's world transform and then the
placement; ``range`` is not modelled).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .gltf import Asset, AssetError, load_asset
from .lights import DirectionalLight, PointLight, SpotLight

#: model-viewer's default vertical field of view (degrees), orbit (degrees) and radius factor.
FRAMING_FOV_DEG = 45.0
FRAMING_THETA_DEG = 0.0
FRAMING_PHI_DEG = 75.0
FRAMING_RADIUS_FACTOR = 1.05
#: Image size of an asset scene without ``--size`` (width, height).
DEFAULT_ASSET_SIZE = (512, 512)
#: The neutral built-in environment of an asset scene without ``--env``: constant radiance 1.
NEUTRAL_RADIANCE = (1.0, 1.0, 1.0)
ASSET_SUFFIXES = (".gltf", ".glb")
#: ``[brdf] metallic_blend`` of a scene that holds a glTF asset and does not set one (issue 40): glTF 2.0
#: Appendix B's ``mix(dielectric_brdf, metal_brdf, metallic)``, the blend the asset's own format
#: specifies and every glTF engine renders, in the reference and in the real-time material
#: composition alike. Scenes without an asset keep the seed articles' ``"f0"``
#: (:class:`pbrcheck.scene.BRDFModel`); the blend is the scene's, so analytic objects placed beside an
#: asset take it too. docs/reference.md, "The metallic blend".
ASSET_METALLIC_BLEND = "gltf"



@dataclass(frozen=True)
class AssetOptions:
    """How a scene made from an asset file alone is set up (``pbrcheck COMMAND asset.glb --env FILE
    --size WxH``; :func:`pbrcheck.scene.asset_scene`): ``env`` an .hdr/.exr file (None: the neutral
    constant environment of radiance 1), ``size`` (W, H) (None: 512 x 512, or the asset camera's
    aspect ratio at that height), ``variant`` the
    ``KHR_materials_variants`` variant drawn (None: the file's default materials). Passed to :func:`pbrcheck.scene.load_scene` explicitly; a TOML or
    built-in scene ignores it."""

    env: str | None = None
    size: tuple[int, int] | None = None
    variant: str | None = None   # KHR_materials_variants' variant drawn (None: the file's default materials)


class _AssetSize(tuple):
    """A ``--size WxH`` value given to a command whose own ``--size`` is an integer (the asset's)."""


def _size_or_own(own_type):
    """The type of a command's own ``--size N`` that also takes the asset's ``WxH``."""
    def parse(s: str):
        if "x" in s.lower():
            return _AssetSize(_wxh(s))
        return own_type(s)
    parse.__name__ = getattr(own_type, "__name__", "size")
    return parse


def _wxh(s: str) -> tuple[int, int]:
    try:
        return parse_size(s)
    except ValueError as e:
        import argparse
        raise argparse.ArgumentTypeError(str(e)) from None


#: Help of the asset options (every command that takes a SCENE).
ENV_HELP = "a glTF asset SCENE's environment (.hdr or .exr; default: constant radiance 1)"
SIZE_HELP = "a glTF asset SCENE's image size WxH (default 512x512, or its camera's aspect at height 512)"
VARIANT_HELP = "a glTF asset SCENE's KHR_materials_variants variant to draw (default: the file's default materials)"


def add_asset_arguments(parser) -> bool:
    """Give ``parser`` (a command that takes a ``scene`` or ``scenes``, positional or ``--scene``) ``--env FILE`` and
    ``--size WxH`` for asset paths (:class:`AssetOptions`, read back by :func:`asset_options_of`);
    where the command has an integer ``--size`` of its own, that option takes ``WxH`` too (the
    asset's; ``N`` stays the command's). Returns whether ``parser`` takes a SCENE."""
    actions = parser._actions  # argparse keeps no public list of a parser's arguments
    if not any(a.dest == "scene" or (a.dest == "scenes" and not a.option_strings) for a in actions):
        return False
    opts = parser._option_string_actions
    if "--env" not in opts:
        parser.add_argument("--env", dest="asset_env", default=None, metavar="FILE", help=ENV_HELP)
    if "--variant" not in opts:
        parser.add_argument("--variant", dest="asset_variant", default=None, metavar="NAME", help=VARIANT_HELP)
    if "--size" not in opts:
        parser.add_argument("--size", dest="asset_size", type=_wxh, default=None, metavar="WxH", help=SIZE_HELP)
    else:
        own = opts["--size"]
        parser.set_defaults(_own_size_default=own.default)
        own.type = _size_or_own(own.type or str)
        own.help = f"{own.help or ''}; WxH: {SIZE_HELP}"
    return True


def asset_options_of(args) -> AssetOptions:
    """The :class:`AssetOptions` of parsed command-line ``args`` (:func:`add_asset_arguments`): a
    ``WxH`` given to a command's own integer ``--size`` is the asset's, the command's own size then
    stays its default (``args.size`` is reset here, once)."""
    env = getattr(args, "asset_env", None)
    size = getattr(args, "asset_size", None)
    if isinstance(getattr(args, "size", None), _AssetSize):
        size = tuple(args.size)
        args.size = getattr(args, "_own_size_default", None)
        args.asset_size = size
    return AssetOptions(env, size, getattr(args, "asset_variant", None))


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
    variant: str | None = None       # KHR_materials_variants' variant drawn (None: the default materials)
    content_hash: str = ""
    first_id: int = 0
    lights: int = 0          # point lights of the asset appended to the scene's lights
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
                **({"scene": self.scene} if self.scene is not None else {}),
                **({"variant": self.variant} if self.variant is not None else {}), "content_hash": self.content_hash}


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
    material: object        # pbrcheck.scene.Material
    triangles: int = 0
    type: str = "mesh"


def expand_gltf_object(ctx, t: dict, where: str, first_id: int, instance_index: int, *, check_keys, num, vec3,
                       material_cls):
    """A scene file's ``gltf`` table -> (AssetInstance, [Mesh], [light]); ``ctx`` is the scene
    loader's context (file, base directory), ``check_keys``, ``num``, ``vec3`` its validators,
    ``material_cls`` its Material."""
    _check_keys, _num, _vec3 = check_keys, num, vec3

    _check_keys(ctx, t, {"type", "name", "path", "translation", "rotation", "scale", "scene", "variant", "content_hash"},
                where)
    p = t.get("path")
    if not isinstance(p, str) or not p:
        raise ctx.err(f"{where}.path", "the path of a .gltf or .glb file (required)", p)
    path = ctx.path(f"{where}.path", p)  # a scene file's path stays in its folder (pbrcheck.untrusted)
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
    variant = t.get("variant")
    if variant is not None and not isinstance(variant, str):
        raise ctx.err(f"{where}.variant", "the name of one of the asset's KHR_materials_variants variants", variant)
    asset = load_asset(path, scene=scene_i, variant=variant)
    inst = AssetInstance(path=str(path.resolve()), translation=_vec3(ctx, t, "translation", where, (0.0, 0.0, 0.0)),
                         rotation=_vec3(ctx, t, "rotation", where, (0.0, 0.0, 0.0)),
                         scale=tuple(float(x) for x in sc), scene=scene_i, variant=variant,
                         content_hash=asset.content_hash,
                         first_id=first_id, asset=asset)
    meshes = [Mesh(id=first_id + k, name=prim.name, instance=instance_index, primitive=k,
                   gltf_material=prim.material, material=_summary(material_cls, asset, prim.material),
                   triangles=prim.triangles)
              for k, prim in enumerate(asset.primitives)]
    lights = []
    m = inst.matrix()
    inst = replace(inst, lights=len(asset.lights))
    for L in asset.lights:
        lights.append(scene_light(L, m))
    return inst, meshes, lights


def scene_light(L, m: np.ndarray):
    """A glTF light (world space) placed by the instance matrix ``m`` -> the scene's light."""
    intensity = tuple(float(c) * L.intensity for c in L.color)
    pos = tuple(float(x) for x in np.asarray(L.position) @ m[:3, :3].T + m[:3, 3])
    if L.type == "point":
        return PointLight(position=pos, intensity=intensity)
    # a direction: the placement's linear part (non-singular: scale is non-zero), renormalized
    d = np.asarray(L.direction) @ m[:3, :3].T
    d = tuple(float(x) for x in d / np.linalg.norm(d))
    if L.type == "directional":
        return DirectionalLight(direction=d, intensity=intensity)
    return SpotLight(position=pos, direction=d, intensity=intensity, inner_cone_angle=L.inner_cone,
                     outer_cone_angle=L.outer_cone)


def _summary(material_cls, asset: Asset, index: int):
    """The glTF material's factors as a pbrcheck Material (for summaries and reports)."""
    m = asset.material(index)
    return material_cls(base_color=tuple(float(c) for c in m.base_color[:3]), metallic=m.metallic,
                        roughness=m.roughness, specular=m.specular)


def framing(lo, hi, width: int, height: int) -> tuple[tuple, tuple, float]:
    """model-viewer's default framing of the box [lo, hi] (module docstring): (origin, target,
    horizontal fov in degrees), up +Y."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    c = 0.5 * (lo + hi)
    r = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-6)
    ty = math.tan(math.radians(FRAMING_FOV_DEG) / 2)
    tx = ty * width / height
    half = min(math.atan(tx), math.atan(ty))
    dist = FRAMING_RADIUS_FACTOR * r / math.sin(half)
    th, ph = math.radians(FRAMING_THETA_DEG), math.radians(FRAMING_PHI_DEG)
    d = np.array([math.sin(ph) * math.sin(th), math.cos(ph), math.sin(ph) * math.cos(th)])
    return tuple(float(x) for x in c + dist * d), tuple(float(x) for x in c), math.degrees(2 * math.atan(tx))
