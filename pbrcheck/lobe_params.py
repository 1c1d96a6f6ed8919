"""The parameters of the glTF PBR extensions' lobes -- ``KHR_materials_clearcoat``, ``_sheen``,
``_specular``, ``_anisotropy`` and ``_iridescence`` -- as data: parsed and validated from a glTF
material, from a scene file's material, and written back as the extensions by the export.

This module holds parameters only. The lobes' maths are :mod:`pbrcheck.lobes` (reference) and
``realtime/lobes.py`` (real time); until both renderers render a lobe its extension stays out of
:data:`pbrcheck.gltf.MODELLED_EXTENSIONS`, so an asset or a scene that uses it is named by the
honesty contract (:mod:`pbrcheck.unmodelled`) and the images leave it out.

API
---
- :class:`Clearcoat`, :class:`Sheen`, :class:`Specular`, :class:`Anisotropy`,
  :class:`Iridescence` -- one extension of a glTF material (frozen): every factor with the
  specification's default, every texture a :class:`pbrcheck.gltf.TextureRef` or None;
  ``textures()`` gives ``{slot: TextureRef}``; ``active`` whether the lobe changes the image.
- :data:`LOBE_EXTENSIONS` -- ``{extension: (GltfMaterial field, class)}``;
  :data:`MODELLED_LOBE_EXTENSIONS` -- those both renderers render (all five).
- :data:`TEXTURE_CHANNELS` -- ``{slot: channels read}``; :data:`SRGB_SLOTS` -- the sRGB-encoded ones.
- :func:`parse_material_lobes` -- the five fields of a :class:`pbrcheck.gltf.GltfMaterial` from a
  material's ``extensions`` object (typed errors naming the file and the JSON pointer).
- :data:`SCENE_DEFAULTS` -- the scene-file material fields and their neutral values;
  :func:`scene_material_fields` validates them (:class:`pbrcheck.errors.SceneError` naming the field).
- :func:`scene_features` -- the extensions a scene-file material's lobe fields use.
- :func:`scene_extensions` -- those fields as glTF material extensions (the export).
- :func:`neutral_scene_keys` -- a material dict less its lobe fields at their neutral values
  (``to_dict`` / ``dump_toml`` stay as they were for a scene that sets none: content hashes unchanged).
- :func:`describe_lobes` -- ``check-scene``'s text of a glTF material's or a scene material's lobes;
  :func:`scene_lobe_lines` -- its comment lines for a scene's analytic objects that set lobes.

References (KhronosGroup/glTF, ``extensions/2.0/Khronos/<name>/README.md`` and
``schema/material.<name>.schema.json``, commit 77b44be7bef26e01fb0b140e3d5bb1716421c5e9):

- KHR_materials_clearcoat: ``clearcoatFactor`` [0, 1] default 0 (``clearcoatTexture`` R),
  ``clearcoatRoughnessFactor`` [0, 1] default 0 (``clearcoatRoughnessTexture`` G),
  ``clearcoatNormalTexture`` (a normalTextureInfo: ``scale``); textures linear.
- KHR_materials_sheen: ``sheenColorFactor`` 3 x [0, 1] default (0, 0, 0) (``sheenColorTexture``
  RGB, sRGB), ``sheenRoughnessFactor`` [0, 1] default 0 (``sheenRoughnessTexture`` A).
- KHR_materials_specular: ``specularFactor`` [0, 1] default 1 (``specularTexture`` A),
  ``specularColorFactor`` 3 x [0, inf) default (1, 1, 1) (``specularColorTexture`` RGB, sRGB).
- KHR_materials_anisotropy: ``anisotropyStrength`` [0, 1] default 0, ``anisotropyRotation``
  radians counter-clockwise from the tangent, default 0, ``anisotropyTexture`` (RG: direction in
  [-1, 1] after ``2 x - 1``; B: strength; linear; absent = (1, 0.5, 1)).
- KHR_materials_iridescence: ``iridescenceFactor`` [0, 1] default 0 (``iridescenceTexture`` R),
  ``iridescenceIor`` >= 1 default 1.3, ``iridescenceThicknessMinimum`` >= 0 default 100 nm,
  ``iridescenceThicknessMaximum`` >= 0 default 400 nm (the minimum MAY exceed the maximum),
  ``iridescenceThicknessTexture`` G: ``thickness = mix(min, max, G)``, absent = 1 (the maximum).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any, Callable

CLEARCOAT, SHEEN, SPECULAR = "KHR_materials_clearcoat", "KHR_materials_sheen", "KHR_materials_specular"
ANISOTROPY, IRIDESCENCE = "KHR_materials_anisotropy", "KHR_materials_iridescence"


def _lobe_textures(obj) -> dict:
    """``{slot: TextureRef}`` of a lobe's present textures (the dataclass fields ``*_texture``,
    named by :attr:`SLOTS`)."""
    return {slot: getattr(obj, f) for f, slot in obj.SLOTS.items() if getattr(obj, f) is not None}


@dataclass(frozen=True)
class Clearcoat:
    """``KHR_materials_clearcoat``: clearcoat = factor x texture.R, roughness = roughness x
    roughness_texture.G; ``normal_texture.scale`` is the normalTextureInfo's ``scale``."""
    factor: float = 0.0
    texture: Any = None
    roughness: float = 0.0
    roughness_texture: Any = None
    normal_texture: Any = None
    SLOTS = {"texture": "clearcoat", "roughness_texture": "clearcoatRoughness", "normal_texture": "clearcoatNormal"}
    textures = _lobe_textures

    @property
    def active(self) -> bool:       # README: "If clearcoatFactor is zero, the whole clearcoat layer is disabled"
        return self.factor > 0.0


