"""The glTF PBR extensions' lobes as the ratified specification writes them (issue 36 item 2), numpy.

The truth is the spec text: the extension READMEs of KhronosGroup/glTF
(``extensions/2.0/Khronos/KHR_materials_{sheen,clearcoat,specular,anisotropy,iridescence}``) and the
glTF 2.0 specification's Appendix B ("BRDF Implementation": ``specular_brdf = V_GGX D_GGX``,
``fresnel_mix``, ``mix(dielectric_brdf, metal_brdf, metallic)``). Each lobe is a small object with
``eval`` (the BRDF times the cosine of the light direction, Mitsuba's convention), ``sample`` (a light
direction and its density), ``pdf`` and the directional ``albedo`` by quadrature (never a LUT);
:mod:`reference.lobes` holds the Dr.Jit class of each, of the same name and method
(``tests/test_lobes.py`` compares them on grids with the extremes).

Local shading frame: ``n = +Z``, the tangent ``+X``, bitangent ``+Y``; ``v`` towards the viewer, ``l``
towards the light, arrays (..., 3) of unit vectors, float64; ``u`` (..., 2) in [0, 1)^2.

API
---
Constants :data:`SHEEN_MIN_ALPHA`, :data:`SHEEN_L_FIT` (:func:`sheen_l`; the Charlie terms :func:`charlie_D`,
:func:`charlie_lambda`, :func:`charlie_V`, :func:`charlie_sample_h`, which realtime.lobes' twins import), :data:`CLEARCOAT_IOR`, :data:`FILM_R123_MIN`, :data:`FILM_R123_MAX`,
:data:`BASE_F0_GUARD`, :data:`CIE_CMFS`, :data:`FILM_WAVELENGTHS`, :data:`XYZ_TO_REC709`;
:func:`f0_from_ior`, :func:`schlick`, :func:`to_frame`;
:class:`SheenCharlie` (KHR_materials_sheen) and :func:`sheen_layer`;
:class:`AnisotropicGGX` (KHR_materials_anisotropy; isotropic at strength 0: the coat's and the base's
GGX lobe, Appendix B), :func:`fresnel_coat`, :class:`ClearcoatLobe` and :func:`coat_layer`
(KHR_materials_clearcoat);
:func:`specular_f0`, :func:`specular_f90`, :func:`specular_fresnel` (KHR_materials_specular);
:func:`iridescence_rgb` (Belcour & Barla 2017 as the iridescence README writes it),
:func:`iridescence_spectral` (the same film by its Airy sum per wavelength, integrated with the CIE
1931 2 degree colour matching functions), :func:`film_reflectance` (one wavelength), :func:`spectrum_to_rgb`, and with Fresnel's equations in
place of the README's Schlick interfaces :func:`fresnel_exact`, :func:`film_reflectance_exact`,
:func:`iridescence_spectral_exact`; :func:`iridescence_mix`.

References
----------
[glTF-B]   glTF 2.0 Specification, Appendix B "BRDF Implementation" (B.3.1-B.3.5: fresnel_mix,
           specular_brdf, V_GGX, D_GGX).
[Sheen]    KHR_materials_sheen README, "Implementation Notes": "Sheen distribution", "Sheen
           visibility", "Albedo-scaling technique".
[Coat]     KHR_materials_clearcoat README, "Implementation": "Clearcoat BRDF", "Layering".
[Spec]     KHR_materials_specular README, "Implementation" (dielectric_f0 / dielectric_f90) and
           "Interaction with other extensions" (the KHR_materials_ior form).
[Aniso]    KHR_materials_anisotropy README, "Anisotropy" (alpha_t = mix(alpha, 1, strength^2), D(h))
           and "Implementation" (the direction in the tangent frame, V_GGX_anisotropic).
[Irid]     KHR_materials_iridescence README, "Iridescence Fresnel": material interfaces, phase
           shift, "Analytic Spectral Integration" (evalSensitivity, XYZ_TO_REC709).
[EK17]     A. Estevez, C. Kulla, "Production Friendly Microfacet Sheen BRDF", 2017 (Charlie, eq. 2;
           the Lambda fit, sec. 3).
[Heitz14]  E. Heitz, "Understanding the Masking-Shadowing Function", JCGT 2014 (eq. 86 anisotropic
           Lambda, eq. 99 height-correlated G2).
[Heitz18]  E. Heitz, "Sampling the GGX Distribution of Visible Normals", JCGT 7(4) 2018 (listing 1).
[BB17]     L. Belcour, P. Barla, "A Practical Extension to Microfacet Theory for the Modeling of
           Varying Iridescence", SIGGRAPH 2017 (eq. 2-9: the Airy sum; sec. 4 the Fourier integration).
[CIE]      CIE 1931 2 degree standard observer, as tabulated by colour-science
           (``colour.MSDS_CMFS['CIE 1931 2 Degree Standard Observer']``).
"""

from __future__ import annotations

import numpy as np

from pbrcheck.terms import COS_EPS, GGX, MIN_ALPHA, SmithGGXCorrelated

PI = np.pi

