"""The microfacet BRDF's terms in numpy, one class per term (pbrt-v4's shape, ``util/scattering.h``).

An NDF class holds its ``eval`` (D), its Smith ``Lambda`` (None where it has none), its half-vector
sampler ``sample`` of ``D (n.h)`` and that density ``pdf``, and the albedo quadrature's inverse CDF
pair in theta_h (``theta_h``, ``cdf_theta_h``: :func:`pbrcheck.brdf.specular_dfg`'s nodes); a
geometry (G) class its ``eval`` at its width; a Fresnel class its ``eval``. Every class names its
GLSL function (``realtime/shaders/brdf.glsl``; an NDF's sampler in ``sampling.glsl``) and its width's
as strings (``glsl``, ``glsl_sample``, ``glsl_width``: ``tests/test_registry.py`` checks them
against the shader sources). The registries (:mod:`pbrcheck.registry`: ``NDFS``, ``GEOMETRIES``,
``FRESNELS``) hold these classes; :mod:`reference.terms` holds the Dr.Jit class of each, keyed by
the same entry. The classes are namespaces of static methods (the width and alpha travel as
arguments, arrays broadcast); :mod:`pbrcheck.brdf` keeps the module names of the GLSL twins
(``D_GGX = GGX.eval``, ...).

Arguments are cosines (clamped by each function as written), ``alpha`` the GGX width
``roughness^2``, ``u`` (..., 2) in [0, 1)^2 in tangent space (z the normal).

API
---
:data:`MIN_ALPHA`, :data:`COS_EPS`, :data:`PI`, :data:`ERFCC_COEFFS`, :func:`erfcx_fit`,
:func:`erfcx_nr`, :func:`alpha_from_roughness`, :func:`k_schlick_ibl`, :func:`k_schlick_direct`,
:func:`blinn_phong_exponent`, :func:`G1_SmithGGX`, :func:`G1_SchlickGGX`; the bases :class:`Term`,
:class:`NDF`; NDFs :class:`GGX`, :class:`Beckmann`, :class:`BlinnPhong`; G terms
:class:`SmithGGXCorrelated`, :class:`SmithGGX`, :class:`SchlickGGXIBL`, :class:`SchlickGGXDirect`,
:class:`SchlickBeckmann`, :class:`SmithBeckmannCorrelated`; Fresnel :class:`Schlick`, :class:`NoFresnel`.

References
----------
[Walter07]  B. Walter et al., "Microfacet Models for Refraction through Rough Surfaces", EGSR 2007.
[Heitz14]   E. Heitz, "Understanding the Masking-Shadowing Function in Microfacet-Based BRDFs", JCGT 3(2), 2014.
[Karis13]   B. Karis, "Real Shading in Unreal Engine 4", SIGGRAPH 2013 course notes.
[Schlick94] C. Schlick, "An Inexpensive BRDF Model for Physically-based Rendering", CGF 13(3), 1994.
[NR92]      W. Press et al., "Numerical Recipes in C", 2nd ed., sec. 6.2, erfcc.
"""

from __future__ import annotations

import math

import numpy as np

# Smallest alpha the term functions evaluate with. alpha = 0 is a delta distribution that no
# function can evaluate; renderers treat roughness 0 as a perfect mirror explicitly. 1e-7 keeps
# alpha^2 = 1e-14 well inside float32's normal range and D_GGX(1) = 1/(pi alpha^2) finite (3e13).
MIN_ALPHA = 1e-7
# Guard for divisions by cosines that reach 0 at grazing angles (n.v, n.l -> 0).
COS_EPS = 1e-8

PI = np.pi

#: Numerical Recipes' erfcc Chebyshev fit [NR92]: ``erfc(z) = t exp(-z^2 + P(t))``, ``t = 1 / (1 + z/2)``,
#: ``P`` of these coefficients (lowest degree first); fractional error below 1.2e-7. The one fit of
#: the project: numpy and Dr.Jit evaluate it by :func:`erfcx_fit`, ``brdf.glsl``'s ``erfcx_nr`` holds
#: the same numbers (``tests/test_realtime_glsl.py`` reads them from the shader).
ERFCC_COEFFS = (-1.26551223, 1.00002368, 0.37409196, 0.09678418, -0.18628806, 0.27886807, -1.13520398,
                1.48851587, -0.82215223, 0.17087277)


