"""Multiple-scattering GGX and Beckmann microfacet reflection: the random walk of Heitz et al. 2016.

``[brdf] multiscatter = "random_walk"`` replaces the material's specular lobe (single scattering,
``D G2 F / (4 n.l n.v)`` with the height-correlated Smith G2) by the full multiple-scattering
microfacet BSDF of the same Smith microsurface [Heitz16]: a ray enters the microsurface, bounces
on microfacets (each bounce a reflection about a visible normal, weighted by the Schlick Fresnel
of that bounce) until it leaves. The diffuse term is unchanged. Used by :mod:`reference.bsdf`
through two hooks (:func:`eval_pdf_hook`, :func:`sample_hook`) and, under the glTF lobes, by
:mod:`reference.lobe_bsdf` (:func:`walk_eval` with the dielectric's Schlick ``F90``:
KHR_materials_specular); all the walk's maths is here.

The walk [Heitz16, sec. 4 and 5, algorithms 1-3]
------------------------------------------------
NDFs: GGX and Beckmann, each with its own height-correlated Smith term as the first bounce
(:data:`pbrcheck.registry.MULTISCATTER_GEOMETRY`: ``smith_ggx_correlated``,
``smith_beckmann_correlated``). The walk only needs the NDF's ``Lambda`` (both signs of ``w.z``),
``D`` and a sampler of visible normals for any direction (:data:`WALK_NDFS`: the NDF's Dr.Jit class of
:mod:`reference.terms`, its ``Lambda``, ``eval`` and ``sample_visible``); everything else is shared.

Heights: any height distribution gives the same BSDF [Heitz16 sec. 4.2]; we take the uniform one on
[-1, 1] and track ``L = log C1(h)`` (``C1`` its CDF, ``L`` in (-inf, 0], 0 above the surface) so
that deep walks do not underflow. ``Lambda`` is Smith's GGX Lambda extended to downward directions
by ``Lambda(-w) = -1 - Lambda(w)`` [Heitz16 eq. 12]::

    Lambda(w) = (-1 + sign(w.z) sqrt(1 + alpha^2 tan^2 theta)) / 2

Beckmann's [Heitz14 eq. 80, Walter07 eq. 27] with ``a = 1 / (alpha tan theta)`` (signed with w.z)::

    Lambda(a) = (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi))
              = exp(-a^2) (1 / (a sqrt(pi)) - erfcx(a)) / 2      (a > 0; erfcx(a) = exp(a^2) erfc(a))

which satisfies ``Lambda(-a) = -1 - Lambda(a)`` as written; the second form (with the scaled
complementary error function of :func:`reference.terms.erfcx_pos`) avoids ``erf(a) - 1`` cancelling for large ``a``.

Next height along a ray of direction ``w`` from log-height ``L`` [Heitz16 eq. 17-18, alg. 2] with
``U`` uniform in (0, 1]: the probability of leaving (``w.z > 0``) is the height-dependent masking
``G1(w, L) = C1^Lambda(w) = exp(Lambda(w) L)``; if ``U < G1(w, L)`` the ray leaves, else it hits
at ``L' = L - log(U) / Lambda(w)`` (always hits when ``w.z < 0``, where ``Lambda < -1``;
``|w.z| < GRAZING_Z`` hits at the same height, as in the paper's code).

At each hit the next direction is the reflection of the incoming ray about a normal drawn from the
distribution of normals visible from ``-w`` [Heitz16 eq. 16; sampled with Heitz 2018's listing 1,
which also holds for directions below the horizon: the visible region of the hemisphere of normals
is then the half-disk minus a half-ellipse, still a column-wise linear image of the disk], and the
path throughput is multiplied by the Fresnel of that bounce ``F(w_in . m)``.

Beckmann's visible normals (:meth:`reference.terms.Beckmann.sample_visible`; Heitz and d'Eon 2014, "Importance Sampling
Microfacet-Based BSDFs using the Distribution of Visible Normals", sec. 4 and appendix): stretch
``v`` by alpha to the alpha = 1 configuration, rotate it into the xz-plane at angle ``theta``, draw
the slopes ``(x, y)``: ``y`` is independent of ``v`` (a Gaussian, ``y = erfinv(2 u - 1)``) and ``x``
has the density ``(cos theta - x sin theta) exp(-x^2) / sqrt(pi)`` on ``x < cot theta`` (the normal
``(-x, -y, 1)`` must face ``v``), whose unnormalised CDF is::

    F(x) = (cos theta (1 + erf x) + sin theta exp(-x^2) / sqrt(pi)) / 2,   F(cot theta) = A(v),

valid for both signs of ``cos theta`` (directions below the horizon: ``cot theta < 0``). ``x``
solves ``F(x) = u F(cot theta)`` by :data:`reference.terms.VNDF_BISECTION_STEPS` bisection steps on ``log F`` (for
``x < 0`` written ``-x^2 + log(cos theta erfcx(-x) + sin theta / sqrt(pi))``, free of underflow);
``cot theta`` is clamped to [``VNDF_COT_MIN``, ``VNDF_COT_MAX``] of :mod:`reference.terms` (outside it the dropped
mass is below 1e-17 for the upper end; the lower end only concerns rays within 7 degrees of straight
up that still hit the microsurface, a vanishing fraction of walks). Rotate the slopes back, unstretch
by alpha, ``m = normalize(-x, -y, 1)``.

* ``sample``: the walk itself; the exit direction and the throughput (product of Fresnels) are an
  exact sample of ``f cos / pdf`` [Heitz16 alg. 3 with Fresnel, sec. 5.2].
* ``eval`` (``f cos``): the unbiased stochastic estimator of [Heitz16 sec. 5.3 / alg. 4]: along a
  walk from ``wi``, at every hit of order ``k`` add the next-event estimate
  ``throughput F(-w . h) p(-w -> wo) G1(wo, L)`` with the phase function
  ``p(wi -> wo) = D_wi(h) / (4 wi.h) = D(h) / (4 A(wi))`` (``h = normalize(wi + wo)``,
  ``A(wi) = wi.z (1 + Lambda(wi))`` the projected area). Its order-1 expectation is exactly the
  single-scattering term ``D F / (4 n.v (1 + Lambda(v) + Lambda(l)))`` = the existing lobe with the
  height-correlated G2 [Heitz14 eq. 99], so :func:`eval_pdf_hook` adds the analytic order 1 (no
  noise) and the walk's orders >= 2 (``min_order = 2``).
* ``pdf``: not available in closed form for the walk. ``pdf`` returns a documented approximation,
  ``(1 - m) pdf_ss + m cos / pi`` with ``pdf_ss`` the single-scattering VNDF density and
  ``m = MS_PDF_WEIGHT alpha`` (a cosine lobe for the multiply-scattered energy, which is broad and
  grows with alpha). It is used only for multiple importance sampling weights: the integrator
  computes both MIS weights of a direction with the same ``pdf`` function, so they still sum to one,
  and each strategy's estimate stays unbiased (``sample``'s weight is an unbiased ``f cos / pdf``
  for any test function, ``eval`` an unbiased ``f cos``): only the variance depends on the
  approximation.

Lobe choice in ``sample``: the specular walk with probability ``P_spec`` (the BSDF's), weight
``throughput / P_spec``; else the cosine-sampled diffuse lobe, weight
``(1 - F(v.h)) (1 - metallic) base_color / (1 - P_spec)``. (The single-scattering BSDF's sample uses
the one-sample mixture ``f cos / pdf_mix``; the walk's density is unknown, so here each lobe's
weight is its own.)

Random numbers: a stateless integer hash ([Wellons18] "lowbias32"): the walk's state starts at a
per-query key and is re-hashed at every bounce; each bounce's three numbers hash the state with
three constants. ``eval``'s key hashes the bits of ``wi``, ``wo`` and the BSDF's
``seed``; ``sample``'s hashes the bits of ``wi``, the sampler's ``sample1``/``sample2`` and ``seed``.
Renders are therefore reproducible for a given render seed (the sampler's numbers differ per seed).

Roughness below the BSDF's delta threshold (``alpha < DELTA_LOBE_ALPHA``): the mirror limit, where
the multiply scattered energy vanishes (it scales with the fraction of the surface seen at grazing
slopes, ~alpha), so the delta lobe is kept as it is (single scattering, no walk).

Differentiation: the walk runs on detached parameters (a symbolic loop with per-lane lengths is not
reverse-differentiable in Dr.Jit); the analytic single-scattering part keeps its gradients, so
``random_walk`` gradients miss the derivative of the multiply scattered energy (documented in
docs/reference.md).

The walk is capped at ``MAX_SCATTERING_ORDER`` bounces; the energy still inside after the cap is
dropped (at alpha = 1, F0 = 1 and n.v = 0.05 it is below 1e-4 of the albedo: measured by
``tests/test_multiscatter.py``).

API
---
:data:`WALK_NDFS`, :data:`WALK_GEOMETRY`, :func:`walk_sample`,
:func:`walk_eval`, :func:`query_key`, :func:`approx_spec_pdf`, :func:`eval_pdf_hook`,
:func:`sample_hook`, :func:`check_model`.

References
----------
[Heitz16]  E. Heitz, J. Hanika, E. d'Eon, C. Dachsbacher, "Multiple-Scattering Microfacet BSDFs
           with the Smith Model", ACM TOG 35(4) (SIGGRAPH 2016).
[Heitz14]  E. Heitz, "Understanding the Masking-Shadowing Function in Microfacet-Based BRDFs",
           JCGT 3(2), 2014.
[Heitz18]  E. Heitz, "Sampling the GGX Distribution of Visible Normals", JCGT 7(4), 2018.
[HdE14]    E. Heitz, E. d'Eon, "Importance Sampling Microfacet-Based BSDFs using the Distribution of
           Visible Normals", EGSR 2014 (Computer Graphics Forum 33(4)).
[Walter07] B. Walter et al., "Microfacet Models for Refraction through Rough Surfaces", EGSR 2007.
[NR92]     W. Press et al., "Numerical Recipes in C", 2nd ed., sec. 6.2, erfcc (Chebyshev fit,
           fractional error below 1.2e-7 everywhere).
[Wellons18] C. Wellons, "Prospecting for Hash Functions", 2018 (lowbias32 constants).
"""

