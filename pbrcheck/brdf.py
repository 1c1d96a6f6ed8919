"""BRDF terms in numpy: the ground truth both renderers are checked against.

The terms are classes of :mod:`pbrcheck.terms` (one per NDF, G and Fresnel term), which the scene's
registries hold (:mod:`pbrcheck.registry`); here the dispatch by name (:func:`ndf_term`,
:func:`geometry_term`, :func:`fresnel_term`), the material's lobes as objects (:class:`SpecularLobe`,
:class:`DiffuseLobe`: eval, sample, pdf, albedo), the full material BRDF (:func:`brdf_eval`, the two
lobes' sum) and the albedo quadrature. Every
function here (and each term under its GLSL name: ``D_GGX = GGX.eval``) has a GLSL twin of the *same
name* in ``realtime/shaders/brdf.glsl`` (the test harness runs both on the same grids). Arguments are cosines clamped by the caller to [0, 1];
``alpha`` is the GGX width ``roughness^2``.

The material model both renderers implement (README, "Material model")::

    F0    = mix(specular, base_color, metallic),   alpha = roughness^2
    f(l,v) = (1 - F(v.h)) (1 - metallic) base_color / pi  +  D(h) G(l, v) F(v.h) / (4 (n.l)(n.v))

with ``[brdf] metallic_blend = "gltf"`` (glTF 2.0 Appendix B) the diffuse weight is ``1 - F(v.h)`` of
``F0 = specular`` instead (:func:`brdf_eval`).

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

import numpy as np

from .registry import FRESNELS, GEOMETRIES, NDFS
from .terms import (COS_EPS, MIN_ALPHA, PI, G1_SchlickGGX, G1_SmithGGX, alpha_from_roughness,  # noqa: F401
                    blinn_phong_exponent, erfcx_nr, k_schlick_direct, k_schlick_ibl)
from .terms import (GGX, Beckmann, BlinnPhong, NoFresnel, SchlickBeckmann, SchlickGGXIBL, Schlick,
                    SmithBeckmannCorrelated, SmithGGX, SmithGGXCorrelated)

# Below this alpha the quadrature uses the mirror limit of the lobe: at alpha ~ 1e-5 the lobe is
# ~1e-5 rad wide and 1 - cos(theta_h) ~ 1e-10 nears float64's resolution of cos near 1. The limit
# differs from alpha = 1e-4 by < 1e-7 in A + B.
DELTA_LOBE_ALPHA = 1e-4

# The GLSL twins' names (brdf.glsl): the term classes' functions (pbrcheck.terms).
D_GGX, D_Beckmann, D_BlinnPhong = GGX.eval, Beckmann.eval, BlinnPhong.eval
Lambda_GGX, Lambda_Beckmann = GGX.Lambda, Beckmann.Lambda
G_SmithGGXCorrelated, G_SmithGGX, G_SchlickGGX = SmithGGXCorrelated.eval, SmithGGX.eval, SchlickGGXIBL.eval
G_SchlickBeckmann, G_SmithBeckmannCorrelated = SchlickBeckmann.eval, SmithBeckmannCorrelated.eval
F_Schlick, F_None = Schlick.eval, NoFresnel.eval


def term(registry, name: str):
    """The term class of member ``name`` of a term registry (:data:`pbrcheck.registry.NDFS`,
    ``GEOMETRIES``, ``FRESNELS``); ValueError naming the list for an unknown member."""
    if name not in registry:
        raise ValueError(f"unknown {registry.define.lower()} term {name!r}; terms are: {', '.join(registry.names)}")
    return registry[name].term


def geometry_term(geometry: str, NoV, NoL, roughness):
    """Dispatch on the scene's ``[brdf] geometry`` name (:data:`pbrcheck.registry.GEOMETRIES`: the
    member's function at its width); ``roughness`` is perceptual."""
    g = term(GEOMETRIES, geometry)
    return g.eval(NoV, NoL, g.width(roughness))


def ndf_term(ndf: str, NoH, roughness):
    """Dispatch on ``[brdf] ndf`` (:data:`pbrcheck.registry.NDFS`); ``roughness`` is perceptual."""
    d = term(NDFS, ndf)
    return d.eval(NoH, d.width(roughness))


# ------------------------------------------------------------------------------------------------
# Fresnel and diffuse
# ------------------------------------------------------------------------------------------------