def erfcx_fit(z, exp):
    """``exp(z^2) erfc(z)`` for ``z >= 0`` by :data:`ERFCC_COEFFS` without the fit's ``exp(-z^2)``
    factor, Horner's scheme innermost first; ``exp`` the array library's (``np.exp``, ``dr.exp``), so
    numpy and Dr.Jit evaluate the same operations. Finite for every z (1 / (z sqrt(pi)) asymptotically)."""
    t = 1.0 / (1.0 + 0.5 * z)
    p = ERFCC_COEFFS[-1]
    for c in ERFCC_COEFFS[-2::-1]:
        p = c + t * p
    return t * exp(p)


def erfcx_nr(z):
    """:func:`erfcx_fit` in float64 for ``z`` clamped to ``>= 0``: the GLSL twin's erfc (GLSL has
    none); checked against ``math.erfc``."""
    return erfcx_fit(np.maximum(np.asarray(z, dtype=np.float64), 0.0), np.exp)


def alpha_from_roughness(roughness):
    """alpha = roughness^2 ([Karis13] p. 3: perceptually linear roughness), clamped to MIN_ALPHA."""
    r = np.asarray(roughness, dtype=np.float64)
    return np.maximum(r * r, MIN_ALPHA)


def k_schlick_ibl(roughness):
    """[Karis13] eq. 4 footnote, image-based lighting: ``k = alpha / 2``."""
    return alpha_from_roughness(roughness) / 2.0


def k_schlick_direct(roughness):
    """[Karis13] eq. 4, analytic lights ("Disney's remapping"): ``k = (roughness + 1)^2 / 8``."""
    r = np.asarray(roughness, dtype=np.float64)
    return (r + 1.0) ** 2 / 8.0


def blinn_phong_exponent(alpha):
    """Phong exponent equivalent to a Beckmann alpha, [Walter07] sec. 5.2: ``n = 2 / alpha^2 - 2``."""
    a2 = np.maximum(np.asarray(alpha, dtype=np.float64), MIN_ALPHA) ** 2
    return np.maximum(2.0 / a2 - 2.0, 0.0)


def _alpha2(alpha):
    return np.maximum(np.asarray(alpha, dtype=np.float64), MIN_ALPHA) ** 2


def _dir(ct, st, phi):
    return np.stack([st * np.cos(phi), st * np.sin(phi), ct], axis=-1)


class Term:
    """A term: its GLSL function's name (``glsl``), and its width of the perceptual roughness in numpy
    (``width``) and GLSL (``glsl_width``, the same name); Fresnel terms have no width (None, "")."""

    glsl = ""
    glsl_width = "alpha_from_roughness"
    width = staticmethod(alpha_from_roughness)


class NDF(Term):
    """An NDF, normalized so that ``int D(h) (n.h) dw_h = 1``. Subclasses define ``eval``,
    ``sample``, ``theta_h``, ``cdf_theta_h`` (and ``Lambda`` where the NDF has a Smith Lambda)."""

    glsl_sample = ""
    Lambda = None

    @classmethod
    def pdf(cls, NoH, alpha):
        """Density of :meth:`sample`'s half vectors: ``D(h) (n.h)``."""
        return cls.eval(NoH, alpha) * np.clip(np.asarray(NoH, dtype=np.float64), 0.0, 1.0)