#: Smallest sheen alpha (sheenRoughness^2). The Charlie D has the exponent 1/alpha; alpha = 0 is no
#: distribution. 1e-4 is sheenRoughness 0.01, the smallest the tests evaluate; below it the lobe is a
#: numerically empty sliver at theta_h = 90 degrees (sin^(1e4) underflows everywhere else).
SHEEN_MIN_ALPHA = 1e-4
#: [Coat] "Layering": the coat's IOR, fixed at 1.5 (f0 = 0.04).
CLEARCOAT_IOR = 1.5
#: [Irid] "Analytic Spectral Integration": ``R123 = clamp(R12 R23, 1e-5, 0.9999)`` (the spec's guard
#: of the 1 / (1 - R123) pole; the spectral sum uses the same clamp so the two differ only by the
#: spectral integration).
FILM_R123_MIN = 1e-5
FILM_R123_MAX = 0.9999
#: [Irid] "Material Interfaces": ``Fresnel0ToIor(baseF0 + 0.0001)``, the guard against F0 = 1.
BASE_F0_GUARD = 1e-4
#: Quadrature of the sheen albedo: Gauss-Legendre nodes in cos(theta_l) and midpoint nodes in phi
#: over [0, pi] (the lobe is symmetric about the plane of v). 192 x 96 is converged to below 1e-5 at
#: sheenRoughness 0.01 (tests/test_lobes.py::test_sheen_albedo_converged).
ALBEDO_N_THETA = 192
ALBEDO_N_PHI = 96
#: Nodes per axis of the GGX albedo's midpoint rule in the sampler's u (:meth:`AnisotropicGGX.albedo`):
#: 512^2 agrees with 2048^2 to 2.7e-4 on the tests' grid (roughness 0.3, n.v 1; 1e-5 elsewhere).
ALBEDO_U_NODES = 512


def f0_from_ior(ior, outside_ior=1.0):
    """[glTF-B] / [Spec]: ``f0 = ((ior - outside_ior) / (ior + outside_ior))^2``."""
    ior = np.asarray(ior, dtype=np.float64)
    return ((ior - outside_ior) / (ior + outside_ior)) ** 2


def schlick(c, f0, f90=1.0):
    """[glTF-B] B.3.4 ``F = f0 + (f90 - f0) (1 - |c|)^5``; ``c`` the cosine (v.h, or n.v for the coat)."""
    w = (1.0 - np.abs(np.asarray(c, dtype=np.float64))) ** 5
    return f0 + (f90 - np.asarray(f0, dtype=np.float64)) * w


def to_frame(w, n):
    """``w`` in the orthonormal frame around the unit normal ``n`` (3,) [Duff et al. 2017, "Building
    an Orthonormal Basis, Revisited", listing 3]; ``n = +Z`` gives the frame (X, Y, Z) itself, so a
    coat normal equal to the base normal is bit-identical to no coat normal."""
    n = np.asarray(n, dtype=np.float64)
    sign = 1.0 if n[2] >= 0 else -1.0
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    t = np.array([1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]])
    s = np.array([b, sign + n[1] * n[1] * a, -n[1]])
    w = np.asarray(w, dtype=np.float64)
    return np.stack([w @ t, w @ s, w @ n], axis=-1)


def _normalize(x):
    return x / np.maximum(np.linalg.norm(x, axis=-1, keepdims=True), 1e-300)


def _half(v, l):
    return _normalize(v + l)


def _reflect(v, h):
    return 2.0 * np.sum(v * h, axis=-1, keepdims=True) * h - v


def _cosine_sample(u):
    r = np.sqrt(u[..., 0])
    phi = 2.0 * PI * u[..., 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(1.0 - u[..., 0], 0.0))], axis=-1)


def _hemisphere_quadrature(n_theta, n_phi):
    """Directions and weights of ``int_{H} g(l) dl`` for g symmetric in phi -> -phi: Gauss-Legendre
    in cos(theta) on [0, 1], midpoint in phi on [0, pi], weights doubled."""
    x, w = np.polynomial.legendre.leggauss(n_theta)
    c, wc = 0.5 * (x + 1.0), 0.5 * w
    phi = (np.arange(n_phi) + 0.5) * PI / n_phi
    s = np.sqrt(1.0 - c * c)
    l = np.stack([s[:, None] * np.cos(phi)[None], s[:, None] * np.sin(phi)[None],
                  np.broadcast_to(c[:, None], (n_theta, n_phi))], axis=-1)
    return l.reshape(-1, 3), (wc[:, None] * np.full(n_phi, 2.0 * PI / n_phi)[None]).reshape(-1)


def _view(mu):
    mu = float(mu)
    return np.array([np.sqrt(max(1.0 - mu * mu, 0.0)), 0.0, mu])


# ------------------------------------------------------------------------------------------------
# KHR_materials_sheen
# ------------------------------------------------------------------------------------------------

#: [Sheen] "Sheen visibility": the fit ``l(x) = a / (1 + b x^c) + d x + e`` of [EK17], each
#: coefficient ``mix(at alpha 1, at alpha 0, (1 - alpha_g)^2)``: the pairs (a, b, c, d, e).
SHEEN_L_FIT = ((21.5473, 25.3245), (3.82987, 3.32435), (0.19823, 0.16801), (-1.97760, -1.27393),
               (-4.32054, -4.85967))