def Fd_Lambert():
    """Lambertian diffuse: ``1 / pi``."""
    return 1.0 / PI


def fresnel_term(fresnel: str, VoH, F0):
    """Dispatch on ``[brdf] fresnel`` (:data:`pbrcheck.registry.FRESNELS`): Schlick, or ``none`` (F = 1)."""
    return term(FRESNELS, fresnel).eval(VoH, F0)


def material_f0(base_color, metallic, specular):
    """``F0 = mix(specular, base_color, metallic)``; ``base_color`` (..., 3), the others (...)."""
    m = np.asarray(metallic, dtype=np.float64)[..., None]
    s = np.asarray(specular, dtype=np.float64)[..., None]
    return s * (1.0 - m) + np.asarray(base_color, dtype=np.float64) * m


#: The values of ``[brdf] metallic_blend`` (:func:`brdf_eval`): ``"f0"`` the seed articles' F0 mix,
#: ``"gltf"`` glTF 2.0 Appendix B's mix of a dielectric and a metal BRDF.
METALLIC_BLENDS = ("f0", "gltf")


def diffuse_fresnel(spec_lobe, VoH, specular, metallic_blend: str):
    """The Fresnel factor under which the diffuse lobe is weighted for ``metallic_blend = "gltf"``:
    ``F(v.h)`` of the dielectric's ``F0 = specular`` (glTF 2.0 Appendix B's ``fresnel_mix``)."""
    if metallic_blend != "gltf":
        raise ValueError(f"metallic_blend must be one of {METALLIC_BLENDS}, not {metallic_blend!r}")
    s = np.asarray(specular, dtype=np.float64)[..., None] * np.ones(3)
    return spec_lobe.F.eval(np.asarray(VoH)[..., None], s)


