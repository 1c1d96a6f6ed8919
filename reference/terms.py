"""The microfacet BRDF's terms in Dr.Jit, one class per term (pbrt-v4's shape): the twins of
:mod:`pbrcheck.terms`' numpy classes of the same names, shared by the BSDF (:mod:`reference.bsdf`)
and the random walk (:mod:`reference.multiscatter`), so both evaluate the very same functions.
Local shading frame, ``n = +Z``; cosines clamped by the caller to [0, 1].

An NDF class holds ``eval`` (D of the local half vector), the BSDF's half-vector sampler ``sample``
and its density ``pdf`` (GGX: visible normals [Heitz18]; the others ``D (n.h)`` [Walter07]),
``sample_cos`` (``D (n.h)`` in GLSL's ``u`` order: the twin of ``sampling.glsl``'s sampler) and,
where the random walk is defined for it, the signed ``Lambda`` of any direction and
``sample_visible``, the normals visible from any direction [Heitz16]. A geometry class holds ``eval``
and its ``width(roughness, alpha)``; a Fresnel class ``eval``. :data:`NDFS`, :data:`GEOMETRIES`,
:data:`FRESNELS` are the reference's registries: the Dr.Jit class of each member of
:mod:`pbrcheck.registry`'s list of the same name (``tests/test_registry.py`` checks that they key the
same members with classes of the numpy class's name). The NDFs are written in their numerically
stable forms (identical functions): with ``s = h.x^2 + h.y^2 = sin^2(theta_h)``,

* GGX = 1 / (pi a^2 (s / a^2 + h.z^2)^2)           (= a^2 / (pi (h.z^2 (a^2 - 1) + 1)^2))
* Beckmann = exp(-s / (a^2 h.z^2)) / (pi a^2 h.z^4) (tan^2 = s / h.z^2)
* BlinnPhong = (n + 2) / (2 pi) exp(n/2 log1p(-s))  (h.z^n)

so that narrow lobes stay accurate in float32 (1 - cos(theta_h) underflows, sin^2 does not).

API: :data:`INV_PI`, :data:`INV_SQRT_PI`, :func:`erfcx_pos`, :func:`blinn_phong_exponent`,
:func:`G1_SmithGGX`, :func:`G1_SchlickGGX`, the classes :class:`GGX`, :class:`Beckmann`,
:class:`BlinnPhong`, :class:`SmithGGXCorrelated`, :class:`SmithGGX`, :class:`SchlickGGXIBL`,
:class:`SchlickGGXDirect`, :class:`SchlickBeckmann`, :class:`SmithBeckmannCorrelated`,
:class:`Schlick`, :class:`NoFresnel`; :data:`NDFS`, :data:`GEOMETRIES`, :data:`FRESNELS`,
:func:`ndf`, :func:`geometry_term`, :func:`fresnel_term`.
References: [Walter07] Walter et al., "Microfacet Models for Refraction through Rough Surfaces",
EGSR 2007 (eq. 25, 28, 30, 33, 35); [Heitz14] Heitz, "Understanding the Masking-Shadowing Function",
JCGT 2014 (eq. 43, 72, 80, 98, 99); [Heitz16] Heitz et al., "Multiple-Scattering Microfacet BSDFs
with the Smith Model", SIGGRAPH 2016 (eq. 12); [Heitz18] Heitz, "Sampling the GGX Distribution of
Visible Normals", JCGT 2018 (listing 1, eq. 3); [HdE14] Heitz, d'Eon, "Importance Sampling
Microfacet-Based BSDFs using the Distribution of Visible Normals", EGSR 2014; [Karis13] (eq. 4);
[Schlick94] Schlick, CGF 1994 (eq. 15, 19).
"""

from __future__ import annotations

import math

import pbrcheck  # noqa: F401  (sets DRJIT_LIBLLVM_PATH before drjit loads)
from pbrcheck.brdf import COS_EPS, MIN_ALPHA
from pbrcheck.terms import erfcx_fit

import drjit as dr
import mitsuba as mi

INV_PI = 1.0 / math.pi
INV_SQRT_PI = 1.0 / math.sqrt(math.pi)

#: Bisection steps of the Beckmann visible-slope inversion (bracket <= 14 wide: 14 / 2^30 is below
#: float32's resolution there).
VNDF_BISECTION_STEPS = 30
#: Clamp of cot(theta) in the Beckmann visible-slope sampler (reference.multiscatter's docstring).
VNDF_COT_MIN = -8.0
VNDF_COT_MAX = 6.0
#: Width of the Beckmann slope bracket below min(cot theta, 0): exp(-36) of the mass lies beyond.
VNDF_SLOPE_SPAN = 6.0


