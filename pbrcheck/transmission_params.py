"""The parameters of the glTF extensions that let light through a surface --
``KHR_materials_transmission``, ``_volume``, ``_dispersion`` and ``_diffuse_transmission`` -- and the
validation of ``KHR_materials_ior``, as data: parsed and validated from a glTF material, from a scene
file's material, and written back as the extensions by the export (issue 37, data side).

This module holds parameters only, in :mod:`pbrcheck.lobe_params`' pattern (and with its textureInfo
checks). The truth maths are :mod:`pbrcheck.transmission` (numpy) and ``reference/transmission.py``
(Dr.Jit). Both renderers render the four extensions (:data:`MODELLED_TRANSMISSION_EXTENSIONS`, part of
:data:`pbrcheck.gltf.MODELLED_EXTENSIONS`): the reference in its ``path`` mode, the real-time renderer
in both pipelines. A glTF material the reference's path mode renders opaque (:func:`reference_renders`
false, :func:`reference_refusal` says why) stays named by the honesty contract (:mod:`pbrcheck.unmodelled`)
for that material.

API
---
- :class:`Transmission`, :class:`Volume`, :class:`Dispersion`, :class:`DiffuseTransmission` -- one
  extension of a glTF material (frozen): every factor with the specification's default, every
  texture a :class:`pbrcheck.gltf.TextureRef` or None; ``textures()`` gives ``{slot: TextureRef}``;
  ``active`` whether the extension changes the image.
- :data:`TRANSMISSION_EXTENSIONS` -- ``{extension: (GltfMaterial field, class)}``.
- :data:`TEXTURE_CHANNELS`, :data:`SRGB_SLOTS` -- the slots' channels and the sRGB-encoded ones.
- :data:`MODELLED_TRANSMISSION_EXTENSIONS` -- those both renderers render (all four);
  :data:`REFERENCE_RENDERED` -- those the reference renders.
- :func:`is_transmissive`, :func:`reference_renders` (whether the reference's path mode renders a
  transmissive glTF material), :func:`reference_refusal` (why not, in words), :func:`has_varying`,
  :data:`VARYING_SLOTS`, :data:`READ_SLOTS` (the textures it reads per hit).
- :data:`TRANSMISSIVE_LOBE_EXTENSIONS` -- the lobe extensions the reference's transmissive BSDF
  renders; :func:`lobes_left_out` -- the active others on a material it renders transmissive.
- :func:`parse_ior` -- ``KHR_materials_ior``'s ``ior`` (>= 1, or 0), typed error naming the pointer.
- :func:`abbe_number`, :func:`dispersion_ior` -- the IOR at a wavelength from ``dispersion`` (the
  README's Cauchy form).
- :func:`parse_material_transmission` -- the four fields of a :class:`pbrcheck.gltf.GltfMaterial`.
- :data:`SCENE_DEFAULTS` -- the scene-file material fields and their neutral values;
  :func:`scene_material_fields` validates them (:class:`pbrcheck.errors.SceneError` naming the field).
- :func:`scene_features`, :func:`scene_extensions`, :func:`scene_fields_of`,
  :func:`neutral_scene_keys`, :func:`describe_transmission`, :func:`scene_transmission_lines` --
  as :mod:`pbrcheck.lobe_params`' functions of the same role.

References (KhronosGroup/glTF, ``extensions/2.0/Khronos/<name>/README.md``):

- KHR_materials_transmission: ``transmissionFactor`` [0, 1] default 0 (``transmissionTexture`` R,
  linear, multiplied); "unless otherwise specified by another extension, this transmissive surface is
  really two surfaces back-to-back, representing a thin material" (thin-walled).
- KHR_materials_volume: ``thicknessFactor`` [0, inf) default 0, "in the coordinate space of the mesh.
  If the value is 0 the material is thin-walled. Otherwise the material is a volume boundary"
  (``thicknessTexture`` G, multiplied; a real-time hint, path tracers derive the thickness from the
  geometry); ``attenuationDistance`` (0, inf) default +inf, "in world space";
  ``attenuationColor`` 3 x [0, 1] default (1, 1, 1): ``sigma_t = -ln(attenuationColor) /
  attenuationDistance``.
- KHR_materials_ior: ``ior`` default 1.5; valid values are >= 1 and the special 0 (the Fresnel term
  is 1 at every angle).
- KHR_materials_dispersion: ``dispersion`` [0, inf) default 0 (none) = 20 / V_d (the Abbe number);
  ``n(lambda) = max(n_d + (n_d - 1) / V_d (523655 / lambda^2 - 1.5168), 1)``, lambda in nm.
- KHR_materials_diffuse_transmission: ``diffuseTransmissionFactor`` [0, 1] default 0
  (``diffuseTransmissionTexture`` A), ``diffuseTransmissionColorFactor`` 3 x [0, 1] default
  (1, 1, 1) (``diffuseTransmissionColorTexture`` RGB, sRGB).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

from .lobe_params import IRIDESCENCE, LOBE_EXTENSIONS, _Fields, _is_number, _lobe_textures, describe_extensions, parse_extensions
from .lobe_params import scene_features as lobe_scene_features

TRANSMISSION, VOLUME = "KHR_materials_transmission", "KHR_materials_volume"
DISPERSION, DIFFUSE_TRANSMISSION = "KHR_materials_dispersion", "KHR_materials_diffuse_transmission"
IOR = "KHR_materials_ior"

#: [dispersion] "Specifically we store 20/V_d so that a value of 1.0 is equivalent to V_d=20".
DISPERSION_ABBE_SCALE = 20.0
#: [dispersion] the Cauchy form's constants: 523655 nm^2 (= 1 / (lambda_F^-2 - lambda_C^-2)) and
#: 1.5168 (= that constant / lambda_d^2) with the Fraunhofer lines F 486.1, d 587.6, C 656.3 nm.
DISPERSION_CAUCHY_NM2 = 523655.0
DISPERSION_CAUCHY_OFFSET = 1.5168
#: The d line, where ``ior`` is given (nm).
LAMBDA_D_NM = 587.6


@dataclass(frozen=True)
class Transmission:
    """``KHR_materials_transmission``: transmission = factor x texture.R."""
    factor: float = 0.0
    texture: Any = None
    SLOTS = {"texture": "transmission"}
    textures = _lobe_textures

    @property
    def active(self) -> bool:       # factor 0: mix(diffuse, btdf, 0) is the core material
        return self.factor > 0.0


@dataclass(frozen=True)
class Volume:
    """``KHR_materials_volume``: thickness = thickness x thickness_texture.G (mesh space; 0:
    thin-walled); attenuation_distance in world units (``math.inf``: no absorption);
    attenuation_color the colour white light turns into after that distance."""
    thickness: float = 0.0
    thickness_texture: Any = None
    attenuation_distance: float = math.inf
    attenuation_color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    SLOTS = {"thickness_texture": "thickness"}
    textures = _lobe_textures

    @property
    def active(self) -> bool:       # README: thicknessFactor 0 is thin-walled (the extension's no-op)
        return self.thickness > 0.0

    @property
    def sigma_t(self) -> tuple[float, float, float]:
        """The extinction per world unit: -ln(attenuation_color) / attenuation_distance (inf where a
        channel's colour is 0; 0 at the default infinite distance)."""
        if math.isinf(self.attenuation_distance):
            return (0.0, 0.0, 0.0)
        return tuple(math.inf if c <= 0.0 else -math.log(c) / self.attenuation_distance
                     for c in self.attenuation_color)  # type: ignore[return-value]


@dataclass(frozen=True)
class Dispersion:
    """``KHR_materials_dispersion``: dispersion = 20 / V_d (0: none)."""
    dispersion: float = 0.0
    SLOTS = {}   # type: ignore[var-annotated]  (no texture)
    textures = _lobe_textures

    @property
    def active(self) -> bool:
        return self.dispersion > 0.0


@dataclass(frozen=True)
class DiffuseTransmission:
    """``KHR_materials_diffuse_transmission``: factor x texture.A of Lambertian transmission, colour
    x color_texture.RGB (sRGB-decoded)."""
    factor: float = 0.0
    texture: Any = None
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    color_texture: Any = None
    SLOTS = {"texture": "diffuseTransmission", "color_texture": "diffuseTransmissionColor"}
    textures = _lobe_textures

    @property
    def active(self) -> bool:
        return self.factor > 0.0


#: extension -> (GltfMaterial field, class); the field is None where the material lacks the extension.
TRANSMISSION_EXTENSIONS = {TRANSMISSION: ("transmission", Transmission), VOLUME: ("volume", Volume),
                           DISPERSION: ("dispersion", Dispersion),
                           DIFFUSE_TRANSMISSION: ("diffuse_transmission", DiffuseTransmission)}
#: The extensions the reference renders (its ``path`` mode, analytic objects;
#: ``reference.transmission.REFERENCE_TRANSMISSION_EXTENSIONS`` is this tuple): check-scene's wording.
REFERENCE_RENDERED = (TRANSMISSION, VOLUME, DISPERSION, DIFFUSE_TRANSMISSION)
#: The transmission extensions both renderers render (part of :data:`pbrcheck.gltf.MODELLED_EXTENSIONS`):
#: the reference in its path mode (its local mode refuses them in one typed line), the real-time renderer
#: in both pipelines (raster: screen space; ray-cast: Filament's cube-map refraction). Held by
#: tests/test_transmission_modelled.py to ``reference.transmission.REFERENCE_TRANSMISSION_EXTENSIONS`` and
#: ``realtime.transmission.REALTIME_TRANSMISSION_EXTENSIONS``: an extension one renderer drops leaves it
#: (and is named as unmodelled again). A material :func:`reference_renders` refuses stays named.
MODELLED_TRANSMISSION_EXTENSIONS: tuple[str, ...] = (TRANSMISSION, VOLUME, DISPERSION, DIFFUSE_TRANSMISSION)
#: The texture slots that make a glTF material's lobe parameters vary over the surface: a transmissive
#: material with none of them (the thickness texture is a real-time hint a path tracer ignores,
#: [volume]; occlusion is not light through anything) has constant factors, what the reference's
#: ``pbr_transmissive`` takes (:func:`reference_renders`).
VARYING_SLOTS = ("baseColor", "metallicRoughness", "normal", "transmission", "diffuseTransmission",
                 "diffuseTransmissionColor", "clearcoat", "clearcoatRoughness", "clearcoatNormal", "sheenColor",
                 "sheenRoughness", "specular", "specularColor", "anisotropy", "iridescence", "iridescenceThickness")


def is_transmissive(material) -> bool:
    """Whether a glTF material lets light through (transmission or diffuse transmission active)."""
    t, dt = getattr(material, "transmission", None), getattr(material, "diffuse_transmission", None)
    return (t is not None and t.active) or (dt is not None and dt.active)


#: The slots of :data:`VARYING_SLOTS` the reference's textured transmissive material reads per hit
#: (``reference.transmission.TexturedTransmissive``; issue 37): the core material's, the
#: transmission extensions' and KHR_materials_iridescence's (the film on the interface). The others
#: (the other lobes') leave a transmissive material opaque.
READ_SLOTS = ("baseColor", "metallicRoughness", "normal", "transmission", "diffuseTransmission",
              "diffuseTransmissionColor", "iridescence", "iridescenceThickness")


def has_varying(material) -> bool:
    """Whether a glTF material has a texture of :data:`VARYING_SLOTS` (its parameters vary per hit)."""
    return bool(set(material.textures()) & set(VARYING_SLOTS))


def reference_renders(material) -> bool:
    """Whether the reference's path mode renders a transmissive glTF material: not unlit, and no
    texture of :data:`VARYING_SLOTS` outside :data:`READ_SLOTS` (constant factors, or the textures
    the textured variant reads per hit); any ``alphaMode``. Another transmissive material renders
    opaque (its transmission named as unmodelled)."""
    # alphaMode MASK / BLEND are rendered too (issue 37): alpha is coverage, transmission applies to
    # the surface that is there ([Trans] "Blend Mode"); reference.transmission's materials pass a ray
    # unchanged with probability 1 - coverage (a null interaction, as pbr_textured's cut-outs).
    return (is_transmissive(material) and not material.unlit
            and not set(material.textures()) & (set(VARYING_SLOTS) - set(READ_SLOTS)))


def reference_refusal(material) -> str:
    """Why the reference's path mode renders transmissive glTF ``material`` opaque, in words for a notice
    ("" where it renders it, or the material lets no light through): its alpha mode, unlit, or the
    textures of :data:`VARYING_SLOTS` it does not read per hit (:func:`reference_renders`' conditions)."""
    if not is_transmissive(material) or reference_renders(material):
        return ""
    why = []
    if material.alpha_mode != "OPAQUE":
        why.append(f"alphaMode {material.alpha_mode}")
    if material.unlit:
        why.append("KHR_materials_unlit")
    slots = [s for s in VARYING_SLOTS if s in material.textures() and s not in READ_SLOTS]
    if slots:
        why.append(f"textures it does not read per hit: {', '.join(slots)}")
    return "; ".join(why) or "a material its path mode does not take"


#: The glTF lobe extensions (:data:`pbrcheck.lobe_params.LOBE_EXTENSIONS`) the reference's transmissive
#: BSDF (``reference.transmission``: ``pbr_transmissive`` and its textured variant) renders: the
#: iridescent film on the interface. Its other lobes' factors (clearcoat, sheen, KHR_materials_specular,
#: anisotropy) it does not take: :func:`lobes_left_out` names them, so the honesty contract records
#: them for those materials instead of dropping them silently.
TRANSMISSIVE_LOBE_EXTENSIONS: tuple[str, ...] = (IRIDESCENCE,)


def lobes_left_out(material) -> tuple[str, ...]:
    """The active lobe extensions of ``material`` (a glTF material, or a scene file's material) that the
    reference leaves out because it renders the material with its transmissive BSDF: those outside
    :data:`TRANSMISSIVE_LOBE_EXTENSIONS`, in :data:`pbrcheck.lobe_params.LOBE_EXTENSIONS`' order; ``()``
    for a material it renders opaque (there the lobes are rendered and the transmission is named:
    :func:`reference_refusal`) or one that lets no light through."""
    if hasattr(material, "khr_specular"):   # a glTF material: the lobe objects, None when absent
        if not reference_renders(material):
            return ()
        used = [e for e, (field, _) in LOBE_EXTENSIONS.items()
                if getattr(material, field, None) is not None and getattr(material, field).active]
    else:                                   # a scene file's material: the lobe fields' values
        if not (getattr(material, "transmission", 0.0) > 0.0 or getattr(material, "diffuse_transmission", 0.0) > 0.0):
            return ()
        used = list(lobe_scene_features(material))
    return tuple(e for e in used if e not in TRANSMISSIVE_LOBE_EXTENSIONS)


#: Texture slot -> the channels the extension reads (its README).
TEXTURE_CHANNELS = {"transmission": "R", "thickness": "G", "diffuseTransmission": "A",
                    "diffuseTransmissionColor": "RGB"}
#: Slots whose images hold sRGB-encoded colour (the others are linear data).
SRGB_SLOTS = ("diffuseTransmissionColor",)


def abbe_number(dispersion: float) -> float:
    """V_d = 20 / dispersion (``math.inf`` at 0: no dispersion)."""
    return math.inf if dispersion <= 0.0 else DISPERSION_ABBE_SCALE / dispersion


def dispersion_ior(ior, dispersion: float, wavelength_nm):
    """[dispersion] ``n(lambda) = max(n_d + (n_d - 1) / V_d (523655 / lambda^2 - 1.5168), 1)``;
    ``ior`` (n_d) as given where ``dispersion`` is 0. Works on floats and numpy arrays."""
    if dispersion <= 0.0:
        return ior + 0.0 * wavelength_nm
    k = (ior - 1.0) * dispersion / DISPERSION_ABBE_SCALE
    n = ior + k * (DISPERSION_CAUCHY_NM2 / (wavelength_nm * wavelength_nm) - DISPERSION_CAUCHY_OFFSET)
    return n if not isinstance(n, float) else max(n, 1.0)


# ------------------------------------------------------------------------------------------------
# glTF
# ------------------------------------------------------------------------------------------------

def parse_ior(ext: dict, pointer: str, err: Callable[[str, str], Exception]) -> float:
    """``KHR_materials_ior``'s ``ior`` of a material's ``extensions`` (1.5 where absent): a finite
    number >= 1 or exactly 0 (the README's two valid forms)."""
    e = ext.get(IOR) if isinstance(ext, dict) else None
    if e is None:
        return 1.5
    p = f"{pointer}/extensions/{IOR}"
    if not isinstance(e, dict):
        raise err(p, f"an object, found {e!r}")
    v = e.get("ior", 1.5)
    if not _is_number(v) or not (v >= 1.0 or v == 0.0):
        raise err(f"{p}/ior", f"a finite number >= 1 or 0, found {v!r}")
    return float(v)


def parse_material_transmission(ext: dict, pointer: str, err: Callable[[str, str], Exception], tex) -> dict[str, Any]:
    """``{GltfMaterial field: extension or None}`` of a material's ``extensions`` object, as
    :func:`pbrcheck.lobe_params.parse_material_lobes` (same ``err`` and ``tex``)."""
    return parse_extensions(ext, pointer, err, tex, TRANSMISSION_EXTENSIONS, _PARSERS)


def _transmission(f: _Fields) -> Transmission:
    return Transmission(factor=f.num("transmissionFactor", 0.0, 0.0, 1.0), texture=f.texture("transmissionTexture"))


def _volume(f: _Fields) -> Volume:
    d = f.ext.get("attenuationDistance", math.inf)
    if "attenuationDistance" in f.ext and (not _is_number(d) or d <= 0.0):   # schema: exclusiveMinimum 0
        raise f.err(f"{f.p}/attenuationDistance", f"a finite number > 0, found {d!r}")
    return Volume(thickness=f.num("thicknessFactor", 0.0, 0.0), thickness_texture=f.texture("thicknessTexture"),
                  attenuation_distance=float(d), attenuation_color=f.vec3("attenuationColor", (1.0, 1.0, 1.0), 0.0, 1.0))


def _dispersion(f: _Fields) -> Dispersion:
    return Dispersion(dispersion=f.num("dispersion", 0.0, 0.0))


def _diffuse_transmission(f: _Fields) -> DiffuseTransmission:
    return DiffuseTransmission(factor=f.num("diffuseTransmissionFactor", 0.0, 0.0, 1.0),
                               texture=f.texture("diffuseTransmissionTexture"),
                               color=f.vec3("diffuseTransmissionColorFactor", (1.0, 1.0, 1.0), 0.0, 1.0),
                               color_texture=f.texture("diffuseTransmissionColorTexture"))


_PARSERS = {TRANSMISSION: _transmission, VOLUME: _volume, DISPERSION: _dispersion,
            DIFFUSE_TRANSMISSION: _diffuse_transmission}


# ------------------------------------------------------------------------------------------------
# Scene files
# ------------------------------------------------------------------------------------------------

#: The scene-file material fields and their neutral values (the specifications' defaults, except
#: ``attenuation_distance``: 0 stands for glTF's +inf, no absorption, as a TOML scene holds finite
#: numbers only). The IOR of a scene material is its ``specular`` F0's (``pbrcheck.export.ior_from_f0``).
SCENE_DEFAULTS: dict[str, Any] = {
    "transmission": 0.0,
    "thickness": 0.0, "attenuation_distance": 0.0, "attenuation_color": (1.0, 1.0, 1.0),
    "dispersion": 0.0,
    "diffuse_transmission": 0.0, "diffuse_transmission_color": (1.0, 1.0, 1.0),
}
#: Which extension each scene-file field belongs to.
SCENE_FIELD_EXTENSION = {"transmission": TRANSMISSION, "thickness": VOLUME, "attenuation_distance": VOLUME,
                         "attenuation_color": VOLUME, "dispersion": DISPERSION,
                         "diffuse_transmission": DIFFUSE_TRANSMISSION, "diffuse_transmission_color": DIFFUSE_TRANSMISSION}
# (lo, hi) of each scalar field (None: unbounded), from the schemas.
_SCENE_RANGES = {"transmission": (0.0, 1.0), "thickness": (0.0, None), "attenuation_distance": (0.0, None),
                 "dispersion": (0.0, None), "diffuse_transmission": (0.0, 1.0)}


def scene_material_fields(ctx, t: dict, where: str, num, vec3) -> dict[str, Any]:
    """The fields of scene-file material table ``t`` at ``where`` (defaults filled), checked with
    the scene loader's ``num`` / ``vec3`` (colours in [0, 1])."""
    out: dict[str, Any] = {}
    for k, d in SCENE_DEFAULTS.items():
        if k in _SCENE_RANGES:
            lo, hi = _SCENE_RANGES[k]
            out[k] = num(ctx, t, k, where, d, lo=lo, hi=hi)
        else:
            v = vec3(ctx, t, k, where, d, nonneg=True)
            if any(c > 1.0 for c in v):
                raise ctx.err(f"{where}.{k}", "3 numbers in [0, 1]", list(v))
            out[k] = v
    return out


def _changed(material, key: str) -> bool:
    v, d = getattr(material, key), SCENE_DEFAULTS[key]
    return tuple(v) != tuple(d) if isinstance(d, tuple) else v != d


def scene_features(material) -> tuple[str, ...]:
    """The extensions whose fields a scene-file material sets to other than their neutral values."""
    used = {SCENE_FIELD_EXTENSION[k] for k in SCENE_DEFAULTS if _changed(material, k)}
    return tuple(e for e in TRANSMISSION_EXTENSIONS if e in used)


def scene_extensions(material) -> dict[str, dict]:
    """The glTF material extensions of a scene-file material's fields (factors only): they load back
    as the same fields."""
    m = material
    out: dict[str, dict] = {}
    for e in scene_features(m):
        if e == TRANSMISSION:
            out[e] = {"transmissionFactor": m.transmission}
        elif e == VOLUME:
            out[e] = {"thicknessFactor": m.thickness, "attenuationColor": list(m.attenuation_color)}
            if m.attenuation_distance > 0.0:    # 0: glTF's +inf default, which JSON cannot write
                out[e]["attenuationDistance"] = m.attenuation_distance
        elif e == DISPERSION:
            out[e] = {"dispersion": m.dispersion}
        else:
            out[e] = {"diffuseTransmissionFactor": m.diffuse_transmission,
                      "diffuseTransmissionColorFactor": list(m.diffuse_transmission_color)}
    return out


def scene_fields_of(parsed: dict[str, Any]) -> dict[str, Any]:
    """The scene-file fields of a glTF material's untextured extensions (``{field: extension or
    None}`` as :func:`parse_material_transmission` gives)."""
    out = dict(SCENE_DEFAULTS)
    t, v, d, dt = (parsed.get(TRANSMISSION_EXTENSIONS[e][0]) for e in TRANSMISSION_EXTENSIONS)
    if t is not None:
        out.update(transmission=t.factor)
    if v is not None:
        out.update(thickness=v.thickness, attenuation_color=v.attenuation_color,
                   attenuation_distance=0.0 if math.isinf(v.attenuation_distance) else v.attenuation_distance)
    if d is not None:
        out.update(dispersion=d.dispersion)
    if dt is not None:
        out.update(diffuse_transmission=dt.factor, diffuse_transmission_color=dt.color)
    return out


def neutral_scene_keys(material: dict) -> dict:
    """``material`` (a scene material as a dict) less these fields at their neutral values."""
    def tup(x):
        return tuple(x) if isinstance(x, (list, tuple)) else (x,)
    return {k: v for k, v in material.items() if k not in SCENE_DEFAULTS or tup(v) != tup(SCENE_DEFAULTS[k])}


def describe_transmission(material) -> str:
    """``check-scene``'s text of the transmission extensions of a :class:`pbrcheck.gltf.GltfMaterial`
    (factors, textures with slot, channels, image, UV set and transform) or of a scene-file material
    (the fields it sets); "" where none."""
    if hasattr(material, "clearcoat_roughness"):   # a scene-file material
        return ", ".join(f"{k} {list(getattr(material, k)) if isinstance(SCENE_DEFAULTS[k], tuple) else getattr(material, k)}"
                         for k in SCENE_DEFAULTS if _changed(material, k))
    return describe_extensions(material, TRANSMISSION_EXTENSIONS, TEXTURE_CHANNELS)


def scene_transmission_lines(scene) -> list[str]:
    """``check-scene``'s comment lines: each analytic object whose material sets these fields, and
    which renders them (both, the reference's path mode only, or neither)."""
    out = []
    for o in scene.objects:
        if getattr(o, "type", "") in ("sphere", "plane") and scene_features(o.material):
            feats = scene_features(o.material)
            groups = (([f for f in feats if f in MODELLED_TRANSMISSION_EXTENSIONS],
                       "rendered (the reference in path mode, the real-time image)"),
                      ([f for f in feats if f in REFERENCE_RENDERED and f not in MODELLED_TRANSMISSION_EXTENSIONS],
                       "the reference's path mode only, not yet real time"),
                      ([f for f in feats if f not in REFERENCE_RENDERED and f not in MODELLED_TRANSMISSION_EXTENSIONS],
                       "parsed, not yet rendered"))
            state = "; ".join(f"{', '.join(fs)}: {what}" for fs, what in groups if fs)
            out.append(f"# object {o.id} {o.name}: {describe_transmission(o.material)} ({state})")
    return out