def sheen_l(x, alpha, power):
    """[Sheen]'s ``l(x, alpha_g)`` from :data:`SHEEN_L_FIT`; ``power`` the array library's (``np.power``,
    ``dr.power``), so numpy and Dr.Jit evaluate the same operations."""
    t = (1.0 - alpha) ** 2
    a, b, c, d, e = (p0 * (1 - t) + p1 * t for p0, p1 in SHEEN_L_FIT)
    return a / (1.0 + b * power(x, c)) + d * x + e


def charlie_D(sin2, alpha):
    """[Sheen] "Sheen distribution" ([EK17] eq. 2) in ``sin^2 theta_h``: ``(2 + 1/alpha) (sin^2)^(1/(2 alpha))
    / (2 pi)``. The one numpy Charlie D: :meth:`SheenCharlie.D` (sin^2 from h.x, h.y) and the real-time
    twins (:func:`realtime.lobes.D_Charlie`, sin^2 = (1 - n.h)(1 + n.h), alpha at their own floor) call it."""
    inv_r = 1.0 / alpha
    return (2.0 + inv_r) * np.power(sin2, 0.5 * inv_r) / (2.0 * PI)


def charlie_lambda(c, alpha):
    """[Sheen] ``lambda_sheen`` ([EK17] sec. 3's fit) at the cosine ``c`` in [0, 1]: ``exp(l(c))`` below 0.5,
    ``exp(2 l(0.5) - l(1 - c))`` above (:func:`sheen_l`)."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c < 0.5, np.exp(sheen_l(c, alpha, np.power)),
                    np.exp(2.0 * sheen_l(0.5, alpha, np.power) - sheen_l(1.0 - c, alpha, np.power)))


def charlie_V(NoV, NoL, alpha, guard=COS_EPS):
    """[Sheen] "Sheen visibility": ``V = 1 / ((1 + Lambda(n.v) + Lambda(n.l)) 4 (n.v)(n.l))``, the
    denominator kept >= ``guard`` (the shaders' guard of grazing cosines). :meth:`SheenCharlie.eval` uses
    it with its n.l cancelled (``D V n.l = D / ((1 + Lambda + Lambda) 4 n.v)``)."""
    den = (1.0 + charlie_lambda(NoV, alpha) + charlie_lambda(NoL, alpha)) * 4.0 * NoV * NoL
    return 1.0 / np.maximum(den, guard)


def charlie_sample_h(u, alpha):
    """Half vectors (z = n) of density ``D (n.h)``: the inverse of sin theta's CDF ``s^(2 + 1/alpha)``,
    ``sin theta_h = u1^(alpha / (2 alpha + 1))``, ``phi = 2 pi u0``."""
    u = np.asarray(u, dtype=np.float64)
    st = np.power(u[..., 1], alpha / (2.0 * alpha + 1.0))
    ct = np.sqrt(np.maximum(1.0 - st * st, 0.0))
    phi = 2.0 * PI * u[..., 0]
    return np.stack([st * np.cos(phi), st * np.sin(phi), ct], axis=-1)


class SheenCharlie:
    """The sheen lobe of [Sheen] "Implementation Notes": ``SheenBRDF = V_s D_s`` with the Charlie
    distribution ([EK17] eq. 2, [Sheen] "Sheen distribution": ``alpha_g = sheenRoughness^2``,
    ``D = (2 + 1/alpha_g) sin^(1/alpha_g)(theta_h) / (2 pi)``) and the Charlie visibility ([Sheen]
    "Sheen visibility": ``V = 1 / ((1 + Lambda(n.v) + Lambda(n.l)) 4 (n.v)(n.l))`` with [EK17]'s fitted
    ``Lambda = exp(l(x))`` below cos 0.5, ``exp(2 l(0.5) - l(1 - x))`` above). Not multiplied by
    sheenColor (the layering does that). ``eval`` returns ``D V (n.l)``.

    Sampled by a one-sample mixture (weight :data:`MIX`) of the cosine and of the Charlie NDF's half
    vectors (``D (n.h)``: ``sin theta_h = u^(alpha / (2 alpha + 1))``, docs/realtime.md's worked
    example) reflected about v; ``pdf`` is the mixture's density."""

    MIX = 0.5

    def __init__(self, roughness):
        r = float(roughness)
        self.roughness = r
        self.alpha = max(r * r, SHEEN_MIN_ALPHA)

    def D(self, h):
        """[Sheen] "Sheen distribution" with ``sin^2 theta_h = h.x^2 + h.y^2`` (exact near h.z = 1)."""
        s2 = np.minimum(h[..., 0] ** 2 + h[..., 1] ** 2, 1.0)
        with np.errstate(under="ignore", divide="ignore"):
            return np.where(h[..., 2] > 0, charlie_D(s2, self.alpha), 0.0)

    def Lambda(self, c):
        """[Sheen] ``lambda_sheen`` (:func:`charlie_lambda`), ``c`` the cosine (its absolute value)."""
        return charlie_lambda(np.abs(np.asarray(c, dtype=np.float64)), self.alpha)

    def eval(self, v, l):
        """``D V (n.l) = D / ((1 + Lambda(v) + Lambda(l)) 4 (n.v))``; 0 below either horizon."""
        NoV, NoL = v[..., 2], l[..., 2]
        ok = (NoV > 0) & (NoL > 0)
        cv, cl = np.clip(NoV, COS_EPS, 1.0), np.clip(NoL, COS_EPS, 1.0)
        val = self.D(_half(v, l)) / ((1.0 + self.Lambda(cv) + self.Lambda(cl)) * 4.0 * cv)
        return np.where(ok, val, 0.0)

    def sample_h(self, u):
        """A half vector of density ``D (n.h)`` (:func:`charlie_sample_h`)."""
        return charlie_sample_h(u, self.alpha)

    def pdf(self, v, l):
        h = _half(v, l)
        VoH = np.sum(v * h, axis=-1)
        pd = self.D(h) * h[..., 2] / np.maximum(4.0 * np.abs(VoH), COS_EPS)
        pc = np.maximum(l[..., 2], 0.0) / PI
        return np.where((v[..., 2] > 0) & (l[..., 2] > 0), self.MIX * pc + (1.0 - self.MIX) * pd, 0.0)

    def sample(self, v, u):
        """``(l, pdf)``: u0 < MIX picks the cosine branch (u0 / MIX reused), else the NDF's."""
        u = np.asarray(u, dtype=np.float64)
        pick = u[..., 0] < self.MIX
        uc = np.stack([u[..., 0] / self.MIX, u[..., 1]], axis=-1)
        ud = np.stack([(u[..., 0] - self.MIX) / (1.0 - self.MIX), u[..., 1]], axis=-1)
        l = np.where(pick[..., None], _cosine_sample(np.clip(uc, 0, 1)),
                     _reflect(np.broadcast_to(v, ud.shape[:-1] + (3,)), self.sample_h(np.clip(ud, 0, 1))))
        return l, self.pdf(v, l)

    def albedo(self, mu, n_theta=ALBEDO_N_THETA, n_phi=ALBEDO_N_PHI):
        """``E(mu) = int D V (n.l) dl`` by quadrature ([Sheen] "Albedo-scaling technique"'s E)."""
        l, w = _hemisphere_quadrature(n_theta, n_phi)
        return float(np.sum(self.eval(_view(mu)[None], l) * w))


def sheen_layer(sheen, base, sheen_color, E_v, E_l=None):
    """[Sheen] "Albedo-scaling technique": ``sheenColor * sheen_brdf + material * scaling`` with
    ``scaling = min(1 - max3(sheenColor) E(n.v), 1 - max3(sheenColor) E(n.l))`` (or, ``E_l`` None,
    the spec's cheaper ``1 - max3(sheenColor) E(n.v)``). ``sheen`` (...) the lobe's value, ``base``
    (..., 3), ``sheen_color`` (3,). sheenColor 0 returns ``base`` bit for bit."""
    c = np.asarray(sheen_color, dtype=np.float64)
    m = np.max(c)
    scale = 1.0 - m * np.asarray(E_v, dtype=np.float64)
    if E_l is not None:
        scale = np.minimum(scale, 1.0 - m * np.asarray(E_l, dtype=np.float64))
    return c * np.asarray(sheen)[..., None] + base * np.asarray(scale)[..., None]


# ------------------------------------------------------------------------------------------------
# GGX (Appendix B), anisotropic (KHR_materials_anisotropy): also the coat's lobe
# ------------------------------------------------------------------------------------------------

class AnisotropicGGX:
    """The specular lobe ``D V (n.l)`` without Fresnel ([glTF-B] B.3.2 ``specular_brdf = V D``) of
    the anisotropic GGX of [Aniso]: ``alpha = roughness^2``, ``alpha_t = mix(alpha, 1, strength^2)``
    along the direction ``t = (cos rotation, sin rotation, 0)`` of the tangent frame, ``alpha_b =
    alpha`` along ``b = n x t``; ``D = 1 / (pi a_t a_b ((h.t/a_t)^2 + (h.b/a_b)^2 + (h.n)^2)^2)``; the
    height-correlated Smith ``G2 = 1 / (1 + Lambda(v) + Lambda(l))`` [Heitz14] eq. 99 with the
    anisotropic ``Lambda = (-1 + sqrt(1 + (a_t^2 w.t^2 + a_b^2 w.b^2) / w.n^2)) / 2`` [Heitz14] eq. 86
    (= the README's ``V_GGX_anisotropic`` without its real-time clamp to 1). Sampled by the visible
    normals [Heitz18] at (a_t, a_b). At strength 0 the isotropic terms of :mod:`pbrcheck.terms`
    (``GGX.eval``, ``SmithGGXCorrelated.eval``: the base lobe) are returned bit for bit."""

    def __init__(self, roughness, strength=0.0, rotation=0.0):
        r, s = float(roughness), float(strength)
        self.alpha = max(r * r, MIN_ALPHA)
        self.at = self.alpha * (1.0 - s * s) + 1.0 * (s * s)  # [Aniso]'s mix(x, y, m) = x (1 - m) + y m
        self.ab = self.alpha
        self.rotation = float(rotation)
        self.isotropic = self.at == self.ab
        self.c, self.s = np.cos(self.rotation), np.sin(self.rotation)

    def local(self, w):
        """``(w.t, w.b, w.n)`` in the anisotropy direction's frame."""
        return np.stack([self.c * w[..., 0] + self.s * w[..., 1], -self.s * w[..., 0] + self.c * w[..., 1],
                         w[..., 2]], axis=-1)

    def world(self, w):
        return np.stack([self.c * w[..., 0] - self.s * w[..., 1], self.s * w[..., 0] + self.c * w[..., 1],
                         w[..., 2]], axis=-1)

    def D(self, h):
        if self.isotropic:  # n.h clipped as pbrcheck.brdf.brdf_eval clips it
            return GGX.eval(np.clip(h[..., 2], 0.0, 1.0), self.alpha)
        hl = self.local(h)
        t = (hl[..., 0] / self.at) ** 2 + (hl[..., 1] / self.ab) ** 2 + hl[..., 2] ** 2
        return np.where(h[..., 2] > 0, 1.0 / (PI * self.at * self.ab * t * t), 0.0)

    def Lambda(self, w):
        wl = self.local(w)
        z2 = np.maximum(wl[..., 2] ** 2, COS_EPS * COS_EPS)
        return 0.5 * (np.sqrt(1.0 + (self.at ** 2 * wl[..., 0] ** 2 + self.ab ** 2 * wl[..., 1] ** 2) / z2) - 1.0)

    def G2(self, v, l):
        if self.isotropic:
            return SmithGGXCorrelated.eval(v[..., 2], l[..., 2], self.alpha)
        return 1.0 / (1.0 + self.Lambda(v) + self.Lambda(l))

    def G1(self, v):
        return 1.0 / (1.0 + self.Lambda(v))

    def brdf(self, v, l):
        """``D G2 / (4 (n.v)(n.l))`` (the operations of :meth:`pbrcheck.brdf.SpecularLobe.eval` with F = 1)."""
        cv, cl = np.maximum(v[..., 2], COS_EPS), np.maximum(l[..., 2], COS_EPS)
        h = _half(v, l)
        return self.D(h) * self.G2(v, l) / (4.0 * cv * cl)

    def eval(self, v, l):
        """:meth:`brdf` times n.l; 0 below either horizon."""
        NoV, NoL = v[..., 2], l[..., 2]
        return np.where((NoV > 0) & (NoL > 0), self.brdf(v, l) * np.clip(NoL, 0, 1), 0.0)

    def sample_h(self, v, u):
        """A normal visible from v [Heitz18] listing 1 (stretch by (a_t, a_b) in the direction's frame)."""
        vl = self.local(np.broadcast_to(v, u.shape[:-1] + (3,)))
        vh = _normalize(np.stack([self.at * vl[..., 0], self.ab * vl[..., 1], vl[..., 2]], axis=-1))
        lensq = vh[..., 0] ** 2 + vh[..., 1] ** 2
        inv = 1.0 / np.sqrt(np.maximum(lensq, 1e-300))
        T1 = np.where((lensq > 0)[..., None], np.stack([-vh[..., 1] * inv, vh[..., 0] * inv, 0 * inv], axis=-1),
                      np.array([1.0, 0.0, 0.0]))
        T2 = np.cross(vh, T1)
        r = np.sqrt(u[..., 0])
        phi = 2.0 * PI * u[..., 1]
        t1, t2 = r * np.cos(phi), r * np.sin(phi)
        s = 0.5 * (1.0 + vh[..., 2])
        t2 = (1.0 - s) * np.sqrt(np.maximum(1.0 - t1 * t1, 0.0)) + s * t2
        nh = t1[..., None] * T1 + t2[..., None] * T2 + np.sqrt(np.maximum(1.0 - t1 * t1 - t2 * t2, 0.0))[..., None] * vh
        h = _normalize(np.stack([self.at * nh[..., 0], self.ab * nh[..., 1], np.maximum(nh[..., 2], 0.0)], axis=-1))
        return self.world(h)

    def pdf(self, v, l):
        """Density in l of :meth:`sample`: ``G1(v) D(h) / (4 (n.v))`` [Heitz18] eq. 3 with the reflection's
        Jacobian ``1 / (4 v.h)``."""
        h = _half(v, l)
        NoV = np.maximum(v[..., 2], COS_EPS)
        val = self.G1(v) * self.D(h) / (4.0 * NoV)
        return np.where((v[..., 2] > 0) & (l[..., 2] > 0), val, 0.0)

    def sample(self, v, u):
        u = np.asarray(u, dtype=np.float64)
        h = self.sample_h(v, u)
        l = _reflect(np.broadcast_to(v, h.shape), h)
        return l, self.pdf(v, l)

    def albedo(self, mu, n=ALBEDO_U_NODES):
        """``int D G2 / (4 n.v) dl`` by quadrature in the visible-normal sampler's primary space: the
        midpoint rule on an n x n grid of u, integrand ``eval / pdf = G2 / G1(v)`` (<= 1 and smooth, so
        the rule converges at every roughness, 0.01 included, and at grazing view, where a quadrature
        over directions misses the lobe hugging the horizon: 0.778 against 0.907 at roughness 0.3,
        n.v 0.05 with 192 x 192 nodes)."""
        g = (np.arange(n) + 0.5) / n
        u = np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1).reshape(-1, 2)
        v = _view(mu)
        l, pdf = self.sample(v, u)
        f = self.eval(v[None], l)
        return float(np.mean(np.where(pdf > 0, f / np.maximum(pdf, 1e-300), 0.0)))