@dataclass(frozen=True)
class Sheen:
    """``KHR_materials_sheen``: colour = color x color_texture.RGB (sRGB-decoded), roughness =
    roughness x roughness_texture.A."""
    color: tuple[float, float, float] = (0.0, 0.0, 0.0)
    color_texture: Any = None
    roughness: float = 0.0
    roughness_texture: Any = None
    SLOTS = {"color_texture": "sheenColor", "roughness_texture": "sheenRoughness"}
    textures = _lobe_textures

    @property
    def active(self) -> bool:       # README: "If sheenColorFactor is zero, the whole sheen layer is disabled"
        return any(c > 0.0 for c in self.color)


@dataclass(frozen=True)
class Specular:
    """``KHR_materials_specular``: strength = factor x texture.A, F0 colour = color x
    color_texture.RGB (sRGB-decoded)."""
    factor: float = 1.0
    texture: Any = None
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    color_texture: Any = None
    SLOTS = {"texture": "specular", "color_texture": "specularColor"}
    textures = _lobe_textures

    @property
    def active(self) -> bool:       # the defaults (1, white, no texture) are the core material's Fresnel
        return (self.factor != 1.0 or self.color != (1.0, 1.0, 1.0) or self.texture is not None
                or self.color_texture is not None)


@dataclass(frozen=True)
class Anisotropy:
    """``KHR_materials_anisotropy``: strength x texture.B along the texture's RG direction (tangent
    space, ``2 x - 1``; absent: +X) rotated by ``rotation`` radians counter-clockwise."""
    strength: float = 0.0
    rotation: float = 0.0
    texture: Any = None
    SLOTS = {"texture": "anisotropy"}
    textures = _lobe_textures

    @property
    def active(self) -> bool:       # strength 0 leaves the alpha roughness (mix(a, 1, 0) = a)
        return self.strength > 0.0


@dataclass(frozen=True)
class Iridescence:
    """``KHR_materials_iridescence``: factor x texture.R; the film's ior; its thickness in nm,
    mix(thickness_minimum, thickness_maximum, thickness_texture.G) (no texture: the maximum)."""
    factor: float = 0.0
    texture: Any = None
    ior: float = 1.3
    thickness_minimum: float = 100.0
    thickness_maximum: float = 400.0
    thickness_texture: Any = None
    SLOTS = {"texture": "iridescence", "thickness_texture": "iridescenceThickness"}
    textures = _lobe_textures

    @property
    def active(self) -> bool:
        return self.factor > 0.0


