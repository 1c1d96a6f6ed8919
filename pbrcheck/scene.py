"""The scene model both renderers read, and its TOML loader.

A scene file names a camera, exactly one environment, optional punctual lights (point, spot,
directional: :mod:`pbrcheck.lights`, glTF's ``KHR_lights_punctual`` semantics), the ground-truth BRDF
model and a list of objects (spheres, planes, sphere grids and glTF assets, the latter two expanded
here into one sphere object each and one mesh object per (node, primitive):
:mod:`pbrcheck.gltf_objects`). A ``.gltf`` / ``.glb`` path is a scene too (:func:`asset_scene`). The
field names are a contract (see README.md, "Scene files").

Every problem is a :class:`~pbrcheck.errors.SceneError` naming the file, the dotted field, what was
expected and what was found. Loading never writes anything.

Object ids are the index in :attr:`Scene.objects` after expansion (the ``object`` AOV of both
renderers); ``-1`` is the background.

Writing: :func:`dump_toml` (a resolved scene as TOML), with :func:`toml_string` and :func:`toml_key`
escaping every string and key, so the text parses whatever an untrusted name holds (docs/security.md).
"""

from __future__ import annotations

import json
import math
import re
import tomllib
from dataclasses import asdict, dataclass, field, replace
from importlib import resources
from pathlib import Path
from typing import Any

from . import lobe_params, transmission_params
from .brdf import METALLIC_BLENDS
from .errors import SceneError, decode_reason
from .gltf_objects import (ASSET_METALLIC_BLEND, DEFAULT_ASSET_SIZE, NEUTRAL_RADIANCE, AssetOptions, expand_gltf_object,
                           framing, scene_light)
from .lights import LIGHT_TYPES, DirectionalLight, PointLight, SpotLight
from .registry import FRESNELS as _FRESNELS
from .registry import GEOMETRIC_ROUGHNESSES as _GEOMETRIC_ROUGHNESSES
from .registry import GEOMETRIES as _GEOMETRIES
from .registry import MULTISCATTER_GEOMETRY
from .registry import MULTISCATTERS as _MULTISCATTERS
from .registry import NDFS as _NDFS
from .unmodelled import announce_scene, scene_unmodelled

Vec3 = tuple[float, float, float]

#: The ``[brdf]`` values a scene may name: tuples of names (pbrcheck.registry owns the lists, as
#: :class:`~pbrcheck.registry.Registry` objects named without ``_NAMES``).
NDF_NAMES = _NDFS.scene_names
GEOMETRY_NAMES = _GEOMETRIES.scene_names
FRESNEL_NAMES = _FRESNELS.scene_names
MULTISCATTER_NAMES = _MULTISCATTERS.scene_names
GEOMETRIC_ROUGHNESS_NAMES = _GEOMETRIC_ROUGHNESSES.scene_names
#: The scene ``pbrcheck`` commands use when none is named.
DEFAULT_SCENE = "spheres"
ENVIRONMENT_TYPES = ("constant", "file", "sky", "none")
OBJECT_TYPES = ("sphere", "plane", "sphere_grid", "gltf")

# Smallest |up x view| (sine of the angle) accepted before the camera frame is called degenerate.
CAMERA_UP_PARALLEL_SINE = 1e-6
#: LDR environment files (8-bit sRGB, decoded to linear by pbrcheck.environment.read_image_file).
LDR_ENVIRONMENT_SUFFIXES = (".jpg", ".jpeg", ".png")
# Longest side of an image either renderer is asked to make (a typo guard, 16k).
MAX_IMAGE_SIDE = 16384


@dataclass(frozen=True)
class Camera:
    """Pinhole camera. ``fov`` is the *horizontal* field of view in degrees; pixel (row i, column j)
    has its centre at ndc ``x = 2 (j + 0.5) / width - 1``, ``y = 1 - 2 (i + 0.5) / height`` (row 0 at
    the top). See :mod:`pbrcheck.camera`."""

    origin: Vec3 = (0.0, 0.0, 6.0)
    target: Vec3 = (0.0, 0.0, 0.0)
    up: Vec3 = (0.0, 1.0, 0.0)
    fov: float = 40.0
    width: int = 256
    height: int = 256


@dataclass(frozen=True)
class Environment:
    """Exactly one environment. All types become one equirectangular radiance image in Mitsuba's
    convention (:mod:`pbrcheck.environment`); ``scale`` and ``rotation`` (degrees about +Y) apply
    to every type alike."""

    type: str = "constant"
    radiance: Vec3 = (1.0, 1.0, 1.0)          # constant
    path: str | None = None                   # file (absolute after loading)
    scale: float = 1.0
    rotation: float = 0.0
    # sky
    sun_direction: Vec3 = (0.3, 0.8, 0.5)
    sun_angular_diameter: float = 0.53
    sun_radiance: Vec3 = (2000.0, 1900.0, 1700.0)
    sky_radiance: Vec3 = (0.35, 0.5, 0.9)
    horizon_radiance: Vec3 = (0.9, 0.9, 0.95)
    ground_radiance: Vec3 = (0.2, 0.18, 0.15)
    resolution: tuple[int, int] = (1024, 512)  # sky raster (width, height)