def erfcx_pos(z):
    """``exp(z^2) erfc(z)`` for ``z >= 0``: :func:`pbrcheck.terms.erfcx_fit` (the project's one erfc fit)
    in float32; fractional error below 1.2e-7."""
    return erfcx_fit(z, dr.exp)


def _log1p_neg(s):
    """log(1 - s) for s in [0, 1], accurate for small s (series below 1e-2: error < s^5/5)."""
    series = -s * (1.0 + s * (0.5 + s * (1.0 / 3.0 + s * 0.25)))
    return dr.select(s < 1e-2, series, dr.log(dr.maximum(1.0 - s, 1e-30)))


def _neg_expm1(x):
    """1 - exp(x) for x <= 0, accurate for small |x|."""
    series = -x * (1.0 + x * (0.5 + x * (1.0 / 6.0 + x / 24.0)))
    return dr.select(x > -1e-2, series, 1.0 - dr.exp(x))


def blinn_phong_exponent(alpha):
    """[Walter07] sec. 5.2: n = 2 / alpha^2 - 2."""
    return dr.maximum(2.0 / (alpha * alpha) - 2.0, 0.0)


def _h_from_theta(cos_t, sin_t, u):
    phi = 2.0 * dr.pi * u.y
    return mi.Vector3f(sin_t * dr.cos(phi), sin_t * dr.sin(phi), cos_t)


def _ggx_visible(v, u1, u2, alpha, lensq_min, z_min):
    """A GGX normal visible from ``v`` [Heitz18 listing 1]: stretch, sample the projected hemisphere,
    unstretch. The two callers' guards: the BSDF's ``v`` is above the horizon (``lensq_min = 0``,
    ``z_min = 0``); the walk's any direction (``lensq_min = 1e-14``: a nearly vertical ``v`` takes the
    fixed tangent instead of normalizing a vanishing one; ``z_min = 1e-7``: a normal in the
    plane, m.z = 0, is no microfacet normal: it stays strictly above)."""
    vh = dr.normalize(mi.Vector3f(alpha * v.x, alpha * v.y, v.z))
    lensq = vh.x * vh.x + vh.y * vh.y
    inv = dr.rsqrt(dr.maximum(lensq, 1e-30))
    T1 = dr.select(lensq > lensq_min, mi.Vector3f(-vh.y * inv, vh.x * inv, 0.0), mi.Vector3f(1.0, 0.0, 0.0))
    T2 = dr.cross(vh, T1)
    r = dr.sqrt(u1)
    phi = 2.0 * dr.pi * u2
    t1 = r * dr.cos(phi)
    t2 = r * dr.sin(phi)
    s = 0.5 * (1.0 + vh.z)
    t2 = (1.0 - s) * dr.sqrt(dr.maximum(1.0 - t1 * t1, 0.0)) + s * t2
    nh = t1 * T1 + t2 * T2 + dr.sqrt(dr.maximum(1.0 - t1 * t1 - t2 * t2, 0.0)) * vh
    return dr.normalize(mi.Vector3f(alpha * nh.x, alpha * nh.y, dr.maximum(nh.z, z_min)))


def G1_SmithGGX(c, alpha):
    """[Heitz14] eq. 43 with eq. 72: ``2 c / (c + sqrt(alpha^2 + (1 - alpha^2) c^2))``."""
    a2 = alpha * alpha
    return 2.0 * c / dr.maximum(c + dr.sqrt(a2 + (1.0 - a2) * c * c), COS_EPS)


def G1_SchlickGGX(c, k):
    """[Schlick94] eq. 19: ``c / (c (1 - k) + k)``."""
    return c / dr.maximum(c * (1.0 - k) + k, COS_EPS)


# ---- NDFs ---------------------------------------------------------------------------------------