#: The lobe extensions both renderers render (part of :data:`pbrcheck.gltf.MODELLED_EXTENSIONS`): all
#: five, since the reference (``reference.lobe_bsdf.REFERENCE_LOBES``) and the real-time renderer
#: (``realtime.lobes.REALTIME_LOBES``) model them; the core cannot import either layer, so
#: tests/test_lobes_modelled.py holds this tuple to their intersection. An extension one of them
#: drops leaves it, and the honesty contract (:mod:`pbrcheck.unmodelled`) names it again.
MODELLED_LOBE_EXTENSIONS: tuple[str, ...] = (CLEARCOAT, SHEEN, SPECULAR, ANISOTROPY, IRIDESCENCE)
#: The lobe extensions the reference's random walk (``[brdf] multiscatter = "random_walk"``) carries:
#: the walk gives the base's specular (Schlick F0 / F90 per bounce, so KHR_materials_specular too) and
#: the coat and sheen layer on it as [Coat] / [Sheen] write (reference.lobe_bsdf). The walk is isotropic
#: and its per-bounce Fresnel is Schlick's, so anisotropy and iridescence are refused with it
#: (``reference.lobe_bsdf.model_problem``); the core cannot import the reference, so compare reads this.
WALK_LOBE_EXTENSIONS: tuple[str, ...] = (CLEARCOAT, SHEEN, SPECULAR)
#: extension -> (GltfMaterial field, class); the field is None where the material lacks the extension.
LOBE_EXTENSIONS = {CLEARCOAT: ("clearcoat", Clearcoat), SHEEN: ("sheen", Sheen), SPECULAR: ("khr_specular", Specular),
                   ANISOTROPY: ("anisotropy", Anisotropy), IRIDESCENCE: ("iridescence", Iridescence)}
#: Texture slot -> the channels the extension reads (its README).
TEXTURE_CHANNELS = {"clearcoat": "R", "clearcoatRoughness": "G", "clearcoatNormal": "RGB (normal)",
                    "sheenColor": "RGB", "sheenRoughness": "A", "specular": "A", "specularColor": "RGB",
                    "anisotropy": "RG direction, B strength", "iridescence": "R", "iridescenceThickness": "G"}
#: Slots whose images hold sRGB-encoded colour (the others are linear data).
SRGB_SLOTS = ("sheenColor", "specularColor")


# ------------------------------------------------------------------------------------------------
# glTF
# ------------------------------------------------------------------------------------------------

def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


class _Fields:
    """One extension object's fields, each checked against the schema's range; errors name the
    pointer ``<material>/extensions/<ext>/<field>``."""

    def __init__(self, ext: dict, pointer: str, err: Callable[[str, str], Exception], tex):
        self.ext, self.p, self.err, self.tex = ext, pointer, err, tex

    def num(self, key: str, default: float, lo: float | None = None, hi: float | None = None) -> float:
        v = self.ext.get(key, default)
        rng = ("" if lo is None and hi is None else f" in [{lo if lo is not None else '-inf'}, "
               f"{hi if hi is not None else 'inf'}]")
        if not _is_number(v) or (lo is not None and v < lo) or (hi is not None and v > hi):
            raise self.err(f"{self.p}/{key}", f"a finite number{rng}, found {v!r}")
        return float(v)

    def vec3(self, key: str, default, lo: float, hi: float | None) -> tuple[float, float, float]:
        v = self.ext.get(key, list(default))
        if (not isinstance(v, list) or len(v) != 3 or not all(_is_number(c) and c >= lo and (hi is None or c <= hi)
                                                               for c in v)):
            raise self.err(f"{self.p}/{key}", f"3 finite numbers in [{lo}, {hi if hi is not None else 'inf'}], "
                           f"found {v!r}")
        return tuple(float(c) for c in v)  # type: ignore[return-value]

    def texture(self, key: str, scale_key: str | None = None):
        if key not in self.ext:
            return None
        _check_texture_info(self.ext[key], f"{self.p}/{key}", self.err, scale_key)
        return self.tex(self.ext, key, self.p, scale_key)


def _is_index(x) -> bool:
    return isinstance(x, int) and not isinstance(x, bool) and x >= 0


def _is_numbers(x, n: int) -> bool:
    return isinstance(x, list) and len(x) == n and all(_is_number(c) for c in x)