@dataclass(frozen=True)
class BRDFModel:
    """The scene's ground-truth terms (``[brdf]``): members of :mod:`pbrcheck.registry`."""
    ndf: str = "ggx"
    geometry: str = "smith_ggx_correlated"
    fresnel: str = "schlick"
    # "none" | "random_walk" (reference only: reference/multiscatter.py; needs ndf = "ggx" with
    # geometry = "smith_ggx_correlated" or ndf = "beckmann" with "smith_beckmann_correlated").
    multiscatter: str = "none"
    # Perceptual roughness floor of the reference's material (reference only, like multiscatter):
    # the reference shades max(roughness, roughness_floor), the model of an engine that clamps
    # roughness (three.js r187 lights_physical_fragment: max(roughnessFactor, 0.045), Filament's
    # MIN_PERCEPTUAL_ROUGHNESS on desktop). 0 (default): no floor. The real-time renderer and the
    # external clients render the scene's roughness as written (the clients apply their own floor).
    roughness_floor: float = 0.0
    # Screen-space geometric roughness added to the (floored) roughness, reference only like the
    # floor: "none" (default) or "threejs" (three.js r187 lights_physical_fragment: + max(max |dFdx n|,
    # max |dFdy n|) of the view-space normal, then min(., 1)); derivatives over one sample of the
    # engine's raster, 1 / geometric_roughness_supersample of a pixel (the three.js client renders
    # 2 x 2 samples per pixel: 2). reference/integrator.py, docs/reference.md.
    geometric_roughness: str = "none"
    geometric_roughness_supersample: int = 1
    # How metallic mixes the material (docs/reference.md, "The metallic blend"): "f0" (default, the
    # seed articles' model: F0 = mix(specular, base_color, metallic), the diffuse weighted by 1 - F of
    # that F0) or "gltf" (glTF 2.0 Appendix B: mix(dielectric_brdf, metal_brdf, metallic), the
    # dielectric's diffuse weighted by 1 - F of its own F0 = specular). Schlick is linear in F0, so the
    # specular lobes agree; only the diffuse weight differs, and only at 0 < metallic < 1.
    metallic_blend: str = "f0"


@dataclass(frozen=True)
class Material:
    """F0 = mix(specular, base_color, metallic); alpha = roughness^2 (roughness is perceptual).

    The lobes of the glTF PBR extensions (:mod:`pbrcheck.lobe_params`; neutral defaults, the
    specifications'): parsed, validated, exported and rendered by both renderers
    (:data:`pbrcheck.lobe_params.MODELLED_LOBE_EXTENSIONS`; one they do not both render is named as
    unmodelled by :func:`pbrcheck.unmodelled.scene_unmodelled` where set). ``specular`` stays the dielectric F0;
    ``KHR_materials_specular``'s factor and colour are ``specular_factor`` and ``specular_color``."""

    base_color: Vec3 = (1.0, 1.0, 1.0)
    metallic: float = 0.0
    roughness: float = 0.5
    specular: float = 0.04
    clearcoat: float = 0.0                                   # KHR_materials_clearcoat
    clearcoat_roughness: float = 0.0
    sheen_color: Vec3 = (0.0, 0.0, 0.0)                      # KHR_materials_sheen (linear)
    sheen_roughness: float = 0.0
    specular_factor: float = 1.0                             # KHR_materials_specular
    specular_color: Vec3 = (1.0, 1.0, 1.0)
    anisotropy_strength: float = 0.0                         # KHR_materials_anisotropy
    anisotropy_rotation: float = 0.0                         # radians, counter-clockwise from the tangent
    iridescence: float = 0.0                                 # KHR_materials_iridescence
    iridescence_ior: float = 1.3
    iridescence_thickness: float = 400.0                     # nm
    # Light through the surface (pbrcheck.transmission_params, issue 37; the IOR is the specular F0's).
    transmission: float = 0.0                                # KHR_materials_transmission
    thickness: float = 0.0                                   # KHR_materials_volume (0: thin-walled)
    attenuation_distance: float = 0.0                        # world units; 0: glTF's +inf (none)
    attenuation_color: Vec3 = (1.0, 1.0, 1.0)
    dispersion: float = 0.0                                  # KHR_materials_dispersion: 20 / Abbe number
    diffuse_transmission: float = 0.0                        # KHR_materials_diffuse_transmission
    diffuse_transmission_color: Vec3 = (1.0, 1.0, 1.0)

    @property
    def alpha(self) -> float:
        return self.roughness * self.roughness

    @property
    def f0(self) -> Vec3:
        m = self.metallic
        return tuple(self.specular * (1.0 - m) + c * m for c in self.base_color)  # type: ignore[return-value]


@dataclass(frozen=True)
class Sphere:
    """A sphere object (after sphere grids are expanded); ``id`` is its index in :attr:`Scene.objects`."""
    id: int
    center: Vec3
    radius: float
    material: Material
    name: str = ""
    type: str = "sphere"


@dataclass(frozen=True)
class Plane:
    """A rectangle of ``size = (sx, sy)`` centred at ``center`` with unit ``normal``; its in-plane
    axes are :func:`plane_frame` of the normal (sx along the tangent, sy along the bitangent)."""

    id: int
    center: Vec3
    normal: Vec3
    size: tuple[float, float]
    material: Material
    name: str = ""
    type: str = "plane"


