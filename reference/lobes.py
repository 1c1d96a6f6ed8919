"""The glTF PBR extensions' lobes in Dr.Jit: the twins of :mod:`pbrcheck.lobes`' numpy classes and
functions of the same names (the spec's equations, cited there per method), for the reference's BSDF
to compose. Local frame ``n = +Z``; ``v`` towards the viewer, ``l`` towards the light
(``mi.Vector3f``); ``eval`` is the BRDF times ``n.l``; ``sample(v, u)`` returns ``(l, pdf)``.
Written in float32 in the stable forms of :mod:`reference.terms` (sin^2 theta_h = h.x^2 + h.y^2).
The isotropic GGX (strength 0, the coat) calls :mod:`reference.terms`' ``GGX.eval`` and
``SmithGGXCorrelated.eval``: the base lobe's very functions.

API: :class:`SheenCharlie`, :class:`AnisotropicGGX`, :class:`ClearcoatLobe`, :func:`to_frame`,
:func:`fresnel_coat`, :func:`coat_layer`, :func:`sheen_layer`, :func:`specular_f0`,
:func:`specular_f90`, :func:`iridescence_rgb`, :func:`iridescence_spectral` (the wavelengths as a
second axis of the wavefront, reduced by ``dr.block_sum``), :func:`iridescence_mix`.
References: as :mod:`pbrcheck.lobes` ([glTF-B], [Sheen], [Coat], [Spec], [Aniso], [Irid], [EK17],
[Heitz14], [Heitz18], [BB17], [CIE]).
"""

from __future__ import annotations

import math

import numpy as np

import pbrcheck  # noqa: F401  (sets DRJIT_LIBLLVM_PATH before drjit loads)
from pbrcheck import lobes as np_lobes
from pbrcheck.lobes import (BASE_F0_GUARD, CLEARCOAT_IOR, FILM_R123_MAX, FILM_R123_MIN, SHEEN_MIN_ALPHA,
                            XYZ_TO_REC709)
from pbrcheck.terms import COS_EPS, MIN_ALPHA

import drjit as dr
import mitsuba as mi

from reference import terms as T
from reference.lobe_bsdf import aniso_sample_h

PI = math.pi


def _half(v, l):
    return dr.normalize(v + l)


def _reflect(v, h):
    return 2.0 * dr.dot(v, h) * h - v


def _cosine_sample(u0, u1):
    r = dr.sqrt(u0)
    phi = 2.0 * PI * u1
    return mi.Vector3f(r * dr.cos(phi), r * dr.sin(phi), dr.sqrt(dr.maximum(1.0 - u0, 0.0)))


def _albedo(lobe, mu, n_theta, n_phi):
    """:func:`pbrcheck.lobes._hemisphere_quadrature`'s nodes (phi over [0, pi], doubled):
    Gauss-Legendre in cos(theta), midpoint in phi; each node weighs ``w_c 2 pi / n_phi``."""
    x, w = np.polynomial.legendre.leggauss(n_theta)
    c, wc = 0.5 * (x + 1.0), 0.5 * w
    phi = (np.arange(n_phi) + 0.5) * PI / n_phi
    cc, pp = np.meshgrid(c, phi, indexing="ij")
    ss = np.sqrt(1.0 - cc * cc)
    wt = (wc[:, None] * np.full(n_phi, 2.0 * PI / n_phi)[None]).ravel()
    l = mi.Vector3f(mi.Float((ss * np.cos(pp)).ravel()), mi.Float((ss * np.sin(pp)).ravel()), mi.Float(cc.ravel()))
    vv = np_lobes._view(mu)
    v = mi.Vector3f(float(vv[0]), float(vv[1]), float(vv[2]))
    return float(dr.sum(lobe.eval(v, l) * mi.Float(wt))[0])


