"""The glTF PBR extensions' lobes in the reference's material BSDF: ``KHR_materials_clearcoat``,
``_sheen``, ``_specular``, ``_anisotropy`` and ``_iridescence`` composed with the base material of
:class:`reference.bsdf.PBRLobes` exactly as the ratified extension READMEs write the layering
(issue 36 item 2), per lane, importance-sampled and combined by MIS.

Where a material has no lobe, none of this is traced: :class:`reference.bsdf.PBRLobes` calls
:func:`eval_pdf` / :func:`sample` only where its ``lobes`` is not None (a :class:`LobeParams` naming the
lobes some material of the view uses), so a scene without lobes renders today's kernels bit for bit.

The material, per lane (local frame ``n = +Z``, tangent ``+X`` = Mitsuba's ``sh_frame.s``, the
direction of increasing u; ``v`` = wi, ``l`` = wo)::

    alpha   = max(roughness^2, LOBE_MIN_ALPHA)                          [glTF-B]
    alpha_t = mix(alpha, 1, strength^2), alpha_b = alpha along t = (cos r, sin r, 0)   [Aniso]
    spec    = D(h; alpha_t, alpha_b) G2(v, l) / (4 n.v n.l)               [glTF-B], [Aniso], [Heitz14]
    f0_d    = min(specular * specularColor, 1) * specularFactor, f90_d = specularFactor   [Spec]
    F_d     = f0_d + (f90_d - f0_d)(1 - v.h)^5,  F_m = base + (1 - base)(1 - v.h)^5      [glTF-B]
    F_d, F_m = mix(F_d, film(v.h, d, ior_f, f0_d), irid), mix(F_m, film(v.h, d, ior_f, base), irid)   [Irid]
    F       = mix(F_d, F_m, metallic)
    diffuse = (1 - max3 F_d)(1 - metallic) base / pi   (metallic_blend "gltf", [Spec] dielectric_brdf)
              (1 - F)(1 - metallic) base / pi          (metallic_blend "f0", the scene model's blend)
    material = diffuse + F spec
    sheened  = sheenColor D_s V_s + material * min(1 - max3(sheenColor) E(n.v), 1 - max3(sheenColor) E(n.l))   [Sheen]
    coated   = sheened (1 - clearcoat Fc) + clearcoat Fc coat(v, l),  Fc = 0.04 + 0.96 (1 - n.v)^5   [Coat]

with ``film`` the thin film's reflectance evaluated spectrally (:func:`film_spectral`: the Airy sum per
wavelength, 380-780 nm at 1 nm, integrated with the CIE 1931 CMFs: :func:`pbrcheck.lobes.iridescence_spectral`
per lane), ``D_s V_s`` the Charlie sheen lobe (:class:`pbrcheck.lobes.SheenCharlie`), ``E`` its
directional albedo by quadrature (:func:`sheen_albedo_table`: Gauss-Legendre x midpoint quadrature of
:meth:`pbrcheck.lobes.SheenCharlie.albedo` on a grid of n.v and sheen roughness, bilinear between its
nodes; the largest interpolation error at the cells' centres is :data:`SHEEN_TABLE_TOL`, tested), and
``coat`` the isotropic GGX at ``max(clearcoatRoughness^2, LOBE_MIN_ALPHA)`` in the frame of the coat's
normal (the geometric normal: an analytic object has no normal map; [Coat] "If clearcoatNormalTexture is
not given, no normal mapping is applied to the clear coat layer").

Energy: every lobe's albedo is at most 1 (Smith GGX, Charlie with its visibility) and the layerings are
convex: the coat's weights ``1 - c Fc`` and ``c Fc`` sum to 1 and do not depend on l; the sheen's
``min(1 - m E(v), 1 - m E(l)) <= 1 - m E(v)`` (m = max3 sheenColor), so a white furnace returns at
most ``m E(v) + (1 - m E(v)) = 1`` (tests/test_lobes_reference.py measures each).

Sampling: one-sample MIS over the components (the balance heuristic of a mixture, as the base): the
diffuse lobe (cosine), the specular lobe (the anisotropic VNDF [Heitz18] at ``(alpha_t, alpha_b)``, the
model's sampler without anisotropy), the sheen lobe (:class:`pbrcheck.lobes.SheenCharlie`'s cosine /
NDF mixture) and the coat (the VNDF in the coat's frame), chosen with probabilities proportional to
their albedo estimates at h = n (Schlick at n.v for the specular and diffuse, as the base;
``mean(sheenColor) E(n.v)`` for the sheen; ``clearcoat Fc`` for the coat), each scaled by the layers
above it. ``pdf`` is the mixture's density; ``sample`` returns ``f cos / pdf``.

The random walk (``multiscatter = "random_walk"``; issue 40): the walk is the base's specular, the
lobes layered on it as above. ``eval`` adds the walk's orders >= 2 [Heitz16 alg. 4;
:func:`reference.multiscatter.walk_eval`, the non-lobe walk's key] to ``F spec``, each bounce's Fresnel
Schlick of ``f0_d`` / ``f90_d`` (the dielectric) and of ``base_color`` / 1 (the metal), blended as
:func:`reference.multiscatter.blend_walk` blends them; so ``coated`` and ``sheened`` layer the multiply
scattered base. Sampling stays the mixture above (the specular component from its single-scattering
VNDF, whose support is the hemisphere): ``sample``'s ``f cos / pdf`` has the walk's unbiased estimate in
``f`` and the mixture's exact density in ``pdf``. :data:`WALK_LOBES` are the lobes it carries; the walk
is isotropic with a per-bounce Schlick Fresnel, so anisotropy and iridescence refuse it
(:func:`model_problem`).

Mirror limits: a lobe's alpha is floored at :data:`LOBE_MIN_ALPHA` (= ``pbrcheck.brdf.DELTA_LOBE_ALPHA``,
roughness 0.01) rather than made a Dirac component: a glossy lobe of width 1e-4 rad, far below an
environment texel (0.012 rad at 512 x 256), sampled by its VNDF with weight ``F G2 / G1``. A material
with lobes is therefore never ``delta``.

Differentiable like the base: the values are Dr.Jit expressions of the parameters (gradients through
``eval``); the thin film's spectral loop and the sheen albedo table are evaluated detached (their
inputs, thickness, film IOR, sheen roughness and n.v, are no differentiable parameters; the film's
base F0 is, through ``base_color`` of a metal: that path carries no gradient, stated here).

API: :data:`LOBES`, :data:`REFERENCE_LOBES`, :func:`reference_models`, :data:`WALK_LOBES`, :data:`LOBE_DEFAULTS`,
:data:`LOBE_MIN_ALPHA`, :data:`SHEEN_TABLE_TOL`, :class:`LobeParams`, :func:`lobes_of_material`,
:func:`eval_pdf`, :func:`sample`, :func:`film_spectral`, :func:`sheen_albedo_table`, :func:`sheen_albedo`,
:func:`aniso_D`, :func:`aniso_G2`, :func:`aniso_G1`, :func:`aniso_sample_h`, :func:`sheen_eval`,
:func:`sheen_pdf`, :func:`sheen_sample`.
References: as :mod:`pbrcheck.lobes` ([glTF-B], [Sheen], [Coat], [Spec], [Aniso], [Irid], [EK17],
[Heitz14], [Heitz18], [BB17], [CIE]); [Heitz16] as :mod:`reference.multiscatter`.
"""