@dataclass(frozen=True)
class Scene:
    """A resolved scene: camera, environment, punctual lights, BRDF model and objects (sphere grids
    expanded; ``grids`` keeps their layout); immutable."""
    name: str
    description: str
    camera: Camera
    environment: Environment
    lights: tuple[PointLight | SpotLight | DirectionalLight, ...]
    brdf: BRDFModel
    objects: tuple[Sphere | Plane, ...]
    source: str = "<dict>"
    # The grid layout of sphere_grid objects, for reports: (first id, rows, columns, metallic range,
    # roughness range) per grid.
    grids: tuple[dict, ...] = field(default_factory=tuple)
    # glTF assets (pbrcheck.gltf_objects.AssetInstance), their primitives in ``objects`` as Mesh.
    assets: tuple = field(default_factory=tuple)

    def own_lights(self) -> tuple:
        """The scene file's own lights: :attr:`lights` less those its glTF assets brought (loaded
        after the scene file's, in the assets' order)."""
        return self.lights[:len(self.lights) - sum(a.lights for a in self.assets)]

    def to_dict(self) -> dict[str, Any]:
        """Resolved scene as plain data (objects expanded, defaults filled)."""
        # glTF assets: their ``gltf`` table in place of their mesh objects, their lights left out
        # (both come back from the asset when the resolved scene is loaded again)
        objects = [a.to_dict() if o.type == "mesh" else _object_dict(o) for o in self.objects
                   for a in ([self.assets[o.instance]] if o.type == "mesh" else [None])
                   if o.type != "mesh" or o.id == a.first_id]
        d = {
            "name": self.name,
            "description": self.description,
            "camera": asdict(self.camera),
            "environment": _environment_dict(self.environment),
            "lights": [asdict(l) for l in self.own_lights()],
            "brdf": asdict(self.brdf),
            "objects": objects,
        }
        return _plain(d)

    def content_dict(self) -> dict[str, Any]:
        """What determines the pixels: :meth:`to_dict` less name, description and file paths."""
        d = self.to_dict()
        for k in ("name", "description"):
            d.pop(k)
        d["environment"].pop("path", None)
        if d["brdf"].get("multiscatter") == "none":
            d["brdf"].pop("multiscatter")  # the default keeps the content hashes of earlier versions
        if d["brdf"].get("roughness_floor") == 0.0:
            d["brdf"].pop("roughness_floor")  # likewise
        if d["brdf"].get("geometric_roughness") == "none":
            d["brdf"].pop("geometric_roughness")  # likewise
        if d["brdf"].get("geometric_roughness_supersample") == 1:
            d["brdf"].pop("geometric_roughness_supersample")  # likewise
        if d["brdf"].get("metallic_blend") == "f0":
            d["brdf"].pop("metallic_blend")  # likewise
        for o in d["objects"]:
            o.pop("name", None)
            if o["type"] == "gltf":
                o.pop("path")  # the content hash stands for the file and its resources
        # the assets' lights are their content hashes', unless edited (diagnose's light units): then
        # the lights themselves, so that an edited scene is not another scene's cache entry
        brought = self.lights[len(self.own_lights()):]
        if all(a.asset is not None for a in self.assets) and brought != self.assets_lights():
            d["asset_lights"] = [asdict(li) for li in brought]
        return d

    def assets_lights(self) -> tuple:
        """The lights the glTF assets bring as loaded (``KHR_lights_punctual``, placed by each
        instance), in the assets' order: what :attr:`lights` ends with unless a caller edited them."""
        return tuple(scene_light(L, a.matrix()) for a in self.assets for L in a.asset.lights)

    def with_camera(self, **changes) -> "Scene":
        return replace(self, camera=replace(self.camera, **changes))

    @property
    def unmodelled(self) -> tuple:
        """The features of the scene's glTF assets that pbrcheck does not model
        (:class:`pbrcheck.unmodelled.Unmodelled`: feature, material names, object ids, asset path)."""
        return scene_unmodelled(self)


def _object_dict(o) -> dict[str, Any]:
    """An analytic object as plain data, its material's lobe fields at their neutral values left
    out (a scene that sets none keeps its text and content hash)."""
    d = asdict(o)
    d["material"] = transmission_params.neutral_scene_keys(lobe_params.neutral_scene_keys(d["material"]))
    return d


def _environment_dict(env: Environment) -> dict[str, Any]:
    keep = {"type", "scale", "rotation"}
    if env.type == "constant":
        keep |= {"radiance"}
    elif env.type == "file":
        keep |= {"path"}
    elif env.type == "sky":
        keep |= {"sun_direction", "sun_angular_diameter", "sun_radiance", "sky_radiance",
                 "horizon_radiance", "ground_radiance", "resolution"}
    return {k: v for k, v in asdict(env).items() if k in keep}


def _plain(x):
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    return x


def plane_frame(normal: Vec3) -> tuple[Vec3, Vec3, Vec3]:
    """(tangent, bitangent, normal) of a plane: an orthonormal right-handed frame, deterministic in
    the normal. The tangent is +X projected into the plane, or +Z where the normal is within ~8
    degrees of X, so that a floor (normal +Y) has its ``size[0]`` along X and ``size[1]`` along -Z."""
    n = _normalize(normal)
    hint = (1.0, 0.0, 0.0) if abs(n[0]) < 0.99 else (0.0, 0.0, 1.0)
    d = _dot(hint, n)
    t = _normalize(tuple(h - d * c for h, c in zip(hint, n)))
    b = _cross(n, t)
    return t, b, n