class SheenCharlie:
    """:class:`pbrcheck.lobes.SheenCharlie` ([Sheen] "Implementation Notes", [EK17])."""

    MIX = np_lobes.SheenCharlie.MIX

    def __init__(self, roughness):
        r = float(roughness)
        self.alpha = max(r * r, SHEEN_MIN_ALPHA)

    def D(self, h):
        s2 = dr.minimum(h.x * h.x + h.y * h.y, 1.0)
        inv_r = 1.0 / self.alpha
        # s2^(inv_r / 2) as exp(log): 0 at s2 = 0 (log -> -inf).
        val = (2.0 + inv_r) * dr.exp(0.5 * inv_r * dr.log(dr.maximum(s2, 1e-38))) / (2.0 * PI)
        return dr.select((h.z > 0) & (s2 > 0), val, 0.0)

    def _l(self, x):
        return np_lobes.sheen_l(x, self.alpha, dr.power)

    def Lambda(self, c):
        c = dr.abs(c)
        return dr.select(c < 0.5, dr.exp(self._l(c)), dr.exp(2.0 * self._l(0.5) - self._l(1.0 - c)))

    def eval(self, v, l):
        cv, cl = dr.clip(v.z, COS_EPS, 1.0), dr.clip(l.z, COS_EPS, 1.0)
        val = self.D(_half(v, l)) / ((1.0 + self.Lambda(cv) + self.Lambda(cl)) * 4.0 * cv)
        return dr.select((v.z > 0) & (l.z > 0), val, 0.0)

    def sample_h(self, u0, u1):
        st = dr.power(u1, self.alpha / (2.0 * self.alpha + 1.0))
        ct = dr.sqrt(dr.maximum(1.0 - st * st, 0.0))
        phi = 2.0 * PI * u0
        return mi.Vector3f(st * dr.cos(phi), st * dr.sin(phi), ct)

    def pdf(self, v, l):
        h = _half(v, l)
        pd = self.D(h) * h.z / dr.maximum(4.0 * dr.abs(dr.dot(v, h)), COS_EPS)
        pc = dr.maximum(l.z, 0.0) / PI
        return dr.select((v.z > 0) & (l.z > 0), self.MIX * pc + (1.0 - self.MIX) * pd, 0.0)

    def sample(self, v, u):
        pick = u.x < self.MIX
        lc = _cosine_sample(dr.clip(u.x / self.MIX, 0.0, 1.0), u.y)
        ld = _reflect(v, self.sample_h(dr.clip((u.x - self.MIX) / (1.0 - self.MIX), 0.0, 1.0), u.y))
        l = dr.select(pick, lc, ld)
        return l, self.pdf(v, l)

    def albedo(self, mu, n_theta=np_lobes.ALBEDO_N_THETA, n_phi=np_lobes.ALBEDO_N_PHI):
        return _albedo(self, mu, n_theta, n_phi)