class GGX(NDF):
    """GGX / Trowbridge-Reitz."""

    glsl, glsl_sample = "D_GGX", "sample_GGX"

    @staticmethod
    def eval(NoH, alpha):
        """[Walter07] eq. 33: ``D = alpha^2 / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2)``."""
        NoH = np.asarray(NoH, dtype=np.float64)
        a2 = _alpha2(alpha)
        d = NoH * NoH * (a2 - 1.0) + 1.0
        return np.where(NoH > 0, a2 / (PI * d * d), 0.0)

    @staticmethod
    def Lambda(NoX, alpha):
        """[Heitz14] eq. 72: ``(-1 + sqrt(1 + alpha^2 tan^2)) / 2``, written as
        ``(sqrt(alpha^2 + (1 - alpha^2) c^2) / c - 1) / 2`` which stays accurate as c -> 1."""
        c = np.maximum(np.asarray(NoX, dtype=np.float64), COS_EPS)
        a2 = _alpha2(alpha)
        return 0.5 * (np.sqrt(a2 + (1.0 - a2) * c * c) / c - 1.0)

    @staticmethod
    def sample(u, alpha):
        """[Walter07] eq. 35-36 (Karis's form): ``phi = 2 pi u0``,
        ``cos theta_h = sqrt((1 - u1) / (1 + (alpha^2 - 1) u1))``."""
        u = np.asarray(u, dtype=np.float64)
        a2 = _alpha2(alpha)
        den = np.maximum(1.0 + (a2 - 1.0) * u[..., 1], COS_EPS)
        ct = np.sqrt(np.clip((1.0 - u[..., 1]) / den, 0.0, 1.0))
        st = np.sqrt(np.clip(a2 * u[..., 1] / den, 0.0, 1.0))
        return _dir(ct, st, 2 * np.pi * u[..., 0])

    @staticmethod
    def theta_h(u, a):
        """[Walter07] eq. 35: the inverse CDF of ``D cos(theta_h)`` in theta_h."""
        return np.arctan(a * np.sqrt(u / (1.0 - u)))

    @staticmethod
    def cdf_theta_h(theta, a):
        """The CDF of ``D cos(theta_h)`` at theta_h < pi/2: ``t / (1 + t)``, ``t = tan^2 / alpha^2``."""
        t2 = np.tan(theta) ** 2 / (a * a)
        return t2 / (1.0 + t2)


_erfc = np.vectorize(math.erfc, otypes=[np.float64])


class Beckmann(NDF):
    """Beckmann."""

    glsl, glsl_sample = "D_Beckmann", "sample_Beckmann"

    @staticmethod
    def eval(NoH, alpha):
        """[Walter07] eq. 25: ``D = exp(-tan^2(theta_h) / alpha^2) / (pi alpha^2 cos^4(theta_h))``."""
        NoH = np.asarray(NoH, dtype=np.float64)
        a2 = _alpha2(alpha)
        c2 = np.maximum(NoH * NoH, COS_EPS)
        tan2 = (1.0 - c2) / c2
        with np.errstate(over="ignore", under="ignore"):
            v = np.exp(-tan2 / a2) / (PI * a2 * c2 * c2)
        return np.where(NoH > 0, v, 0.0)

    @staticmethod
    def Lambda(NoX, alpha):
        """[Heitz14] eq. 80 ([Walter07] eq. 27 before its rational fit):
        ``Lambda = (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi))`` with ``a = c / (alpha sqrt(1 - c^2))``;
        written ``(exp(-a^2) / (a sqrt(pi)) - erfc(a)) / 2`` (exact erfc, float64). 0 at c = 1."""
        c = np.clip(np.asarray(NoX, dtype=np.float64), COS_EPS, 1.0)
        al = np.maximum(np.asarray(alpha, dtype=np.float64), MIN_ALPHA)
        with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
            a = np.minimum(c / (al * np.sqrt(np.maximum(1.0 - c * c, 0.0))), 1e15)
            lam = 0.5 * (np.exp(-a * a) / (a * np.sqrt(PI)) - _erfc(a))
        return np.maximum(lam, 0.0)

    @staticmethod
    def sample(u, alpha):
        """[Walter07] eq. 28: ``tan^2 theta_h = -alpha^2 log(1 - u1)``."""
        u = np.asarray(u, dtype=np.float64)
        t2 = -_alpha2(alpha) * np.log(np.maximum(1.0 - u[..., 1], 1e-12))
        ct = 1.0 / np.sqrt(1.0 + t2)
        return _dir(ct, np.sqrt(t2) * ct, 2 * np.pi * u[..., 0])

    @staticmethod
    def theta_h(u, a):
        """[Walter07] eq. 28: ``tan^2 theta_h = -alpha^2 log(1 - u)``."""
        return np.arctan(np.sqrt(-a * a * np.log1p(-u)))

    @staticmethod
    def cdf_theta_h(theta, a):
        """``1 - exp(-tan^2 / alpha^2)``."""
        return -np.expm1(-np.tan(theta) ** 2 / (a * a))