# ------------------------------------------------------------------------------------------------
# KHR_materials_clearcoat
# ------------------------------------------------------------------------------------------------

def fresnel_coat(NcoV, ior=CLEARCOAT_IOR):
    """[Coat] "Layering": ``fr = f0 + (1 - f0) (1 - |v.n_c|)^5``, ``f0 = ((1 - ior) / (1 + ior))^2``
    at the coat's n.v (not v.h: [Coat] "Discussion")."""
    f0 = ((1.0 - ior) / (1.0 + ior)) ** 2
    return f0 + (1.0 - f0) * (1.0 - np.abs(np.asarray(NcoV, dtype=np.float64))) ** 5


class ClearcoatLobe:
    """[Coat] "Clearcoat BRDF": ``clearcoat_brdf = D(a) G(a) / (4 |v.n_c| |l.n_c|)``, ``a =
    clearcoatRoughness^2``, the Appendix B GGX (isotropic :class:`AnisotropicGGX`) in the frame of
    the coat's own normal ``normal`` (3,) in the base's local frame. ``eval`` is that times the base's
    n.l (the cosine of the shading normal, which the layering multiplies all lobes by)."""

    def __init__(self, roughness, normal=(0.0, 0.0, 1.0)):
        self.ggx = AnisotropicGGX(roughness)
        self.normal = np.asarray(normal, dtype=np.float64)

    def eval(self, v, l):
        vc, lc = to_frame(v, self.normal), to_frame(l, self.normal)
        ok = (l[..., 2] > 0) & (lc[..., 2] > 0) & (vc[..., 2] > 0)
        return np.where(ok, self.ggx.brdf(vc, lc) * np.clip(l[..., 2], 0, 1), 0.0)

    def fresnel(self, v):
        return fresnel_coat(to_frame(v, self.normal)[..., 2])

    def sample(self, v, u):
        """The coat's visible normals in its frame, reflected; returned in the base frame."""
        vc = to_frame(v, self.normal)
        h = self.ggx.sample_h(vc, np.asarray(u, dtype=np.float64))
        lc = _reflect(np.broadcast_to(vc, h.shape), h)
        n = self.normal
        sign = 1.0 if n[2] >= 0 else -1.0
        a = -1.0 / (sign + n[2])
        b = n[0] * n[1] * a
        t = np.array([1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]])
        s = np.array([b, sign + n[1] * n[1] * a, -n[1]])
        l = lc[..., :1] * t + lc[..., 1:2] * s + lc[..., 2:] * n
        return l, self.pdf(v, l)

    def pdf(self, v, l):
        """The sampler's density of l above the base's horizon: ``G1(v) D(h) / (4 v.n_c)`` in the coat's
        frame, also where l is below the coat's horizon (the sampler reaches it; eval is 0 there)."""
        vc, lc = to_frame(v, self.normal), to_frame(l, self.normal)
        h = _half(vc, lc)
        val = self.ggx.G1(vc) * self.ggx.D(h) / (4.0 * np.maximum(vc[..., 2], COS_EPS))
        return np.where((l[..., 2] > 0) & (vc[..., 2] > 0), val, 0.0)

    def albedo(self, mu, **quad):
        """The coat lobe's albedo with n_c = n (the GGX quadrature of :class:`AnisotropicGGX`)."""
        return self.ggx.albedo(mu, **quad)