class AnisotropicGGX:
    """:class:`pbrcheck.lobes.AnisotropicGGX` ([Aniso], [Heitz14] eq. 86 and 99, [Heitz18])."""

    def __init__(self, roughness, strength=0.0, rotation=0.0):
        r, s = float(roughness), float(strength)
        self.alpha = max(r * r, MIN_ALPHA)
        self.at = self.alpha * (1.0 - s * s) + 1.0 * (s * s)
        self.ab = self.alpha
        self.isotropic = self.at == self.ab
        self.c, self.s = math.cos(float(rotation)), math.sin(float(rotation))

    def local(self, w):
        return mi.Vector3f(self.c * w.x + self.s * w.y, -self.s * w.x + self.c * w.y, w.z)

    def world(self, w):
        return mi.Vector3f(self.c * w.x - self.s * w.y, self.s * w.x + self.c * w.y, w.z)

    def D(self, h):
        if self.isotropic:
            return T.GGX.eval(h, self.alpha)
        hl = self.local(h)
        t = dr.square(hl.x / self.at) + dr.square(hl.y / self.ab) + hl.z * hl.z
        return dr.select(h.z > 0, 1.0 / (PI * self.at * self.ab * t * t), 0.0)

    def Lambda(self, w):
        wl = self.local(w)
        z2 = dr.maximum(wl.z * wl.z, COS_EPS * COS_EPS)
        return 0.5 * (dr.sqrt(1.0 + (self.at ** 2 * wl.x * wl.x + self.ab ** 2 * wl.y * wl.y) / z2) - 1.0)

    def G2(self, v, l):
        if self.isotropic:
            return T.SmithGGXCorrelated.eval(dr.clip(v.z, 0.0, 1.0), dr.clip(l.z, 0.0, 1.0), self.alpha)
        return 1.0 / (1.0 + self.Lambda(v) + self.Lambda(l))

    def G1(self, v):
        return 1.0 / (1.0 + self.Lambda(v))

    def brdf(self, v, l):
        cv, cl = dr.maximum(v.z, COS_EPS), dr.maximum(l.z, COS_EPS)
        return self.D(_half(v, l)) * self.G2(v, l) / (4.0 * cv * cl)

    def eval(self, v, l):
        return dr.select((v.z > 0) & (l.z > 0), self.brdf(v, l) * dr.clip(l.z, 0.0, 1.0), 0.0)

    def sample_h(self, v, u):
        # [Heitz18] listing 1: the per-lane sampler of reference.lobe_bsdf at this lobe's constants
        return aniso_sample_h(v, u, self.at, self.ab, self.c, self.s)

    def pdf(self, v, l):
        h = _half(v, l)
        val = self.G1(v) * self.D(h) / (4.0 * dr.maximum(v.z, COS_EPS))
        return dr.select((v.z > 0) & (l.z > 0), val, 0.0)

    def sample(self, v, u):
        l = _reflect(v, self.sample_h(v, u))
        return l, self.pdf(v, l)

    def albedo(self, mu, n=np_lobes.ALBEDO_U_NODES):
        """:meth:`pbrcheck.lobes.AnisotropicGGX.albedo`: the midpoint rule in the sampler's u."""
        g = (np.arange(n) + 0.5) / n
        uu, vv_ = np.meshgrid(g, g, indexing="ij")
        u = mi.Point2f(mi.Float(uu.ravel()), mi.Float(vv_.ravel()))
        vv = np_lobes._view(mu)
        v = mi.Vector3f(float(vv[0]), float(vv[1]), float(vv[2]))
        l, pdf = self.sample(v, u)
        w = dr.select(pdf > 0, self.eval(v, l) / dr.maximum(pdf, 1e-30), 0.0)
        return float(dr.sum(w)[0]) / (n * n)


def _frame(n):
    n = [float(x) for x in n]
    sign = 1.0 if n[2] >= 0 else -1.0
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    return [1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]], [b, sign + n[1] * n[1] * a, -n[1]], n


def to_frame(w, n):
    """:func:`pbrcheck.lobes.to_frame`: ``w`` in the frame of ``n`` [Duff et al. 2017]."""
    t, s, n = _frame(n)
    return mi.Vector3f(w.x * t[0] + w.y * t[1] + w.z * t[2], w.x * s[0] + w.y * s[1] + w.z * s[2],
                       w.x * n[0] + w.y * n[1] + w.z * n[2])


def fresnel_coat(NcoV, ior=CLEARCOAT_IOR):
    """[Coat] "Layering": ``f0 + (1 - f0) (1 - |v.n_c|)^5``."""
    f0 = ((1.0 - ior) / (1.0 + ior)) ** 2
    w = 1.0 - dr.abs(NcoV)
    return f0 + (1.0 - f0) * (w * w * w * w * w)