from __future__ import annotations

import functools
import math

import numpy as np

import pbrcheck  # noqa: F401  (sets DRJIT_LIBLLVM_PATH before drjit loads)
from pbrcheck import lobes as np_lobes
from pbrcheck import lobe_params as LP
from pbrcheck.brdf import DELTA_LOBE_ALPHA
from pbrcheck.lobes import (BASE_F0_GUARD, CLEARCOAT_IOR, FILM_R123_MAX, FILM_R123_MIN, SHEEN_MIN_ALPHA,
                            XYZ_TO_REC709)
from pbrcheck.terms import COS_EPS

import drjit as dr
import mitsuba as mi

from . import multiscatter, terms
from .material_tables import material_table

PI = math.pi
INV_PI = 1.0 / PI

#: The lobes, in the order of :data:`pbrcheck.lobe_params.LOBE_EXTENSIONS`, by the short name the
#: material props use.
LOBES = ("clearcoat", "sheen", "specular", "anisotropy", "iridescence")
#: The extensions the reference renders (``local`` and ``path``): the set the lead's flip of
#: :data:`pbrcheck.lobe_params.MODELLED_LOBE_EXTENSIONS` intersects with the real-time side's.
REFERENCE_LOBES = frozenset(LP.LOBE_EXTENSIONS)


def reference_models(extension: str) -> bool:
    """Whether the reference renders ``extension`` (a ``KHR_materials_*`` name)."""
    return extension in REFERENCE_LOBES


#: The lobes ``multiscatter = "random_walk"`` carries (:data:`pbrcheck.lobe_params.WALK_LOBE_EXTENSIONS`):
#: the walk is the base's specular (Schlick F0 / F90 per bounce), the coat and sheen layer on it.
WALK_LOBES = tuple(n for n in LOBES if any(e.endswith("_" + n) for e in LP.WALK_LOBE_EXTENSIONS))


#: Each lobe's material props and their neutral values (the specifications' defaults);
#: ``anisotropy_rotation`` in radians, ``iridescence_thickness`` in nm.
LOBE_DEFAULTS = {
    "clearcoat": {"clearcoat": 0.0, "clearcoat_roughness": 0.0},
    "sheen": {"sheen_color": (0.0, 0.0, 0.0), "sheen_roughness": 0.0},
    "specular": {"specular_factor": 1.0, "specular_color": (1.0, 1.0, 1.0)},
    "anisotropy": {"anisotropy_strength": 0.0, "anisotropy_rotation": 0.0},
    "iridescence": {"iridescence": 0.0, "iridescence_ior": 1.3, "iridescence_thickness": 400.0},
}
#: Smallest alpha of a GGX lobe in a material with lobes: ``pbrcheck.brdf.DELTA_LOBE_ALPHA`` (module
#: docstring, "Mirror limits").
LOBE_MIN_ALPHA = DELTA_LOBE_ALPHA
#: Nodes of the sheen albedo table in n.v (uniform on [0, 1]) and in sheen roughness (uniform on [0, 1]).
SHEEN_TABLE_MU = 129
SHEEN_TABLE_ROUGHNESS = 65
#: The table's n.v at its node 0: the sheen albedo grows without bound as n.v -> 0 (the visibility's
#: 1 / (4 n.v) outgrows the fitted Lambda: E = 18 at n.v 1e-4, roughness 0; measured), so the
#: first cell [0, 1/128] is interpolated towards this node's finite value.
SHEEN_TABLE_MU_MIN = 1e-4
#: Largest |bilinear - quadrature| of the sheen albedo at the table cells' centres over n.v >= 1/128
#: and sheen roughness >= SHEEN_TABLE_TOL_ROUGHNESS (measured 2.6e-3, at n.v 0.012; 1.2e-3 at n.v >= 0.03;
#: tests/test_lobes_reference.py::test_sheen_table_interpolation). Below that roughness the Charlie lobe
#: changes faster than the nodes: 1.0e-2 at roughness 0.1, 4.2e-2 at 0.05, 0.11 at 0.02 (n.v 0.012).
SHEEN_TABLE_TOL = 4e-3
SHEEN_TABLE_TOL_ROUGHNESS = 0.2


def _vec(x) -> tuple:
    """An RGB prop as 3 floats (a list, or Mitsuba's array of one; a number is grey)."""
    return (float(x),) * 3 if isinstance(x, (int, float)) else tuple(float(c) for c in x)


def model_problem(ndf: str, geometry: str, fresnel: str, multiscatter: str, used):
    """What of the scene-wide model a material with the lobes ``used`` cannot take, as ``(field,
    expected, found)``, or None: Schlick's Fresnel (the extensions' Fresnel, with its f90), the random
    walk only beside the lobes it carries (:data:`WALK_LOBES`: anisotropy and iridescence are refused with
    it), and for anisotropy
    the GGX with its height-correlated Smith G2 (the only anisotropic terms written)."""
    if fresnel != "schlick":
        return "brdf.fresnel", f"'schlick' with the glTF lobes {list(used)}", fresnel
    walkless = [n for n in used if n not in WALK_LOBES]
    if multiscatter != "none" and walkless:
        return ("brdf.multiscatter", f"'none' with the glTF lobes {walkless} (the random walk is isotropic with "
                f"Schlick's Fresnel: it carries {list(WALK_LOBES)} only)", multiscatter)
    if "anisotropy" in used and (ndf, geometry) != ("ggx", "smith_ggx_correlated"):
        return ("brdf.ndf / brdf.geometry", "'ggx' and 'smith_ggx_correlated' with anisotropy",
                f"{ndf} / {geometry}")
    return None


def check_model(ndf: str, geometry: str, fresnel: str, multiscatter: str, used) -> None:
    """:func:`model_problem` as a ``ValueError`` naming the model: a material built by hand meets it
    here (a scene meets :func:`check_scene` first, a typed error naming its file)."""
    problem = model_problem(ndf, geometry, fresnel, multiscatter, used)
    if problem is not None:
        field, expected, found = problem
        raise ValueError(f"pbr_material: {field}: expected {expected}, found {found!r}")