class GGX:
    @staticmethod
    def eval(h, alpha):
        """[Walter07] eq. 33 in its stable form (module docstring)."""
        a2 = alpha * alpha
        s = h.x * h.x + h.y * h.y
        t = s / a2 + h.z * h.z
        return dr.select(h.z > 0, INV_PI / (a2 * t * t), 0.0)

    @staticmethod
    def Lambda(w, alpha):
        """Signed Smith Lambda for any direction ``w`` [Heitz16 eq. 12]:
        ``(-1 + sign(z) sqrt(z^2 + alpha^2 (x^2 + y^2)) / |z|) / 2``; huge (+-) near the horizon."""
        z = w.z
        s2 = dr.maximum(w.x * w.x + w.y * w.y, 0.0)
        r = dr.sqrt(z * z + alpha * alpha * s2) / dr.maximum(dr.abs(z), 1e-20)
        return 0.5 * (-1.0 + dr.select(z >= 0, r, -r))

    @staticmethod
    def sample(wi, u, alpha):
        """Visible normals seen from ``wi`` (upper hemisphere) [Heitz18 listing 1]."""
        return _ggx_visible(wi, u.x, u.y, alpha, 0.0, 0.0)

    @classmethod
    def pdf(cls, wi, h, alpha):
        """[Heitz18] eq. 2/3: D_v(h) = G1(v) max(0, v.h) D(h) / (n.v)."""
        return G1_SmithGGX(dr.clip(wi.z, 0, 1), alpha) * dr.maximum(dr.dot(wi, h), 0.0) * cls.eval(h, alpha) \
            / dr.maximum(wi.z, COS_EPS)

    @staticmethod
    def sample_visible(v, u1, u2, alpha):
        """A normal visible from ``v``, any sign of ``v.z`` [Heitz18 listing 1] (the walk's)."""
        return _ggx_visible(v, u1, u2, alpha, 1e-14, 1e-7)

    @staticmethod
    def sample_cos(u, alpha):
        """[Walter07] eq. 35-36 in Karis's form: ``cos theta_h = sqrt((1 - u.y) / (1 + (a^2 - 1) u.y))``."""
        a2 = dr.square(dr.maximum(alpha, MIN_ALPHA))
        den = dr.maximum(1.0 + (a2 - 1.0) * u.y, COS_EPS)
        ct = dr.sqrt(dr.clip((1.0 - u.y) / den, 0.0, 1.0))
        st = dr.sqrt(dr.clip(a2 * u.y / den, 0.0, 1.0))
        phi = 2.0 * dr.pi * u.x
        return mi.Vector3f(st * dr.cos(phi), st * dr.sin(phi), ct)


class _DCosSampled:
    """An NDF whose BSDF sampler draws ``D (n.h)`` (density ``D (n.h)``, any ``wi``)."""

    @classmethod
    def pdf(cls, wi, h, alpha):
        return cls.eval(h, alpha) * dr.maximum(h.z, 0.0)

    @classmethod
    def sample_cos(cls, u, alpha):
        """:meth:`sample` in GLSL's ``u`` order (``u.x`` the azimuth)."""
        return cls.sample(None, mi.Point2f(u.y, u.x), cls.clamp(alpha))


