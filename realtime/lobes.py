"""The engines' real-time approximations of the glTF PBR extensions' lobes: numpy twins of the GLSL
terms in ``realtime/shaders/lobes_coat.glsl``, ``lobes_sheen.glsl``, ``lobes_anisotropy.glsl`` and
``lobes_iridescence.glsl`` (each function here has a GLSL function of the same name;
``tests/test_realtime_lobes.py`` runs both on grids with the extremes, and
``tests/test_realtime_material_lobes.py`` the point lights' anisotropic GGX and film and the material
composition's terms), and the numpy side of the
sheen LUT's bake (``sheen_lut.comp``: :func:`sheen_albedo_quadrature` is the quadrature its texels
are checked against). The truth (the extensions' lobes as the specification defines them) is
:mod:`pbrcheck.lobes`; these are what real-time engines ship instead. The registries choosing among
them are :data:`realtime.registry.LOBE_REGISTRIES`; docs/realtime.md's "Lobe approximations"
section lists every variant with its source and equation.

Vectors are ``(..., 3)`` arrays; cosines are clamped to [0, 1] by the caller, as in the shaders.

API
---
Coat: :func:`coat_f0`, :func:`coat_fresnel`, :func:`coat_attenuation_nov`, :func:`coat_attenuation_voh`,
:func:`coat_ibl_weight_filament`, :func:`coat_ibl_weight_sample_viewer`, :func:`coat_ibl_weight_threejs`,
:func:`coat_ibl_weight_splitsum`.
Sheen: :func:`D_Charlie`, :func:`charlie_lambda`, :func:`V_Charlie`, :func:`V_Neubelt`,
:func:`sample_Charlie` (the Charlie D, Lambda, visibility and sampler are the truth's, imported from
:mod:`pbrcheck.lobes` and called at this renderer's alpha floor :data:`SHEEN_MIN_ALPHA`: one formula,
the GLSL's twin; the engines' own variants keep their own names: :func:`V_Neubelt`, the older IBL
sampler's alpha = roughness in :func:`sheen_albedo_quadrature`), :func:`charlie_prefilter_pdf`, :func:`sheen_dg_fit`, :func:`sheen_dfg_threejs`,
:func:`sheen_dfg_playcanvas`, :func:`sheen_dfg_lut_charlie`, :func:`sheen_dfg_lut_neubelt`,
:func:`sheen_dfg_lut_ibl_sampler_legacy`, :func:`sheen_dfg_fitted` (the AD-fitted table of :mod:`realtime.fitted_lobes`),
:func:`sheen_scaling_lut`, :func:`sheen_scaling_threejs`, :func:`sheen_scaling_filament`, :func:`lut_bilinear`,
:func:`sheen_lut_lookup`, :data:`SHEEN_LUT_CONVENTIONS` (the bake: :mod:`realtime.lobe_luts`),
:data:`CHARLIE_CUBE_CONVENTIONS` (the bake: :func:`realtime.render.charlie_cube`),
:func:`sheen_albedo_quadrature`.
Anisotropy: :func:`aniso_bend_weight`, :func:`aniso_bent_normal_sample_viewer`, :func:`aniso_bent_normal_threejs`,
:func:`aniso_bent_normal_filament`,
:func:`aniso_bent_normal_babylon`, :func:`aniso_reflection_sample_viewer`, :func:`aniso_reflection_threejs`,
:func:`aniso_reflection_filament`, :func:`aniso_reflection_babylon`, :func:`threejs_reflection`,
:func:`aniso_bent_normal_fitted`, :func:`aniso_reflection_fitted` (the AD-fitted weight of :mod:`realtime.fitted_lobes`);
under point, spot and directional lights the README's anisotropic GGX: :func:`aniso_alpha_t`,
:func:`D_GGX_anisotropic`, :func:`V_GGX_anisotropic`, :func:`aniso_specular_dv`.
:data:`REALTIME_LOBES` (the lobe extensions the renderer renders).
The material composition's own terms (``lobes_material.glsl``): :func:`specular_dielectric_f0`,
:func:`specular_f90_blend`, :func:`split_sum_albedo_f90`, :func:`aniso_direction`, :func:`sphere_tangent`.
Iridescence: :func:`iridescence_sensitivity`, :func:`iridescence_fresnel`, :func:`iridescence_factor`,
:func:`iridescence_mix`, :func:`iridescence_light_fresnel` (a light's, at v.h).

References
----------
[Estevez17] A. Estevez, C. Kulla, "Production Friendly Microfacet Sheen BRDF", Sony Imageworks 2017.
[Neubelt13] D. Neubelt, M. Pettineo, "Crafting a Next-Gen Material Pipeline for The Order: 1886", 2013.
[EntPBR] Dassault Systemes, Enterprise PBR Shading Model 2022x, sec. "Sheen" (the DG fit three.js and
PlayCanvas ship).
[McAuley15] S. McAuley, "Rendering the World of Far Cry 4", GDC 2015 (the anisotropic bent normal).
[Filament] R. Guy, M. Agopian, "Physically Based Rendering in Filament", sec. 4.9 (clear coat),
4.12.2 (cloth / sheen), 5.3.6 (anisotropic image-based lighting).
[Belcour17] L. Belcour, P. Barla, "A Practical Extension to Microfacet Theory for the Modeling of
Varying Iridescence", ACM TOG 36(4), 2017 (and its supplemental: the XYZ sensitivity's Gaussian fit).
[FdezAguera19] C. J. Fdez-Aguera, "A Multiple-Scattering Microfacet Model for Real-Time Image-based
Lighting", JCGT 8(1), 2019 (the roughness-dependent Fresnel the Sample Viewer's split sum uses).
"""