def check_scene(scene) -> None:
    """A scene whose materials carry lobes and whose ``[brdf]`` the lobes cannot take:
    :class:`pbrcheck.errors.SceneError` naming the scene file and the ``[brdf]`` field, before
    Mitsuba builds a plugin (whose constructor's error would come back as a RuntimeError)."""
    from pbrcheck import lobe_params
    from pbrcheck.errors import SceneError

    used = set()
    for o in scene.objects:
        if hasattr(o, "material") and hasattr(o.material, "clearcoat_roughness"):
            used.update(lobe_params.scene_features(o.material))
    for inst in getattr(scene, "assets", ()):
        for m in inst.asset.materials:
            for ext, (f, _cls) in lobe_params.LOBE_EXTENSIONS.items():
                if getattr(m, f, None) is not None and getattr(m, f).active:
                    used.add(ext)
    if not used:
        return
    names = [n for n in LOBES if any(e.endswith("_" + n) for e in used)]
    b = scene.brdf
    problem = model_problem(b.ndf, b.geometry, b.fresnel, b.multiscatter, names)
    if problem is not None:
        field, expected, found = problem
        raise SceneError(getattr(scene, "source", None), field, expected, found)


class LobeParams:
    """The lobe parameters of one material (scalars) or of the lanes of a view (arrays): ``used`` the
    lobes traced (a tuple of :data:`LOBES`), ``values`` ``{prop: mi.Float | mi.Color3f}`` for every
    prop of the used lobes."""

    def __init__(self, used, values: dict):
        self.used = tuple(n for n in LOBES if n in used)
        self.values = values

    def __getattr__(self, name):
        v = self.__dict__.get("values", {})
        if name in v:
            return v[name]
        raise AttributeError(name)

    @staticmethod
    def props_type(prop: str):
        return mi.Color3f if prop in ("sheen_color", "specular_color") else mi.Float

    @classmethod
    def from_props(cls, get):
        """The lobes of a material's props (``get(name, default)``): those whose props are present."""
        used, values = [], {}
        for lobe, props in LOBE_DEFAULTS.items():
            if not any(get(p, None) is not None for p in props):
                continue
            used.append(lobe)
            for p, d in props.items():
                x = get(p, d)
                values[p] = mi.Color3f(*_vec(x)) if cls.props_type(p) is mi.Color3f else mi.Float(float(x))
        return cls(used, values) if used else None

    def neutral(self, prop):
        d = next(props[prop] for props in LOBE_DEFAULTS.values() if prop in props)
        return mi.Color3f(*_vec(d)) if self.props_type(prop) is mi.Color3f else mi.Float(float(d))

    def props(self):
        return [p for lobe in self.used for p in LOBE_DEFAULTS[lobe]]

    def traverse(self, callback) -> None:
        """Each factor as a differentiable parameter (``traverse`` of a material with lobes): a new
        value is assigned in place, so the view's tables read it at the next gather."""
        for p, v in self.values.items():
            callback.put(p, v, mi.ParamFlags.Differentiable)

    def make_opaque(self) -> None:
        dr.make_opaque(*self.values.values())


#: Whether a scene-file material's lobe changes the image: the glTF classes' ``active``
#: (:mod:`pbrcheck.lobe_params`: clearcoatFactor, sheenColorFactor, anisotropyStrength or
#: iridescenceFactor 0 disables the layer whatever its other fields; specular at (1, white) is the core's).
_ACTIVE = {
    "clearcoat": lambda m: m.clearcoat > 0.0,
    "sheen": lambda m: max(m.sheen_color) > 0.0,
    "specular": lambda m: m.specular_factor != 1.0 or tuple(m.specular_color) != (1.0, 1.0, 1.0),
    "anisotropy": lambda m: m.anisotropy_strength > 0.0,
    "iridescence": lambda m: m.iridescence > 0.0,
}


def lobes_of_material(material) -> dict:
    """The material props of a scene-file material's active lobes (:data:`_ACTIVE`: a lobe whose
    factor disables it adds nothing, e.g. clearcoat 0 with a clearcoat_roughness), for
    :func:`reference.bsdf.material_dict`; {} for a material without lobes."""
    out = {}
    for lobe, props in LOBE_DEFAULTS.items():
        if not _ACTIVE[lobe](material):
            continue
        for p in props:
            v = getattr(material, p)
            out[p] = [float(c) for c in v] if isinstance(v, (tuple, list)) else float(v)
    return out


def view_tables(mats, indices):
    """``(used, {prop: table})`` of the materials ``mats`` (entry j = material j's value, its neutral
    value where material j lacks the lobe; ``indices``: ``reference.material_tables.table_indices(n)``), or None where none has a lobe
    (:meth:`reference.bsdf.MaterialView.gather`)."""
    used = {lobe for m in mats if getattr(m, "lobes", None) is not None for lobe in m.lobes.used}
    if not used:
        return None
    proto = LobeParams(used, {})
    tables = {}
    for p in proto.props():
        tp = LobeParams.props_type(p)
        tables[p] = material_table(tp, [m.lobes.values[p] if m.lobes is not None and p in m.lobes.values
                                        else proto.neutral(p) for m in mats], indices)
    return proto.used, tables


def gather_view(lobes, idx, active) -> LobeParams:
    """The lanes' :class:`LobeParams` from :func:`view_tables`' tables by material index ``idx``."""
    used, tables = lobes
    return LobeParams(used, {p: dr.gather(LobeParams.props_type(p), t, idx, active) for p, t in tables.items()})


# ------------------------------------------------------------------------------------------------
# per-lane lobe maths (twins of pbrcheck.lobes with per-lane parameters)
# ------------------------------------------------------------------------------------------------

def _max3(c):
    return dr.maximum(dr.maximum(c.x, c.y), c.z)


def _mean(c):
    return (c.x + c.y + c.z) * (1.0 / 3.0)


def _pow5(w):
    w2 = w * w
    return w2 * w2 * w


def _schlick(c, f0, f90):
    return f0 + (f90 - f0) * _pow5(1.0 - dr.abs(c))


def _rot(w, c, s):
    return mi.Vector3f(c * w.x + s * w.y, -s * w.x + c * w.y, w.z)


def _unrot(w, c, s):
    return mi.Vector3f(c * w.x - s * w.y, s * w.x + c * w.y, w.z)


def aniso_D(h, at, ab, c, s):
    """[Aniso] D, :meth:`pbrcheck.lobes.AnisotropicGGX.D` with per-lane ``(alpha_t, alpha_b)`` and
    direction ``(cos, sin)`` of the rotation."""
    hl = _rot(h, c, s)
    t = dr.square(hl.x / at) + dr.square(hl.y / ab) + hl.z * hl.z
    return dr.select(h.z > 0, 1.0 / (PI * at * ab * t * t), 0.0)


def _aniso_lambda(w, at, ab, c, s):
    wl = _rot(w, c, s)
    z2 = dr.maximum(wl.z * wl.z, COS_EPS * COS_EPS)
    return 0.5 * (dr.sqrt(1.0 + (at * at * wl.x * wl.x + ab * ab * wl.y * wl.y) / z2) - 1.0)


def aniso_G2(v, l, at, ab, c, s):
    """[Heitz14] eq. 99 with eq. 86's anisotropic Lambda."""
    return 1.0 / (1.0 + _aniso_lambda(v, at, ab, c, s) + _aniso_lambda(l, at, ab, c, s))


