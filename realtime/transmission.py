"""The engines' real-time approximation of light through a surface (issue 37 item 2). Raster pipeline
(source ``screen``): the opaque objects rendered first into a framebuffer with a mip chain, the
transmissive ones sampling it along the refracted ray at a level from roughness and IOR, the prefiltered
environment where that ray leaves the screen. Source ``cubemap`` (Filament's ``REFRACTION_MODE_CUBEMAP``;
the ray-cast pipeline's, which has no opaque-pass framebuffer, and the raster pipeline's on request): the
prefiltered environment along the direction leaving the object. Both: Beer-Lambert attenuation over the
material's ``thickness`` (not the path travelled), dispersion as three IORs, diffuse transmission.
GLSL: ``realtime/shaders/transmission.glsl``, compiled into raster.frag and render.comp only where the
scene draws a transmissive material (the ``TRANSMISSION`` define): a scene without one has the programs
(sources) and images it had before.

The numpy twins below are the closed forms of the GLSL (``tests/test_realtime_transmission.py`` runs
both on grids with the extremes).

Forms (registry :data:`TRANSMISSION_LODS`, option ``transmission_lod``):

* ``sample_viewer``: KhronosGroup/glTF-Sample-Viewer ``source/Renderer/shaders/ibl.glsl``
  ``getTransmissionSample``: ``textureLod(framebuffer, uv, log2(width) applyIorToRoughness(r, ior))``
  (trilinear), ``applyIorToRoughness(r, ior) = r clamp(2 ior - 2, 0, 1)`` (IOR 1: no blur; 1.5 and
  above: the roughness as it is).
* ``threejs``: mrdoob/three.js ``src/renderers/shaders/ShaderChunk/transmission_pars_fragment.glsl.js``
  ``getTransmissionSample``: the same level, read by ``textureBicubic`` (a B-spline bicubic filter of
  levels floor(lod) and ceil(lod), mixed by fract(lod)).

Common to both (each engine's ``getVolumeTransmissionRay`` / ``applyVolumeAttenuation`` /
``volumeAttenuation``): the refracted ray ``refract(-v, n, 1 / ior)`` scaled by ``thickness`` (world
units here: the draw's scale is in its vertices) exits at ``p + thickness t``, projected by the camera
into the framebuffer; attenuation ``attenuationColor^(thickness / attenuationDistance)`` (=
``exp(-sigma_t thickness)``, ``sigma_t = -ln(c) / d``; none at the infinite distance, the scene files'
0); the transmitted radiance weighted ``(1 - (F0 A + B)) base_colour`` (the DFG LUT's specular albedo:
the Sample Viewer's form; three.js's ``EnvironmentBRDF`` is the same with its analytic fit) replaces
the dielectric diffuse in proportion ``transmission`` (``mix(f_diffuse, f_transmission, T)``).
Sources (registry :data:`TRANSMISSION_SOURCES`, option ``transmission_source``; the ray-cast pipeline
always reads the cube):

* ``screen``: the opaque-pass framebuffer above (raster), the cube where the ray leaves the screen.
* ``cubemap``: google/filament ``shaders/src/surface_light_indirect.fs`` ``evaluateRefraction`` with
  ``REFRACTION_MODE_CUBEMAP``: ``prefilteredRadiance(direction, r')`` at Filament's refraction roughness
  ``r' = mix(r, 0, saturate(3 / ior - 2))`` (:func:`filament_refraction_roughness`); the direction
  (:func:`refraction_direction`) by ``REFRACTION_TYPE``: ``solid`` where the material has a thickness
  (``refractionSolidSphere``: a sphere of diameter ``thickness``, refracted in, out through
  ``n1 = normalize(dot(n, r) r - n / 2)``), ``thin`` where it has none (``refractionThinSphere``: the
  slab offsets the ray, the direction is the view ray's, and a cube lookup has no position).

Dispersion (three.js): three IORs ``ior -/+ (ior - 1) 0.025 dispersion`` for R, G, B, each channel
its own refracted lookup. Diffuse transmission (the Sample Viewer's pbr.frag): the irradiance from the
back ``E(-n) / pi`` x ``diffuseTransmissionColor`` x base colour (attenuated over the thickness) replaces
the diffuse in proportion ``diffuseTransmissionFactor``, before transmission's mix.

API
---
:data:`REALTIME_TRANSMISSION_EXTENSIONS`, :data:`TRANSMISSION_LODS`,
:data:`DISPERSION_SPREAD`, :func:`apply_ior_to_roughness`, :func:`transmission_lod`, :func:`biased_lod`, :func:`lod_bias_defines`, :func:`bspline_weights`,
:func:`volume_attenuation`, :func:`dispersion_iors`, :func:`ior_from_f0`, :func:`mip_count`,
:data:`TRANSMISSION_SOURCES`, :func:`filament_refraction_roughness`, :func:`refraction_direction`,
:func:`object_transmission_rows`, :func:`scene_transmissive`, :func:`transmission_defines`,
:func:`raycast_notice` (now: a composition other than ``material``), :func:`transmission_source_used`,
:func:`transmission_meta` (the source a render used, in its metadata).
"""