from __future__ import annotations

import pbrcheck  # noqa: F401  (sets DRJIT_LIBLLVM_PATH before drjit loads)
from pbrcheck.errors import SceneError
from pbrcheck.registry import MULTISCATTER_GEOMETRY

import drjit as dr
import mitsuba as mi

from . import terms
from .terms import INV_PI, fresnel_term

#: Walks longer than this are cut (their remaining energy dropped; see the module docstring).
MAX_SCATTERING_ORDER = 256
#: |w.z| below which a ray is taken as horizontal (hits at its current height) [Heitz16 code].
GRAZING_Z = 1e-4
#: Weight of the cosine lobe in the approximate pdf: m = MS_PDF_WEIGHT alpha (MIS weights only).
MS_PDF_WEIGHT = 0.25
#: The models the walk is defined for: NDF -> its height-correlated Smith term (the first bounce).
WALK_GEOMETRY = MULTISCATTER_GEOMETRY
#: The walk's NDFs: each with its Dr.Jit class (reference.terms), which has the signed ``Lambda`` and
#: ``sample_visible`` of any direction the walk needs.
WALK_NDFS = {name: terms.ndf(name) for name in WALK_GEOMETRY}

_U24 = 1.0 / float(1 << 24)


def check_model(ndf: str, geometry: str, multiscatter: str, *, file: str | None = None) -> None:
    """Raise :class:`pbrcheck.errors.SceneError` naming the field unless ``random_walk`` is used
    with an NDF of :data:`WALK_GEOMETRY` and its height-correlated Smith term (``none`` accepts
    anything)."""
    if multiscatter == "none":
        return
    need = WALK_GEOMETRY.get(ndf)
    if need is None:
        raise SceneError(file, "brdf.ndf", f'one of {", ".join(WALK_GEOMETRY)} with multiscatter = "{multiscatter}" '
                         "(the walk is implemented for these NDFs)", ndf)
    if geometry != need:
        raise SceneError(file, "brdf.geometry", f'"{need}" with ndf = "{ndf}" and multiscatter = "{multiscatter}" '
                         "(the walk's first bounce is the height-correlated Smith term)", geometry)