def coat_layer(base, coat, clearcoat, Fc):
    """[Coat] "Layering": ``mix(material, clearcoat_brdf, clearcoat * Fc) = material (1 - clearcoat Fc)
    + clearcoat Fc clearcoat_brdf``. clearcoat 0 returns ``base`` bit for bit."""
    w = float(clearcoat) * np.asarray(Fc, dtype=np.float64)
    return base * (1.0 - w)[..., None] + (w * np.asarray(coat))[..., None]


# ------------------------------------------------------------------------------------------------
# KHR_materials_specular
# ------------------------------------------------------------------------------------------------

def specular_f0(f0_ior, specular=1.0, specular_color=(1.0, 1.0, 1.0)):
    """[Spec] "Interaction with other extensions": ``dielectric_f0 = min(((ior - outside_ior) / (ior +
    outside_ior))^2 * specularColor, 1) * specular``; ``f0_ior`` that squared ratio (0.04 at ior 1.5,
    :func:`f0_from_ior`). The neutral values (1, (1, 1, 1)) return ``f0_ior`` bit for bit."""
    c = np.asarray(specular_color, dtype=np.float64)
    return np.minimum(np.asarray(f0_ior, dtype=np.float64)[..., None] * c, 1.0) * np.asarray(specular)[..., None]