from __future__ import annotations

import numpy as np

from pbrcheck.brdf import EnvBRDFApprox
from pbrcheck.lobes import charlie_D, charlie_lambda as _charlie_lambda, charlie_sample_h, charlie_V, sheen_l

from .fitted_lobes import aniso_bend_weight_fitted, sheen_albedo_fitted

PI = np.pi
#: The lobe extensions the real-time renderer renders (realtime/shaders/material_lobes.glsl, compiled
#: into the programs of scenes whose materials use them: realtime.material_lobes). The honesty contract's
#: pbrcheck.lobe_params.MODELLED_LOBE_EXTENSIONS holds those both renderers render; the lead adds an
#: extension there once the reference renders it too (its intersection with this set).
REALTIME_LOBES = frozenset({"KHR_materials_clearcoat", "KHR_materials_sheen", "KHR_materials_specular",
                            "KHR_materials_anisotropy", "KHR_materials_iridescence"})
#: The smallest sheen alpha (= sheenRoughness^2) the Charlie terms evaluate with: its exponent
#: 1/alpha reaches 1e3, where sin^(1/alpha) is already a spike of width ~0.03 rad and float32's
#: pow still resolves it (pow amplifies the input's rounding by the exponent: 1e3 x 6e-8 = 6e-5).
SHEEN_MIN_ALPHA = 1e-3
#: Guard of divisions by cosines at grazing angles (as pbrcheck.brdf.COS_EPS).
COS_EPS = 1e-8
#: three.js's sheen energy compensation: 1 - 0.157 max(sheenColor) (its comment: the directional
#: albedo of the Charlie lobe averaged over n.v and roughness, from its sheen note).
THREEJS_SHEEN_ALBEDO = 0.157
#: The Sample Viewer's guard of the base F0 -> IOR inversion (F0 = 1 is an infinite IOR).
IRIDESCENCE_MAX_F0 = 0.9999
#: The film thickness (nm) over which the Sample Viewer's film IOR fades in from the outside IOR
#: (smoothstep(0, 0.03 nm, d)): a zero-thickness film is no film.
IRIDESCENCE_FADE_NM = 0.03
#: Belcour & Barla's Gaussian fit of the CIE XYZ matching functions' Fourier transforms
#: (supplemental, evalSensitivity): amplitude, centre (1/m), variance (1/m^2) per X, Y, Z, X's second
#: lobe, and the normalization 1 / 1.0685e-7 that makes S(0) the white point.
IRI_VAL = np.array([5.4856e-13, 4.4201e-13, 5.2481e-13])
IRI_POS = np.array([1.6810e+06, 1.7953e+06, 2.2084e+06])
IRI_VAR = np.array([4.3278e+09, 9.3046e+09, 6.6121e+09])
IRI_X2 = (9.7470e-14, 2.2399e+06, 4.5282e+09)
IRI_NORM = 1.0685e-7
#: CIE XYZ -> linear Rec. 709 (sRGB primaries, D65), IEC 61966-2-1.
XYZ_TO_REC709 = np.array([[3.2404542, -1.5371385, -0.4985314],
                          [-0.9692660, 1.8760108, 0.0415560],
                          [0.0556434, -0.2040259, 1.0572252]])


def _dot(a, b):
    return np.sum(np.asarray(a) * np.asarray(b), axis=-1)


def _normalize(a):
    a = np.asarray(a, np.float64)
    return a / np.maximum(np.linalg.norm(a, axis=-1, keepdims=True), 1e-30)


def _mix(a, b, t):
    return a + (b - a) * t


def _schlick(c, f0, f90=1.0):
    return f0 + (f90 - f0) * (1.0 - np.asarray(c, np.float64)) ** 5


# ---- coat (KHR_materials_clearcoat) ----------------------------------------------------------------

def coat_f0(ior):
    """The coat's normal-incidence reflectance from its IOR against air: ((ior - 1) / (ior + 1))^2."""
    ior = np.asarray(ior, np.float64)
    return ((ior - 1.0) / (ior + 1.0)) ** 2


def coat_fresnel(c, f0):
    """Schlick's Fresnel of the coat, F90 = 1."""
    return _schlick(c, f0)