class BlinnPhong(NDF):
    """Normalized Blinn-Phong with ``n = 2 / alpha^2 - 2`` (alpha = 1 is the uniform D = 1/pi)."""

    glsl, glsl_sample = "D_BlinnPhong", "sample_BlinnPhong"

    @staticmethod
    def eval(NoH, alpha):
        """[Walter07] eq. 30: ``D = (n + 2) / (2 pi) (n.h)^n``."""
        NoH = np.asarray(NoH, dtype=np.float64)
        n = blinn_phong_exponent(alpha)
        with np.errstate(under="ignore"):
            v = (n + 2.0) / (2.0 * PI) * np.power(np.clip(NoH, 0.0, 1.0), n)
        return np.where(NoH > 0, v, 0.0)

    @staticmethod
    def sample(u, alpha):
        """[Walter07] sec. 5.2: ``cos theta_h = (1 - u1)^(1/(n+2))``."""
        u = np.asarray(u, dtype=np.float64)
        n = blinn_phong_exponent(alpha)
        ct = np.power(np.maximum(1.0 - u[..., 1], 1e-12), 1.0 / (n + 2.0))
        return _dir(ct, np.sqrt(np.maximum(1.0 - ct * ct, 0.0)), 2 * np.pi * u[..., 0])

    @staticmethod
    def theta_h(u, a):
        """pdf ``cos^(n+1) sin``: ``cos theta_h = (1 - u)^(1 / (n + 2))``."""
        n = float(blinn_phong_exponent(a))
        return np.arccos(np.power(1.0 - u, 1.0 / (n + 2.0)))

    @staticmethod
    def cdf_theta_h(theta, a):
        """``1 - cos^(n+2)``."""
        return 1.0 - np.cos(theta) ** (float(blinn_phong_exponent(a)) + 2.0)


# ---- geometry (masking-shadowing) terms G(l, v), each in [0, 1] -----------------------------------

def G1_SmithGGX(NoX, alpha):
    """Smith masking of GGX, [Heitz14] eq. 43 with eq. 72: ``G1 = 1 / (1 + Lambda) =
    2 c / (c + sqrt(alpha^2 + (1 - alpha^2) c^2))``."""
    c = np.clip(np.asarray(NoX, dtype=np.float64), 0.0, 1.0)
    a2 = _alpha2(alpha)
    return 2.0 * c / np.maximum(c + np.sqrt(a2 + (1.0 - a2) * c * c), COS_EPS)


def G1_SchlickGGX(NoX, k):
    """Schlick's approximation of Smith G1, [Schlick94] eq. 19 with [Karis13]'s k:
    ``G1 = c / (c (1 - k) + k)``."""
    c = np.clip(np.asarray(NoX, dtype=np.float64), 0.0, 1.0)
    k = np.asarray(k, dtype=np.float64)
    return c / np.maximum(c * (1.0 - k) + k, COS_EPS)


class SmithGGXCorrelated(Term):
    glsl = "G_SmithGGXCorrelated"

    @staticmethod
    def eval(NoV, NoL, alpha):
        """Height-correlated Smith, [Heitz14] eq. 99: ``G = 1 / (1 + Lambda(v) + Lambda(l))``, i.e.
        ``2 (n.v)(n.l) / ((n.l) sqrt(a2 + (1-a2)(n.v)^2) + (n.v) sqrt(a2 + (1-a2)(n.l)^2))``.
        The guard keeps 0/0 at n.v = n.l = 0 at 0."""
        v = np.clip(np.asarray(NoV, dtype=np.float64), 0.0, 1.0)
        l = np.clip(np.asarray(NoL, dtype=np.float64), 0.0, 1.0)
        a2 = _alpha2(alpha)
        den = l * np.sqrt(a2 + (1.0 - a2) * v * v) + v * np.sqrt(a2 + (1.0 - a2) * l * l)
        return 2.0 * v * l / np.maximum(den, COS_EPS)