# ---- random numbers --------------------------------------------------------------------------

def _hash(x):
    """lowbias32 [Wellons18]: a bijective 32-bit integer hash (UInt32 arithmetic wraps)."""
    x = mi.UInt32(x)
    x ^= x >> 16
    x *= 0x7FEB352D
    x ^= x >> 15
    x *= 0x846CA68B
    x ^= x >> 16
    return x


def _unfolded(x, key):
    """``x`` unchanged, as a value the JIT cannot constant-fold (``key == key ^ 1`` is never true,
    but the compiler does not know it). A literal F0 = 1 would otherwise fold the Fresnel product to
    ``energy * 1 = energy`` and the symbolic loop would see its state presumed constant. The other
    branch is ``x + 1``, never ``x`` itself: a literal 0 (F0 = F90 = 0, a specularFactor of 0) would
    fold ``select(c, 0, 0)`` back to the literal."""
    return dr.select(mi.UInt32(key) == (mi.UInt32(key) ^ 1), x + 1.0, x)


def _bits(f):
    return dr.reinterpret_array(mi.UInt32, mi.Float(f))


def query_key(seed: int, *values):
    """Per-lane UInt32 key: the hash chain of ``seed`` and the float bits of ``values``."""
    k = _hash(mi.UInt32(seed & 0xFFFFFFFF) + 0x9E3779B9)
    for v in values:
        k = _hash(k ^ _bits(v))
    return k