def coat_attenuation_nov(NoV, VoH, coat, f0):
    """The base under the coat scaled by 1 - coat Fc(n_c.v) (the spec's fresnel_coat, Filament, three.js;
    the Sample Viewer's image-based term). ``VoH`` unread."""
    return 1.0 - coat * coat_fresnel(NoV, f0)


def coat_attenuation_voh(NoV, VoH, coat, f0):
    """The base under the coat scaled by 1 - coat Fc(v.h) (the Fresnel inside the Sample Viewer's
    punctual coat BRDF, applied to the base as its attenuation). ``NoV`` unread."""
    return 1.0 - coat * coat_fresnel(VoH, f0)


def coat_ibl_weight_filament(NoV, roughness, coat, f0, A, B):
    """Filament's coat image-based weight: the prefiltered radiance times Fc(n.v) coat alone, no DFG."""
    return coat * coat_fresnel(NoV, f0)


def coat_ibl_weight_sample_viewer(NoV, roughness, coat, f0, A, B):
    """The Sample Viewer's split sum at the coat's roughness: coat (k_S A + B), k_S the roughness-dependent
    Schlick F0 + (max(1 - r, F0) - F0)(1 - n.v)^5 [FdezAguera19], (A, B) the DFG LUT at (n.v, r)."""
    k_s = f0 + (np.maximum(1.0 - roughness, f0) - f0) * (1.0 - NoV) ** 5
    return coat * (k_s * A + B)


def coat_ibl_weight_splitsum(NoV, roughness, coat, f0, A, B):
    """The plain split sum at the coat's roughness (the Sample Viewer's form before its Fdez-Aguera k_S):
    coat (F0 A + B)."""
    return coat * (f0 * A + B)


def coat_ibl_weight_threejs(NoV, roughness, coat, f0, A, B):
    """three.js: coat (F0 A + B) with (A, B) Karis's analytic EnvBRDFApprox at the coat's roughness (the
    LUT's A, B unread)."""
    ab = EnvBRDFApprox(NoV, roughness)
    return coat * (f0 * ab[..., 0] + ab[..., 1])


# ---- sheen (KHR_materials_sheen) -------------------------------------------------------------------

def _sheen_alpha(alpha):
    return np.maximum(np.asarray(alpha, np.float64), SHEEN_MIN_ALPHA)


def D_Charlie(NoH, alpha):
    """[Estevez17] eq. 2: D = (2 + 1/alpha) sin^(1/alpha)(theta_h) / (2 pi), alpha = sheenRoughness^2: the
    truth's :func:`pbrcheck.lobes.charlie_D` with sin^2 = (1 - n.h)(1 + n.h) (exact as n.h -> 1) and alpha
    at this renderer's floor :data:`SHEEN_MIN_ALPHA` (the GLSL's)."""
    sin2 = np.maximum((1.0 - NoH) * (1.0 + NoH), 0.0)
    return charlie_D(sin2, _sheen_alpha(alpha))


def _charlie_L(x, alpha):
    """The GLSL charlie_L's twin: the truth's :func:`pbrcheck.lobes.sheen_l` at this renderer's alpha floor."""
    return sheen_l(np.asarray(x, np.float64), _sheen_alpha(alpha), np.power)


def charlie_lambda(c, alpha):
    """[Estevez17] eq. 3-4: Lambda(cos) = exp(L(cos)) for cos < 0.5, exp(2 L(0.5) - L(1 - cos)) above: the
    truth's :func:`pbrcheck.lobes.charlie_lambda` at this renderer's alpha floor."""
    return _charlie_lambda(c, _sheen_alpha(alpha))


def V_Charlie(NoV, NoL, alpha):
    """The spec's sheen visibility [Estevez17]: 1 / ((1 + Lambda(n.v) + Lambda(n.l)) 4 n.v n.l), the truth's
    :func:`pbrcheck.lobes.charlie_V` (denominator >= COS_EPS) at this renderer's alpha floor."""
    return charlie_V(NoV, NoL, _sheen_alpha(alpha), COS_EPS)


def V_Neubelt(NoV, NoL):
    """[Neubelt13] (Ashikhmin's form; Filament's, PlayCanvas's and the glTF-IBL-Sampler's Charlie LUT's sheen
    V; an older IBL sampler clamped it to 1): 1 / (4 (n.l + n.v - n.l n.v))."""
    return 1.0 / np.maximum(4.0 * (NoL + NoV - NoL * NoV), COS_EPS)


def sample_Charlie(u, alpha):
    """Half vectors (tangent space, z = n) with density D_Charlie(h) (n.h) over solid angle: the truth's
    :func:`pbrcheck.lobes.charlie_sample_h` (sin theta = u1^(alpha / (2 alpha + 1)), phi = 2 pi u0) at this
    renderer's alpha floor."""
    return charlie_sample_h(u, _sheen_alpha(alpha))