class SmithGGX(Term):
    glsl = "G_SmithGGX"

    @staticmethod
    def eval(NoV, NoL, alpha):
        """Separable Smith, [Heitz14] eq. 98: ``G1(v) G1(l)`` (Mitsuba's ``roughconductor``)."""
        return G1_SmithGGX(NoV, alpha) * G1_SmithGGX(NoL, alpha)


class SchlickGGXIBL(Term):
    """Schlick-GGX at [Karis13]'s image-based k = alpha / 2."""

    glsl, glsl_width = "G_SchlickGGX", "k_schlick_ibl"
    width = staticmethod(k_schlick_ibl)

    @staticmethod
    def eval(NoV, NoL, k):
        """Separable Schlick-GGX: ``G1_SchlickGGX(v, k) G1_SchlickGGX(l, k)``."""
        return G1_SchlickGGX(NoV, k) * G1_SchlickGGX(NoL, k)


class SchlickGGXDirect(SchlickGGXIBL):
    """Schlick-GGX at [Karis13]'s analytic-light k = (roughness + 1)^2 / 8 (the same function)."""

    glsl_width = "k_schlick_direct"
    width = staticmethod(k_schlick_direct)


class SchlickBeckmann(Term):
    glsl = "G_SchlickBeckmann"

    @staticmethod
    def eval(NoV, NoL, alpha):
        """Schlick's approximation of Smith-Beckmann (article 001's catalogue):
        ``k = alpha sqrt(2 / pi)``, ``G = G1_SchlickGGX(v, k) G1_SchlickGGX(l, k)``."""
        k = np.maximum(np.asarray(alpha, dtype=np.float64), MIN_ALPHA) * np.sqrt(2.0 / PI)
        return G1_SchlickGGX(NoV, k) * G1_SchlickGGX(NoL, k)


class SmithBeckmannCorrelated(Term):
    glsl = "G_SmithBeckmannCorrelated"

    @staticmethod
    def eval(NoV, NoL, alpha):
        """Height-correlated Smith for Beckmann, [Heitz14] eq. 99 with eq. 80:
        ``G = 1 / (1 + Lambda(v) + Lambda(l))``; 0 at n.v = 0 or n.l = 0. The first bounce of the
        Beckmann random walk (reference/multiscatter.py)."""
        v = np.clip(np.asarray(NoV, dtype=np.float64), 0.0, 1.0)
        l = np.clip(np.asarray(NoL, dtype=np.float64), 0.0, 1.0)
        g = 1.0 / (1.0 + Beckmann.Lambda(v, alpha) + Beckmann.Lambda(l, alpha))
        return np.where((v > 0) & (l > 0), g, 0.0)


# ---- Fresnel ------------------------------------------------------------------------------------

class Schlick(Term):
    glsl, glsl_width, width = "F_Schlick", "", None

    @staticmethod
    def eval(VoH, F0, F90=1.0):
        """[Schlick94] eq. 15: ``F = F0 + (F90 - F0) (1 - v.h)^5``. Broadcasts F0 (e.g. RGB in a
        trailing axis: pass ``VoH[..., None]``)."""
        c = np.clip(np.asarray(VoH, dtype=np.float64), 0.0, 1.0)
        f = (1.0 - c) ** 5
        return np.asarray(F0, dtype=np.float64) + (np.asarray(F90, dtype=np.float64) - F0) * f


class NoFresnel(Term):
    glsl, glsl_width, width = "F_None", "", None

    @staticmethod
    def eval(VoH, F0):
        """No Fresnel factor: ``F = 1``, broadcast to the shapes of ``VoH`` and ``F0``."""
        return np.ones(np.broadcast_shapes(np.shape(VoH), np.shape(F0)))