class ClearcoatLobe:
    """:class:`pbrcheck.lobes.ClearcoatLobe` ([Coat] "Clearcoat BRDF")."""

    def __init__(self, roughness, normal=(0.0, 0.0, 1.0)):
        self.ggx = AnisotropicGGX(roughness)
        self.normal = tuple(float(x) for x in normal)

    def eval(self, v, l):
        vc, lc = to_frame(v, self.normal), to_frame(l, self.normal)
        ok = (l.z > 0) & (lc.z > 0) & (vc.z > 0)
        return dr.select(ok, self.ggx.brdf(vc, lc) * dr.clip(l.z, 0.0, 1.0), 0.0)

    def fresnel(self, v):
        return fresnel_coat(to_frame(v, self.normal).z)

    def sample(self, v, u):
        vc = to_frame(v, self.normal)
        lc = _reflect(vc, self.ggx.sample_h(vc, u))
        t, s, n = _frame(self.normal)
        l = mi.Vector3f(lc.x * t[0] + lc.y * s[0] + lc.z * n[0], lc.x * t[1] + lc.y * s[1] + lc.z * n[1],
                        lc.x * t[2] + lc.y * s[2] + lc.z * n[2])
        return l, self.pdf(v, l)

    def pdf(self, v, l):
        vc, lc = to_frame(v, self.normal), to_frame(l, self.normal)
        val = self.ggx.G1(vc) * self.ggx.D(_half(vc, lc)) / (4.0 * dr.maximum(vc.z, COS_EPS))
        return dr.select((l.z > 0) & (vc.z > 0), val, 0.0)


def coat_layer(base, coat, clearcoat, Fc):
    """[Coat] "Layering": ``base (1 - clearcoat Fc) + clearcoat Fc coat``."""
    w = float(clearcoat) * Fc
    return base * (1.0 - w) + w * coat


def sheen_layer(sheen, base, sheen_color, E_v, E_l=None):
    """[Sheen] "Albedo-scaling technique" (:func:`pbrcheck.lobes.sheen_layer`)."""
    m = max(float(x) for x in sheen_color)
    scale = 1.0 - m * E_v
    if E_l is not None:
        scale = dr.minimum(scale, 1.0 - m * E_l)
    return mi.Color3f(*[float(x) for x in sheen_color]) * sheen + base * scale


def specular_f0(f0_ior, specular=1.0, specular_color=(1.0, 1.0, 1.0)):
    """[Spec]: ``min(f0_ior * specularColor, 1) * specular``."""
    return dr.minimum(f0_ior * mi.Color3f(*[float(x) for x in specular_color]), 1.0) * specular


def specular_f90(specular=1.0):
    """[Spec]: ``dielectric_f90 = specular``."""
    return specular


def _schlick(c, f0, f90=1.0):
    w = 1.0 - dr.abs(c)
    return f0 + (f90 - f0) * (w * w * w * w * w)


def _interfaces(cos1, film_ior, base_f0, outside_ior):
    """[Irid] "Material Interfaces", "Phase Shift" (:func:`pbrcheck.lobes._film_interfaces`)."""
    R0 = ((film_ior - outside_ior) / (film_ior + outside_ior)) ** 2
    R12 = _schlick(cos1, R0)
    T121 = 1.0 - R12
    sin2 = (outside_ior / film_ior) ** 2 * (1.0 - cos1 * cos1)
    tir = (1.0 - sin2) < 0.0
    cos2 = dr.sqrt(dr.maximum(1.0 - sin2, 0.0))
    sf0 = [math.sqrt(float(f) + BASE_F0_GUARD) for f in base_f0]
    base_ior = [(1.0 + s) / (1.0 - s) for s in sf0]
    R1 = mi.Color3f(*[((b - film_ior) / (b + film_ior)) ** 2 for b in base_ior])
    R23 = _schlick(mi.Color3f(cos2), R1)
    phi12 = PI if film_ior < outside_ior else 0.0
    phi = mi.Color3f(*[(PI - phi12) + (PI if b < film_ior else 0.0) for b in base_ior])
    R123 = dr.clip(R12 * R23, FILM_R123_MIN, FILM_R123_MAX)
    Rs = T121 * T121 * R23 / (1.0 - R123)
    return R12, T121, cos2, phi, R123, Rs, tir