def charlie_prefilter_pdf(NoH, alpha):
    """The density of a sampled reflection in the prefilter pass, where n = v = r makes v.h = n.h:
    pdf_l = D (n.h) / (4 v.h) = D / 4 (its solid angle picks the source mip, ibl.glsl filtered_is_lod)."""
    return D_Charlie(NoH, alpha) / 4.0


def sheen_dg_fit(NoV, roughness):
    """[EntPBR]'s fit of the Charlie lobe's directional albedo times pi, in sheen roughness r:
    exp(a n.v + b) + (r < 0.25 ? 0 : 0.1 (r - 0.25)), a, b quadratics in r on each side of 0.25."""
    r = np.asarray(roughness, np.float64)
    r2 = r * r
    a = np.where(r < 0.25, -339.2 * r2 + 161.4 * r - 25.9, -8.48 * r2 + 14.3 * r - 9.95)
    b = np.where(r < 0.25, 44.0 * r2 - 23.7 * r + 3.26, 1.97 * r2 - 3.27 * r + 0.72)
    return np.exp(a * NoV + b) + np.where(r < 0.25, 0.0, 0.1 * (r - 0.25))


def sheen_dfg_threejs(NoV, roughness, E):
    """three.js IBLSheenBRDF: saturate(DG / pi); it multiplies the irradiance E(n) (not a prefiltered
    radiance). ``E`` (the LUT's texel pair) unread."""
    return np.clip(sheen_dg_fit(NoV, roughness) / PI, 0.0, 1.0)


def sheen_dfg_playcanvas(NoV, roughness, E):
    """PlayCanvas addReflectionSheen: saturate(DG) (no 1/pi) times the environment at the normal's
    roughest level. ``E`` unread."""
    return np.clip(sheen_dg_fit(NoV, roughness), 0.0, 1.0)


def sheen_dfg_lut_charlie(NoV, roughness, E):
    """The sheen LUT's R channel (Charlie D, the spec's V_Charlie): the spec's directional albedo."""
    return np.asarray(E)[..., 0]


def sheen_dfg_lut_neubelt(NoV, roughness, E):
    """The sheen LUT's G channel (Charlie D at alpha = roughness^2, V_Neubelt): Filament's DFG.z and the
    Sample Viewer's Charlie LUT (glTF-IBL-Sampler LUT_CharlieUniform)."""
    return np.asarray(E)[..., 1]


def sheen_dfg_lut_ibl_sampler_legacy(NoV, roughness, E):
    """The sheen LUT's B channel: an older glTF-IBL-Sampler's Charlie LUT (commit 203dccf: Charlie D at
    alpha = roughness, not squared; V_Neubelt clamped to 1; the integral it meant, not its estimator)."""
    return np.asarray(E)[..., 2]


def sheen_dfg_fitted(NoV, roughness, E):
    """``sheen_dfg = fitted``: the spec's albedo E (the LUT's R, :func:`sheen_dfg_lut_charlie`) from the
    8 x 8 table ``pbrcheck fit-lobes`` fits by AD (:func:`realtime.fitted_lobes.sheen_albedo_fitted`, read
    at (sqrt(n.v), roughness)); times the Charlie-prefiltered cube. ``E`` unread."""
    return sheen_albedo_fitted(NoV, roughness)


def _max3(c):
    return np.max(np.asarray(c, np.float64), axis=-1)


def sheen_scaling_lut(color, E):
    """The spec's albedo scaling 1 - max(sheenColor) E(n.v), E the LUT's R channel."""
    return 1.0 - _max3(color) * np.asarray(E)[..., 0]


def sheen_scaling_filament(color, E):
    """Filament's 1 - max(sheenColor) DFG.z, the LUT's G channel (V_Neubelt)."""
    return 1.0 - _max3(color) * np.asarray(E)[..., 1]


def sheen_scaling_threejs(color, E):
    """three.js's constant 1 - 0.157 max(sheenColor) (:data:`THREEJS_SHEEN_ALBEDO`). ``E`` unread."""
    return 1.0 - THREEJS_SHEEN_ALBEDO * _max3(color)


def lut_bilinear(lut, NoV, roughness):
    """ibl.glsl dfg_lookup's numpy twin on an ``(N, N, C)`` LUT ([j, i] at n.v (i + 0.5)/N, roughness
    (j + 0.5)/N): bilinear between texel centres, linear extrapolation within half a texel of 0 and 1."""
    lut = np.asarray(lut, np.float64)
    h, w = lut.shape[:2]
    x = np.clip(np.asarray(NoV, np.float64), 0, 1) * w - 0.5
    y = np.clip(np.asarray(roughness, np.float64), 0, 1) * h - 0.5
    i0 = np.clip(np.floor(x).astype(int), 0, max(w - 2, 0))
    j0 = np.clip(np.floor(y).astype(int), 0, max(h - 2, 0))
    i1, j1 = np.minimum(i0 + 1, w - 1), np.minimum(j0 + 1, h - 1)
    fx = (x - i0)[..., None] if w > 1 else 0.0
    fy = (y - j0)[..., None] if h > 1 else 0.0
    v0 = _mix(lut[j0, i0], lut[j0, i1], fx)
    v1 = _mix(lut[j1, i0], lut[j1, i1], fx)
    return np.maximum(_mix(v0, v1, fy), 0.0)


