"""The glTF PBR extensions' lobes in the real-time renderer's programs (issue 36 item 3): which lobes a
scene's materials use, the ``#define`` switches that compile them in (``realtime/shaders/material_lobes.glsl``,
Filament's ``MATERIAL_HAS_*`` style: a program whose scene uses no lobe has none of their code, and its
source is the one it had before the lobes existed), and the per-object parameter rows of the ray-cast
pass. The engines' forms are the registries of :data:`realtime.registry.LOBE_REGISTRIES`, chosen by the
options of :mod:`realtime.presets` (``coat_ibl``, ``coat_attenuation``, ``sheen_dfg``, ``sheen_scaling``,
``sheen_cube``, ``anisotropy_bend``, ``iridescence``).

Conventions, stated again in ``material_lobes.glsl``:

* :data:`LOBE_ROW_LAYOUT`: 4 vec4 per object, (clearcoat, clearcoat_roughness, sheen_roughness,
  specular_factor), (sheen_color, anisotropy_strength), (specular_color, anisotropy_rotation),
  (iridescence, iridescence_ior, iridescence_thickness nm, 0).
* The ray-cast sphere's tangent: Mitsuba's sphere ``dp/du`` direction ``(-n.y, n.x, 0)`` normalized
  (+X at the poles on the z axis); a plane's: :func:`pbrcheck.scene.plane_frame`'s. The anisotropy
  direction is the tangent rotated by ``anisotropy_rotation`` counter-clockwise toward ``n x t``.
* A lobe is active (compiled in) where a material sets it to other than its neutral value
  (:attr:`pbrcheck.lobe_params.Clearcoat.active` and its siblings; for scene files the same tests on
  the fields). Only the ``material`` composition renders lobes; the article compositions are their
  articles' code and ignore them (the render's ``lobes_ignored`` warning says so).

API
---
:data:`LOBE_DEFINES`, :data:`LOBE_ROW_LAYOUT`, :func:`material_active_lobes`, :func:`scene_material_active_lobes`,
:func:`scene_lobes`, :func:`lobe_defines`, :func:`object_lobe_rows`, :func:`needs_split_sum_bakes`,
:func:`needs_charlie_cube`; the raster pass's: :data:`LOBE_TEXTURE_SLOTS`, :func:`gltf_lobe_rows`, :func:`scene_lobe_rows`.
"""

from __future__ import annotations

import numpy as np

from pbrcheck import lobe_params as lp

from .lobes import REALTIME_LOBES
from .registry import ANISOTROPY_BENDS, COAT_ATTENUATIONS, COAT_IBLS, IRIDESCENCES, SHEEN_DFGS, SHEEN_SCALINGS

#: Each lobe extension's ``#define`` (material_lobes.glsl), and the option -> registry switches it
#: brings into the program.
LOBE_DEFINES = {lp.CLEARCOAT: ("LOBE_CLEARCOAT", {"coat_ibl": COAT_IBLS, "coat_attenuation": COAT_ATTENUATIONS}),
                lp.SHEEN: ("LOBE_SHEEN", {"sheen_dfg": SHEEN_DFGS, "sheen_scaling": SHEEN_SCALINGS}),
                lp.SPECULAR: ("LOBE_SPECULAR", {}),
                lp.ANISOTROPY: ("LOBE_ANISOTROPY", {"anisotropy_bend": ANISOTROPY_BENDS}),
                lp.IRIDESCENCE: ("LOBE_IRIDESCENCE", {"iridescence": IRIDESCENCES})}
#: The ray-cast pass's rows per object (material_lobes.glsl lobes_from_rows).
LOBE_ROW_LAYOUT = (("clearcoat", "clearcoat_roughness", "sheen_roughness", "specular_factor"),
                   ("sheen_color", "anisotropy_strength"),
                   ("specular_color", "anisotropy_rotation"),
                   ("iridescence", "iridescence_ior", "iridescence_thickness", None))