class Beckmann(_DCosSampled):
    @staticmethod
    def eval(h, alpha):
        """[Walter07] eq. 25 in its stable form (module docstring). The guard: ``c2 = max(h.z^2,
        COS_EPS)`` keeps the denominator ``a2 c2^2 >= MIN_ALPHA^2 COS_EPS^2 = 1e-30`` a normal float32
        (a guard of 1e-30 on ``h.z^2`` gave ``1e-60 -> 0`` and ``0 / 0 = NaN`` for a normal in the
        plane), and changes no value: below ``h.z = 1e-4``, ``tan^2 > 1e8`` and ``exp(-tan^2 /
        alpha^2)`` is 0 in float32 for every alpha <= 1."""
        a2 = alpha * alpha
        s = h.x * h.x + h.y * h.y
        c2 = dr.maximum(h.z * h.z, COS_EPS)
        return dr.select(h.z > 0, dr.exp(-s / (a2 * c2)) * INV_PI / (a2 * c2 * c2), 0.0)

    @staticmethod
    def lambda_a(a):
        """Smith Lambda of the signed ``a = cot(theta) / alpha`` [Heitz14 eq. 80, Heitz16 eq. 12]:
        ``exp(-a^2) (1/(a sqrt(pi)) - erfcx(a)) / 2`` for ``a > 0``, ``-1 - Lambda(-a)`` below."""
        b = dr.clip(dr.abs(a), 1e-20, 1e15)
        up = dr.maximum(0.5 * dr.exp(-b * b) * (INV_SQRT_PI / b - erfcx_pos(b)), 0.0)
        return dr.select(a >= 0, up, -1.0 - up)

    @classmethod
    def Lambda(cls, w, alpha):
        """Signed Smith Lambda for any direction ``w``; 0 straight up, -1 straight down."""
        s = dr.sqrt(dr.maximum(w.x * w.x + w.y * w.y, 0.0))
        return cls.lambda_a(w.z / dr.maximum(alpha * s, 1e-30))

    @classmethod
    def Lambda_cos(cls, c, alpha):
        """Lambda of the cosine ``c`` in [0, 1] (the geometry term's)."""
        s = dr.sqrt(dr.maximum(1.0 - c * c, 0.0))
        return cls.lambda_a(dr.maximum(c, COS_EPS) / dr.maximum(alpha * s, 1e-30))

    @staticmethod
    def clamp(alpha):
        return dr.maximum(alpha, MIN_ALPHA)

    @staticmethod
    def sample(wi, u, alpha):
        """[Walter07] eq. 28: tan^2 theta = -alpha^2 log(1 - u), density D (n.h)."""
        t2 = -alpha * alpha * _log1p_neg(u.x)
        cos_t = dr.rsqrt(1.0 + t2)
        return _h_from_theta(cos_t, dr.sqrt(t2) * cos_t, u)

    @staticmethod
    def _log_slope_cdf(x, c, s):
        """``log(2 F(x))`` of the visible-slope CDF (reference.multiscatter's docstring) at ``x``."""
        neg = -x * x + dr.log(dr.maximum(c * erfcx_pos(dr.maximum(-x, 0.0)) + s * INV_SQRT_PI, 1e-30))
        pos = dr.log(dr.maximum(c * (1.0 + dr.erf(x)) + s * dr.exp(-x * x) * INV_SQRT_PI, 1e-30))
        return dr.select(x < 0, neg, pos)

    @classmethod
    def sample_visible(cls, v, u1, u2, alpha):
        """A normal visible from ``v``, any sign of ``v.z`` [HdE14]: the slope inversion of
        reference.multiscatter's docstring."""
        vs = dr.normalize(mi.Vector3f(alpha * v.x, alpha * v.y, v.z))
        sin_t = dr.sqrt(dr.maximum(vs.x * vs.x + vs.y * vs.y, 0.0))
        cos_t = vs.z
        ok = sin_t > 1e-7
        inv = 1.0 / dr.maximum(sin_t, 1e-7)
        cphi = dr.select(ok, vs.x * inv, 1.0)
        sphi = dr.select(ok, vs.y * inv, 0.0)
        cot = dr.select(ok, cos_t * inv, VNDF_COT_MAX)
        hi = dr.clip(cot, VNDF_COT_MIN, VNDF_COT_MAX)
        lo = dr.minimum(hi, 0.0) - VNDF_SLOPE_SPAN
        target = dr.log(u1) + cls._log_slope_cdf(hi, cos_t, sin_t)
        for _ in range(VNDF_BISECTION_STEPS):  # unrolled: the bracket halves each step
            mid = 0.5 * (lo + hi)
            below = cls._log_slope_cdf(mid, cos_t, sin_t) < target
            lo = dr.select(below, mid, lo)
            hi = dr.select(below, hi, mid)
        x = 0.5 * (lo + hi)
        y = dr.erfinv(2.0 * u2 - 1.0)
        sx = cphi * x - sphi * y
        sy = sphi * x + cphi * y
        return dr.normalize(mi.Vector3f(-alpha * sx, -alpha * sy, 1.0))


class BlinnPhong(_DCosSampled):
    Lambda = sample_visible = None

    @staticmethod
    def eval(h, alpha):
        """[Walter07] eq. 30 in its stable form (module docstring)."""
        n = blinn_phong_exponent(alpha)
        s = dr.clip(h.x * h.x + h.y * h.y, 0.0, 1.0)
        v = (n + 2.0) * (0.5 * INV_PI) * dr.exp(0.5 * n * _log1p_neg(s))
        return dr.select(h.z > 0, v, 0.0)

    @staticmethod
    def clamp(alpha):
        return alpha

    @staticmethod
    def sample(wi, u, alpha):
        """pdf cos^(n+1) sin: cos theta = (1 - u)^(1/(n+2)); sin^2 = 1 - exp(2 log(1-u)/(n+2))."""
        n = blinn_phong_exponent(alpha)
        x = _log1p_neg(u.x) / (n + 2.0)
        return _h_from_theta(dr.exp(x), dr.sqrt(dr.maximum(_neg_expm1(2.0 * x), 0.0)), u)


# ---- geometry terms G(l, v) (cosines clamped to [0, 1]) and their widths of (roughness, alpha) ----