def sheen_lut_lookup(lut, NoV, roughness):
    """lobes_sheen.glsl sheen_lut_lookup's twin: the sheen LUT's three channels, bilinear (:func:`lut_bilinear`)."""
    return lut_bilinear(lut, NoV, roughness)


def sheen_albedo_quadrature(NoV, roughness, n_theta: int = 512, n_phi: int = 256):
    """The sheen LUT's three channels at one (n.v, sheen roughness) by a midpoint quadrature over the
    incident hemisphere (theta_l, phi_l), independent of the bake's importance sampling:
    (int D_Charlie V_Charlie n.l dl, int D_Charlie V_Neubelt n.l dl at alpha = roughness^2, and
    int D_Charlie min(V_Neubelt, 1) n.l dl at alpha = roughness, an older glTF-IBL-Sampler's)."""
    alpha = max(float(roughness) ** 2, SHEEN_MIN_ALPHA)
    v = np.array([np.sqrt(max(1.0 - NoV * NoV, 0.0)), 0.0, NoV])
    th = (np.arange(n_theta) + 0.5) * (0.5 * PI / n_theta)
    ph = (np.arange(n_phi) + 0.5) * (2.0 * PI / n_phi)
    T, P = np.meshgrid(th, ph, indexing="ij")
    l = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], axis=-1)
    NoH = _normalize(l + v)[..., 2]
    NoL = l[..., 2]
    dw = np.sin(T) * (0.5 * PI / n_theta) * (2.0 * PI / n_phi)
    D = D_Charlie(NoH, alpha)
    e1 = np.sum(D * V_Charlie(NoV, NoL, alpha) * NoL * dw)
    e2 = np.sum(D * V_Neubelt(NoV, NoL) * NoL * dw)
    e3 = np.sum(D_Charlie(NoH, float(roughness)) * np.minimum(V_Neubelt(NoV, NoL), 1.0) * NoL * dw)
    return np.array([e1, e2, e3])


# ---- anisotropy (KHR_materials_anisotropy) ---------------------------------------------------------

def _mcauley_normal(direction, v):
    """[McAuley15]: the normal of the plane holding the grain ``direction`` that faces v most:
    (direction x v) x direction (length |direction x v|: not normalized, as the engines that use it raw)."""
    return np.cross(np.cross(direction, v), direction)


def aniso_bend_weight(anisotropy, roughness):
    """The Sample Viewer's and three.js's weight of n against the bent plane's normal: (1 - s (1 - r))^4."""
    return (1.0 - np.asarray(anisotropy, np.float64) * (1.0 - np.asarray(roughness, np.float64))) ** 4


def aniso_bent_normal_sample_viewer(n, t, b, v, anisotropy, roughness):
    """The Sample Viewer: normalize(mix((b x v) x b, n, (1 - s (1 - r))^4)), the plane's normal
    unnormalized; b the anisotropy bitangent n x t, s the strength, r the roughness."""
    w = aniso_bend_weight(anisotropy, roughness)[..., None]
    return _normalize(_mix(_mcauley_normal(b, v), n, w))


def aniso_bent_normal_threejs(n, t, b, v, anisotropy, roughness):
    """three.js: the Sample Viewer's with the plane's normal normalized first."""
    w = aniso_bend_weight(anisotropy, roughness)[..., None]
    return _normalize(_mix(_normalize(_mcauley_normal(b, v)), n, w))


def aniso_bent_normal_filament(n, t, b, v, anisotropy, roughness):
    """Filament: d = b for s >= 0, t below; normalize(mix(n, (d x v) x d, |s| saturate(5 r)))."""
    s = np.asarray(anisotropy, np.float64)[..., None]
    d = np.where(s >= 0, b, t)
    w = np.abs(s) * np.clip(5.0 * np.asarray(roughness, np.float64)[..., None], 0.0, 1.0)
    return _normalize(_mix(n, _mcauley_normal(d, v), w))


def aniso_bent_normal_babylon(n, t, b, v, anisotropy, roughness):
    """Babylon.js (ANISOTROPIC_LEGACY): as Filament's frame, normalize(mix(n, (d x v) x d, |s|)), no
    roughness term. ``roughness`` unread."""
    s = np.asarray(anisotropy, np.float64)[..., None]
    d = np.where(s >= 0, b, t)
    return _normalize(_mix(n, _mcauley_normal(_normalize(d), v), np.abs(s)))


def aniso_bent_normal_fitted(n, t, b, v, anisotropy, roughness):
    """The Sample Viewer's bent normal with ``pbrcheck fit-lobes``' weight in place of (1 - s (1 - r))^4:
    normalize(mix((b x v) x b, n, w(s, r))), w :func:`realtime.fitted_lobes.aniso_bend_weight_fitted`."""
    w = np.asarray(aniso_bend_weight_fitted(anisotropy, roughness))[..., None]
    return _normalize(_mix(_mcauley_normal(b, v), n, w))