# ---------------------------------------------------------------------------------------------
# Loading and validation
# ---------------------------------------------------------------------------------------------


class _Ctx:
    """Where we are: the file (for messages) and its directory (for relative paths)."""

    def __init__(self, file: str, base_dir: Path | None, contained: bool = False):
        self.file = file
        self.base_dir = base_dir
        self.contained = contained  # a scene file's own paths stay in its folder (pbrcheck.untrusted)

    def path(self, fieldname: str, p: str) -> Path:
        """A path written in the scene, resolved (:func:`pbrcheck.untrusted.scene_file_path`)."""
        from .untrusted import scene_file_path
        try:
            return scene_file_path(self.base_dir, p, self.contained)
        except ValueError as e:
            raise SceneError(self.file, fieldname, "", message=f"{self.file}: {fieldname}: refused: {e}") from None

    def err(self, fieldname: str, expected: str, found: object = None) -> SceneError:
        return SceneError(self.file, fieldname, expected, found)


def _check_keys(ctx: _Ctx, table: dict, allowed: set[str], where: str) -> None:
    if not isinstance(table, dict):
        raise ctx.err(where, "a table", table)
    for k in table:
        if k not in allowed:
            raise ctx.err(f"{where}.{k}" if where else k, "one of the keys " + ", ".join(sorted(allowed)),
                          f"unknown key {k!r}")