def aniso_G1(v, at, ab, c, s):
    return 1.0 / (1.0 + _aniso_lambda(v, at, ab, c, s))


def aniso_sample_h(v, u, at, ab, c, s):
    """[Heitz18] listing 1 in the direction's frame (:meth:`pbrcheck.lobes.AnisotropicGGX.sample_h`)."""
    vl = _rot(v, c, s)
    vh = dr.normalize(mi.Vector3f(at * vl.x, ab * vl.y, vl.z))
    lensq = vh.x * vh.x + vh.y * vh.y
    inv = dr.rsqrt(dr.maximum(lensq, 1e-30))
    T1 = dr.select(lensq > 0, mi.Vector3f(-vh.y * inv, vh.x * inv, 0.0), mi.Vector3f(1.0, 0.0, 0.0))
    T2 = dr.cross(vh, T1)
    r = dr.sqrt(u.x)
    phi = 2.0 * PI * u.y
    t1, t2 = r * dr.cos(phi), r * dr.sin(phi)
    sw = 0.5 * (1.0 + vh.z)
    t2 = (1.0 - sw) * dr.sqrt(dr.maximum(1.0 - t1 * t1, 0.0)) + sw * t2
    nh = t1 * T1 + t2 * T2 + dr.sqrt(dr.maximum(1.0 - t1 * t1 - t2 * t2, 0.0)) * vh
    h = dr.normalize(mi.Vector3f(at * nh.x, ab * nh.y, dr.maximum(nh.z, 0.0)))
    return _unrot(h, c, s)


def _sheen_alpha(roughness):
    return dr.maximum(roughness * roughness, SHEEN_MIN_ALPHA)


def _sheen_D(h, alpha):
    s2 = dr.minimum(h.x * h.x + h.y * h.y, 1.0)
    inv_r = 1.0 / alpha
    val = (2.0 + inv_r) * dr.exp(0.5 * inv_r * dr.log(dr.maximum(s2, 1e-38))) / (2.0 * PI)
    return dr.select((h.z > 0) & (s2 > 0), val, 0.0)


def _sheen_lambda(cos, alpha):
    c = dr.abs(cos)
    l = functools.partial(np_lobes.sheen_l, alpha=alpha, power=dr.power)
    return dr.select(c < 0.5, dr.exp(l(c)), dr.exp(2.0 * l(0.5) - l(1.0 - c)))


def sheen_eval(v, l, alpha):
    """[Sheen] ``D_s V_s (n.l)`` (:meth:`pbrcheck.lobes.SheenCharlie.eval`), per-lane alpha."""
    cv, cl = dr.clip(v.z, COS_EPS, 1.0), dr.clip(l.z, COS_EPS, 1.0)
    val = _sheen_D(dr.normalize(v + l), alpha) / ((1.0 + _sheen_lambda(cv, alpha) + _sheen_lambda(cl, alpha)) * 4.0 * cv)
    return dr.select((v.z > 0) & (l.z > 0), val, 0.0)


def sheen_pdf(v, l, alpha):
    """The density of :func:`sheen_sample` (:meth:`pbrcheck.lobes.SheenCharlie.pdf`)."""
    h = dr.normalize(v + l)
    pd = _sheen_D(h, alpha) * h.z / dr.maximum(4.0 * dr.abs(dr.dot(v, h)), COS_EPS)
    pc = dr.maximum(l.z, 0.0) * INV_PI
    mix = np_lobes.SheenCharlie.MIX
    return dr.select((v.z > 0) & (l.z > 0), mix * pc + (1.0 - mix) * pd, 0.0)


def sheen_sample(v, u, alpha):
    """:meth:`pbrcheck.lobes.SheenCharlie.sample`'s direction (cosine with probability MIX, else the
    Charlie half vectors reflected)."""
    mix = np_lobes.SheenCharlie.MIX
    pick = u.x < mix
    r = dr.sqrt(dr.clip(u.x / mix, 0.0, 1.0))   # reference.lobes._cosine_sample's mapping
    lc = mi.Vector3f(r * dr.cos(2.0 * PI * u.y), r * dr.sin(2.0 * PI * u.y),
                     dr.sqrt(dr.maximum(1.0 - dr.clip(u.x / mix, 0.0, 1.0), 0.0)))
    u0 = dr.clip((u.x - mix) / (1.0 - mix), 0.0, 1.0)
    st = dr.power(u.y, alpha / (2.0 * alpha + 1.0))
    ct = dr.sqrt(dr.maximum(1.0 - st * st, 0.0))
    phi = 2.0 * PI * u0
    h = mi.Vector3f(st * dr.cos(phi), st * dr.sin(phi), ct)
    return dr.select(pick, lc, 2.0 * dr.dot(v, h) * h - v)


@functools.lru_cache(maxsize=None)
def sheen_albedo_table() -> np.ndarray:
    """``E[i, j]``: the sheen lobe's directional albedo at n.v = ``i / (SHEEN_TABLE_MU - 1)`` (n.v 0
    takes :data:`SHEEN_TABLE_MU_MIN`) and sheen roughness ``j / (SHEEN_TABLE_ROUGHNESS - 1)``, by the
    quadrature of :meth:`pbrcheck.lobes.SheenCharlie.albedo` (its nodes and weights) of
    :func:`sheen_eval`, one row of roughness per kernel (float32 sums of 18k nodes: 1e-6 relative)."""
    l, w = np_lobes._hemisphere_quadrature(np_lobes.ALBEDO_N_THETA, np_lobes.ALBEDO_N_PHI)
    nq = len(w)
    mus = np.maximum(np.linspace(0.0, 1.0, SHEEN_TABLE_MU), SHEEN_TABLE_MU_MIN)
    v = np.repeat(np.stack([np.sqrt(1.0 - mus * mus), np.zeros_like(mus), mus], axis=-1), nq, axis=0)
    L = np.tile(l, (SHEEN_TABLE_MU, 1))
    V, Ld, W = _v3np(v), _v3np(L), mi.Float(np.tile(w, SHEEN_TABLE_MU).astype(np.float32))
    out = np.zeros((SHEEN_TABLE_MU, SHEEN_TABLE_ROUGHNESS))
    with dr.suspend_grad():
        for j, r in enumerate(np.linspace(0.0, 1.0, SHEEN_TABLE_ROUGHNESS)):
            a = mi.Float(max(r * r, SHEEN_MIN_ALPHA))
            out[:, j] = np.array(dr.block_sum(sheen_eval(V, Ld, a) * W, nq), dtype=np.float64)
    return out


def _v3np(a):
    return mi.Vector3f(*[mi.Float(np.ascontiguousarray(a[:, k], np.float32)) for k in range(3)])


@functools.lru_cache(maxsize=None)
def _sheen_table_dr(variant: str):
    return mi.Float(sheen_albedo_table().astype(np.float32).ravel())