def _reflect_about(v, n):
    return 2.0 * _dot(v, n)[..., None] * n - v


def aniso_reflection_sample_viewer(n, t, b, v, anisotropy, roughness):
    """The Sample Viewer's lookup direction: reflect(-v, bent normal)."""
    return _normalize(_reflect_about(v, aniso_bent_normal_sample_viewer(n, t, b, v, anisotropy, roughness)))


def aniso_reflection_filament(n, t, b, v, anisotropy, roughness):
    """Filament's lookup direction: reflect(-v, bent normal)."""
    return _normalize(_reflect_about(v, aniso_bent_normal_filament(n, t, b, v, anisotropy, roughness)))


def aniso_reflection_babylon(n, t, b, v, anisotropy, roughness):
    """Babylon.js's lookup direction: reflect(-v, bent normal)."""
    return _normalize(_reflect_about(v, aniso_bent_normal_babylon(n, t, b, v, anisotropy, roughness)))


def aniso_reflection_fitted(n, t, b, v, anisotropy, roughness):
    """``anisotropy_bend = fitted``'s lookup direction: reflect(-v, :func:`aniso_bent_normal_fitted`)."""
    return _normalize(_reflect_about(v, aniso_bent_normal_fitted(n, t, b, v, anisotropy, roughness)))


def threejs_reflection(n, v, roughness):
    """three.js getIBLRadiance's direction: normalize(mix(reflect(-v, n), n, r^2)) (it leans every
    lookup toward the normal by roughness^2; r160's form)."""
    r = _reflect_about(v, n)
    return _normalize(_mix(r, n, (np.asarray(roughness, np.float64) ** 2)[..., None]))


def aniso_reflection_threejs(n, t, b, v, anisotropy, roughness):
    """three.js: its bent normal, then its own lean of the reflection toward it."""
    return threejs_reflection(aniso_bent_normal_threejs(n, t, b, v, anisotropy, roughness), v, roughness)


# ---- the direct lights' anisotropic GGX (lobes_anisotropy.glsl, KHR_materials_anisotropy README) ----

def aniso_alpha_t(alpha, strength):
    """The README's alpha_t = mix(alpha, 1, strength^2), written as the truth writes mix:
    alpha (1 - s^2) + s^2 (:class:`pbrcheck.lobes.AnisotropicGGX`)."""
    s2 = np.asarray(strength, np.float64) ** 2
    return np.asarray(alpha, np.float64) * (1.0 - s2) + 1.0 * s2


def D_GGX_anisotropic(NoH, ToH, BoH, at, ab):
    """The README's D_GGX_anisotropic: a2 = at ab, f = (ab t.h, at b.h, a2 n.h), w2 = a2 / f.f,
    a2 w2^2 / pi; 0 for n.h <= 0."""
    NoH, ToH, BoH, at, ab = (np.asarray(x, np.float64) for x in (NoH, ToH, BoH, at, ab))
    a2 = at * ab
    ff = (ab * ToH) ** 2 + (at * BoH) ** 2 + (a2 * NoH) ** 2
    w2 = a2 / ff
    return np.where(NoH > 0.0, a2 * w2 * w2 / PI, 0.0)


def V_GGX_anisotropic(NoV, NoL, ToV, BoV, ToL, BoL, at, ab):
    """The README's V_GGX_anisotropic without its clamp to 1 (the truth's G2 / (4 n.v n.l)):
    0.5 / ((n.l) |(at t.v, ab b.v, n.v)| + (n.v) |(at t.l, ab b.l, n.l)|)."""
    NoV, NoL, ToV, BoV, ToL, BoL, at, ab = (np.asarray(x, np.float64) for x in (NoV, NoL, ToV, BoV, ToL, BoL, at, ab))
    gv = NoL * np.sqrt((at * ToV) ** 2 + (ab * BoV) ** 2 + NoV ** 2)
    gl = NoV * np.sqrt((at * ToL) ** 2 + (ab * BoL) ** 2 + NoL ** 2)
    return 0.5 / np.maximum(gv + gl, COS_EPS)


def aniso_specular_dv(n, t, b, v, l, alpha, strength):
    """A light's anisotropic specular lobe without Fresnel, D V at alpha_t = :func:`aniso_alpha_t`,
    alpha_b = alpha (n, t unit and orthogonal, b = n x t); 0 below either horizon."""
    n, t, b, v, l = (np.asarray(x, np.float64) for x in (n, t, b, v, l))
    NoV, NoL = _dot(n, v), _dot(n, l)
    h = _normalize(v + l)
    at = aniso_alpha_t(alpha, strength)
    dv = (D_GGX_anisotropic(np.clip(_dot(n, h), 0.0, 1.0), _dot(t, h), _dot(b, h), at, alpha)
          * V_GGX_anisotropic(NoV, NoL, _dot(t, v), _dot(b, v), _dot(t, l), _dot(b, l), at, alpha))
    return np.where((NoV > 0.0) & (NoL > 0.0), dv, 0.0)