def _uniforms(state):
    """(u1, u2, u3, next state): three uniform numbers in (0, 1) (24 bits, never 0 or 1) from the
    walk's hash state, and the state of the next step."""
    us = tuple((mi.Float(_hash(state ^ c) >> 8) + 0.5) * _U24 for c in (0x632BE5AB, 0x85157AF5, 0x2C1B3C6D))
    return (*us, _hash(state + 0x9E3779B9))


def _next_height(w, L, u, alpha, ndf="ggx"):
    """(escaped, L') for a ray of direction ``w`` from log-height ``L`` [Heitz16 alg. 2]."""
    lam = WALK_NDFS[ndf].Lambda(w, alpha)
    horizontal = dr.abs(w.z) < GRAZING_Z
    # Up: leave with probability G1(w, L) = exp(Lambda L) (L = 0 above the surface: always).
    g1 = dr.exp(dr.minimum(lam * L, 0.0))
    escaped = (w.z > 0) & ~horizontal & (u < g1)
    Ln = dr.select(horizontal | (lam == 0), L, L - dr.log(u) / lam)
    return escaped, dr.minimum(Ln, 0.0)


def _phase_shadowed(wi, wo, L, alpha, ndf="ggx"):
    """Next-event estimate without Fresnel: ``p(wi -> wo) G1(wo, L)`` with
    ``p = D(h) / (4 A(wi))``, ``A(wi) = wi.z (1 + Lambda(wi))`` (>= 0 for both signs of wi.z)."""
    h = dr.normalize(wi + wo)
    D = WALK_NDFS[ndf]
    area = wi.z * (1.0 + D.Lambda(wi, alpha))
    p = D.eval(h, alpha) / dr.maximum(4.0 * area, 1e-20)
    lam_o = D.Lambda(wo, alpha)
    shadow = dr.exp(dr.minimum(lam_o * L, 0.0))
    ok = (dr.dot(wi, h) > 0) & (wo.z > 0) & (area > 0)
    return dr.select(ok, p * shadow, 0.0), h


def _bounce_fresnel(fresnel, c, F0, F90):
    """One bounce's Fresnel: the model's term of ``F0`` (``F90`` None), or Schlick's with its ``F90``
    (``KHR_materials_specular``'s dielectric ``f90 = specularFactor``: reference.lobe_bsdf's walk hook)."""
    if F90 is None:
        return fresnel_term(fresnel, c, F0)
    c = dr.clip(c, 0.0, 1.0)
    w = dr.square(dr.square(1.0 - c)) * (1.0 - c)   # terms.Schlick's form: F90 = 1 gives its bits
    return F0 + (F90 - F0) * w


def _detached_f90(F90, key):
    return None if F90 is None else _unfolded(dr.detach(mi.Color3f(F90)), key)