from __future__ import annotations

import json

import math

import numpy as np

from pbrcheck import transmission_params as tp
from pbrcheck.registry import Entry, Registry, role

#: The extensions the real-time renderer renders, both pipelines (raster: screen space or the cube;
#: ray-cast: the cube); the honesty contract's list (pbrcheck.transmission_params.
#: MODELLED_TRANSMISSION_EXTENSIONS) is held to this and the reference's by tests/test_transmission_modelled.py.
REALTIME_TRANSMISSION_EXTENSIONS = (tp.TRANSMISSION, tp.VOLUME, tp.DISPERSION, tp.DIFFUSE_TRANSMISSION)
#: three.js transmission_pars_fragment: ``halfSpread = (ior - 1) * 0.025 * dispersion``.
DISPERSION_SPREAD = 0.025


def apply_ior_to_roughness(roughness, ior):
    """Sample Viewer / three.js ``applyIorToRoughness``: ``r clamp(2 ior - 2, 0, 1)``."""
    return np.asarray(roughness, float) * np.clip(2.0 * np.asarray(ior, float) - 2.0, 0.0, 1.0)


def transmission_lod(roughness, ior, width):
    """Both engines' level: ``log2(width) applyIorToRoughness(r, ior)`` (width: the framebuffer's)."""
    return np.log2(np.asarray(width, float)) * apply_ior_to_roughness(roughness, ior)


def biased_lod(lod, bias):
    """Option ``transmission_lod_bias`` (no engine's: compare.transmission_split's LOD scan): the rule's
    level moved by ``bias``, clamped at level 0 (GLSL ``transmission_lod_biased``)."""
    return np.maximum(np.asarray(lod, float) + np.asarray(bias, float), 0.0)


def lod_bias_defines(tdefs: dict, o) -> dict:
    """``TRANSMISSION_LOD_BIAS`` for a transmission program (``tdefs``, :func:`transmission_defines`, not
    empty) whose option ``transmission_lod_bias`` is not 0; ``{}`` otherwise, so the program of bias 0 is
    the one it was before the option."""
    bias = float(o.transmission_lod_bias)
    return {"TRANSMISSION_LOD_BIAS": repr(bias)} if tdefs and bias != 0.0 else {}


def bspline_weights(a):
    """three.js textureBicubic's cubic B-spline weights ``w0..w3`` at fraction ``a`` (sum 1), the
    GLSL ``bc_w0..bc_w3``: (1 - a)^3 / 6, (3 a^3 - 6 a^2 + 4) / 6, (-3 a^3 + 3 a^2 + 3 a + 1) / 6, a^3 / 6."""
    a = np.asarray(a, float)
    return np.stack([(1 - a) ** 3, 3 * a ** 3 - 6 * a ** 2 + 4, -3 * a ** 3 + 3 * a ** 2 + 3 * a + 1, a ** 3], -1) / 6.0


def volume_attenuation(thickness, attenuation_color, attenuation_distance):
    """Beer-Lambert over the thickness: ``c^(t / d)`` per channel (= exp(-sigma_t t)); 1 where ``d``
    is 0 or infinite (the scene files' and glTF's "none")."""
    c = np.asarray(attenuation_color, float)
    if attenuation_distance <= 0.0 or math.isinf(attenuation_distance):
        return np.ones_like(c)
    return np.power(c, float(thickness) / attenuation_distance)