def _num(ctx, t, key, where, default=None, *, lo=None, hi=None, lo_open=False, integer=False):
    f = f"{where}.{key}" if where else key
    if key not in t:
        if default is None:
            raise ctx.err(f, "a number (required)", "nothing")
        return default
    v = t[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or (integer and not isinstance(v, int)):
        raise ctx.err(f, "an integer" if integer else "a number", v)
    if not math.isfinite(v):
        raise ctx.err(f, "a finite number", v)
    if lo is not None and (v <= lo if lo_open else v < lo):
        raise ctx.err(f, f"a number {'>' if lo_open else '>='} {lo}", v)
    if hi is not None and v > hi:
        raise ctx.err(f, f"a number <= {hi}", v)
    return int(v) if integer else float(v)


def _vec3(ctx, t, key, where, default=None, *, nonneg=False, nonzero=False):
    f = f"{where}.{key}" if where else key
    if key not in t:
        if default is None:
            raise ctx.err(f, "an array of 3 numbers (required)", "nothing")
        return default
    v = t[key]
    if (not isinstance(v, list) or len(v) != 3
            or any(isinstance(x, bool) or not isinstance(x, (int, float)) for x in v)):
        raise ctx.err(f, "an array of 3 numbers", v)
    if not all(math.isfinite(x) for x in v):
        raise ctx.err(f, "3 finite numbers", v)
    if nonneg and any(x < 0 for x in v):
        raise ctx.err(f, "3 non-negative numbers", v)
    if nonzero and math.sqrt(sum(x * x for x in v)) < 1e-12:
        raise ctx.err(f, "a non-zero vector", v)
    return (float(v[0]), float(v[1]), float(v[2]))


def _str(ctx, t, key, where, default=None, choices=None):
    f = f"{where}.{key}" if where else key
    if key not in t:
        if default is None:
            raise ctx.err(f, "a string (required)", "nothing")
        return default
    v = t[key]
    if not isinstance(v, str):
        raise ctx.err(f, "a string", v)
    if choices is not None and v not in choices:
        raise ctx.err(f, "one of " + " | ".join(choices), v)
    return v


def _range2(ctx, t, key, where, default):
    f = f"{where}.{key}"
    if key not in t:
        return default
    v = t[key]
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        v = [v, v]
    if (not isinstance(v, list) or len(v) != 2
            or any(isinstance(x, bool) or not isinstance(x, (int, float)) for x in v)):
        raise ctx.err(f, "a number or an array [min, max] in [0, 1]", v)
    if any(not (0.0 <= x <= 1.0) for x in v):
        raise ctx.err(f, "values in [0, 1]", v)
    return (float(v[0]), float(v[1]))


def _camera(ctx, t) -> Camera:
    _check_keys(ctx, t, {"origin", "target", "up", "fov", "width", "height"}, "camera")
    c = Camera(
        origin=_vec3(ctx, t, "origin", "camera", Camera.origin),
        target=_vec3(ctx, t, "target", "camera", Camera.target),
        up=_vec3(ctx, t, "up", "camera", Camera.up, nonzero=True),
        fov=_num(ctx, t, "fov", "camera", Camera.fov, lo=0.0, lo_open=True, hi=179.0),
        width=_num(ctx, t, "width", "camera", Camera.width, lo=1, hi=MAX_IMAGE_SIDE, integer=True),
        height=_num(ctx, t, "height", "camera", Camera.height, lo=1, hi=MAX_IMAGE_SIDE, integer=True),
    )
    view = tuple(a - b for a, b in zip(c.target, c.origin))
    if _norm(view) < 1e-12:
        raise ctx.err("camera.target", "a point different from camera.origin", list(c.target))
    s = _norm(_cross(_normalize(view), _normalize(c.up)))
    if s < CAMERA_UP_PARALLEL_SINE:
        raise ctx.err("camera.up", "a vector not parallel to the view direction", list(c.up))
    return c


def _environment(ctx, t) -> Environment:
    if not isinstance(t, dict):
        raise ctx.err("environment", "a table", t)
    typ = _str(ctx, t, "type", "environment", choices=ENVIRONMENT_TYPES)
    common = {"type", "scale", "rotation"}
    per_type = {
        "constant": {"radiance"},
        "file": {"path"},
        "sky": {"sun_direction", "sun_angular_diameter", "sun_radiance", "sky_radiance",
                "horizon_radiance", "ground_radiance", "resolution"},
        "none": set(),
    }
    _check_keys(ctx, t, common | per_type[typ], "environment")
    kw: dict[str, Any] = {
        "type": typ,
        "scale": _num(ctx, t, "scale", "environment", 1.0, lo=0.0),
        "rotation": _num(ctx, t, "rotation", "environment", 0.0),
    }
    if typ == "constant":
        kw["radiance"] = _vec3(ctx, t, "radiance", "environment", (1.0, 1.0, 1.0), nonneg=True)
    elif typ == "file":
        p = _str(ctx, t, "path", "environment")
        path = ctx.path("environment.path", p)
        if not path.is_file():
            raise ctx.err("environment.path", "an existing .exr or .hdr file", str(path))
        if path.suffix.lower() not in (".exr", ".hdr") + LDR_ENVIRONMENT_SUFFIXES:
            raise ctx.err("environment.path", "a .exr or .hdr file (or an sRGB " + ", ".join(LDR_ENVIRONMENT_SUFFIXES)
                          + " file)", str(path))
        kw["path"] = str(path.resolve())
    elif typ == "sky":
        d = Environment()
        kw["sun_direction"] = _normalize(_vec3(ctx, t, "sun_direction", "environment", d.sun_direction, nonzero=True))
        kw["sun_angular_diameter"] = _num(ctx, t, "sun_angular_diameter", "environment", d.sun_angular_diameter,
                                          lo=0.0, lo_open=True, hi=90.0)
        for k in ("sun_radiance", "sky_radiance", "horizon_radiance", "ground_radiance"):
            kw[k] = _vec3(ctx, t, k, "environment", getattr(d, k), nonneg=True)
        if "resolution" in t:
            r = t["resolution"]
            if (not isinstance(r, list) or len(r) != 2 or any(isinstance(x, bool) or not isinstance(x, int) for x in r)
                    or not (2 <= r[0] <= 16384 and 3 <= r[1] <= 8192)):
                raise ctx.err("environment.resolution", "[width, height] integers, width in [2, 16384], height in [3, 8192]", r)
            kw["resolution"] = (r[0], r[1])
    return Environment(**kw)


def _lights(ctx, lst) -> tuple[PointLight | SpotLight | DirectionalLight, ...]:
    """``[[lights]]``: pbrcheck.lights has the types and their conventions (glTF's semantics)."""
    if not isinstance(lst, list):
        raise ctx.err("lights", "an array of tables [[lights]]", lst)
    keys = {"point": {"position"}, "spot": {"position", "direction", "inner_cone_angle", "outer_cone_angle"},
            "directional": {"direction"}}
    out = []
    for i, t in enumerate(lst):
        w = f"lights[{i}]"
        if not isinstance(t, dict):
            raise ctx.err(w, "a table", t)
        typ = _str(ctx, t, "type", w, "point", choices=LIGHT_TYPES)
        _check_keys(ctx, t, {"type", "intensity"} | keys[typ], w)
        intensity = _vec3(ctx, t, "intensity", w, nonneg=True)
        if typ == "point":
            out.append(PointLight(position=_vec3(ctx, t, "position", w), intensity=intensity))
            continue
        direction = _normalize(_vec3(ctx, t, "direction", w, nonzero=True))
        if typ == "directional":
            out.append(DirectionalLight(direction=direction, intensity=intensity))
            continue
        outer = _num(ctx, t, "outer_cone_angle", w, SpotLight.outer_cone_angle, lo=0.0, lo_open=True, hi=math.pi / 2)
        inner = _num(ctx, t, "inner_cone_angle", w, SpotLight.inner_cone_angle, lo=0.0)
        if not inner < outer:
            raise ctx.err(f"{w}.inner_cone_angle", f"an angle in radians >= 0 and < outer_cone_angle ({outer!r})", inner)
        out.append(SpotLight(position=_vec3(ctx, t, "position", w), direction=direction, intensity=intensity,
                             inner_cone_angle=inner, outer_cone_angle=outer))
    return tuple(out)


def _brdf(ctx, t, *, has_assets: bool = False) -> BRDFModel:
    """The ``[brdf]`` table. ``has_assets``: the scene holds a glTF asset, so its ``metallic_blend``
    defaults to glTF's (:data:`pbrcheck.gltf_objects.ASSET_METALLIC_BLEND`), not the seeds' ``"f0"``."""
    blend_default = ASSET_METALLIC_BLEND if has_assets else BRDFModel.metallic_blend
    _check_keys(ctx, t, {"ndf", "geometry", "fresnel", "multiscatter", "roughness_floor", "geometric_roughness",
                         "geometric_roughness_supersample", "metallic_blend"}, "brdf")
    model = BRDFModel(
        ndf=_str(ctx, t, "ndf", "brdf", "ggx", NDF_NAMES),
        geometry=_str(ctx, t, "geometry", "brdf", "smith_ggx_correlated", GEOMETRY_NAMES),
        fresnel=_str(ctx, t, "fresnel", "brdf", "schlick", FRESNEL_NAMES),
        multiscatter=_str(ctx, t, "multiscatter", "brdf", "none", MULTISCATTER_NAMES),
        roughness_floor=float(_num(ctx, t, "roughness_floor", "brdf", 0.0, lo=0.0, hi=1.0)),
        geometric_roughness=_str(ctx, t, "geometric_roughness", "brdf", "none", GEOMETRIC_ROUGHNESS_NAMES),
        geometric_roughness_supersample=int(_num(ctx, t, "geometric_roughness_supersample", "brdf", 1, lo=1, hi=16,
                                                 integer=True)),
        metallic_blend=_str(ctx, t, "metallic_blend", "brdf", blend_default, METALLIC_BLENDS),
    )
    if model.multiscatter != "none":
        # The random walk's first bounce is the NDF's height-correlated Smith term.
        need = MULTISCATTER_GEOMETRY.get(model.ndf)
        if need is None:
            raise ctx.err("brdf.ndf", f'one of {", ".join(MULTISCATTER_GEOMETRY)} with multiscatter = '
                          f'"{model.multiscatter}"', model.ndf)
        if model.geometry != need:
            raise ctx.err("brdf.geometry", f'"{need}" with ndf = "{model.ndf}" and multiscatter = '
                          f'"{model.multiscatter}"', model.geometry)
    return model


def _material(ctx, t, where, *, grid=False) -> Material:
    keys = {"base_color", "specular"} if grid else {"base_color", "metallic", "roughness", "specular"}
    _check_keys(ctx, t, keys | set(lobe_params.SCENE_DEFAULTS) | set(transmission_params.SCENE_DEFAULTS), where)
    d = Material()
    return Material(
        base_color=_vec3(ctx, t, "base_color", where, d.base_color, nonneg=True),
        metallic=d.metallic if grid else _num(ctx, t, "metallic", where, d.metallic, lo=0.0, hi=1.0),
        roughness=d.roughness if grid else _num(ctx, t, "roughness", where, d.roughness, lo=0.0, hi=1.0),
        specular=_num(ctx, t, "specular", where, d.specular, lo=0.0, hi=1.0),
        **lobe_params.scene_material_fields(ctx, t, where, _num, _vec3),
        **transmission_params.scene_material_fields(ctx, t, where, _num, _vec3),
    )


def _objects(ctx, lst):
    if not isinstance(lst, list) or not lst:
        raise ctx.err("objects", "a non-empty array of tables [[objects]]", lst)
    objects: list[Sphere | Plane] = []
    grids: list[dict] = []
    assets: list = []
    asset_lights: list = []
    for i, t in enumerate(lst):
        w = f"objects[{i}]"
        if not isinstance(t, dict):
            raise ctx.err(w, "a table", t)
        typ = _str(ctx, t, "type", w, choices=OBJECT_TYPES)
        name = t.get("name", "")
        if not isinstance(name, str):
            raise ctx.err(f"{w}.name", "a string", name)
        if typ != "sphere_grid" and "id" in t and t["id"] != len(objects):
            # resolved scenes (check-scene output) carry ids; they must be the index after expansion
            raise ctx.err(f"{w}.id", f"{len(objects)} (the object's index after sphere grids are expanded)", t["id"])
        if typ == "gltf":  # pbrcheck.gltf_objects: one Mesh object per (node, primitive)
            inst, meshes, lights = expand_gltf_object(ctx, t, w, len(objects), len(assets), check_keys=_check_keys,
                                                      num=_num, vec3=_vec3, material_cls=Material)
            assets.append(inst)
            objects.extend(meshes)
            asset_lights.extend(lights)
        elif typ == "sphere":
            _check_keys(ctx, t, {"type", "name", "id", "center", "radius", "material"}, w)
            objects.append(Sphere(id=len(objects), name=name or f"sphere{len(objects)}",
                                  center=_vec3(ctx, t, "center", w, (0.0, 0.0, 0.0)),
                                  radius=_num(ctx, t, "radius", w, 1.0, lo=0.0, lo_open=True),
                                  material=_material(ctx, t.get("material", {}), f"{w}.material")))
        elif typ == "plane":
            _check_keys(ctx, t, {"type", "name", "id", "center", "normal", "size", "material"}, w)
            size = t.get("size", [10.0, 10.0])
            if isinstance(size, (int, float)) and not isinstance(size, bool):
                size = [size, size]
            if (not isinstance(size, list) or len(size) != 2
                    or any(isinstance(x, bool) or not isinstance(x, (int, float)) or not x > 0 or not math.isfinite(x)
                           for x in size)):
                raise ctx.err(f"{w}.size", "a positive number or [sx, sy]", size)
            objects.append(Plane(id=len(objects), name=name or f"plane{len(objects)}",
                                 center=_vec3(ctx, t, "center", w, (0.0, 0.0, 0.0)),
                                 normal=_normalize(_vec3(ctx, t, "normal", w, (0.0, 1.0, 0.0), nonzero=True)),
                                 size=(float(size[0]), float(size[1])),
                                 material=_material(ctx, t.get("material", {}), f"{w}.material")))
        else:
            _check_keys(ctx, t, {"type", "name", "center", "rows", "columns", "spacing", "radius",
                                 "metallic", "roughness", "right", "up", "material"}, w)
            center = _vec3(ctx, t, "center", w, (0.0, 0.0, 0.0))
            rows = _num(ctx, t, "rows", w, 4, lo=1, hi=64, integer=True)
            cols = _num(ctx, t, "columns", w, 6, lo=1, hi=64, integer=True)
            radius = _num(ctx, t, "radius", w, 0.45, lo=0.0, lo_open=True)
            spacing = _num(ctx, t, "spacing", w, 2.2 * radius, lo=0.0, lo_open=True)
            met = _range2(ctx, t, "metallic", w, (0.0, 1.0))
            rough = _range2(ctx, t, "roughness", w, (0.0, 1.0))
            right = _normalize(_vec3(ctx, t, "right", w, (1.0, 0.0, 0.0), nonzero=True))
            up = _normalize(_vec3(ctx, t, "up", w, (0.0, 1.0, 0.0), nonzero=True))
            if abs(_dot(right, up)) > 1e-6:
                raise ctx.err(f"{w}.up", "a vector perpendicular to right", list(up))
            base = _material(ctx, t.get("material", {}), f"{w}.material", grid=True)
            first = len(objects)
            for r in range(rows):           # bottom to top: metallic
                m = met[0] + (met[1] - met[0]) * (r / (rows - 1) if rows > 1 else 0.0)
                for c in range(cols):       # left to right: roughness
                    g = rough[0] + (rough[1] - rough[0]) * (c / (cols - 1) if cols > 1 else 0.0)
                    x = (c - (cols - 1) / 2) * spacing
                    y = (r - (rows - 1) / 2) * spacing
                    pos = tuple(center[k] + x * right[k] + y * up[k] for k in range(3))
                    objects.append(Sphere(id=len(objects), name=f"{name or 'grid'}[r{r},c{c}]",
                                          center=pos, radius=radius,
                                          material=replace(base, metallic=round(m, 9), roughness=round(g, 9))))
            grids.append({"first_id": first, "rows": rows, "columns": cols, "metallic": met, "roughness": rough})
    return tuple(objects), tuple(grids), tuple(assets), tuple(asset_lights)


def scene_from_dict(data: dict, *, file: str = "<dict>", base_dir: Path | None = None,
                    contained: bool = False) -> Scene:
    """Validate a parsed scene table; raise :class:`SceneError` on the first problem. ``contained``
    (a scene read from a file, :func:`load_scene`): every path it names must resolve inside
    ``base_dir`` (docs/assets.md, "Paths an asset or a scene may name")."""
    ctx = _Ctx(file, base_dir, contained)
    if not isinstance(data, dict):
        raise ctx.err("", "a table", data)
    _check_keys(ctx, data, {"name", "description", "camera", "environment", "lights", "brdf", "objects"}, "")
    if "environment" not in data:
        raise ctx.err("environment", "exactly one [environment] table", "nothing")
    objects, grids, assets, asset_lights = _objects(ctx, data.get("objects"))
    return announce_scene(Scene(   # the analytic objects' unmodelled lobes named on stderr (pbrcheck.unmodelled)
        name=_str(ctx, data, "name", "", Path(file).stem if file != "<dict>" else "scene"),
        description=_str(ctx, data, "description", "", ""),
        camera=_camera(ctx, data.get("camera", {})),
        environment=_environment(ctx, data["environment"]),
        lights=_lights(ctx, data.get("lights", [])) + asset_lights,
        brdf=_brdf(ctx, data.get("brdf", {}), has_assets=bool(assets)),
        objects=objects,
        source=file,
        grids=grids,
        assets=assets,
    ))


def builtin_scene_names() -> list[str]:
    """Names of the built-in scenes (``pbrcheck/scenes/*.toml``), sorted."""
    root = resources.files("pbrcheck") / "scenes"
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith(".toml"))