def specular_f90(specular=1.0):
    """[Spec]: ``dielectric_f90 = specular``."""
    return np.asarray(specular, dtype=np.float64)


def specular_fresnel(VoH, f0_ior, specular=1.0, specular_color=(1.0, 1.0, 1.0)):
    """[Spec] "Implementation": ``dielectric_fresnel = mix(dielectric_f0, dielectric_f90, fresnel_w)``,
    ``fresnel_w = (1 - |v.h|)^5`` ([glTF-B] B.3.4's Schlick), RGB (..., 3). The diffuse lobe is then
    weighted by ``1 - max3(dielectric_fresnel)`` ([Spec] ``dielectric_brdf``)."""
    f0 = specular_f0(f0_ior, specular, specular_color)
    f90 = specular_f90(specular)[..., None]
    return schlick(np.asarray(VoH, dtype=np.float64)[..., None], f0, f90)


# ------------------------------------------------------------------------------------------------
# KHR_materials_iridescence
# ------------------------------------------------------------------------------------------------

#: [Irid] "Analytic Spectral Integration": XYZ -> linear Rec.709 (sRGB primaries, D65 white), row-major
#: here (the README's GLSL ``mat3`` is column-major).
XYZ_TO_REC709 = np.array([[3.2404542, -1.5371385, -0.4985314],
                          [-0.9692660, 1.8760108, 0.0415560],
                          [0.0556434, -0.2040259, 1.0572252]])