def _check_texture_info(t, pointer: str, err, scale_key: str | None) -> None:
    """The types of a textureInfo inside an extension (the JSON reader checks the core slots'; an
    extension's are raw JSON): ``index`` and ``texCoord`` integers >= 0, the normalTextureInfo's
    ``scale`` a number, ``KHR_texture_transform``'s ``offset`` / ``scale`` 2 numbers, ``rotation`` a
    number, ``texCoord`` an integer >= 0 (the extension's schema)."""
    if not isinstance(t, dict) or not _is_index(t.get("index")):
        raise err(pointer, f"a textureInfo with an index (an integer >= 0), found {t!r}")
    if "texCoord" in t and not _is_index(t["texCoord"]):
        raise err(f"{pointer}/texCoord", f"an integer >= 0, found {t['texCoord']!r}")
    if scale_key and scale_key in t and not _is_number(t[scale_key]):
        raise err(f"{pointer}/{scale_key}", f"a finite number, found {t[scale_key]!r}")
    exts = t.get("extensions", {})
    if not isinstance(exts, dict):
        raise err(f"{pointer}/extensions", f"an object, found {exts!r}")
    tt = exts.get("KHR_texture_transform")
    if tt is None:
        return
    tp = f"{pointer}/extensions/KHR_texture_transform"
    if not isinstance(tt, dict):
        raise err(tp, f"an object, found {tt!r}")
    for k, ok, what in (("offset", lambda v: _is_numbers(v, 2), "2 finite numbers"),
                        ("scale", lambda v: _is_numbers(v, 2), "2 finite numbers"),
                        ("rotation", _is_number, "a finite number (radians)"),
                        ("texCoord", _is_index, "an integer >= 0")):
        if k in tt and not ok(tt[k]):
            raise err(f"{tp}/{k}", f"{what}, found {tt[k]!r}")


def parse_material_lobes(ext: dict, pointer: str, err: Callable[[str, str], Exception], tex) -> dict[str, Any]:
    """``{GltfMaterial field: lobe or None}`` of a material's ``extensions`` object ``ext`` (the
    material at ``pointer``). ``err(pointer, problem)`` makes the typed error (the loader's
    :class:`pbrcheck.errors.AssetError`); ``tex(dict, key, pointer, scale_key)`` resolves a
    textureInfo (the loader's ``_texture_ref``: texCoord, sampler, ``KHR_texture_transform``)."""
    return parse_extensions(ext, pointer, err, tex, LOBE_EXTENSIONS, _PARSERS)


def parse_extensions(ext: dict, pointer: str, err, tex, registry: dict, parsers: dict) -> dict[str, Any]:
    """``{field: parsed or None}`` of the extensions of ``registry`` (``{extension: (field, class)}``)
    in a material's ``extensions`` object, each parsed by ``parsers[extension](_Fields)`` (shared with
    :mod:`pbrcheck.transmission_params`; ``err`` and ``tex`` as :func:`parse_material_lobes`)."""
    out: dict[str, Any] = {}
    for name, (attr, _) in registry.items():
        e = ext.get(name) if isinstance(ext, dict) else None
        if e is None:
            out[attr] = None
            continue
        p = f"{pointer}/extensions/{name}"
        if not isinstance(e, dict):
            raise err(p, f"an object, found {e!r}")
        out[attr] = parsers[name](_Fields(e, p, err, tex))
    return out


def _clearcoat(f: _Fields) -> Clearcoat:
    return Clearcoat(factor=f.num("clearcoatFactor", 0.0, 0.0, 1.0), texture=f.texture("clearcoatTexture"),
                     roughness=f.num("clearcoatRoughnessFactor", 0.0, 0.0, 1.0),
                     roughness_texture=f.texture("clearcoatRoughnessTexture"),
                     normal_texture=f.texture("clearcoatNormalTexture", "scale"))


def _sheen(f: _Fields) -> Sheen:
    return Sheen(color=f.vec3("sheenColorFactor", (0.0, 0.0, 0.0), 0.0, 1.0), color_texture=f.texture("sheenColorTexture"),
                 roughness=f.num("sheenRoughnessFactor", 0.0, 0.0, 1.0), roughness_texture=f.texture("sheenRoughnessTexture"))


def _specular(f: _Fields) -> Specular:
    return Specular(factor=f.num("specularFactor", 1.0, 0.0, 1.0), texture=f.texture("specularTexture"),
                    color=f.vec3("specularColorFactor", (1.0, 1.0, 1.0), 0.0, None),
                    color_texture=f.texture("specularColorTexture"))


def _anisotropy(f: _Fields) -> Anisotropy:
    return Anisotropy(strength=f.num("anisotropyStrength", 0.0, 0.0, 1.0), rotation=f.num("anisotropyRotation", 0.0),
                      texture=f.texture("anisotropyTexture"))


def _iridescence(f: _Fields) -> Iridescence:
    return Iridescence(factor=f.num("iridescenceFactor", 0.0, 0.0, 1.0), texture=f.texture("iridescenceTexture"),
                       ior=f.num("iridescenceIor", 1.3, 1.0),
                       thickness_minimum=f.num("iridescenceThicknessMinimum", 100.0, 0.0),
                       thickness_maximum=f.num("iridescenceThicknessMaximum", 400.0, 0.0),
                       thickness_texture=f.texture("iridescenceThicknessTexture"))