#: SHEEN_RADIANCE of material_lobes.glsl from the SHEEN_DFG member's ``extra["radiance"]`` (and, for
#: ``charlie_cube``, option ``sheen_cube``).
_SHEEN_RADIANCE = {"charlie_cube": "SHEEN_RADIANCE_CHARLIE", "ggx_cube": "SHEEN_RADIANCE_GGX",
                   "irradiance": "SHEEN_RADIANCE_IRRADIANCE", "normal_roughest": "SHEEN_RADIANCE_NORMAL_ROUGHEST"}


def scene_material_active_lobes(m) -> tuple[str, ...]:
    """The lobe extensions a scene-file :class:`pbrcheck.scene.Material` sets to a non-neutral value
    (the same tests as :mod:`pbrcheck.lobe_params`' ``active``), in :data:`~pbrcheck.lobe_params.LOBE_EXTENSIONS` order."""
    active = {lp.CLEARCOAT: m.clearcoat > 0.0, lp.SHEEN: any(c > 0.0 for c in m.sheen_color),
              lp.SPECULAR: m.specular_factor != 1.0 or tuple(m.specular_color) != (1.0, 1.0, 1.0),
              lp.ANISOTROPY: m.anisotropy_strength > 0.0, lp.IRIDESCENCE: m.iridescence > 0.0}
    return tuple(e for e in lp.LOBE_EXTENSIONS if active[e])


def material_active_lobes(gm) -> tuple[str, ...]:
    """The active lobe extensions of a :class:`pbrcheck.gltf.GltfMaterial` (its lobe objects' ``active``)."""
    out = []
    for e, (attr, _) in lp.LOBE_EXTENSIONS.items():
        lobe = getattr(gm, attr, None)
        if lobe is not None and lobe.active:
            out.append(e)
    return tuple(out)


def scene_lobes(scene) -> tuple[str, ...]:
    """The lobe extensions the real-time renderer renders (:data:`realtime.lobes.REALTIME_LOBES`) that some
    material of ``scene`` uses: the analytic objects' and every glTF material a mesh object draws."""
    used: set = set()
    for ob in scene.objects:
        if getattr(ob, "type", "") == "mesh":
            inst = scene.assets[ob.instance]
            used.update(material_active_lobes(inst.asset.material(ob.gltf_material)))
        else:
            used.update(scene_material_active_lobes(ob.material))
    return tuple(e for e in lp.LOBE_EXTENSIONS if e in used and e in REALTIME_LOBES)


def lobe_defines(lobes, o) -> dict:
    """The ``#define``s of the lobes ``lobes`` (:func:`scene_lobes`) under options ``o``: none for no
    lobe or a composition other than ``material`` (the program is then exactly the lobe-free one);
    else ``MATERIAL_LOBES``, each lobe's ``LOBE_<NAME>``, its registries' switches and the sheen's
    ``SHEEN_RADIANCE``."""
    if not lobes or o.shading != "material":
        return {}
    d = {"MATERIAL_LOBES": 1}
    for e in lobes:
        name, regs = LOBE_DEFINES[e]
        d[name] = 1
        for opt, reg in regs.items():
            d.update(reg.select(getattr(o, opt)))
    if lp.SHEEN in lobes:
        radiance = SHEEN_DFGS[o.sheen_dfg].extra["radiance"]
        if radiance == "charlie_cube" and o.sheen_cube == "ggx":
            radiance = "ggx_cube"
        d["SHEEN_RADIANCE"] = _SHEEN_RADIANCE[radiance]
    return d


def needs_charlie_cube(defines: dict) -> bool:
    """Whether a program with ``defines`` reads the Charlie-prefiltered cube."""
    return defines.get("SHEEN_RADIANCE") == "SHEEN_RADIANCE_CHARLIE"