# ---- iridescence (KHR_materials_iridescence) -------------------------------------------------------

def iridescence_sensitivity(opd, shift):
    """[Belcour17] eq. 11 with the supplemental's fit: the XYZ matching functions' Fourier transform at
    the phase 2 pi OPD (OPD in nm), shifted by ``shift`` (per channel), to linear Rec. 709."""
    opd = np.asarray(opd, np.float64)[..., None]
    shift = np.asarray(shift, np.float64)
    phase = 2.0 * PI * opd * 1e-9
    xyz = IRI_VAL * np.sqrt(2.0 * PI * IRI_VAR) * np.cos(IRI_POS * phase + shift) * np.exp(-phase ** 2 * IRI_VAR)
    a2, p2, v2 = IRI_X2
    x2 = a2 * np.sqrt(2.0 * PI * v2) * np.cos(p2 * phase[..., 0] + shift[..., 0]) * np.exp(-v2 * phase[..., 0] ** 2)
    xyz = np.concatenate([xyz[..., :1] + x2[..., None], xyz[..., 1:]], axis=-1) / IRI_NORM
    return xyz @ XYZ_TO_REC709.T


def iridescence_fresnel(outside_ior, film_ior, cos1, thickness, base_f0):
    """[Belcour17] sec. 4 as the Sample Viewer evaluates it (Schlick Fresnel at both interfaces, the
    Airy sum's first two orders in RGB through :func:`iridescence_sensitivity`): the reflectance of a
    film of IOR ``film_ior`` and ``thickness`` nm over a base of normal reflectance ``base_f0`` (RGB),
    seen at cos ``cos1`` from a medium of ``outside_ior``. Total internal reflection: 1."""
    cos1 = np.asarray(cos1, np.float64)
    thickness = np.asarray(thickness, np.float64)
    x = np.clip(thickness / IRIDESCENCE_FADE_NM, 0.0, 1.0)
    eta2 = _mix(outside_ior, film_ior, x * x * (3.0 - 2.0 * x))
    k = (outside_ior / eta2) ** 2
    cos2sq = (1.0 - k) + k * cos1 * cos1  # Snell, in the form exact for k = 1 (lobes_iridescence.glsl)
    tir = cos2sq < 0.0
    cos2 = np.sqrt(np.maximum(cos2sq, 0.0))
    R12 = _schlick(cos1, ((eta2 - outside_ior) / (eta2 + outside_ior)) ** 2)
    T121 = 1.0 - R12
    phi12 = np.where(eta2 < outside_ior, PI, 0.0)
    phi21 = PI - phi12
    sf0 = np.sqrt(np.clip(np.asarray(base_f0, np.float64), 0.0, IRIDESCENCE_MAX_F0))
    base_ior = (1.0 + sf0) / (1.0 - sf0)
    eta2v = np.asarray(eta2)[..., None]
    R23 = _schlick(cos2[..., None], ((base_ior - eta2v) / (base_ior + eta2v)) ** 2)
    phi23 = np.where(base_ior < eta2v, PI, 0.0)
    opd = 2.0 * eta2 * thickness * cos2
    phi = np.asarray(phi21)[..., None] + phi23
    R123 = np.minimum(R12[..., None] * R23, IRIDESCENCE_MAX_F0)
    r123 = np.sqrt(R123)
    Rs = T121[..., None] ** 2 * R23 / (1.0 - R123)
    I = R12[..., None] + Rs
    Cm = Rs - T121[..., None]
    for m in (1, 2):
        Cm = Cm * r123
        I = I + Cm * 2.0 * iridescence_sensitivity(m * opd, m * phi)
    return np.where(tir[..., None], 1.0, np.maximum(I, 0.0))


def iridescence_factor(factor, thickness):
    """The Sample Viewer's switch-off: the factor is 0 at a zero film thickness (where
    :func:`iridescence_fresnel` keeps Schlick's F90 = 1 at the matched interface, so it is not the base's
    Fresnel towards grazing: up to +0.44 of a base F0 0, near n.v = 0.2)."""
    return np.where(np.asarray(thickness) > 0.0, factor, 0.0)


def iridescence_mix(F, F_iri, factor):
    """The Sample Viewer's use: the specular Fresnel mix(F, F_iridescence, iridescenceFactor)."""
    return _mix(np.asarray(F, np.float64), np.asarray(F_iri, np.float64), np.asarray(factor, np.float64)[..., None])


def iridescence_light_fresnel(VoH, f0, f90, film_ior, thickness, factor):
    """A light's Fresnel with the film (the README's dielectric_fresnel / metal_fresnel mixed with the
    film over their own F0), at v.h: mix(Schlick(v.h; f0, f90), iridescence_fresnel(1, film_ior, v.h, d,
    f0), factor). ``f0`` RGB."""
    c = np.clip(np.asarray(VoH, np.float64), 0.0, 1.0)
    f0 = np.asarray(f0, np.float64)
    F = _schlick(c[..., None], f0, np.asarray(f90, np.float64)[..., None])
    return iridescence_mix(F, iridescence_fresnel(1.0, film_ior, c, thickness, f0), factor)