def _cie_cmfs():
    """CIE 1931 2 degree CMFs from colour-science, 380-780 nm at 1 nm (the visible range Belcour's
    Gaussian fit covers)."""
    import colour

    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    lam = np.arange(380.0, 781.0, 1.0)
    return lam, np.asarray(cmfs[lam], dtype=np.float64)


FILM_WAVELENGTHS, CIE_CMFS = _cie_cmfs()


def _film_interfaces(cos1, film_ior, base_f0, outside_ior):
    """[Irid] "Material Interfaces" and "Phase Shift", shared by both integrations: ``R12``, ``T121``,
    ``R23`` (RGB), ``cos theta_2``, the phase ``phi = phi21 + phi23`` (RGB) and a mask of total
    internal reflection."""
    cos1 = np.asarray(cos1, dtype=np.float64)
    R0 = ((film_ior - outside_ior) / (film_ior + outside_ior)) ** 2
    R12 = schlick(cos1, R0)
    T121 = 1.0 - R12
    sin2 = (outside_ior / film_ior) ** 2 * (1.0 - cos1 * cos1)
    tir = (1.0 - sin2) < 0.0
    cos2 = np.sqrt(np.maximum(1.0 - sin2, 0.0))
    sf0 = np.sqrt(np.asarray(base_f0, dtype=np.float64) + BASE_F0_GUARD)
    base_ior = (1.0 + sf0) / (1.0 - sf0)
    R1 = ((base_ior - film_ior) / (base_ior + film_ior)) ** 2
    R23 = schlick(cos2[..., None], R1)
    phi12 = PI if film_ior < outside_ior else 0.0
    phi = (PI - phi12) + np.where(base_ior < film_ior, PI, 0.0)
    R123 = np.clip(R12[..., None] * R23, FILM_R123_MIN, FILM_R123_MAX)
    Rs = T121[..., None] ** 2 * R23 / (1.0 - R123)
    return R12, T121, R23, cos2, phi, R123, Rs, tir


def _sensitivity(opd, shift):
    """[Irid] ``evalSensitivity``: Belcour's Gaussian fit of the CMFs' Fourier transform, in Rec.709."""
    phase = 2.0 * PI * opd * 1.0e-9
    val = np.array([5.4856e-13, 4.4201e-13, 5.2481e-13])
    pos = np.array([1.6810e+06, 1.7953e+06, 2.2084e+06])
    var = np.array([4.3278e+09, 9.3046e+09, 6.6121e+09])
    p = phase[..., None]
    xyz = val * np.sqrt(2.0 * PI * var) * np.cos(pos * p + shift) * np.exp(-(p * p) * var)
    xyz[..., 0] += (9.7470e-14 * np.sqrt(2.0 * PI * 4.5282e+09) * np.cos(2.2399e+06 * phase + shift[..., 0])
                    * np.exp(-4.5282e+09 * phase * phase))
    xyz /= 1.0685e-7
    return xyz @ XYZ_TO_REC709.T


def iridescence_rgb(cos1, thickness, film_ior=1.3, base_f0=(0.04, 0.04, 0.04), outside_ior=1.0):
    """[Irid] ``iridescent_fresnel`` as the README writes it (Belcour & Barla 2017's RGB evaluation,
    the spec's reference): the m = 0 term ``C0 = R12 + Rs`` and the m = 1, 2 terms through
    ``evalSensitivity``; 1 under total internal reflection; clamped at 0. ``thickness`` in nm,
    ``cos1`` (...), returns (..., 3)."""
    R12, T121, R23, cos2, phi, R123, Rs, tir = _film_interfaces(cos1, film_ior, base_f0, outside_ior)
    opd = 2.0 * film_ior * float(thickness) * cos2
    I = R12[..., None] + Rs
    Cm = Rs - T121[..., None]
    r123 = np.sqrt(R123)
    for m in (1, 2):
        Cm = Cm * r123
        I = I + Cm * 2.0 * _sensitivity(m * opd, m * phi)
    return np.where(tir[..., None], 1.0, np.maximum(I, 0.0))


def film_reflectance(cos1, thickness, wavelength, film_ior=1.3, base_f0=(0.04, 0.04, 0.04), outside_ior=1.0):
    """The film's reflectance at one wavelength (nm), per base channel (..., 3): the Airy sum of
    [BB17] eq. 2-9 over every order, in closed form. With ``z = sqrt(R123) e^(i theta)``, ``theta =
    2 pi OPD / lambda + phi``, ``R = C0 + 2 (Rs - T121) Re(z / (1 - z))`` (the geometric series
    ``sum_m z^m``: the README's series truncated at m = 2 is the same with the CMFs' Fourier
    transform in place of ``cos(m theta)``)."""
    R12, T121, R23, cos2, phi, R123, Rs, tir = _film_interfaces(cos1, film_ior, base_f0, outside_ior)
    opd = 2.0 * film_ior * float(thickness) * cos2
    theta = 2.0 * PI * opd[..., None] / float(wavelength) + phi
    z = np.sqrt(R123) * np.exp(1j * theta)
    R = R12[..., None] + Rs + 2.0 * (Rs - T121[..., None]) * np.real(z / (1.0 - z))
    return np.where(tir[..., None], 1.0, R)


