"""BRDF terms in numpy: the ground truth both renderers are checked against.

Every function here has a GLSL twin of the *same name* in ``realtime/shaders/brdf.glsl`` (the test
harness runs both on the same grids). Arguments are cosines clamped by the caller to [0, 1];
``alpha`` is the GGX width ``roughness^2``.

The material model both renderers implement (README, "Material model")::

    F0    = mix(specular, base_color, metallic),   alpha = roughness^2
    f(l,v) = (1 - F(v.h)) (1 - metallic) base_color / pi  +  D(h) G(l, v) F(v.h) / (4 (n.l)(n.v))

References
----------
[Walter07]  B. Walter, S. Marschner, H. Li, K. Torrance, "Microfacet Models for Refraction through
            Rough Surfaces", EGSR 2007.
[Heitz14]   E. Heitz, "Understanding the Masking-Shadowing Function in Microfacet-Based BRDFs",
            JCGT 3(2), 2014.
[Karis13]   B. Karis, "Real Shading in Unreal Engine 4", SIGGRAPH 2013 course notes.
[Schlick94] C. Schlick, "An Inexpensive BRDF Model for Physically-based Rendering", CGF 13(3), 1994.
[Heitz18]   E. Heitz, "Sampling the GGX Distribution of Visible Normals", JCGT 7(4), 2018.
"""

from __future__ import annotations

import math

import numpy as np

from .registry import FRESNELS, GEOMETRIES, NDFS

# Smallest alpha the term functions evaluate with. alpha = 0 is a delta distribution that no
# function can evaluate; renderers treat roughness 0 as a perfect mirror explicitly. 1e-7 keeps
# alpha^2 = 1e-14 well inside float32's normal range and D_GGX(1) = 1/(pi alpha^2) finite (3e13).
MIN_ALPHA = 1e-7
# Below this alpha the quadrature uses the mirror limit of the lobe: at alpha ~ 1e-5 the lobe is
# ~1e-5 rad wide and 1 - cos(theta_h) ~ 1e-10 nears float64's resolution of cos near 1. The limit
# differs from alpha = 1e-4 by < 1e-7 in A + B.
DELTA_LOBE_ALPHA = 1e-4
# Guard for divisions by cosines that reach 0 at grazing angles (n.v, n.l -> 0).
COS_EPS = 1e-8

PI = np.pi


def alpha_from_roughness(roughness):
    """alpha = roughness^2 ([Karis13] p. 3: perceptually linear roughness), clamped to MIN_ALPHA."""
    r = np.asarray(roughness, dtype=np.float64)
    return np.maximum(r * r, MIN_ALPHA)


# ------------------------------------------------------------------------------------------------
# Normal distribution functions. Each is normalized so that the projected area is one:
#   integral over the hemisphere of D(h) (n.h) dw_h = 1.
# ------------------------------------------------------------------------------------------------

def D_GGX(NoH, alpha):
    """GGX / Trowbridge-Reitz NDF, [Walter07] eq. 33:
    ``D = alpha^2 / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2)``."""
    NoH = np.asarray(NoH, dtype=np.float64)
    a2 = np.maximum(np.asarray(alpha, dtype=np.float64), MIN_ALPHA) ** 2
    d = NoH * NoH * (a2 - 1.0) + 1.0
    return np.where(NoH > 0, a2 / (PI * d * d), 0.0)


def D_Beckmann(NoH, alpha):
    """Beckmann NDF, [Walter07] eq. 25:
    ``D = exp(-tan^2(theta_h) / alpha^2) / (pi alpha^2 cos^4(theta_h))``."""
    NoH = np.asarray(NoH, dtype=np.float64)
    a2 = np.maximum(np.asarray(alpha, dtype=np.float64), MIN_ALPHA) ** 2
    c2 = np.maximum(NoH * NoH, COS_EPS)
    tan2 = (1.0 - c2) / c2
    with np.errstate(over="ignore", under="ignore"):
        v = np.exp(-tan2 / a2) / (PI * a2 * c2 * c2)
    return np.where(NoH > 0, v, 0.0)