def sheen_albedo(mu, roughness):
    """Bilinear in :func:`sheen_albedo_table` (detached)."""
    tab = _sheen_table_dr(mi.variant())
    nm, nr = SHEEN_TABLE_MU, SHEEN_TABLE_ROUGHNESS
    x = dr.clip(dr.detach(mu), 0.0, 1.0) * (nm - 1)
    y = dr.clip(dr.detach(roughness), 0.0, 1.0) * (nr - 1)
    i0 = mi.UInt32(dr.minimum(dr.floor(x), nm - 2))
    j0 = mi.UInt32(dr.minimum(dr.floor(y), nr - 2))
    fx, fy = x - mi.Float(i0), y - mi.Float(j0)

    def at(i, j):
        return dr.gather(mi.Float, tab, i * nr + j)

    return ((1.0 - fx) * ((1.0 - fy) * at(i0, j0) + fy * at(i0, j0 + 1))
            + fx * ((1.0 - fy) * at(i0 + 1, j0) + fy * at(i0 + 1, j0 + 1)))


@functools.lru_cache(maxsize=None)
def _film_weights(variant: str):
    """The wavelengths and each channel's white-balanced CMF weights (:func:`pbrcheck.lobes.iridescence_spectral`)."""
    lam = np_lobes.FILM_WAVELENGTHS
    white = np_lobes.CIE_CMFS.sum(axis=0) @ XYZ_TO_REC709.T
    wrgb = (np_lobes.CIE_CMFS @ XYZ_TO_REC709.T) / white
    return len(lam), mi.Float(lam), [mi.Float(wrgb[:, k]) for k in range(3)]


def film_spectral(cos1, thickness, film_ior, base_f0, outside_ior=1.0):
    """:func:`pbrcheck.lobes.iridescence_spectral` per lane (``thickness``, ``film_ior`` Float,
    ``base_f0`` Color3f per lane): the Airy sum per wavelength, ``R = R12 + Rs + 2 (Rs - T121)
    (r cos th - r^2) / (1 - 2 r cos th + r^2)``, accumulated with the CMF weights in a Dr.Jit loop over
    the 401 wavelengths (detached: module docstring)."""
    cos1, d, nf = dr.detach(cos1), dr.detach(thickness), dr.detach(film_ior)
    f0 = dr.detach(base_f0)
    R0 = dr.square((nf - outside_ior) / (nf + outside_ior))
    R12 = _schlick(cos1, R0, 1.0)
    T121 = 1.0 - R12
    sin2 = dr.square(outside_ior / nf) * (1.0 - cos1 * cos1)
    tir = (1.0 - sin2) < 0.0
    cos2 = dr.sqrt(dr.maximum(1.0 - sin2, 0.0))
    rs, rr, shift = [], [], []
    for k in range(3):
        sf0 = dr.sqrt(f0[k] + BASE_F0_GUARD)
        bior = (1.0 + sf0) / (1.0 - sf0)
        R23 = _schlick(cos2, dr.square((bior - nf) / (bior + nf)), 1.0)
        # phi = (pi - phi12) + phi23, phi12 = pi where the film is below the outside medium
        phi = dr.select(nf < outside_ior, 0.0, PI) + dr.select(bior < nf, PI, 0.0)
        R123 = dr.clip(R12 * R23, FILM_R123_MIN, FILM_R123_MAX)
        rs.append(T121 * T121 * R23 / (1.0 - R123))
        rr.append(dr.sqrt(R123))
        shift.append(phi)
    opd2pi = 2.0 * PI * 2.0 * nf * d * cos2
    n, lam, w = _film_weights(mi.variant())

    def cond(i, acc):
        return i < n

    def body(i, acc):
        wl = dr.gather(mi.Float, lam, i)
        out = []
        for k in range(3):
            ct = dr.cos(opd2pi / wl + shift[k])
            r = rr[k]
            re = (r * ct - r * r) / (1.0 - 2.0 * r * ct + r * r)
            R = R12 + rs[k] + 2.0 * (rs[k] - T121) * re
            out.append(acc[k] + R * dr.gather(mi.Float, w[k], i))
        return i + 1, mi.Color3f(*out)

    _, acc = dr.while_loop((mi.UInt32(0), dr.zeros(mi.Color3f, dr.width(cos1))), cond, body,
                           labels=("i", "acc"), label="thin_film")
    return dr.select(tir, mi.Color3f(1.0), acc)


# ------------------------------------------------------------------------------------------------
# the layered material
# ------------------------------------------------------------------------------------------------

class _Setup:
    """The per-lane quantities of one (material, v) shared by ``eval_pdf`` and ``sample``."""

    def __init__(self, m, wi):
        P = m.lobes
        self.m, self.P, self.used = m, P, P.used
        self.wi = wi
        NoV = mi.Frame3f.cos_theta(wi)
        self.NoV = dr.clip(NoV, 0.0, 1.0)
        alpha = dr.maximum(m.roughness * m.roughness, LOBE_MIN_ALPHA)
        self.alpha = alpha
        self.aniso = "anisotropy" in self.used
        if self.aniso:
            st = P.anisotropy_strength
            self.at = alpha * (1.0 - st * st) + st * st
            self.ab = alpha
            self.cr, self.sr = dr.cos(P.anisotropy_rotation), dr.sin(P.anisotropy_rotation)
        spec = mi.Color3f(m.specular)
        if "specular" in self.used:
            self.f0_d = dr.minimum(spec * P.specular_color, 1.0) * P.specular_factor
            self.f90_d = P.specular_factor
        else:
            self.f0_d, self.f90_d = spec, mi.Float(1.0)
        # component weights at h = n (the base's estimate), scaled by the layers above
        Fd = _schlick(self.NoV, self.f0_d, self.f90_d)
        Fm = _schlick(self.NoV, m.base_color, 1.0)
        F = Fd * (1.0 - m.metallic) + Fm * m.metallic
        wdiff = self._diffuse_weight(Fd, F) * m.base_color * (1.0 - m.metallic)
        w_spec, w_diff = _mean(F), _mean(wdiff)
        layer = mi.Float(1.0)
        w_sheen = mi.Float(0.0)
        if "sheen" in self.used:
            self.sheen_alpha = _sheen_alpha(P.sheen_roughness)
            self.sheen_m = _max3(P.sheen_color)
            self.E_v = sheen_albedo(self.NoV, P.sheen_roughness)
            w_sheen = _mean(P.sheen_color) * self.E_v
            layer = dr.maximum(1.0 - self.sheen_m * self.E_v, 0.0)
        w_coat = mi.Float(0.0)
        if "clearcoat" in self.used:
            self.coat_alpha = dr.maximum(P.clearcoat_roughness * P.clearcoat_roughness, LOBE_MIN_ALPHA)
            # the coat's own normal (glTF assets: the geometric normal or clearcoatNormalTexture's, in
            # the base's shading frame), else the shading normal +Z (an analytic object: no normal map)
            self.coat_frame = mi.Frame3f(P.clearcoat_normal) if "clearcoat_normal" in P.values else None
            self.vc = wi if self.coat_frame is None else self.coat_frame.to_local(wi)
            self.coat_w = P.clearcoat * np_fresnel_coat(dr.clip(self.vc.z, 0.0, 1.0))
            w_coat = self.coat_w
            below = 1.0 - self.coat_w
            layer, w_sheen = layer * below, w_sheen * below
        w_spec, w_diff = w_spec * layer, w_diff * layer
        total = dr.maximum(w_spec + w_diff + w_sheen + w_coat, 1e-20)
        self.p = [w_diff / total, w_spec / total, w_sheen / total, w_coat / total]   # diffuse, spec, sheen, coat
        self.p[0] = dr.select(total <= 1e-20, 1.0, self.p[0])

    def _diffuse_weight(self, Fd, F):
        if self.m.metallic_blend == "f0":
            return 1.0 - F
        return mi.Color3f(1.0 - _max3(Fd))

    def spec_pdf(self, wo, h):
        if self.aniso:
            return (aniso_G1(self.wi, self.at, self.ab, self.cr, self.sr) * aniso_D(h, self.at, self.ab, self.cr, self.sr)
                    / (4.0 * dr.maximum(self.NoV, COS_EPS)))
        jac = 1.0 / dr.maximum(4.0 * dr.abs(dr.dot(wo, h)), 1e-20)
        return terms.ndf(self.m.ndf).pdf(self.wi, h, self.alpha) * jac

    def spec_sample_h(self, u):
        if self.aniso:
            return aniso_sample_h(self.wi, u, self.at, self.ab, self.cr, self.sr)
        return terms.ndf(self.m.ndf).sample(self.wi, u, self.alpha)