def fresnel_exact(cos1, n1, n2):
    """The unpolarized dielectric Fresnel reflectance (real IORs, Fresnel's equations averaged over s
    and p), from ``n1`` into ``n2``; 1 under total internal reflection."""
    c1 = np.asarray(cos1, dtype=np.float64).astype(complex)
    c2 = np.sqrt(1.0 - (n1 / n2) ** 2 * (1.0 - c1 * c1))
    rs = (n1 * c1 - n2 * c2) / (n1 * c1 + n2 * c2)
    rp = (n2 * c1 - n1 * c2) / (n2 * c1 + n1 * c2)
    return 0.5 * (np.abs(rs) ** 2 + np.abs(rp) ** 2)


def film_reflectance_exact(cos1, thickness, wavelength, film_ior=1.3, base_ior=1.5, outside_ior=1.0):
    """The film's reflectance at one wavelength with Fresnel's amplitudes in place of the README's
    Schlick magnitudes and phase rule (the physics [BB17] eq. 2-9 approximate): per polarization
    ``r = (r12 + r23 e^(i delta)) / (1 + r12 r23 e^(i delta))``, ``delta = 4 pi n2 d cos theta_2 /
    lambda`` (Airy), averaged over s and p; complex cosines carry total internal reflection. At d = 0
    it is :func:`fresnel_exact` from outside into the base (the film vanishes) to rounding."""
    n1, n2, n3 = float(outside_ior), float(film_ior), float(base_ior)
    c1 = np.asarray(cos1, dtype=np.float64).astype(complex)
    c2 = np.sqrt(1.0 - (n1 / n2) ** 2 * (1.0 - c1 * c1))
    c3 = np.sqrt(1.0 - (n1 / n3) ** 2 * (1.0 - c1 * c1))
    e = np.exp(1j * 4.0 * PI * n2 * float(thickness) * c2 / float(wavelength))
    out = 0.0
    for r12, r23 in (((n1 * c1 - n2 * c2) / (n1 * c1 + n2 * c2), (n2 * c2 - n3 * c3) / (n2 * c2 + n3 * c3)),
                     ((n2 * c1 - n1 * c2) / (n2 * c1 + n1 * c2), (n3 * c2 - n2 * c3) / (n3 * c2 + n2 * c3))):
        out = out + 0.5 * np.abs((r12 + r23 * e) / (1.0 + r12 * r23 * e)) ** 2
    return out


def spectrum_to_rgb(R):
    """A reflectance spectrum (..., n_lambda) on :data:`FILM_WAVELENGTHS` to linear Rec.709 with the
    equal-energy white point (R = c gives (c, c, c)): :data:`CIE_CMFS` then :data:`XYZ_TO_REC709`,
    each channel divided by that of R = 1."""
    white = CIE_CMFS.sum(axis=0) @ XYZ_TO_REC709.T
    return (np.asarray(R) @ CIE_CMFS) @ XYZ_TO_REC709.T / white


def iridescence_spectral_exact(cos1, thickness, film_ior=1.3, base_ior=1.5, outside_ior=1.0):
    """:func:`film_reflectance_exact` per wavelength integrated by :func:`spectrum_to_rgb` (..., 3)."""
    R = np.stack([film_reflectance_exact(cos1, thickness, lam, film_ior, base_ior, outside_ior)
                  for lam in FILM_WAVELENGTHS], axis=-1)
    return spectrum_to_rgb(R)


def iridescence_spectral(cos1, thickness, film_ior=1.3, base_f0=(0.04, 0.04, 0.04), outside_ior=1.0):
    """The film of :func:`iridescence_rgb` evaluated spectrally: :func:`film_reflectance` per
    wavelength of :data:`FILM_WAVELENGTHS` (380-780 nm, 1 nm), integrated against the CIE 1931 2
    degree CMFs (:data:`CIE_CMFS`, colour-science) to XYZ, to linear Rec.709 by :data:`XYZ_TO_REC709`,
    and white-balanced per channel so that a flat reflectance R(lambda) = c is RGB (c, c, c): the
    equal-energy illuminant E is the white point (the convention of [BB17]'s m = 0 term, which the
    README adds to every channel unfiltered). The base's RGB F0 is taken as constant over
    wavelength within each channel: channel k of the result is the spectral integral of the film over
    base channel k."""
    R = np.stack([film_reflectance(cos1, thickness, lam, film_ior, base_f0, outside_ior)
                  for lam in FILM_WAVELENGTHS], axis=-1)  # (..., 3 base channels, n_lambda)
    return np.stack([spectrum_to_rgb(R[..., k, :])[..., k] for k in range(3)], axis=-1)


def iridescence_mix(F, F_irid, iridescence):
    """[Irid] "Iridescence BRDF": ``mix(F, iridescent_fresnel, iridescence)``; iridescence 0 returns
    ``F`` bit for bit."""
    w = float(iridescence)
    return F * (1.0 - w) + F_irid * w