def blinn_phong_exponent(alpha):
    """Phong exponent equivalent to a Beckmann alpha, [Walter07] sec. 5.2: ``n = 2 / alpha^2 - 2``."""
    a2 = np.maximum(np.asarray(alpha, dtype=np.float64), MIN_ALPHA) ** 2
    return np.maximum(2.0 / a2 - 2.0, 0.0)


def D_BlinnPhong(NoH, alpha):
    """Normalized Blinn-Phong NDF, [Walter07] eq. 30: ``D = (n + 2) / (2 pi) (n.h)^n`` with
    ``n = 2 / alpha^2 - 2`` (so alpha = 1 is the uniform D = 1/pi)."""
    NoH = np.asarray(NoH, dtype=np.float64)
    n = blinn_phong_exponent(alpha)
    with np.errstate(under="ignore"):
        v = (n + 2.0) / (2.0 * PI) * np.power(np.clip(NoH, 0.0, 1.0), n)
    return np.where(NoH > 0, v, 0.0)




# ------------------------------------------------------------------------------------------------
# Geometry (masking-shadowing) terms G(l, v), each in [0, 1].
# ------------------------------------------------------------------------------------------------

def Lambda_GGX(NoX, alpha):
    """Smith Lambda of GGX, [Heitz14] eq. 72: ``(-1 + sqrt(1 + alpha^2 tan^2)) / 2``, written as
    ``(sqrt(alpha^2 + (1 - alpha^2) c^2) / c - 1) / 2`` which stays accurate as c -> 1."""
    c = np.maximum(np.asarray(NoX, dtype=np.float64), COS_EPS)
    a2 = np.maximum(np.asarray(alpha, dtype=np.float64), MIN_ALPHA) ** 2
    return 0.5 * (np.sqrt(a2 + (1.0 - a2) * c * c) / c - 1.0)


def G1_SmithGGX(NoX, alpha):
    """Smith masking of GGX, [Heitz14] eq. 43 with eq. 72: ``G1 = 1 / (1 + Lambda) =
    2 c / (c + sqrt(alpha^2 + (1 - alpha^2) c^2))``."""
    c = np.clip(np.asarray(NoX, dtype=np.float64), 0.0, 1.0)
    a2 = np.maximum(np.asarray(alpha, dtype=np.float64), MIN_ALPHA) ** 2
    return 2.0 * c / np.maximum(c + np.sqrt(a2 + (1.0 - a2) * c * c), COS_EPS)


def G_SmithGGX(NoV, NoL, alpha):
    """Separable Smith, [Heitz14] eq. 98: ``G1(v) G1(l)`` (Mitsuba's ``roughconductor``)."""
    return G1_SmithGGX(NoV, alpha) * G1_SmithGGX(NoL, alpha)


def G_SmithGGXCorrelated(NoV, NoL, alpha):
    """Height-correlated Smith, [Heitz14] eq. 99: ``G = 1 / (1 + Lambda(v) + Lambda(l))``, i.e.
    ``2 (n.v)(n.l) / ((n.l) sqrt(a2 + (1-a2)(n.v)^2) + (n.v) sqrt(a2 + (1-a2)(n.l)^2))``.
    The guard keeps 0/0 at n.v = n.l = 0 at 0."""
    v = np.clip(np.asarray(NoV, dtype=np.float64), 0.0, 1.0)
    l = np.clip(np.asarray(NoL, dtype=np.float64), 0.0, 1.0)
    a2 = np.maximum(np.asarray(alpha, dtype=np.float64), MIN_ALPHA) ** 2
    den = l * np.sqrt(a2 + (1.0 - a2) * v * v) + v * np.sqrt(a2 + (1.0 - a2) * l * l)
    return 2.0 * v * l / np.maximum(den, COS_EPS)


_erfc = np.vectorize(math.erfc, otypes=[np.float64])