def np_fresnel_coat(NcoV):
    """[Coat] ``fresnel_coat`` at the coat's n.v, per lane (:func:`pbrcheck.lobes.fresnel_coat`)."""
    f0 = ((1.0 - CLEARCOAT_IOR) / (1.0 + CLEARCOAT_IOR)) ** 2
    return f0 + (1.0 - f0) * _pow5(1.0 - dr.abs(NcoV))


def _coat(S, wo, h, cl):
    """(value, pdf) of the coat lobe alone ([Coat] "Clearcoat BRDF" times the base's n.l; the VNDF's
    density), in the coat normal's frame where the material has one."""
    a = S.coat_alpha
    iso = (a, a, 1.0, 0.0)
    if S.coat_frame is None:
        value = terms.GGX.eval(h, a) * terms.SmithGGXCorrelated.eval(S.NoV, cl, a) / (4.0 * dr.maximum(S.NoV, COS_EPS))
        pdf = aniso_G1(S.wi, *iso) * terms.GGX.eval(h, a) / (4.0 * dr.maximum(S.NoV, COS_EPS))
        return value, pdf
    vc, lc = S.vc, S.coat_frame.to_local(wo)
    hc = dr.normalize(vc + lc)
    cv, clc = dr.clip(vc.z, 0.0, 1.0), dr.clip(lc.z, 0.0, 1.0)
    D = terms.GGX.eval(hc, a)
    value = D * terms.SmithGGXCorrelated.eval(cv, clc, a) / (4.0 * dr.maximum(cv, COS_EPS) * dr.maximum(clc, COS_EPS)) * cl
    ok = (vc.z > 0) & (lc.z > 0)
    pdf = dr.select(vc.z > 0, aniso_G1(vc, *iso) * D / (4.0 * dr.maximum(cv, COS_EPS)), 0.0)
    return dr.select(ok, value, 0.0), pdf


def _coat_sample(S, u):
    a = S.coat_alpha
    hc = aniso_sample_h(S.vc, u, a, a, 1.0, 0.0)
    lc = 2.0 * dr.dot(S.vc, hc) * hc - S.vc
    return lc if S.coat_frame is None else S.coat_frame.to_world(lc)


def _eval_pdf(S, wo, active):
    m, P, used = S.m, S.P, S.used
    wi = S.wi
    NoV = mi.Frame3f.cos_theta(wi)
    NoL = mi.Frame3f.cos_theta(wo)
    valid = mi.Bool(active) & (NoV > 0) & (NoL > 0)
    cl = dr.clip(NoL, 0.0, 1.0)
    h = dr.normalize(wi + wo)
    VoH = dr.clip(dr.dot(wi, h), 0.0, 1.0)
    Fd = _schlick(VoH, S.f0_d, S.f90_d)
    Fm = _schlick(VoH, m.base_color, 1.0)
    if "iridescence" in used:
        d, nf, w = P.iridescence_thickness, P.iridescence_ior, P.iridescence
        Fd = Fd * (1.0 - w) + film_spectral(VoH, d, nf, S.f0_d) * w
        Fm = Fm * (1.0 - w) + film_spectral(VoH, d, nf, m.base_color) * w
    F = Fd * (1.0 - m.metallic) + Fm * m.metallic
    diffuse = S._diffuse_weight(Fd, F) * (1.0 - m.metallic) * m.base_color * (INV_PI * cl)
    if S.aniso:
        D = aniso_D(h, S.at, S.ab, S.cr, S.sr)
        G = aniso_G2(wi, wo, S.at, S.ab, S.cr, S.sr)
    else:
        D = terms.ndf(m.ndf).eval(h, S.alpha)
        G = terms.geometry_term(m.geometry, S.NoV, cl, m.roughness, S.alpha)
    value = diffuse + F * (D * G / (4.0 * dr.maximum(S.NoV, COS_EPS)))
    if m.multiscatter != "none":   # the walk's orders >= 2 added to the base's specular, under the layers
        value += _walk_orders(S, wo, valid)
    pdf = S.p[0] * INV_PI * cl + S.p[1] * S.spec_pdf(wo, h)
    if "sheen" in used:
        sv = sheen_eval(wi, wo, S.sheen_alpha)
        E_l = sheen_albedo(cl, P.sheen_roughness)
        # the spec's scaling, kept >= 0: E exceeds 1 at grazing n.v (SHEEN_TABLE_MU_MIN's comment), where
        # 1 - max3(sheenColor) E would make the base's reflection negative (a guard, docs/reference.md)
        scale = dr.maximum(dr.minimum(1.0 - S.sheen_m * S.E_v, 1.0 - S.sheen_m * E_l), 0.0)
        value = P.sheen_color * sv + value * scale
        pdf += S.p[2] * sheen_pdf(wi, wo, S.sheen_alpha)
    if "clearcoat" in used:
        coat, coat_pdf = _coat(S, wo, h, cl)
        value = value * (1.0 - S.coat_w) + S.coat_w * coat
        pdf += S.p[3] * coat_pdf
    return dr.select(valid, value, 0.0), dr.select(valid, pdf, 0.0)