_PARSERS = {CLEARCOAT: _clearcoat, SHEEN: _sheen, SPECULAR: _specular, ANISOTROPY: _anisotropy, IRIDESCENCE: _iridescence}


# ------------------------------------------------------------------------------------------------
# Scene files
# ------------------------------------------------------------------------------------------------

#: The scene-file material fields of the lobes, their neutral values (the specifications' defaults;
#: ``iridescence_thickness`` is the film's thickness in nm, the untextured ``iridescenceThicknessMaximum``).
SCENE_DEFAULTS: dict[str, Any] = {
    "clearcoat": 0.0, "clearcoat_roughness": 0.0,
    "sheen_color": (0.0, 0.0, 0.0), "sheen_roughness": 0.0,
    "specular_factor": 1.0, "specular_color": (1.0, 1.0, 1.0),
    "anisotropy_strength": 0.0, "anisotropy_rotation": 0.0,
    "iridescence": 0.0, "iridescence_ior": 1.3, "iridescence_thickness": 400.0,
}
#: Which extension each scene-file field belongs to.
SCENE_FIELD_EXTENSION = {"clearcoat": CLEARCOAT, "clearcoat_roughness": CLEARCOAT, "sheen_color": SHEEN,
                         "sheen_roughness": SHEEN, "specular_factor": SPECULAR, "specular_color": SPECULAR,
                         "anisotropy_strength": ANISOTROPY, "anisotropy_rotation": ANISOTROPY,
                         "iridescence": IRIDESCENCE, "iridescence_ior": IRIDESCENCE, "iridescence_thickness": IRIDESCENCE}
# (lo, hi) of each scalar field (None: unbounded), from the schemas.
_SCENE_RANGES = {"clearcoat": (0.0, 1.0), "clearcoat_roughness": (0.0, 1.0), "sheen_roughness": (0.0, 1.0),
                 "specular_factor": (0.0, 1.0), "anisotropy_strength": (0.0, 1.0), "anisotropy_rotation": (None, None),
                 "iridescence": (0.0, 1.0), "iridescence_ior": (1.0, None), "iridescence_thickness": (0.0, None)}


def scene_material_fields(ctx, t: dict, where: str, num, vec3) -> dict[str, Any]:
    """The lobe fields of scene-file material table ``t`` at ``where`` (defaults filled), checked
    with the scene loader's ``num`` / ``vec3`` (:class:`pbrcheck.errors.SceneError` naming the field)."""
    out: dict[str, Any] = {}
    for k, d in SCENE_DEFAULTS.items():
        if k in _SCENE_RANGES:
            lo, hi = _SCENE_RANGES[k]
            out[k] = num(ctx, t, k, where, d, lo=lo, hi=hi)
        else:
            v = vec3(ctx, t, k, where, d, nonneg=True)
            if k == "sheen_color" and any(c > 1.0 for c in v):
                raise ctx.err(f"{where}.{k}", "3 numbers in [0, 1]", list(v))
            out[k] = v
    return out


def _changed(material, key: str) -> bool:
    return tuple(getattr(material, key)) != tuple(SCENE_DEFAULTS[key]) if isinstance(SCENE_DEFAULTS[key], tuple) \
        else getattr(material, key) != SCENE_DEFAULTS[key]


def scene_features(material) -> tuple[str, ...]:
    """The extensions whose fields a scene-file material sets to other than their neutral values,
    in :data:`LOBE_EXTENSIONS`' order."""
    used = {SCENE_FIELD_EXTENSION[k] for k in SCENE_DEFAULTS if _changed(material, k)}
    return tuple(e for e in LOBE_EXTENSIONS if e in used)


def scene_extensions(material) -> dict[str, dict]:
    """The glTF material extensions of a scene-file material's lobe fields (only the extensions
    :func:`scene_features` names), factors only: they load back as the same fields."""
    m = material
    out: dict[str, dict] = {}
    for e in scene_features(m):
        if e == CLEARCOAT:
            out[e] = {"clearcoatFactor": m.clearcoat, "clearcoatRoughnessFactor": m.clearcoat_roughness}
        elif e == SHEEN:
            out[e] = {"sheenColorFactor": list(m.sheen_color), "sheenRoughnessFactor": m.sheen_roughness}
        elif e == SPECULAR:
            out[e] = {"specularFactor": m.specular_factor, "specularColorFactor": list(m.specular_color)}
        elif e == ANISOTROPY:
            out[e] = {"anisotropyStrength": m.anisotropy_strength, "anisotropyRotation": m.anisotropy_rotation}
        else:   # untextured: the thickness is iridescenceThicknessMaximum (README); the minimum is set alike
            out[e] = {"iridescenceFactor": m.iridescence, "iridescenceIor": m.iridescence_ior,
                      "iridescenceThicknessMinimum": m.iridescence_thickness,
                      "iridescenceThicknessMaximum": m.iridescence_thickness}
    return out