def erfcx_nr(z):
    """``exp(z^2) erfc(z)`` for ``z >= 0`` by Numerical Recipes' erfcc Chebyshev fit (Press et al.,
    "Numerical Recipes in C", 2nd ed., sec. 6.2; fractional error < 1.2e-7) without its
    ``exp(-z^2)`` factor: the GLSL twin's erfc (GLSL has none); checked against ``math.erfc``."""
    z = np.maximum(np.asarray(z, dtype=np.float64), 0.0)
    t = 1.0 / (1.0 + 0.5 * z)
    p = -1.26551223 + t * (1.00002368 + t * (0.37409196 + t * (0.09678418 + t * (
        -0.18628806 + t * (0.27886807 + t * (-1.13520398 + t * (1.48851587 + t * (
            -0.82215223 + t * 0.17087277))))))))
    return t * np.exp(p)


def Lambda_Beckmann(NoX, alpha):
    """Smith Lambda of Beckmann, [Heitz14] eq. 80 ([Walter07] eq. 27 before its rational fit):
    ``Lambda = (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi))`` with ``a = c / (alpha sqrt(1 - c^2))``;
    written ``(exp(-a^2) / (a sqrt(pi)) - erfc(a)) / 2`` (exact erfc, float64). 0 at c = 1."""
    c = np.clip(np.asarray(NoX, dtype=np.float64), COS_EPS, 1.0)
    al = np.maximum(np.asarray(alpha, dtype=np.float64), MIN_ALPHA)
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        a = np.minimum(c / (al * np.sqrt(np.maximum(1.0 - c * c, 0.0))), 1e15)
        lam = 0.5 * (np.exp(-a * a) / (a * np.sqrt(PI)) - _erfc(a))
    return np.maximum(lam, 0.0)


def G_SmithBeckmannCorrelated(NoV, NoL, alpha):
    """Height-correlated Smith for Beckmann, [Heitz14] eq. 99 with eq. 80:
    ``G = 1 / (1 + Lambda(v) + Lambda(l))``; 0 at n.v = 0 or n.l = 0. The first bounce of the
    Beckmann random walk (reference/multiscatter.py)."""
    v = np.clip(np.asarray(NoV, dtype=np.float64), 0.0, 1.0)
    l = np.clip(np.asarray(NoL, dtype=np.float64), 0.0, 1.0)
    g = 1.0 / (1.0 + Lambda_Beckmann(v, alpha) + Lambda_Beckmann(l, alpha))
    return np.where((v > 0) & (l > 0), g, 0.0)


def G1_SchlickGGX(NoX, k):
    """Schlick's approximation of Smith G1, [Schlick94] eq. 19 with [Karis13]'s k:
    ``G1 = c / (c (1 - k) + k)``."""
    c = np.clip(np.asarray(NoX, dtype=np.float64), 0.0, 1.0)
    k = np.asarray(k, dtype=np.float64)
    return c / np.maximum(c * (1.0 - k) + k, COS_EPS)


def G_SchlickGGX(NoV, NoL, k):
    """Separable Schlick-GGX: ``G1_SchlickGGX(v, k) G1_SchlickGGX(l, k)``."""
    return G1_SchlickGGX(NoV, k) * G1_SchlickGGX(NoL, k)


def k_schlick_ibl(roughness):
    """[Karis13] eq. 4 footnote, image-based lighting: ``k = alpha / 2``."""
    return alpha_from_roughness(roughness) / 2.0


def k_schlick_direct(roughness):
    """[Karis13] eq. 4, analytic lights ("Disney's remapping"): ``k = (roughness + 1)^2 / 8``."""
    r = np.asarray(roughness, dtype=np.float64)
    return (r + 1.0) ** 2 / 8.0


def _term(registry, name: str):
    """The numpy function of member ``name`` of a term registry and its width function (None for a
    term without one); ValueError naming the list for an unknown member."""
    if name not in registry:
        raise ValueError(f"unknown {registry.define.lower()} term {name!r}; terms are: {', '.join(registry.names)}")
    impl = registry[name].impl
    return globals()[impl.numpy], (globals()[impl.width] if impl.width else None)