def walk_sample(wi, alpha, F0, key, *, fresnel="schlick", ndf="ggx", F90=None, active=True):
    """Sample the walk from ``wi`` (upper hemisphere, local frame).

    Returns ``(wo, weight, order)``: the exit direction, the throughput (product of the bounces'
    Fresnel; 0 for walks cut at ``MAX_SCATTERING_ORDER``) and the number of bounces (UInt32).
    ``alpha`` Float, ``F0`` Color3f, ``key`` UInt32 from :func:`query_key`, ``ndf`` ggx or beckmann,
    ``F90`` None (the model's Fresnel) or Schlick's ``F90`` (Color3f; ``fresnel`` must be schlick).
    """
    alpha = _unfolded(dr.detach(mi.Float(alpha)), key)
    F0 = _unfolded(dr.detach(mi.Color3f(F0)), key)
    F90 = _detached_f90(F90, key)
    n = dr.width(key)
    wr = -mi.Vector3f(wi)
    L = dr.zeros(mi.Float, n)
    energy = mi.Color3f(dr.full(mi.Float, 1.0, n))
    order = dr.zeros(mi.UInt32, n)
    k = mi.UInt32(key)
    running = mi.Bool(active) & dr.full(mi.Bool, True, n)
    escaped_any = dr.zeros(mi.Bool, n)

    def cond(wr, L, energy, order, k, running, escaped_any):
        return running

    def body(wr, L, energy, order, k, running, escaped_any):
        u1, u2, u3, k = _uniforms(k)
        escaped, L = _next_height(wr, L, u1, alpha, ndf)
        escaped_any = escaped_any | escaped
        running = running & ~escaped
        order = dr.select(running, order + 1, order)
        v = -wr
        m = WALK_NDFS[ndf].sample_visible(v, u2, u3, alpha)
        c = dr.dot(v, m)
        wn = 2.0 * c * m - v
        energy = dr.select(running, energy * _bounce_fresnel(fresnel, c, F0, F90), energy)
        wr = dr.select(running, wn, wr)
        running = running & (order < MAX_SCATTERING_ORDER)
        return wr, L, energy, order, k, running, escaped_any

    wr, L, energy, order, k, running, escaped_any = dr.while_loop(
        (wr, L, energy, order, k, running, escaped_any), cond, body, label="multiscatter_sample")
    ok = escaped_any & (wr.z > 0)
    return wr, dr.select(ok, energy, 0.0), order


def walk_eval(wi, wo, alpha, F0, key, *, fresnel="schlick", min_order=1, max_order=MAX_SCATTERING_ORDER,
              ndf="ggx", F90=None, active=True):
    """Stochastic estimate of ``f(wi, wo) cos(wo)`` from the scattering orders in
    [``min_order``, ``max_order``] [Heitz16 alg. 4 with Fresnel]: unbiased for every query; Color3f
    (``F90`` as :func:`walk_sample`)."""
    alpha = _unfolded(dr.detach(mi.Float(alpha)), key)
    F0 = _unfolded(dr.detach(mi.Color3f(F0)), key)
    F90 = _detached_f90(F90, key)
    wo = mi.Vector3f(wo)
    n = dr.width(key)
    wr = -mi.Vector3f(wi)
    L = dr.zeros(mi.Float, n)
    energy = mi.Color3f(dr.full(mi.Float, 1.0, n))
    total = mi.Color3f(dr.zeros(mi.Float, n))
    order = dr.zeros(mi.UInt32, n)
    k = mi.UInt32(key)
    running = mi.Bool(active) & (wo.z > 0) & (mi.Vector3f(wi).z > 0) & dr.full(mi.Bool, True, n)

    def cond(wr, L, energy, total, order, k, running):
        return running

    def body(wr, L, energy, total, order, k, running):
        u1, u2, u3, k = _uniforms(k)
        escaped, L = _next_height(wr, L, u1, alpha, ndf)
        running = running & ~escaped
        order = dr.select(running, order + 1, order)
        v = -wr
        ps, h = _phase_shadowed(v, wo, L, alpha, ndf)
        contrib = energy * _bounce_fresnel(fresnel, dr.dot(v, h), F0, F90) * ps
        use = running & (order >= min_order) & dr.isfinite(ps)
        total = dr.select(use, total + contrib, total)
        m = WALK_NDFS[ndf].sample_visible(v, u2, u3, alpha)
        c = dr.dot(v, m)
        energy = dr.select(running, energy * _bounce_fresnel(fresnel, c, F0, F90), energy)
        wr = dr.select(running, 2.0 * c * m - v, wr)
        running = running & (order < min(int(max_order), MAX_SCATTERING_ORDER))
        return wr, L, energy, total, order, k, running

    wr, L, energy, total, order, k, running = dr.while_loop(
        (wr, L, energy, total, order, k, running), cond, body, label="multiscatter_eval")
    return total


def approx_spec_pdf(pdf_ss, NoL, alpha):
    """The approximate density of the walk's exit direction (MIS weights only; module docstring):
    ``(1 - m) pdf_ss + m cos / pi`` with ``m = MS_PDF_WEIGHT alpha``."""
    m = MS_PDF_WEIGHT * dr.detach(dr.minimum(alpha, 1.0))
    return (1.0 - m) * pdf_ss + m * dr.maximum(NoL, 0.0) * INV_PI


# ---- hooks called by reference.bsdf.PBRMaterial -------------------------------------------------