# ---- the material composition's own lobe terms (lobes_material.glsl) -------------------------------

def specular_dielectric_f0(f0_ior, factor, color):
    """KHR_materials_specular's dielectric F0: min(F0_ior specularColor, 1) specularFactor, RGB
    (:func:`pbrcheck.lobes.specular_f0`, the truth's, is the same equation)."""
    c = np.asarray(color, np.float64)
    return np.minimum(np.asarray(f0_ior, np.float64)[..., None] * c, 1.0) * np.asarray(factor, np.float64)[..., None]


def specular_f90_blend(f90, metallic):
    """The split sum's F90: the dielectric's specularFactor blended to the metal's 1: f90 + (1 - f90) metallic."""
    f90 = np.asarray(f90, np.float64)
    return f90 + (1.0 - f90) * np.asarray(metallic, np.float64)


def split_sum_albedo_f90(F0, F90, A, B):
    """The split sum with Schlick's F90 kept: F0 A + F90 B (RGB F0)."""
    return np.asarray(F0, np.float64) * np.asarray(A)[..., None] + (np.asarray(F90) * np.asarray(B))[..., None]


def aniso_direction(T, n, rotation):
    """The anisotropy direction: the tangent rotated counter-clockwise by ``rotation`` toward n x T."""
    rot = np.asarray(rotation, np.float64)[..., None]
    return _normalize(np.cos(rot) * np.asarray(T) + np.sin(rot) * np.cross(n, T))


def sphere_tangent(n):
    """The ray-cast sphere's tangent: Mitsuba's sphere dp/du direction (-n.y, n.x, 0) normalized, +X where
    its length is at most 1e-6 (the poles on the z axis)."""
    n = np.asarray(n, np.float64)
    t = np.stack([-n[..., 1], n[..., 0], np.zeros(n.shape[:-1])], axis=-1)
    ln = np.linalg.norm(t, axis=-1, keepdims=True)
    return np.where(ln > 1e-6, t / np.maximum(ln, 1e-30), np.array([1.0, 0.0, 0.0]))


# ---- the sheen LUT's bake (sheen_lut.comp) ---------------------------------------------------------

#: The sheen LUT's bake (sheen_lut.comp) and its conventions, stated at both ends (the shader's header
#: and ibl.glsl dfg_lookup, which reads it): axes, texel centres, channels, format.
SHEEN_LUT_CONVENTIONS = {
    "axes": "column i: n.v = (i + 0.5)/N; row j: sheen roughness = (j + 0.5)/N, row 0 smoothest; alpha = roughness^2",
    "texel_centres": "texel centres at (i + 0.5)/N; read bilinearly between them, linear extrapolation within "
                     "half a texel of 0 and 1 (ibl.glsl dfg_lookup, numpy lut_bilinear)",
    "channels": "R = int D_Charlie V_Charlie n.l dl (the spec's sheen albedo E); "
                "G = int D_Charlie V_Neubelt n.l dl (Filament DFG.z, the Sample Viewer's Charlie LUT); B = the same "
                "at alpha = roughness with V_Neubelt clamped to 1 (an older glTF-IBL-Sampler); A = 0",
    "format": "rgba16f (f16) or rgba32f (f32), N x N, clamp to edge, linear filter (unused: texelFetch)",
}
#: The Charlie-prefiltered cube's bake (charlie_prefilter.comp, realtime.render.charlie_cube) and its reader
#: (material_lobes.glsl sheen_radiance), stated at both ends.
CHARLIE_CUBE_CONVENTIONS = {
    "levels": "level L of charlie_levels holds sheen roughness L / (levels - 1) (the Sample Viewer's lod = "
              "sheenRoughness (mipCount - 1)); read at lod = sheen roughness x (levels - 1), trilinear",
    "filter": "v = n = r; Hammersley points through the Charlie half-vector distribution at alpha = roughness^2 "
              "conditioned on n.l > 0 (sin theta_h <= sqrt(1/2)), l = reflect(-n, h), weights n.l, each sample read "
              "at its conditioned density's source level (charlie_prefilter_pdf / p_up, filtered_is_lod); a texel "
              "with no weight stores the source's radiance along n",
    "faces": "GL order +X, -X, +Y, -Y, +Z, -Z; texel directions cube_dir (env.glsl), as every cube of realtime.render",
}
#: The sheen LUT's default size and samples per texel (the Charlie sampler's estimate is within
#: SHEEN_LUT_RTOL of the quadrature at these, tests/test_realtime_lobes.py; ~0.3 s on llvmpipe).
SHEEN_LUT_SIZE = 32
SHEEN_LUT_SAMPLES = 4096