def _walk_orders(S, wo, valid):
    """The random walk's scattering orders >= 2 of the base's specular ``f cos`` [Heitz16 alg. 4;
    :func:`reference.multiscatter.walk_eval`], with the base's Fresnel per bounce: Schlick of the
    dielectric's ``f0_d`` / ``f90_d`` ([Spec]) and of the metal's ``base_color`` / 1, mixed as the
    non-lobe walk mixes them (:func:`reference.multiscatter.blend_walk`: ``"gltf"`` the two walks of one
    path, ``"f0"`` one walk of the mixed F0 / F90). ``F90`` is passed only where KHR_materials_specular is
    used (without it ``f90_d = 1`` and the model's Schlick gives the non-lobe walk's bits: a neutral lobe
    renders the walk alone). The walk runs on detached values, ``wi`` and ``wo`` included (a symbolic
    loop is not reverse-differentiable, and ``sample`` evaluates at a direction that carries gradients)."""
    m = S.m
    wi, wo = dr.detach(S.wi), dr.detach(wo)
    key = multiscatter.query_key(m.ms_seed, wi.x, wi.y, wi.z, wo.x, wo.y, wo.z)
    spec = "specular" in S.used

    def walk(f0, f90):
        return multiscatter.walk_eval(wi, wo, S.alpha, f0, key, fresnel=m.fresnel, min_order=2, ndf=m.ndf,
                                      F90=f90 if spec else None, active=valid)
    mt = m.metallic
    if m.metallic_blend == "f0":
        return walk(S.f0_d * (1.0 - mt) + m.base_color * mt, S.f90_d * (1.0 - mt) + mt)
    return walk(S.f0_d, S.f90_d) * (1.0 - mt) + walk(mi.Color3f(m.base_color), 1.0) * mt


def eval_pdf(m, si, wo, active):
    """(f cos, pdf) of material view/instance ``m`` (with ``m.lobes``) at ``si.wi``, ``wo`` (local)."""
    return _eval_pdf(_Setup(m, si.wi), wo, active)


def sample(m, ctx, si, sample1, sample2, active):
    """A direction of the component mixture (module docstring) and ``f cos / pdf``."""
    S = _Setup(m, si.wi)
    wi = si.wi
    active = mi.Bool(active) & (mi.Frame3f.cos_theta(wi) > 0)
    c1 = S.p[0]
    c2 = c1 + S.p[1]
    c3 = c2 + S.p[2]
    pick_diff = sample1 < c1
    pick_spec = ~pick_diff & (sample1 < c2)
    pick_sheen = ~pick_diff & ~pick_spec & (sample1 < c3)
    pick_coat = ~pick_diff & ~pick_spec & ~pick_sheen
    wo = mi.warp.square_to_cosine_hemisphere(sample2)
    h = S.spec_sample_h(sample2)
    wo = dr.select(pick_spec, 2.0 * dr.dot(wi, h) * h - wi, wo)
    if "sheen" in S.used:
        wo = dr.select(pick_sheen, sheen_sample(wi, sample2, S.sheen_alpha), wo)
    if "clearcoat" in S.used:
        wo = dr.select(pick_coat, _coat_sample(S, sample2), wo)
    bs = dr.zeros(mi.BSDFSample3f)
    bs.eta = 1.0
    bs.wo = wo
    active &= mi.Frame3f.cos_theta(wo) > 0
    bs.sampled_type = dr.select(pick_diff, mi.UInt32(+mi.BSDFFlags.DiffuseReflection),
                                mi.UInt32(+mi.BSDFFlags.GlossyReflection))
    bs.sampled_component = dr.select(pick_diff, mi.UInt32(1), mi.UInt32(0))
    value, pdf = _eval_pdf(S, wo, active)
    bs.pdf = pdf
    active &= pdf > 0
    return bs, dr.select(active, value / dr.maximum(pdf, 1e-20), 0.0)


# ------------------------------------------------------------------------------------------------
# glTF assets: the lobes of pbr_textured (reference.textured), with textures
# ------------------------------------------------------------------------------------------------

#: glTF lobe texture slots: slot -> (GltfMaterial field, the lobe's TextureRef attribute, sRGB-encoded,
#: the image channels kept: "rgb", or "a" for the slots the READMEs read from alpha).
GLTF_SLOTS = {
    "clearcoat": ("clearcoat", "texture", False, "rgb"),                      # R
    "clearcoat_roughness": ("clearcoat", "roughness_texture", False, "rgb"),  # G
    "clearcoat_normal": ("clearcoat", "normal_texture", False, "rgb"),        # tangent-space normal
    "sheen_color": ("sheen", "color_texture", True, "rgb"),
    "sheen_roughness": ("sheen", "roughness_texture", False, "a"),
    "specular": ("khr_specular", "texture", False, "a"),
    "specular_color": ("khr_specular", "color_texture", True, "rgb"),
    "anisotropy": ("anisotropy", "texture", False, "rgb"),                    # RG direction, B strength
    "iridescence": ("iridescence", "texture", False, "rgb"),                  # R
    "iridescence_thickness": ("iridescence", "thickness_texture", False, "rgb"),   # G
}


def gltf_lobe_props(asset, m, cache: dict, texture_dict) -> dict:
    """The ``pbr_textured`` props of glTF material ``m``'s active lobes (:attr:`active` of
    :mod:`pbrcheck.lobe_params`' classes: an inactive lobe adds nothing): the factors under the
    scene-file names, ``iridescence_thickness`` = ``iridescenceThicknessMaximum`` and
    ``iridescence_thickness_minimum``, ``clearcoat_normal_scale``, and per present texture
    ``<slot>_lobe_texture`` / ``<slot>_lobe_texcoord`` (:data:`GLTF_SLOTS`; ``cache`` shares the
    decoded images with the core slots'); ``texture_dict`` :func:`reference.textured.texture_dict`
    (passed in: that module imports this one)."""
    out: dict = {}
    # (a material without the lobe fields, e.g. a test's stand-in, has none)
    cc, sh, sp, an, ir = (getattr(m, f, None) for f in ("clearcoat", "sheen", "khr_specular", "anisotropy", "iridescence"))
    if cc is not None and cc.active:
        out.update(clearcoat=cc.factor, clearcoat_roughness=cc.roughness)
        if cc.normal_texture is not None:
            out["clearcoat_normal_scale"] = float(cc.normal_texture.scale)
    if sh is not None and sh.active:
        out.update(sheen_color=list(sh.color), sheen_roughness=sh.roughness)
    if sp is not None and sp.active:
        out.update(specular_factor=sp.factor, specular_color=list(sp.color))
    if an is not None and an.active:
        out.update(anisotropy_strength=an.strength, anisotropy_rotation=an.rotation)
    if ir is not None and ir.active:
        out.update(iridescence=ir.factor, iridescence_ior=ir.ior, iridescence_thickness=ir.thickness_maximum,
                   iridescence_thickness_minimum=ir.thickness_minimum)
    for slot, (field, attr, srgb, ch) in GLTF_SLOTS.items():
        lobe = getattr(m, field, None)
        ref = getattr(lobe, attr) if lobe is not None and lobe.active else None
        if ref is None:
            continue
        key = (ref.image, srgb, ch)
        if key not in cache:
            px = asset.images[ref.image].linear(srgb)
            cache[key] = px[..., 3:4] if ch == "a" else px[..., :3]
        out[f"{slot}_lobe_texture"] = texture_dict(cache[key], ref)
        out[f"{slot}_lobe_texcoord"] = int(ref.texcoord)
    return out