def blend_walk(bsdf, F0, walk):
    """``walk(F0)`` under the material's metallic blend: the mixed ``F0`` itself (``"f0"``), or glTF
    2.0 Appendix B's ``mix(dielectric, metal, metallic)`` of two walks, ``F0 = specular`` and
    ``F0 = base_color`` (``"gltf"``). The walk's energy is a product of Fresnel factors, not linear in
    F0 beyond its first order, so the glTF blend of the multiply scattered lobe is the mix of the two
    lobes' walks; both follow the same path (the path is drawn from the key, F0 only weighs it), so
    the sampled direction is shared and the weights mix."""
    if bsdf.metallic_blend == "f0":
        return walk(F0)
    m = bsdf.metallic
    return walk(mi.Color3f(bsdf.specular)) * (1.0 - m) + walk(mi.Color3f(bsdf.base_color)) * m


def eval_pdf_hook(bsdf, si, wo, spec_pdf, alpha, F0, valid):
    """(orders >= 2 of ``f cos``, approximate specular pdf) for :meth:`PBRMaterial._eval_pdf`."""
    key = query_key(bsdf.ms_seed, si.wi.x, si.wi.y, si.wi.z, wo.x, wo.y, wo.z)
    ms = blend_walk(bsdf, F0, lambda f0: walk_eval(si.wi, wo, alpha, f0, key, fresnel=bsdf.fresnel, min_order=2,
                                                   ndf=bsdf.ndf, active=valid))
    return ms, approx_spec_pdf(spec_pdf, mi.Frame3f.cos_theta(wo), alpha)


def sample_hook(bsdf, ctx, si, sample1, sample2, active):
    """:meth:`PBRMaterial.sample` for ``random_walk`` (non-delta lobes): lobe choice by ``P_spec``,
    the walk for the specular lobe, the cosine for the diffuse one (module docstring)."""
    wi = si.wi
    NoV = mi.Frame3f.cos_theta(wi)
    active = mi.Bool(active) & (NoV > 0)
    F0 = bsdf._f0()
    alpha = bsdf._alpha()
    p_spec = bsdf._p_spec(dr.clip(NoV, 0, 1), F0)
    choose_spec = sample1 < p_spec

    key = query_key(bsdf.ms_seed, wi.x, wi.y, wi.z, sample1, sample2.x, sample2.y)
    wo_walk, w_walk, _ = walk_sample(wi, alpha, F0, key, fresnel=bsdf.fresnel, ndf=bsdf.ndf,
                                     active=active & choose_spec)
    if bsdf.metallic_blend != "f0":  # the same path, the two lobes' weights mixed (blend_walk)
        w_walk = blend_walk(bsdf, F0, lambda f0: walk_sample(wi, alpha, f0, key, fresnel=bsdf.fresnel, ndf=bsdf.ndf,
                                                             active=active & choose_spec)[1])
    wo_diff = mi.warp.square_to_cosine_hemisphere(sample2)

    bs = dr.zeros(mi.BSDFSample3f)
    bs.eta = 1.0
    bs.wo = dr.select(choose_spec, wo_walk, wo_diff)
    NoL = mi.Frame3f.cos_theta(bs.wo)
    active &= NoL > 0
    bs.sampled_type = dr.select(choose_spec, mi.UInt32(+mi.BSDFFlags.GlossyReflection),
                                mi.UInt32(+mi.BSDFFlags.DiffuseReflection))
    bs.sampled_component = dr.select(choose_spec, mi.UInt32(0), mi.UInt32(1))

    # The approximate mixture pdf, the same function as PBRMaterial.pdf (MIS weights only).
    h = dr.normalize(wi + bs.wo)
    spec_pdf = approx_spec_pdf(bsdf._spec_pdf(wi, bs.wo, h, alpha), NoL, alpha)
    pdf = p_spec * spec_pdf
    if bsdf.fresnel != "none":
        pdf += (1.0 - p_spec) * INV_PI * dr.maximum(NoL, 0.0)
        F = fresnel_term(bsdf.fresnel, dr.dot(wi, h), F0)
        Fd = F if bsdf.metallic_blend == "f0" else fresnel_term(bsdf.fresnel, dr.dot(wi, h), bsdf._diffuse_f0(F0))
        w_diff = (1.0 - Fd) * (1.0 - bsdf.metallic) * bsdf.base_color / dr.maximum(1.0 - p_spec, 1e-20)
    else:
        w_diff = mi.Color3f(0.0)
    bs.pdf = pdf
    weight = dr.select(choose_spec, w_walk / dr.maximum(p_spec, 1e-20), w_diff)
    active &= bs.pdf > 0
    return bs, dr.select(active, weight, 0.0)