def needs_split_sum_bakes(defines: dict) -> bool:
    """Whether the lobes of a program with ``defines`` read the prefiltered cube and the DFG LUT (the
    coat's lookup, the sheen's GGX or roughest-level radiance, the split sum's Fresnel): every lobe
    program does, also under ``ibl = runtime`` (whose base samples the environment itself)."""
    return bool(defines.get("MATERIAL_LOBES"))


def _row_values(m) -> np.ndarray:
    out = []
    for row in LOBE_ROW_LAYOUT:
        vals = []
        for k in row:
            v = 0.0 if k is None else getattr(m, k)
            vals.extend(v if isinstance(v, (tuple, list)) else (v,))
        out.append(vals)
    return np.asarray(out, np.float32)


def object_lobe_rows(scene) -> np.ndarray:
    """(4 n_objects, 4) float32: each analytic object's :data:`LOBE_ROW_LAYOUT` rows (the ray-cast
    pass's ObjectLobes buffer, indexed as its object buffer)."""
    rows = [_row_values(ob.material) for ob in scene.objects]
    return np.concatenate(rows) if rows else np.zeros((4, 4), np.float32)


#: The raster pass's lobe texture slots, in raster.frag's ``tex_lobe`` order: (glTF slot, lobe field,
#: the lobe's texture attribute, sRGB). Channels: pbrcheck.lobe_params.TEXTURE_CHANNELS.
LOBE_TEXTURE_SLOTS = (("clearcoat", "clearcoat", "texture", False),
                      ("clearcoatRoughness", "clearcoat", "roughness_texture", False),
                      ("clearcoatNormal", "clearcoat", "normal_texture", False),
                      ("sheenColor", "sheen", "color_texture", True),
                      ("sheenRoughness", "sheen", "roughness_texture", False),
                      ("specular", "khr_specular", "texture", False),
                      ("specularColor", "khr_specular", "color_texture", True),
                      ("anisotropy", "anisotropy", "texture", False),
                      ("iridescence", "iridescence", "texture", False),
                      ("iridescenceThickness", "iridescence", "thickness_texture", False))


def gltf_lobe_rows(gm) -> tuple[np.ndarray, dict]:
    """A glTF material's lobe factors as the :data:`LOBE_ROW_LAYOUT` rows (row 3's last entry: the film's
    ``iridescenceThicknessMinimum``, which raster.frag mixes to with the thickness texture; untextured,
    the thickness is the maximum) and its lobe textures ``{glTF slot: (TextureRef, sRGB)}`` (only the
    active lobes': an inactive lobe's texture is never read). The factors of an absent or inactive lobe
    are the neutral values."""
    active = set(material_active_lobes(gm))
    c = gm.clearcoat if lp.CLEARCOAT in active else lp.Clearcoat()
    s = gm.sheen if lp.SHEEN in active else lp.Sheen()
    sp = gm.khr_specular if lp.SPECULAR in active else lp.Specular()
    a = gm.anisotropy if lp.ANISOTROPY in active else lp.Anisotropy()
    i = gm.iridescence if lp.IRIDESCENCE in active else lp.Iridescence()
    rows = np.asarray([[c.factor, c.roughness, s.roughness, sp.factor], [*s.color, a.strength],
                       [*sp.color, a.rotation], [i.factor, i.ior, i.thickness_maximum, i.thickness_minimum]], np.float32)
    attr_of = {f: e for e, (f, _) in lp.LOBE_EXTENSIONS.items()}
    tex = {}
    for slot, field_, tattr, srgb in LOBE_TEXTURE_SLOTS:
        lobe = getattr(gm, field_, None)
        if lobe is not None and attr_of[field_] in active and getattr(lobe, tattr) is not None:
            tex[slot] = (getattr(lobe, tattr), srgb)
    return rows, tex


def scene_lobe_rows(m) -> np.ndarray:
    """A scene-file material's :data:`LOBE_ROW_LAYOUT` rows for the raster pass (row 3's last entry the
    thickness: no thickness texture, so minimum = maximum)."""
    rows = _row_values(m)
    rows[3, 3] = m.iridescence_thickness
    return rows