def dispersion_iors(ior: float, dispersion: float) -> np.ndarray:
    """three.js's three IORs (R, G, B): ``ior - s, ior, ior + s``, ``s = (ior - 1) 0.025 dispersion``."""
    s = (ior - 1.0) * DISPERSION_SPREAD * dispersion
    return np.array([ior - s, ior, ior + s])


def ior_from_f0(f0: float) -> float:
    """The IOR whose ``((n - 1) / (n + 1))^2`` is ``f0`` (the draw items carry F0): ``(1 + sqrt f0) / (1 - sqrt f0)``."""
    s = math.sqrt(max(f0, 0.0))
    return (1.0 + s) / max(1.0 - s, 1e-6)


def mip_count(width: int, height: int) -> int:
    """Levels of the opaque-pass framebuffer's full chain (glGenerateMipmap): ``floor(log2 max) + 1``."""
    return max(width, height).bit_length()


TRANSMISSION_LODS = Registry("TRANSMISSION_LOD", [
    Entry("sample_viewer", "glTF-Sample-Viewer getTransmissionSample: textureLod at log2(width) "
                           "applyIorToRoughness(r, ior), trilinear",
          roles={"transmission_lod": role(transmission_lod)},
          applies_to="transmission: the opaque-pass framebuffer's level and filter"),
    Entry("threejs", "three.js getTransmissionSample: the same level read by textureBicubic (B-spline bicubic "
                     "of floor and ceil levels, mixed by fract)",
          roles={"transmission_lod": role(transmission_lod)},
          applies_to="transmission: the opaque-pass framebuffer's level and filter"),
])


def filament_refraction_roughness(roughness, ior):
    """Filament ``evaluateRefraction``: ``mix(r, 0, saturate(3 / ior - 2))`` (IOR 1: 0; 1.5 and above: r)."""
    return np.asarray(roughness, float) * (1.0 - np.clip(3.0 / np.asarray(ior, float) - 2.0, 0.0, 1.0))


def _refract(i, n, eta):
    """GLSL ``refract`` on rows (zero where total internal reflection)."""
    c = np.sum(n * i, -1, keepdims=True)
    k = 1.0 - eta * eta * (1.0 - c * c)
    out = eta * i - (eta * c + np.sqrt(np.maximum(k, 0.0))) * n
    return np.where(k < 0.0, 0.0, out)


def refraction_direction(n, v, ior, thickness):
    """The direction leaving the object, Filament's cube-map refraction (rows of unit ``n``, ``v`` towards
    the eye; ``ior`` >= 1): thin (``thickness`` <= 0) ``-v``; solid ``refract(r, n1, ior)`` with
    ``r = refract(-v, n, 1 / ior)``, ``n1 = normalize(dot(n, r) r - n / 2)``, ``r`` where that is total
    internal reflection."""
    n, v = np.asarray(n, float), np.asarray(v, float)
    ior = np.asarray(ior, float)[..., None] if np.ndim(ior) else float(ior)
    thin = (np.asarray(thickness, float) <= 0.0)[..., None] if np.ndim(thickness) else float(thickness) <= 0.0
    r = _refract(-v, n, 1.0 / ior)
    n1 = np.sum(n * r, -1, keepdims=True) * r - 0.5 * n
    n1 = n1 / np.linalg.norm(n1, axis=-1, keepdims=True)
    o = _refract(r, n1, ior)
    ln = np.linalg.norm(o, axis=-1, keepdims=True)
    solid = np.where(ln > 0.0, o / np.where(ln > 0.0, ln, 1.0), r)
    return np.where(thin, -v, solid)