def _sensitivity(opd, shift):
    phase = 2.0 * PI * opd * 1.0e-9
    val = (5.4856e-13, 4.4201e-13, 5.2481e-13)
    pos = (1.6810e+06, 1.7953e+06, 2.2084e+06)
    var = (4.3278e+09, 9.3046e+09, 6.6121e+09)
    xyz = [val[k] * math.sqrt(2.0 * PI * var[k]) * dr.cos(pos[k] * phase + shift[k]) * dr.exp(-phase * phase * var[k])
           for k in range(3)]
    xyz[0] = xyz[0] + (9.7470e-14 * math.sqrt(2.0 * PI * 4.5282e+09) * dr.cos(2.2399e+06 * phase + shift[0])
                       * dr.exp(-4.5282e+09 * phase * phase))
    xyz = [x / 1.0685e-7 for x in xyz]
    M = XYZ_TO_REC709
    return mi.Color3f(*[M[k, 0] * xyz[0] + M[k, 1] * xyz[1] + M[k, 2] * xyz[2] for k in range(3)])


def iridescence_rgb(cos1, thickness, film_ior=1.3, base_f0=(0.04, 0.04, 0.04), outside_ior=1.0):
    """[Irid] ``iridescent_fresnel`` (:func:`pbrcheck.lobes.iridescence_rgb`), ``mi.Color3f``."""
    R12, T121, cos2, phi, R123, Rs, tir = _interfaces(cos1, film_ior, base_f0, outside_ior)
    opd = 2.0 * film_ior * float(thickness) * cos2
    I = R12 + Rs
    Cm = Rs - T121
    r123 = dr.sqrt(R123)
    for m in (1, 2):
        Cm = Cm * r123
        I = I + Cm * 2.0 * _sensitivity(m * opd, m * phi)
    return dr.select(tir, mi.Color3f(1.0), dr.maximum(I, 0.0))


def iridescence_spectral(cos1, thickness, film_ior=1.3, base_f0=(0.04, 0.04, 0.04), outside_ior=1.0):
    """:func:`pbrcheck.lobes.iridescence_spectral`: every (point, wavelength) pair one lane, the Airy
    sum ``C0 + 2 (Rs - T121) Re(z / (1 - z))`` with ``z = sqrt(R123) e^(i theta)`` written in reals
    (``Re(z / (1 - z)) = (r cos theta - r^2) / (1 - 2 r cos theta + r^2)``), weighted by the CMFs'
    white-balanced Rec.709 rows and summed per point (``dr.block_sum``)."""
    lam = np_lobes.FILM_WAVELENGTHS
    nl = len(lam)
    white = np_lobes.CIE_CMFS.sum(axis=0) @ XYZ_TO_REC709.T
    wrgb = (np_lobes.CIE_CMFS @ XYZ_TO_REC709.T) / white  # (n_lambda, 3)
    n = dr.width(cos1)
    idx = dr.arange(mi.UInt32, n * nl)
    c = dr.gather(mi.Float, cos1, idx // nl)
    li = idx % nl
    wl = dr.gather(mi.Float, mi.Float(lam), li)
    R12, T121, cos2, phi, R123, Rs, tir = _interfaces(c, film_ior, base_f0, outside_ior)
    theta0 = 2.0 * PI * (2.0 * film_ior * float(thickness) * cos2) / wl
    r = dr.sqrt(R123)
    out = []
    for k in range(3):
        th = theta0 + phi[k]
        ct = dr.cos(th)
        re = (r[k] * ct - r[k] * r[k]) / (1.0 - 2.0 * r[k] * ct + r[k] * r[k])
        R = dr.select(tir, 1.0, R12 + Rs[k] + 2.0 * (Rs[k] - T121) * re)
        w = dr.gather(mi.Float, mi.Float(wrgb[:, k]), li)
        out.append(dr.block_sum(R * w, nl))
    return mi.Color3f(*out)


def iridescence_mix(F, F_irid, iridescence):
    """[Irid]: ``mix(F, iridescent_fresnel, iridescence)``."""
    w = float(iridescence)
    return F * (1.0 - w) + F_irid * w