def geometry_term(geometry: str, NoV, NoL, roughness):
    """Dispatch on the scene's ``[brdf] geometry`` name (:data:`pbrcheck.registry.GEOMETRIES`: the
    member's function at its width); ``roughness`` is perceptual."""
    g, width = _term(GEOMETRIES, geometry)
    return g(NoV, NoL, width(roughness))


def ndf_term(ndf: str, NoH, roughness):
    """Dispatch on ``[brdf] ndf`` (:data:`pbrcheck.registry.NDFS`); ``roughness`` is perceptual."""
    d, width = _term(NDFS, ndf)
    return d(NoH, width(roughness))


# ------------------------------------------------------------------------------------------------
# Fresnel and diffuse
# ------------------------------------------------------------------------------------------------

def F_Schlick(VoH, F0, F90=1.0):
    """Schlick's Fresnel, [Schlick94] eq. 15: ``F = F0 + (F90 - F0) (1 - v.h)^5``. Broadcasts F0
    (e.g. RGB in a trailing axis: pass ``VoH[..., None]``)."""
    c = np.clip(np.asarray(VoH, dtype=np.float64), 0.0, 1.0)
    f = (1.0 - c) ** 5
    return np.asarray(F0, dtype=np.float64) + (np.asarray(F90, dtype=np.float64) - F0) * f


def Fd_Lambert():
    """Lambertian diffuse: ``1 / pi``."""
    return 1.0 / PI


def F_None(VoH, F0):
    """No Fresnel factor: ``F = 1``, broadcast to the shapes of ``VoH`` and ``F0``."""
    return np.ones(np.broadcast_shapes(np.shape(VoH), np.shape(F0)))


def fresnel_term(fresnel: str, VoH, F0):
    """Dispatch on ``[brdf] fresnel`` (:data:`pbrcheck.registry.FRESNELS`): Schlick, or ``none`` (F = 1)."""
    return _term(FRESNELS, fresnel)[0](VoH, F0)


def material_f0(base_color, metallic, specular):
    """``F0 = mix(specular, base_color, metallic)``; ``base_color`` (..., 3), the others (...)."""
    m = np.asarray(metallic, dtype=np.float64)[..., None]
    s = np.asarray(specular, dtype=np.float64)[..., None]
    return s * (1.0 - m) + np.asarray(base_color, dtype=np.float64) * m


def brdf_eval(n, v, l, base_color, metallic, roughness, specular, *, ndf="ggx",
              geometry="smith_ggx_correlated", fresnel="schlick"):
    """The full material BRDF f(l, v) (without the cosine), shape (..., 3).

    ``n, v, l``: (..., 3) unit vectors (v towards the viewer, l towards the light). Returns 0 where
    either direction is below the surface. Roughness 0 returns the specular lobe evaluated at
    MIN_ALPHA (a finite, very narrow peak): the delta itself is the renderers' business.
    """
    n = np.asarray(n, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    l = np.asarray(l, dtype=np.float64)
    NoV = np.sum(n * v, axis=-1)
    NoL = np.sum(n * l, axis=-1)
    h = v + l
    h = h / np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), COS_EPS)
    NoH = np.clip(np.sum(n * h, axis=-1), 0.0, 1.0)
    VoH = np.clip(np.sum(v * h, axis=-1), 0.0, 1.0)
    F0 = material_f0(base_color, metallic, specular)
    F = fresnel_term(fresnel, VoH[..., None], F0)
    D = ndf_term(ndf, NoH, roughness)
    G = geometry_term(geometry, np.clip(NoV, 0, 1), np.clip(NoL, 0, 1), roughness)
    spec = (D * G)[..., None] * F / (4.0 * np.maximum(NoV, COS_EPS) * np.maximum(NoL, COS_EPS))[..., None]
    m = np.asarray(metallic, dtype=np.float64)[..., None]
    diff = (1.0 - F) * (1.0 - m) * np.asarray(base_color, dtype=np.float64) * Fd_Lambert()
    valid = ((NoV > 0) & (NoL > 0))[..., None]
    return np.where(valid, diff + spec, 0.0)