def scene_fields_of(lobes: dict[str, Any]) -> dict[str, Any]:
    """The scene-file fields of a glTF material's untextured lobes (``{field: lobe or None}`` as
    :func:`parse_material_lobes` gives): what an exported scene material loads back as."""
    out = dict(SCENE_DEFAULTS)
    c, s, sp, a, i = (lobes.get(LOBE_EXTENSIONS[e][0]) for e in LOBE_EXTENSIONS)
    if c is not None:
        out.update(clearcoat=c.factor, clearcoat_roughness=c.roughness)
    if s is not None:
        out.update(sheen_color=s.color, sheen_roughness=s.roughness)
    if sp is not None:
        out.update(specular_factor=sp.factor, specular_color=sp.color)
    if a is not None:
        out.update(anisotropy_strength=a.strength, anisotropy_rotation=a.rotation)
    if i is not None:
        out.update(iridescence=i.factor, iridescence_ior=i.ior, iridescence_thickness=i.thickness_maximum)
    return out


def neutral_scene_keys(material: dict) -> dict:
    """``material`` (a scene material as a dict) less the lobe fields at their neutral values."""
    return {k: v for k, v in material.items()
            if k not in SCENE_DEFAULTS or tuple(v if isinstance(v, (list, tuple)) else (v,))
            != tuple(SCENE_DEFAULTS[k] if isinstance(SCENE_DEFAULTS[k], tuple) else (SCENE_DEFAULTS[k],))}


def describe_lobes(material) -> str:
    """``check-scene``'s text of the lobes of a :class:`pbrcheck.gltf.GltfMaterial` (every present
    extension: factors, textures with slot, channels, image, UV set and transform) or of a
    scene-file material (the fields it sets); "" where none."""
    if hasattr(material, "clearcoat_roughness"):   # a scene-file material
        keys = [k for k in SCENE_DEFAULTS if _changed(material, k)]
        return ", ".join(f"{k} {list(getattr(material, k)) if isinstance(SCENE_DEFAULTS[k], tuple) else getattr(material, k)}"
                         for k in keys)
    return describe_extensions(material, LOBE_EXTENSIONS, TEXTURE_CHANNELS)


def describe_extensions(material, registry: dict, channels: dict) -> str:
    """The text of a :class:`pbrcheck.gltf.GltfMaterial`'s extensions of ``registry`` (``{extension:
    (field, class)}``; every present one: its factors, its textures with slot, ``channels[slot]``,
    image, UV set and transform, "; neutral" where it changes nothing), "; "-joined (shared with
    :mod:`pbrcheck.transmission_params`)."""
    parts = []
    for name, (attr, cls) in registry.items():
        lobe = getattr(material, attr, None)
        if lobe is None:
            continue
        vals = [f"{f.name} {list(v) if isinstance(v, tuple) else v}" for f in fields(cls)
                if f.name not in cls.SLOTS for v in [getattr(lobe, f.name)]]
        tex = [f"{slot}={channels[slot]} of image{t.image}/uv{t.texcoord}" + (" +transform" if t.transform else "")
               for slot, t in lobe.textures().items()]
        parts.append(f"{name.removeprefix('KHR_materials_')} ({', '.join(vals + tex)}"
                     + ("" if lobe.active else "; neutral") + ")")
    return "; ".join(parts)


def scene_lobe_lines(scene) -> list[str]:
    """``check-scene``'s comment lines: each analytic object whose material sets lobe fields, with
    them (none where no object does)."""
    out = []
    for o in scene.objects:
        if getattr(o, "type", "") in ("sphere", "plane") and scene_features(o.material):
            out.append(f"# object {o.id} {o.name}: lobes {describe_lobes(o.material)} "
                       f"({', '.join(scene_features(o.material))}: "
                       + ("rendered" if set(scene_features(o.material)) <= set(MODELLED_LOBE_EXTENSIONS)
                          else "parsed, not rendered by both renderers") + ")")
    return out