class _AlphaWidth:
    @staticmethod
    def width(roughness, alpha):
        return alpha


class SmithGGXCorrelated(_AlphaWidth):
    @staticmethod
    def eval(NoV, NoL, alpha):
        """[Heitz14] eq. 99."""
        a2 = alpha * alpha
        den = NoL * dr.sqrt(a2 + (1.0 - a2) * NoV * NoV) + NoV * dr.sqrt(a2 + (1.0 - a2) * NoL * NoL)
        return 2.0 * NoV * NoL / dr.maximum(den, COS_EPS)


class SmithGGX(_AlphaWidth):
    @staticmethod
    def eval(NoV, NoL, alpha):
        """[Heitz14] eq. 98."""
        return G1_SmithGGX(NoV, alpha) * G1_SmithGGX(NoL, alpha)


class SchlickGGXIBL:
    @staticmethod
    def eval(NoV, NoL, k):
        return G1_SchlickGGX(NoV, k) * G1_SchlickGGX(NoL, k)

    @staticmethod
    def width(roughness, alpha):
        """[Karis13] eq. 4 footnote: k = alpha / 2."""
        return alpha * 0.5


class SchlickGGXDirect(SchlickGGXIBL):
    @staticmethod
    def width(roughness, alpha):
        """[Karis13] eq. 4: k = (roughness + 1)^2 / 8."""
        return (roughness + 1.0) * (roughness + 1.0) * 0.125


class SchlickBeckmann(_AlphaWidth):
    @staticmethod
    def eval(NoV, NoL, alpha):
        """Schlick's approximation of Smith-Beckmann (article 001's catalogue): k = alpha sqrt(2 / pi)."""
        k = alpha * 0.7978845608
        return G1_SchlickGGX(NoV, k) * G1_SchlickGGX(NoL, k)


class SmithBeckmannCorrelated(_AlphaWidth):
    @staticmethod
    def eval(NoV, NoL, alpha):
        """[Heitz14] eq. 99 with eq. 80 (:meth:`Beckmann.Lambda_cos`); 0 at n.v = 0 or n.l = 0."""
        g = 1.0 / (1.0 + Beckmann.Lambda_cos(NoV, alpha) + Beckmann.Lambda_cos(NoL, alpha))
        return dr.select((NoV > 0) & (NoL > 0), g, 0.0)


# ---- Fresnel ------------------------------------------------------------------------------------

class Schlick:
    @staticmethod
    def eval(c, F0):
        """[Schlick94 eq. 15] at the cosine ``c`` (clamped to [0, 1]): ``F0 + (1 - F0) (1 - c)^5``."""
        c = dr.clip(c, 0.0, 1.0)
        w = dr.square(dr.square(1.0 - c)) * (1.0 - c)
        return F0 + (1.0 - F0) * w


class NoFresnel:
    @staticmethod
    def eval(c, F0):
        """No Fresnel factor: 1 (Color3f)."""
        return mi.Color3f(1.0)


#: The reference's registries, keyed by the members of pbrcheck.registry's list of the same name:
#: each member's Dr.Jit class (``tests/test_registry.py``: the same members, each class named as the
#: member's numpy class).
NDFS = {"ggx": GGX, "beckmann": Beckmann, "blinn_phong": BlinnPhong}
GEOMETRIES = {"smith_ggx_correlated": SmithGGXCorrelated, "smith_ggx": SmithGGX, "schlick_ggx_ibl": SchlickGGXIBL,
              "schlick_ggx_direct": SchlickGGXDirect, "schlick_beckmann": SchlickBeckmann,
              "smith_beckmann_correlated": SmithBeckmannCorrelated}
FRESNELS = {"schlick": Schlick, "none": NoFresnel}


def ndf(name):
    """The Dr.Jit class of the NDF ``name`` (:data:`NDFS`)."""
    return NDFS[name]


def geometry_term(geometry, NoV, NoL, roughness, alpha):
    """The member ``geometry`` of :data:`GEOMETRIES` at its width, cosines clamped to [0, 1]."""
    g = GEOMETRIES[geometry]
    return g.eval(dr.clip(NoV, 0.0, 1.0), dr.clip(NoL, 0.0, 1.0), g.width(roughness, alpha))


def fresnel_term(fresnel, c, F0):
    """The member ``fresnel`` of :data:`FRESNELS`: ``schlick`` or ``none`` (F = 1)."""
    return FRESNELS[fresnel].eval(c, F0)