# ------------------------------------------------------------------------------------------------
# Quadrature: directional albedo and the split-sum DFG terms, exact to ~1e-7.
# ------------------------------------------------------------------------------------------------

def _gauss(n, a, b):
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (b - a) * x + 0.5 * (b + a), 0.5 * (b - a) * w


def _theta_h_GGX(u, a):
    """[Walter07] eq. 35: the inverse CDF of ``D_GGX cos(theta_h)`` in theta_h."""
    return np.arctan(a * np.sqrt(u / (1.0 - u)))


def _theta_h_Beckmann(u, a):
    """[Walter07] eq. 28: ``tan^2 theta_h = -alpha^2 log(1 - u)``."""
    return np.arctan(np.sqrt(-a * a * np.log1p(-u)))


def _theta_h_BlinnPhong(u, a):
    """pdf ``cos^(n+1) sin``: ``cos theta_h = (1 - u)^(1 / (n + 2))``."""
    n = float(blinn_phong_exponent(a))
    return np.arccos(np.power(1.0 - u, 1.0 / (n + 2.0)))


def _cdf_theta_h_GGX(theta, a):
    """The CDF of ``D_GGX cos(theta_h)`` at theta_h < pi/2: ``t / (1 + t)``, ``t = tan^2 / alpha^2``."""
    t2 = np.tan(theta) ** 2 / (a * a)
    return t2 / (1.0 + t2)


def _cdf_theta_h_Beckmann(theta, a):
    """``1 - exp(-tan^2 / alpha^2)``."""
    return -np.expm1(-np.tan(theta) ** 2 / (a * a))


def _cdf_theta_h_BlinnPhong(theta, a):
    """``1 - cos^(n+2)``."""
    return 1.0 - np.cos(theta) ** (float(blinn_phong_exponent(a)) + 2.0)


def _ndf_quadrature(ndf: str, kind: str):
    """The NDF's ``_theta_h_<D>`` or ``_cdf_theta_h_<D>`` (``kind`` ``theta_h`` or ``cdf_theta_h``;
    ``<D>`` its registry function's name without ``D_``): a new NDF adds its pair under that name."""
    if ndf not in NDFS:
        raise ValueError(f"unknown ndf {ndf!r}; NDFs are: {', '.join(NDFS.names)}")
    return globals()[f"_{kind}_{NDFS[ndf].impl.numpy[2:]}"]


def _ndf_theta_from_u(ndf, u, alpha):
    """theta_h as the inverse CDF of ``D(h) cos(theta_h)`` at u (the quadrature's variable), so
    that nodes crowd where the lobe is; ``pdf(theta) = 2 pi D cos sin`` is the Jacobian's inverse."""
    a = max(float(alpha), MIN_ALPHA)
    u = np.clip(u, 0.0, 1.0 - 1e-16)
    return _ndf_quadrature(ndf, "theta_h")(u, a)


def _ndf_u_from_theta(ndf, theta, alpha):
    """The NDF's CDF in theta_h: inverse of :func:`_ndf_theta_from_u`."""
    a = max(float(alpha), MIN_ALPHA)
    if theta >= np.pi / 2:
        return 1.0
    return _ndf_quadrature(ndf, "cdf_theta_h")(theta, a)