def builtin_scene_path(name: str) -> Path:
    """Path of built-in scene ``name``'s TOML file."""
    return Path(str(resources.files("pbrcheck") / "scenes" / f"{name}.toml"))


def load_scene(name_or_path: str | Path, assets: AssetOptions | None = None) -> Scene:
    """Load a built-in scene by name (``spheres``), a TOML file by path, or a scene of one glTF asset
    file (``.gltf`` / ``.glb``) set up by ``assets`` (:class:`pbrcheck.gltf_objects.AssetOptions`:
    the command line's ``--env``, ``--size WxH`` and ``--variant``; None: the neutral environment at the default
    size). Reads no module state: the same call gives the same scene."""
    s = str(name_or_path)
    p = Path(s)
    if p.suffix.lower() in (".gltf", ".glb") and p.is_file():
        assets = assets or AssetOptions()
        return asset_scene(p, env=assets.env, size=assets.size, variant=assets.variant)  # an asset alone
    if not p.suffix and s in builtin_scene_names():
        p = builtin_scene_path(s)
    elif not p.exists():
        known = ", ".join(builtin_scene_names())
        raise SceneError(s, None, f"a scene file or a built-in scene name ({known})",
                         message=f"{s}: no such scene file, and not a built-in scene ({known})")
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as e:
        raise SceneError(str(p), None, "a readable file", message=f"{p}: cannot read: {e.strerror}") from None
    except UnicodeDecodeError as e:  # e.g. a binary file given as a TOML scene
        raise SceneError(str(p), None, "a TOML scene file (UTF-8 text)",
                         message=f"{p}: not a TOML scene file: {decode_reason(e)}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise SceneError(str(p), None, "valid TOML", message=f"{p}: invalid TOML: {e}") from None
    return scene_from_dict(data, file=str(p), base_dir=p.parent, contained=True)


def asset_scene(path: str | Path, *, env: str | None = None, size: tuple[int, int] | None = None,
                variant: str | None = None) -> Scene:
    """A scene of one glTF asset (``pbrcheck COMMAND asset.glb``): its first camera, else model-viewer's
    default framing (:func:`pbrcheck.gltf_objects.framing`); ``env`` (an .hdr/.exr file) or the
    neutral constant environment of radiance 1; ``size`` (W, H; default 512 x 512, or the camera's
    aspect ratio at that height); ``variant``: the ``KHR_materials_variants`` variant drawn."""
    p = Path(path)
    data: dict = {"name": p.stem, "description": f"glTF asset {p.name}",
                  "objects": [{"type": "gltf", "path": str(p.resolve()),
                               **({"variant": variant} if variant is not None else {})}],
                  "environment": {"type": "file", "path": str(Path(env).resolve())} if env is not None
                  else {"type": "constant", "radiance": list(NEUTRAL_RADIANCE)}}
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
        target = tuple(float(o + f) for o, f in zip(cam.origin, cam.forward))
        camera = Camera(origin=cam.origin, target=target, up=cam.up, fov=math.degrees(2 * math.atan(tx)),
                        width=W, height=H)
    else:
        W, H = size if size is not None else DEFAULT_ASSET_SIZE
        origin, target, fov = framing(*scene.assets[0].bounds(), W, H)
        camera = Camera(origin=origin, target=target, up=(0.0, 1.0, 0.0), fov=fov, width=W, height=H)
    return replace(scene, camera=camera)


#: Characters a TOML basic string must escape (TOML 1.0: U+0000-U+001F but tab, and U+007F), the C1
#: controls a terminal would act on (U+0080-U+009F, valid TOML but printed by check-scene), and the
#: surrogates (no Unicode scalar value: TOML cannot hold them, so they become U+FFFD).
_TOML_ESCAPE = re.compile("[\x00-\x08\x0a-\x1f\x7f-\x9f\\\\\"\ud800-\udfff]")
_TOML_SHORT = {"\b": "\\b", "\n": "\\n", "\f": "\\f", "\r": "\\r", '"': '\\"', "\\": "\\\\"}
_TOML_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def toml_string(s: str) -> str:
    """``s`` as a TOML basic string: quotes, backslashes and control characters escaped, so that any
    name (a scene's or an asset's: untrusted) reads back as itself (lone surrogates as U+FFFD)."""
    def esc(m):
        c = m.group()
        if "\ud800" <= c <= "\udfff":
            return "\ufffd"
        return _TOML_SHORT.get(c) or f"\\u{ord(c):04x}"
    return '"' + _TOML_ESCAPE.sub(esc, s) + '"'


def toml_key(k: str) -> str:
    """A TOML key: bare when it may be, else a quoted :func:`toml_string`."""
    k = str(k)
    return k if _TOML_BARE_KEY.match(k) else toml_string(k)


def dump_toml(d: dict) -> str:
    """Minimal TOML writer for resolved scenes (tables, arrays of tables, scalars, flat arrays).
    Strings and keys are escaped (:func:`toml_string`, :func:`toml_key`): the output parses with
    ``tomllib`` whatever a name holds."""
    lines: list[str] = []

    def val(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, (int, float)):
            return repr(v)
        if isinstance(v, str):
            return toml_string(v)
        if isinstance(v, list):
            return "[" + ", ".join(val(x) for x in v) + "]"
        if v is None:
            return '""'
        raise TypeError(v)

    def table(prefix, t):
        subs = []
        for k, v in t.items():
            if isinstance(v, dict):
                subs.append(("t", k, v))
            elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
                subs.append(("a", k, v))
            else:
                lines.append(f"{toml_key(k)} = {val(v)}")
        for kind, k, v in subs:
            name = f"{prefix}.{toml_key(k)}" if prefix else toml_key(k)
            if kind == "t":
                lines.append(f"\n[{name}]")
                table(name, v)
            else:
                for item in v:
                    lines.append(f"\n[[{name}]]")
                    table(name, item)

    table("", d)
    return "\n".join(lines).lstrip() + "\n"


# small vector helpers (pure Python: scenes are tiny)
def _dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _norm(a):
    return math.sqrt(_dot(a, a))


def _normalize(a):
    n = _norm(a)
    if abs(n - 1.0) < 1e-12:  # idempotent: a resolved scene re-loads bit-identically (same hash)
        return tuple(float(x) for x in a)
    return tuple(x / n for x in a)