def needs_tangents(m) -> bool:
    """Whether glTF material ``m``'s lobes read the tangent frame: anisotropy (its direction) or a
    clearcoatNormalTexture (tangent space)."""
    an, cc = getattr(m, "anisotropy", None), getattr(m, "clearcoat", None)
    return bool((an is not None and an.active) or (cc is not None and cc.active and cc.normal_texture is not None))


def textured_init(mat, props) -> None:
    """``pbr_textured``'s lobe part of ``__init__``: ``mat.lobes_static`` (the factors, or None),
    ``mat.lobe_tex`` ``{slot: texture}`` (their texCoord sets in ``mat.uvset["lobe_<slot>"]``)."""
    def get(name, default):
        return props.get(name, default)

    mat.lobes_static = LobeParams.from_props(get)
    mat.lobe_tex = {}
    mat.lobe_extra = {"iridescence_thickness_minimum": float(get("iridescence_thickness_minimum", 100.0)),
                      "clearcoat_normal_scale": float(get("clearcoat_normal_scale", 1.0))}
    if mat.lobes_static is None:
        return
    check_model(*mat.model[:4], mat.lobes_static.used)
    for slot in GLTF_SLOTS:
        if f"{slot}_lobe_texture" in props:
            mat.lobe_tex[slot] = props.get(f"{slot}_lobe_texture")
            mat.uvset[f"lobe_{slot}"] = int(get(f"{slot}_lobe_texcoord", 0))


def _tangent_frame(si, shape, active, tangents: bool):
    """The glTF tangent (world) and its sign: the vertex TANGENT where the primitive has one, else
    Mitsuba's ``sh_frame.s`` (dp/du of the texcoords, the direction glTF's tangent follows)."""
    if not tangents:
        return si.sh_frame.s, mi.Float(1.0)
    tw = mi.Vector3f(shape.eval_attribute_3("vertex_tangent", si, active))
    w = dr.select(shape.eval_attribute_1("vertex_tangent_w", si, active) < 0, -1.0, 1.0)
    return tw, w


def _mapped(t, scale, T, B, N):
    """A tangent-space normal texel (glTF 3.9.3: ``(2 t.rg - 1) * scale, 2 t.b - 1``) in world space."""
    x, y, z = (2.0 * t.x - 1.0) * scale, (2.0 * t.y - 1.0) * scale, 2.0 * t.z - 1.0
    return dr.normalize(T * x + B * y + N * z)


def textured_lobes(mat, si, active, shape, n_local, flip, frame):
    """``(LobeParams per lane, frame)`` of a ``pbr_textured`` hit: each factor times its texture
    ([Coat] clearcoat R, roughness G; [Sheen] colour RGB, roughness A; [Spec] A and RGB; [Aniso] RG
    direction ``2 x - 1`` rotated by ``anisotropyRotation``, B strength; [Irid] R, thickness
    ``mix(min, max, G)``); the frame re-made with the tangent as its ``s`` where the material has
    anisotropy (the direction is measured from it); the coat normal (clearcoatNormalTexture's, else
    the interpolated vertex normal: [Coat] no normal mapping of the coat without its own texture) in
    that frame where it can differ from the shading normal."""
    P0 = mat.lobes_static
    vals = dict(P0.values)

    def tex(slot):
        return mat.lobe_tex[slot].eval(mat._uv_si(f"lobe_{slot}", si, active, shape), active)

    has = mat.lobe_tex.__contains__
    used = P0.used
    tangents = bool(getattr(mat, "tangents", False))
    N = si.sh_frame.n
    if "anisotropy" in used or has("clearcoat_normal"):
        tw, w = _tangent_frame(si, shape, active, tangents)
        T = tw - N * dr.dot(N, tw)
        T = dr.select(dr.squared_norm(T) > 1e-12, dr.normalize(T), si.sh_frame.s)
        B = dr.cross(N, T) * w
    if "anisotropy" in used:
        # the shading frame with s along the tangent projected on the (mapped) normal
        n = dr.normalize(n_local)
        Tl = si.sh_frame.to_local(T)
        Tl = Tl - n * dr.dot(n, Tl)
        Tl = dr.select(dr.squared_norm(Tl) > 1e-12, dr.normalize(Tl), frame.s)
        # the bitangent is the mesh's, cross(N, T) w with the vertex normal N (glTF 2.0 "Meshes"), on the
        # back face too, where only the normal is reversed (glTF 2.0 doubleSided; the Sample Viewer negates
        # t, b and n together): the direction stays the same line of the surface seen from either side
        # (cross(n, Tl) with the flipped n is -B there: the rotation would turn the other way)
        frame = mi.Frame3f(Tl, dr.cross(n, Tl) * dr.select(flip, -w, w), n)
        if has("anisotropy"):
            t = tex("anisotropy")
            vals["anisotropy_strength"] = vals["anisotropy_strength"] * t.z
            vals["anisotropy_rotation"] = vals["anisotropy_rotation"] + dr.atan2(2.0 * t.y - 1.0, 2.0 * t.x - 1.0)
    if "clearcoat" in used:
        if has("clearcoat"):
            vals["clearcoat"] = vals["clearcoat"] * tex("clearcoat").x
        if has("clearcoat_roughness"):
            vals["clearcoat_roughness"] = vals["clearcoat_roughness"] * tex("clearcoat_roughness").y
        if has("clearcoat_normal") or "normal" in mat.tex or "anisotropy" in used:
            nc = mi.Vector3f(0.0, 0.0, 1.0)
            if has("clearcoat_normal"):
                nc = si.sh_frame.to_local(_mapped(tex("clearcoat_normal"), mat.lobe_extra["clearcoat_normal_scale"], T, B, N))
            nc = dr.select(flip, -nc, nc)
            vals["clearcoat_normal"] = dr.normalize(frame.to_local(nc))
    if "sheen" in used:
        if has("sheen_color"):
            vals["sheen_color"] = vals["sheen_color"] * tex("sheen_color")
        if has("sheen_roughness"):
            vals["sheen_roughness"] = vals["sheen_roughness"] * tex("sheen_roughness").x
    if "specular" in used:
        if has("specular"):
            vals["specular_factor"] = vals["specular_factor"] * tex("specular").x
        if has("specular_color"):
            vals["specular_color"] = vals["specular_color"] * tex("specular_color")
    if "iridescence" in used:
        if has("iridescence"):
            vals["iridescence"] = vals["iridescence"] * tex("iridescence").x
        if has("iridescence_thickness"):
            lo = mat.lobe_extra["iridescence_thickness_minimum"]
            g = tex("iridescence_thickness").y
            vals["iridescence_thickness"] = lo * (1.0 - g) + vals["iridescence_thickness"] * g
    return LobeParams(used, vals), frame