def specular_dfg(NoV, roughness, *, ndf="ggx", geometry="smith_ggx_correlated", n_theta=24, n_phi=48):
    """Split-sum DFG terms (A, B) of the specular lobe by quadrature over the half vector.

    ``A = int (1 - (1 - v.h)^5) f_s cos(l) dl`` and ``B = int (1 - v.h)^5 f_s cos(l) dl`` with
    ``f_s = D G / (4 (n.l)(n.v))``, so that the specular directional albedo with Schlick Fresnel is
    ``F0 A + B`` [Karis13] eq. 8. With ``fresnel = "none"`` it is ``A + B``.

    Change of variables: ``dl = 4 (v.h) dh`` (the half-vector Jacobian, [Walter07] eq. 14) and
    ``dh = sin(theta_h) dtheta_h dphi``. With v at theta_v, a half vector at (theta_h, phi) reflects v
    above the horizon (n.l > 0) iff ``cos(phi) > c = -cot(theta_v) cot(2 theta_h)``: every phi for
    ``theta_h < theta_1 = pi/4 - theta_v/2``, none beyond ``theta_2 = pi/4 + theta_v/2``, and
    ``|phi| < acos(c)`` in between (integrated over [0, phi_max], doubled by symmetry). theta_h is cut
    at theta_1, theta_2 and at ``atan(alpha 2^k)`` (the lobe's own scale, so a narrow lobe gets as many
    nodes as a wide one), and each piece is mapped with ``t = (1 - cos(pi s)) / 2``, whose zero slope at
    both ends cancels the square-root behaviour of phi_max at theta_1 and theta_2. Gauss-Legendre
    (``n_theta`` per piece, ``n_phi`` in phi) then converges to ~1e-7 with the defaults.
    """
    NoV = float(np.clip(NoV, COS_EPS, 1.0))
    alpha = float(alpha_from_roughness(roughness))
    if alpha < DELTA_LOBE_ALPHA:
        # Mirror limit: D -> delta(h = n), so l = reflect(v), n.l = v.h = n.v and
        # A + B = G(v, v): 1 for the Smith forms and Schlick-GGX with k = alpha/2, but
        # G1(n.v, 1/8)^2 for schlick_ggx_direct, whose k = (roughness + 1)^2 / 8 stays at 1/8.
        G = float(geometry_term(geometry, NoV, NoV, roughness))
        Fc = (1.0 - NoV) ** 5
        return G * (1.0 - Fc), G * Fc
    tv = float(np.arccos(NoV))
    sv, cv = np.sin(tv), NoV
    t1, t2 = max(0.0, np.pi / 4 - tv / 2), min(np.pi / 2, np.pi / 4 + tv / 2)
    cuts = {0.0, t1, t2}
    k = -2
    while alpha * 2.0 ** k <= 64.0:
        t = float(np.arctan(alpha * 2.0 ** k))
        if t < t2:
            cuts.add(t)
        k += 1
    cuts = sorted(c for c in cuts if c <= t2)
    xg, wg = np.polynomial.legendre.leggauss(n_theta)
    s = 0.5 * (xg + 1.0)
    m = 0.5 * (1.0 - np.cos(np.pi * s))
    dm = 0.5 * np.pi * np.sin(np.pi * s) * 0.5 * wg
    th = np.concatenate([a + (b - a) * m for a, b in zip(cuts[:-1], cuts[1:]) if b > a])
    wth = np.concatenate([(b - a) * dm for a, b in zip(cuts[:-1], cuts[1:]) if b > a])
    ct, st = np.cos(th), np.sin(th)
    with np.errstate(divide="ignore", invalid="ignore"):
        c = -cv * (2 * ct * ct - 1.0) / (sv * 2 * st * ct)
    phimax = np.where(th <= t1, np.pi, np.arccos(np.clip(np.nan_to_num(c, nan=1.0), -1.0, 1.0)))
    xp, wp = np.polynomial.legendre.leggauss(n_phi)
    phi = 0.5 * phimax[:, None] * (xp[None, :] + 1.0)
    wphi = phimax[:, None] * wp[None, :]                  # 0.5 phimax wp, times 2 for -phi
    hx = st[:, None] * np.cos(phi)
    hz = np.broadcast_to(ct[:, None], phi.shape)
    VoH = np.clip(sv * hx + cv * hz, 0.0, 1.0)
    NoL = np.clip(2.0 * VoH * hz - cv, 0.0, 1.0)
    G = geometry_term(geometry, np.full_like(NoL, NoV), NoL, roughness)
    D = ndf_term(ndf, hz, roughness)
    # f_s cos(l) dl = D G / (4 n.v) * 4 (v.h) * sin(theta_h) dtheta_h dphi
    w = D * G * VoH / NoV * st[:, None] * wphi * wth[:, None]
    Fc = (1.0 - VoH) ** 5
    return float(np.sum(w * (1.0 - Fc))), float(np.sum(w * Fc))