TRANSMISSION_SOURCES = Registry("TRANSMISSION_SOURCE", [
    Entry("screen", "the opaque-pass framebuffer along the refracted ray (the Sample Viewer's, three.js's), the "
                    "prefiltered cube where the ray leaves the screen; raster only (the ray-cast pipeline reads the cube)",
          applies_to="transmission: what the refracted ray reads"),
    Entry("cubemap", "Filament REFRACTION_MODE_CUBEMAP: the prefiltered cube along the direction leaving the object "
                     "(solid: a sphere of the thickness; thin: the view ray) at Filament's refraction roughness",
          roles={"refraction_roughness": role(filament_refraction_roughness),
                 "refraction_direction": role(refraction_direction)},
          applies_to="transmission: what the refracted ray reads"),
])


def object_transmission_rows(scene) -> np.ndarray:
    """render.comp's ObjectTransmission rows, 3 vec4 per analytic object (float32): (transmission,
    thickness, dispersion, IOR from the specular F0), (attenuation colour, distance; 0: none),
    (diffuse transmission colour, factor)."""
    rows = []
    for ob in scene.objects:
        m = ob.material
        rows += [[m.transmission, m.thickness, m.dispersion, ior_from_f0(m.specular)],
                 [*m.attenuation_color, m.attenuation_distance],
                 [*m.diffuse_transmission_color, m.diffuse_transmission]]
    return np.asarray(rows or [[0.0] * 4] * 3, np.float32)


def _scene_material_transmissive(m) -> bool:
    return m.transmission > 0.0 or m.diffuse_transmission > 0.0


def _gltf_transmissive(gm) -> bool:
    return tp.is_transmissive(gm)


def scene_transmissive(scene) -> bool:
    """Whether some object of ``scene`` lets light through: ``transmission`` or ``diffuse_transmission``
    > 0 (scene-file fields or the glTF extensions' ``active``)."""
    for ob in scene.objects:
        if getattr(ob, "type", "") == "mesh":
            inst = scene.assets[ob.instance]
            if _gltf_transmissive(inst.asset.material(ob.gltf_material)):
                return True
        elif _scene_material_transmissive(ob.material):
            return True
    return False


def transmission_source_used(o, pipeline: str) -> str:
    """The member of :data:`TRANSMISSION_SOURCES` a render uses: the option's in the raster pipeline;
    ``cubemap`` in the ray-cast one, which has no opaque pass to read (whatever the option says)."""
    return o.transmission_source if pipeline == "raster" else "cubemap"


def transmission_meta(tdefs: dict, o, pipeline: str) -> dict:
    """``meta["transmission"]`` of a render whose programs hold transmission (``tdefs``, :func:`transmission_defines`):
    the source it used (:func:`transmission_source_used`, not only the option requested, which
    ``meta["options"]`` keeps), the option requested, the LOD rule, whether the source is per object;
    ``{}`` for a render without transmission (its metadata is what it was)."""
    if not tdefs:
        return {}
    return {"transmission": json.dumps({"source": transmission_source_used(o, pipeline),
                                        "source_requested": o.transmission_source, "lod": o.transmission_lod,
                                        "per_object": bool(tdefs.get("TRANSMISSION_PER_OBJECT"))}, sort_keys=True)}


def transmission_defines(scene, o, pipeline: str) -> dict:
    """``TRANSMISSION``, the ``TRANSMISSION_LOD`` and ``TRANSMISSION_SOURCE`` members (the ray-cast
    pipeline: ``cubemap`` and ``TRANSMISSION_PER_OBJECT``) for a render of a scene with a transmissive
    material under composition ``material``; ``{}`` otherwise (the program is then exactly the
    transmission-free one)."""
    if o.shading != "material" or not scene_transmissive(scene):
        return {}
    source = transmission_source_used(o, pipeline)
    out = {"TRANSMISSION": 1, **TRANSMISSION_LODS.constants(), **TRANSMISSION_LODS.select(o.transmission_lod),
           **TRANSMISSION_SOURCES.constants(), **TRANSMISSION_SOURCES.select(source)}
    if pipeline != "raster":
        out["TRANSMISSION_PER_OBJECT"] = 1
    return out


def raycast_notice(scene, o, pipeline: str) -> str | None:
    """The one-line notice of a render that draws transmissive materials opaque: a composition other
    than ``material`` (both pipelines render them under ``material``)."""
    if scene_transmissive(scene) and o.shading != "material":
        return f"transmission_unmodelled: shading={o.shading} renders transmissive materials opaque; shading=material does"
    return None