def brdf_eval(n, v, l, base_color, metallic, roughness, specular, *, ndf="ggx",
              geometry="smith_ggx_correlated", fresnel="schlick", metallic_blend="f0"):
    """The full material BRDF f(l, v) (without the cosine), shape (..., 3).

    ``n, v, l``: (..., 3) unit vectors (v towards the viewer, l towards the light). Returns 0 where
    either direction is below the surface. Roughness 0 returns the specular lobe evaluated at
    MIN_ALPHA (a finite, very narrow peak): the delta itself is the renderers' business.
    ``metallic_blend`` (``[brdf] metallic_blend``): ``"f0"`` the diffuse under ``1 - F`` of the mixed
    F0 (module docstring); ``"gltf"`` glTF 2.0 Appendix B, ``mix(dielectric_brdf, metal_brdf,
    metallic)``: the diffuse under ``1 - F`` of the dielectric's own ``F0 = specular`` (the specular
    lobe is the same: Schlick, and F = 1, are linear in F0, so ``mix(F(specular), F(base), m) =
    F(mix(specular, base, m))``).
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
    spec_lobe = SpecularLobe(ndf, geometry, fresnel)
    F = spec_lobe.F.eval(VoH[..., None], F0)  # shared by the two lobes
    spec = spec_lobe.eval(NoV, NoL, NoH, F, roughness)
    Fd = F if metallic_blend == "f0" else diffuse_fresnel(spec_lobe, VoH, specular, metallic_blend)
    diff = DiffuseLobe(fresnel).eval(Fd, metallic, base_color)
    valid = ((NoV > 0) & (NoL > 0))[..., None]
    return np.where(valid, diff + spec, 0.0)


# ------------------------------------------------------------------------------------------------
# Quadrature: directional albedo and the split-sum DFG terms, exact to ~1e-7.
# ------------------------------------------------------------------------------------------------

def _gauss(n, a, b):
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (b - a) * x + 0.5 * (b + a), 0.5 * (b - a) * w


def _ndf_theta_from_u(ndf, u, alpha):
    """theta_h as the inverse CDF of ``D(h) cos(theta_h)`` at u (the quadrature's variable), so
    that nodes crowd where the lobe is; ``pdf(theta) = 2 pi D cos sin`` is the Jacobian's inverse."""
    a = max(float(alpha), MIN_ALPHA)
    u = np.clip(u, 0.0, 1.0 - 1e-16)
    return term(NDFS, ndf).theta_h(u, a)


def _ndf_u_from_theta(ndf, theta, alpha):
    """The NDF's CDF in theta_h: inverse of :func:`_ndf_theta_from_u`."""
    a = max(float(alpha), MIN_ALPHA)
    if theta >= np.pi / 2:
        return 1.0
    return term(NDFS, ndf).cdf_theta_h(theta, a)


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
# The material's two lobes (pbrt-v4's BxDF shape): each with its eval, density and albedo.
# ------------------------------------------------------------------------------------------------

class SpecularLobe:
    """The microfacet specular lobe ``D G F / (4 (n.l)(n.v))`` of the scene's terms ``ndf``,
    ``geometry``, ``fresnel`` (members of the registries; their classes ``D``, ``G``, ``F``):
    :meth:`eval`, the half vector's :meth:`sample` from its NDF's ``D (n.h)`` and the density of l
    :meth:`pdf` (``D (n.h) / (4 v.h)``, [Walter07] eq. 14), the split sum's :meth:`dfg` terms and the
    directional :meth:`albedo` (:func:`specular_dfg`, :func:`specular_albedo`)."""

    def __init__(self, ndf: str = "ggx", geometry: str = "smith_ggx_correlated", fresnel: str = "schlick"):
        self.ndf, self.geometry, self.fresnel = ndf, geometry, fresnel
        self.D, self.G, self.F = term(NDFS, ndf), term(GEOMETRIES, geometry), term(FRESNELS, fresnel)

    def eval(self, NoV, NoL, NoH, F, roughness):
        """The lobe's value (..., 3) with the Fresnel factor ``F`` (..., 3) of the half vector."""
        D = self.D.eval(NoH, self.D.width(roughness))
        G = self.G.eval(np.clip(NoV, 0, 1), np.clip(NoL, 0, 1), self.G.width(roughness))
        return (D * G)[..., None] * F / (4.0 * np.maximum(NoV, COS_EPS) * np.maximum(NoL, COS_EPS))[..., None]

    def sample(self, u, roughness):
        """A half vector (tangent space) from the NDF's ``D (n.h)``; l is v reflected about it."""
        return self.D.sample(u, self.D.width(roughness))

    def pdf(self, NoH, VoH, roughness):
        """The density in l of :meth:`sample`'s reflections: ``D (n.h) / (4 v.h)``."""
        return self.D.pdf(NoH, self.D.width(roughness)) / np.maximum(4.0 * np.asarray(VoH, dtype=np.float64), COS_EPS)

    def dfg(self, NoV, roughness, **quad):
        """The split sum's ``(A, B)`` at n.v (:func:`specular_dfg`)."""
        return specular_dfg(NoV, roughness, ndf=self.ndf, geometry=self.geometry, **quad)

    def albedo(self, NoV, roughness, F0=1.0, **quad):
        """The directional albedo for a scalar F0 (:func:`specular_albedo`)."""
        return specular_albedo(NoV, roughness, F0, ndf=self.ndf, geometry=self.geometry, fresnel=self.fresnel, **quad)


class DiffuseLobe:
    """Lambert's lobe weighted by ``(1 - F(v.h)) (1 - metallic)`` (none without Fresnel: the diffuse
    term vanishes with F = 1): :meth:`eval`, the cosine density :meth:`pdf` and :meth:`albedo`
    (:func:`diffuse_albedo`)."""

    def __init__(self, fresnel: str = "schlick"):
        self.fresnel = fresnel

    @staticmethod
    def eval(F, metallic, base_color):
        """``(1 - F) (1 - metallic) base_color / pi`` (..., 3)."""
        m = np.asarray(metallic, dtype=np.float64)[..., None]
        return (1.0 - F) * (1.0 - m) * np.asarray(base_color, dtype=np.float64) * Fd_Lambert()

    @staticmethod
    def pdf(NoL):
        """The cosine density ``max(n.l, 0) / pi`` (Malley's sampler, :func:`pbrcheck.sampling.sample_cosine`)."""
        return np.maximum(np.asarray(NoL, dtype=np.float64), 0.0) / PI

    def albedo(self, NoV, roughness, F0, **quad):
        """Per unit ``(1 - metallic) base_color`` (:func:`diffuse_albedo`)."""
        return diffuse_albedo(NoV, roughness, F0, fresnel=self.fresnel, **quad)


# ------------------------------------------------------------------------------------------------
# Terms the real-time renderer adds (twins of realtime/shaders/brdf.glsl and ibl.glsl).
# ------------------------------------------------------------------------------------------------

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