def specular_albedo(NoV, roughness, F0=1.0, *, ndf="ggx", geometry="smith_ggx_correlated",
                    fresnel="schlick", **quad):
    """Directional albedo of the specular lobe for a scalar F0: ``F0 A + B`` (``A + B`` without
    Fresnel)."""
    A, B = specular_dfg(NoV, roughness, ndf=ndf, geometry=geometry, **quad)
    return A + B if fresnel == "none" else F0 * A + B


def diffuse_albedo(NoV, roughness, F0, *, fresnel="schlick", n_theta=48, n_phi=64):
    """``int (1 - F(v.h)) cos(l) / pi dl`` over the hemisphere (per unit (1-metallic) base_color),
    Gauss-Legendre in (cos^2 theta_l, phi) so the cosine weight is absorbed exactly."""
    if fresnel == "none":
        return 0.0
    NoV = float(np.clip(NoV, COS_EPS, 1.0))
    sv = np.sqrt(1.0 - NoV * NoV)
    s, ws = _gauss(n_theta, 0.0, 1.0)     # s = sin^2 theta_l; cos(l) dl = 0.5 ds dphi
    p, wp = _gauss(n_phi, 0.0, np.pi)     # symmetric in phi
    sl = np.sqrt(s)[:, None]
    cl = np.sqrt(1.0 - s)[:, None]
    lx = sl * np.cos(p)[None, :]
    h = np.stack(np.broadcast_arrays(lx + sv, sl * np.sin(p)[None, :], cl + NoV), -1)
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    VoH = h[..., 0] * sv + h[..., 2] * NoV
    F = F0 + (1.0 - F0) * (1.0 - np.clip(VoH, 0, 1)) ** 5
    return float(np.sum((1.0 - F) / PI * 0.5 * ws[:, None] * wp[None, :]) * 2.0)


# ------------------------------------------------------------------------------------------------
# Terms the real-time renderer adds (twins of realtime/shaders/brdf.glsl and ibl.glsl).
# ------------------------------------------------------------------------------------------------

def G_SchlickBeckmann(NoV, NoL, alpha):
    """Schlick's approximation of Smith-Beckmann (article 001's catalogue):
    ``k = alpha sqrt(2 / pi)``, ``G = G1_SchlickGGX(v, k) G1_SchlickGGX(l, k)``."""
    k = np.maximum(np.asarray(alpha, dtype=np.float64), MIN_ALPHA) * np.sqrt(2.0 / PI)
    return G1_SchlickGGX(NoV, k) * G1_SchlickGGX(NoL, k)


def EnvBRDFApprox(NoV, roughness):
    """[Karis14] "Physically Based Shading on Mobile": analytic fit of the DFG terms, returns (A, B)
    stacked in a trailing axis: ``r = roughness c0 + c1``, ``a004 = min(r.x^2, 2^(-9.28 n.v)) r.x + r.y``,
    ``(A, B) = (-1.04, 1.04) a004 + r.zw``."""
    NoV = np.asarray(NoV, dtype=np.float64)
    r = np.asarray(roughness, dtype=np.float64)
    c0 = np.array([-1.0, -0.0275, -0.572, 0.022])
    c1 = np.array([1.0, 0.0425, 1.04, -0.04])
    rr = r[..., None] * c0 + c1
    a004 = np.minimum(rr[..., 0] ** 2, np.exp2(-9.28 * NoV)) * rr[..., 0] + rr[..., 1]
    return np.stack([-1.04 * a004 + rr[..., 2], 1.04 * a004 + rr[..., 3]], axis=-1)
