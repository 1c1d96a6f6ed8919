"""A physically layered clearcoat (issue 36 item 5a), numpy: a position-free random walk through a
dielectric coat over the glTF base BRDF [Guo18], the truth the spec's albedo-scaling layering
(:func:`pbrcheck.lobes.coat_layer` with :func:`pbrcheck.lobes.fresnel_coat`) is set against.

The model
---------
A dielectric slab of IOR :data:`pbrcheck.lobes.CLEARCOAT_IOR` (1.5) in air, its top interface smooth
(``coat_roughness = 0``) or a rough GGX microfacet dielectric [Walter07] of ``alpha =
coat_roughness^2`` (visible normals [Heitz18], Smith *separable* masking ``G1(i) G1(o)``: the walk
weights each scattering by ``G1`` of the outgoing direction), unpolarized Fresnel's equations
(:func:`pbrcheck.lobes.fresnel_exact`, total internal reflection included: not the spec's Schlick),
no absorption in the slab (so its thickness is irrelevant: position-free), directly over the base
BRDF: the glTF 2.0 Appendix B material (:func:`pbrcheck.brdf.brdf_eval`, ``metallic_blend = "gltf"``,
dielectric ``F0 = specular``), evaluated as is on the directions inside the slab (the base's own
Fresnel is not re-derived for an IOR-1.5 medium above it: the spec's layering does not either, so the
comparison isolates the layering). The clearcoat factor is a coverage: ``f = (1 - c) f_base + c
f_layered`` (``c = 0`` returns the base bit for bit).

``Coat(interface="multiple")``: the rough interface is instead a random walk on its Smith
microsurface [Heitz16] (heights uniform, GGX visible normals from any direction [Dupuy23], Fresnel's
reflectance choosing reflection or refraction at each event): every light path meets the interface
and leaves it above or below, so nothing is lost there (a white furnace under the coat is 1), and its
single-scattering part is the height-correlated microfacet BSDF. :func:`layered_albedo` only (the
top's own all-order reflection lobe of :func:`layered_brdf` would need [Heitz16]'s evaluation
estimator).

The estimators [Guo18] sec. 4-5 with expected-value splitting at each interface event (weights ``F``
and ``1 - F`` instead of a coin flip, so each walk reaches :data:`MAX_DEPTH` base vertices; the
slab's internal diffuse reflectance ~0.6 makes the cut-off's bias < 0.6^64):

* :func:`layered_albedo` ``E(v) = int f(v, l) (n.l) dl``: the walk enters at v, scores the top's
  reflection ``F G1`` and each exit ``beta (1 - F) G1``; the slab's radiance factors ``eta^-2`` on
  entry and ``eta^2`` on exit cancel on every escaping path.
* :func:`layered_brdf` ``f(wi, wo)``: the light walk from ``wi`` (importance transport, no eta
  factor: the irradiance on the base is ``T(wi)`` per unit irradiance outside) with next-event
  estimation at each base vertex through an exit direction sampled from ``wo`` (radiance transport:
  weight ``(1 - F) G1 / eta^2``), plus the top's reflection lobe ``F(i.h) D G1(i) G1(o) / (4 (n.i)
  (n.o))`` in closed form (a delta at ``coat_roughness = 0``, left out of ``f``: the spec's mirror
  coat is a delta too). A smooth coat over a Lambertian base of albedo rho gives the closed form
  ``T(wi) T(wo) rho / (pi eta^2 (1 - rho Fbar))`` with ``Fbar`` the slab's internal hemispherical
  reflectance (:func:`smooth_lambert_brdf`; the tests' known answer).

Directions not unit or not above the surface, and ``n < 2``, raise
:class:`pbrcheck.errors.PbrcheckError`. Both return ``(mean, standard_error)`` over ``n`` independent walks from a seeded
``numpy.random.Generator`` (PCG64): the same seed gives the same numbers.

API
---
Constants :data:`MAX_DEPTH`, :data:`INTERFACES`, :data:`MS_MAX_EVENTS`, :data:`BASE_COSINE_MIX`, :data:`BETA_CUTOFF`, :data:`BATCH`, :data:`DIRECTION_TOL`; :class:`Base`, :class:`Coat`;
:func:`layered_albedo`, :func:`layered_brdf`, :func:`spec_albedo`, :func:`spec_brdf`,
:func:`base_albedo`, :func:`internal_reflectance`, :func:`smooth_lambert_brdf`, :func:`direction`.

References
----------
[Guo18]    Y. Guo, M. Hasan, S. Zhao, "Position-Free Monte Carlo Simulation for Arbitrary Layered
           BSDFs", ACM TOG 37(6) (SIGGRAPH Asia 2018).
[Walter07] B. Walter, S. Marschner, H. Li, K. Torrance, "Microfacet Models for Refraction through
           Rough Surfaces", EGSR 2007 (eq. 21 the BTDF; its reciprocity with the ``eta^2`` factor).
[Heitz18]  E. Heitz, "Sampling the GGX Distribution of Visible Normals", JCGT 7(4) 2018.
[Heitz16]  E. Heitz, J. Hanika, E. d'Eon, C. Dachsbacher, "Multiple-Scattering Microfacet BSDFs with
           the Smith Model", ACM TOG 35(4) (SIGGRAPH 2016): the microsurface random walk (sec. 4-5).
[Dupuy23]  J. Dupuy, A. Benyoub, "Sampling Visible GGX Normals with Spherical Caps", CGF 42(8)
           (HPG 2023): valid for every incident direction, below the horizon included.
[Coat]     KHR_materials_clearcoat README, "Layering".
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from .brdf import brdf_eval
from .errors import PbrcheckError
from .lobes import CLEARCOAT_IOR, AnisotropicGGX, fresnel_coat, fresnel_exact

#: Base vertices per walk. Each internal bounce keeps a fraction ``rho Fbar`` <= 0.6 of the walk's
#: weight (Fbar = 0.596 at IOR 1.5, rho <= 1), so the energy cut off is < 0.6^64 ~ 6e-15.
MAX_DEPTH = 64
#: A walk batch stops once every weight is below this: the energy it leaves is at most
#: ``BETA_CUTOFF / (1 - 0.6)``, far below the standard errors the estimators report (> 1e-5).
BETA_CUTOFF = 1e-7
#: The smallest cosine handed to Fresnel's equations (:func:`_interface`).
COS_FLOOR = 1e-12
#: Probability of the cosine branch of the base's one-sample mixture proposal (the rest: the base's
#: GGX visible normals). Any value in (0, 1) is unbiased; half keeps both lobes' weights bounded.
BASE_COSINE_MIX = 0.5
#: Walks per vectorised batch (memory: a few (batch, 3) float64 arrays).
BATCH = 1 << 16
#: Gauss-Legendre nodes of :func:`internal_reflectance` (smooth in mu except the kink at the critical
#: angle, which 2 panels split exactly).
FBAR_NODES = 256
#: How far from unit length a direction handed to the estimators may be (float rounding of callers'
#: normalisation; a larger deviation is a caller's bug, not rounding).
DIRECTION_TOL = 1e-6
_UP = np.array([0.0, 0.0, 1.0])
#: The rough interface's models (:attr:`Coat.interface`).
INTERFACES = ("single", "multiple")
#: Scattering events on the interface's microsurface after which a [Heitz16] walk is cut (its weight
#: lost). Measured at IOR 1.5 from outside: 1.01-1.7 events on average, at most 13 in 400000 walks
#: at alpha = 1 (``tests/test_layered.py`` holds that no walk reaches the cap).
MS_MAX_EVENTS = 256
#: ``|w.z|`` beyond which a direction is treated as vertical, and below which as horizontal, in the
#: microsurface's height sampling ([Heitz16]'s guards: ``Lambda`` is 0 / infinite there).
MS_VERTICAL = 0.9999
MS_HORIZONTAL = 1e-4


@dataclass(frozen=True)
class Base:
    """The glTF base (Appendix B), grey: ``base_color`` a scalar in [0, 1]; ``lambert`` True: a
    Lambertian of albedo ``base_color`` instead (the tests' known answers)."""

    base_color: float = 0.5
    metallic: float = 0.0
    roughness: float = 0.5
    specular: float = 0.04
    lambert: bool = False

    def f(self, wi, wo):
        """The BRDF (no cosine), (...,); 0 below either horizon."""
        if self.lambert:
            return np.where((wi[..., 2] > 0) & (wo[..., 2] > 0), float(self.base_color) / np.pi, 0.0)
        bc = np.full(3, float(self.base_color))
        return brdf_eval(_UP, wo, wi, bc, self.metallic, self.roughness, self.specular,
                         metallic_blend="gltf")[..., 0]

    def proposals(self, wi, u):
        """The two branches of the base's proposal at primary samples ``u`` (n, 2): the cosine's and
        the GGX visible normals' reflection (:data:`BASE_COSINE_MIX` picks between them)."""
        r, phi = np.sqrt(u[:, 0]), 2.0 * np.pi * u[:, 1]
        cos_dir = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(1.0 - u[:, 0], 0.0))], axis=-1)
        h = AnisotropicGGX(self.roughness).sample_h(wi, u)
        return cos_dir, 2.0 * np.sum(wi * h, axis=-1, keepdims=True) * h - wi

    def weight(self, wi, wo):
        """``f cos / pdf`` of the mixture proposal (0 below the horizon)."""
        pdf = (BASE_COSINE_MIX * np.maximum(wo[:, 2], 0.0) / np.pi
               + (1.0 - BASE_COSINE_MIX) * AnisotropicGGX(self.roughness).pdf(wi, wo))
        ok = (wo[:, 2] > 0) & (pdf > 0)
        return np.where(ok, self.f(wi, wo) * np.maximum(wo[:, 2], 0.0) / np.where(ok, pdf, 1.0), 0.0)

    def sample(self, wi, rng):
        """``(wo, weight = f cos / pdf)``: the mixture proposal (a Lambertian: the cosine alone, whose
        weight is the albedo itself)."""
        n = wi.shape[0]
        cos_dir, refl = self.proposals(wi, rng.random((n, 2)))
        if self.lambert:
            return cos_dir, np.full(n, float(self.base_color))
        wo = np.where((rng.random(n) < BASE_COSINE_MIX)[:, None], cos_dir, refl)
        return wo, self.weight(wi, wo)


@dataclass(frozen=True)
class Coat:
    """The dielectric slab: ``roughness`` 0 a smooth interface, ``ior`` (1 with a smooth interface: no
    coat at all), ``weight`` the clearcoat factor."""

    roughness: float = 0.0
    ior: float = CLEARCOAT_IOR
    weight: float = 1.0
    #: ``"single"``: the rough interface scatters once ([Walter07], separable Smith ``G1 G1``: the
    #: light its microsurface shadows is lost, :data:`INTERFACES`); ``"multiple"``: a random walk on
    #: the interface's Smith microsurface [Heitz16] (every interaction ends above or below it:
    #: energy-conserving). The same at ``roughness = 0`` (a smooth interface has no microsurface).
    interface: str = "single"

    def __post_init__(self):
        if self.interface not in INTERFACES:
            raise PbrcheckError(f"layered: coat interface must be one of {', '.join(INTERFACES)}, "
                                f"got {self.interface!r}")

    @property
    def smooth(self) -> bool:
        return self.roughness == 0.0


def direction(mu, phi=0.0):
    """The unit vector of cosine ``mu`` to the normal (+Z) at azimuth ``phi`` (radians)."""
    s = np.sqrt(max(1.0 - float(mu) ** 2, 0.0))
    return np.array([s * np.cos(phi), s * np.sin(phi), float(mu)])


def _interface(coat, w, n1, n2, rng):
    """Scatter at the coat's interface seen from the side of ``w`` (frame with that side at +Z, ``w``
    pointing away from the interface into it), IORs ``n1`` (w's side) and ``n2``. Returns ``(r, wr,
    t, wt)``: the reflected direction (+Z side) and its weight ``F G1(r)``, the transmitted one (-Z
    side) and ``(1 - F) G1(-t)`` (0 under total internal reflection or where the microfacet sends a
    direction to the wrong side). A rough ``multiple`` interface: :func:`_interface_ms` (one of
    the two weights 1, the other 0)."""
    if coat.interface == "multiple" and not coat.smooth:
        return _interface_ms(coat.roughness ** 2, w, n2 / n1, rng)
    if coat.smooth:
        h = np.broadcast_to(_UP, w.shape)
    else:
        h = AnisotropicGGX(coat.roughness).sample_h(w, rng.random((w.shape[0], 2)))
    # c >= COS_FLOOR: at c = 0 with n1 = n2 Fresnel's ratios are 0 / 0 (the walk's dead directions,
    # weight 0 already, reach here too).
    c = np.clip(np.sum(w * h, axis=-1), COS_FLOOR, 1.0)
    F = fresnel_exact(c, n1, n2)
    r = 2.0 * c[:, None] * h - w
    eta = n1 / n2
    s2 = eta * eta * (1.0 - c * c)
    ct = np.sqrt(np.maximum(1.0 - s2, 0.0))
    t = -eta * w + (eta * c - ct)[:, None] * h
    t = t / np.maximum(np.linalg.norm(t, axis=-1, keepdims=True), 1e-300)
    if coat.smooth:
        g_r = g_t = 1.0
    else:
        ggx = AnisotropicGGX(coat.roughness)
        g_r, g_t = ggx.G1(r), ggx.G1(t)
    wr = np.where(r[:, 2] > 0, F * g_r, 0.0)
    wt = np.where((t[:, 2] < 0) & (s2 < 1.0), (1.0 - F) * g_t, 0.0)
    return r, wr, t, wt


def _ms_lambda(z, alpha):
    """Smith's ``Lambda`` of isotropic GGX for a direction of cosine ``z`` to the mean surface, signed
    as [Heitz16] uses it: downward directions ``Lambda(-w) = -1 - Lambda(w)`` (their masking
    probability ``C1(h)^Lambda >= 1``: a ray going down always meets the microsurface)."""
    az = np.maximum(np.abs(z), MS_HORIZONTAL)
    up = 0.5 * (np.sqrt(1.0 + alpha * alpha * (1.0 - az * az) / (az * az)) - 1.0)
    return np.where(z >= 0.0, up, -1.0 - up)


def _ms_height(wr, hr, u, alpha):
    """The next height at which a ray travelling along ``wr`` from height ``hr`` meets the Smith
    microsurface (uniform heights in [-1, 1], ``C1(h) = (h + 1) / 2``), or +inf where it leaves:
    [Heitz16] sec. 4 (the height CDF of the first intersection ``1 - (C1(hr)/C1(h))^Lambda``
    inverted at ``u``)."""
    c1 = np.clip(0.5 * (hr + 1.0), 0.0, 1.0)
    lam = _ms_lambda(wr[:, 2], alpha)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        # the probability of no intersection (Smith's masking at height hr): a ray going down always
        # meets the surface (the uniform heights end at -1), so only upward rays can leave
        g1 = np.where(wr[:, 2] <= 0.0, 0.0, c1 ** lam)
        h = 2.0 * np.clip(c1 / (1.0 - u) ** (1.0 / lam), 0.0, 1.0) - 1.0
    h = np.where(u > 1.0 - g1, np.inf, h)
    h = np.where(wr[:, 2] < -MS_VERTICAL, 2.0 * (u * c1) - 1.0, h)       # straight down: always meets it
    h = np.where(np.abs(wr[:, 2]) < MS_HORIZONTAL, hr, h)                # horizontal: where it is
    return np.where(wr[:, 2] > MS_VERTICAL, np.inf, h)                  # straight up: leaves


def _ms_visible_normal(wi, alpha, u):
    """A GGX normal (upper hemisphere) visible from ``wi`` (any direction, below the horizon too), pdf
    ``max(0, wi.m) D(m) / proj(wi)``: spherical caps in the stretched space [Dupuy23]."""
    w = np.stack([alpha * wi[:, 0], alpha * wi[:, 1], wi[:, 2]], axis=-1)
    w = w / np.linalg.norm(w, axis=-1, keepdims=True)
    phi = 2.0 * np.pi * u[:, 0]
    z = (1.0 - u[:, 1]) * (1.0 + w[:, 2]) - w[:, 2]
    st = np.sqrt(np.clip(1.0 - z * z, 0.0, 1.0))
    h = np.stack([st * np.cos(phi), st * np.sin(phi), z], axis=-1) + w
    m = np.stack([alpha * h[:, 0], alpha * h[:, 1], np.maximum(h[:, 2], 0.0)], axis=-1)
    return m / np.maximum(np.linalg.norm(m, axis=-1, keepdims=True), 1e-300)


def _interface_ms(alpha, w, eta, rng, events=None):
    """The rough interface as a random walk on its Smith microsurface [Heitz16] (dielectric, GGX of
    ``alpha``, uniform heights), entered from the +Z side along ``-w``; ``eta`` = IOR of the -Z side
    over the +Z side's. Each event: the next height (:func:`_ms_height`; mirrored, ``-h(-w, -h)``,
    below the surface), a visible normal, Fresnel's reflectance picking reflection or refraction
    (which crosses to the other side). Returns ``_interface``'s ``(r, wr, t, wt)`` with one weight 1
    (the walk left on that side along that direction) and the other 0 (both 0: cut after
    :data:`MS_MAX_EVENTS` events). ``events`` (an array, optional) receives each walk's event count."""
    n = w.shape[0]
    wr = -np.asarray(w, dtype=np.float64)
    hr = np.full(n, 1.0 + (2.0 * 0.999 - 1.0))           # just above the microsurface's top
    outside = np.ones(n, dtype=bool)
    live = np.ones(n, dtype=bool)
    count = np.zeros(n, dtype=np.int64)
    for _ in range(MS_MAX_EVENTS):
        idx = np.nonzero(live)[0]
        if idx.size == 0:
            break
        d, h0, out = wr[idx], hr[idx], outside[idx]
        u = rng.random(idx.size)
        sgn = np.where(out, 1.0, -1.0)
        h = sgn * _ms_height(d * sgn[:, None], h0 * sgn, u, alpha)
        left = ~np.isfinite(h)
        live[idx[left]] = False
        go = idx[~left]
        if go.size == 0:
            break
        d, out, hr[go] = wr[go], outside[go], h[~left]
        count[go] += 1
        wi = -d
        sg = np.where(out, 1.0, -1.0)[:, None]
        m = sg * _ms_visible_normal(wi * sg, alpha, rng.random((go.size, 2)))
        c = np.clip(np.sum(wi * m, axis=-1), COS_FLOOR, 1.0)
        e = np.where(out, eta, 1.0 / eta)                  # IOR of the side it enters over its own
        F = fresnel_exact(c, 1.0, e)
        refl = rng.random(go.size) < F
        r = 2.0 * c[:, None] * m - wi
        ct = -np.sqrt(np.maximum(1.0 - (1.0 - c * c) / (e * e), 0.0))
        t = m * (c / e + ct)[:, None] - wi / e[:, None]
        t = t / np.maximum(np.linalg.norm(t, axis=-1, keepdims=True), 1e-300)
        wr[go] = np.where(refl[:, None], r, t)
        outside[go] = np.where(refl, out, ~out)
    if events is not None:
        events[...] = count
    up = ~live & outside
    down = ~live & ~outside
    # the side a walk did not leave on gets a harmless direction of weight 0 (the callers evaluate
    # the base there before multiplying by the weight: no NaN from a direction on the wrong side)
    r = np.where(up[:, None], wr, _UP)
    t = np.where(down[:, None], wr, -_UP)
    return r, up.astype(np.float64), t, down.astype(np.float64)


def _flip(w):
    return w * np.array([1.0, 1.0, -1.0])


def _walk(base, coat, w_in, n, rng, exit_dir=None):
    """One batch of ``n`` walks entering at ``w_in`` (3,). Per walk: the escaping energy (all
    directions) and, with ``exit_dir`` (3,), the next-event estimate of ``f_layered(w_in, exit_dir)``
    without the top's reflection lobe."""
    ior = float(coat.ior)
    w = np.broadcast_to(np.asarray(w_in, dtype=np.float64), (n, 3)).copy()
    _, wr, t, beta = _interface(coat, w, 1.0, ior, rng)
    escaped = wr.copy()
    nee = np.zeros(n)
    wi_b = -t  # the base's light direction (up), in the slab
    for _ in range(MAX_DEPTH):
        if exit_dir is not None:
            wo = np.broadcast_to(np.asarray(exit_dir, dtype=np.float64), (n, 3)).copy()
            _, _, te, we = _interface(coat, wo, 1.0, ior, rng)
            nee += beta * base.f(wi_b, -te) * we / (ior * ior)
        up, wb = base.sample(wi_b, rng)
        beta = beta * wb
        # The interface from below: flip to its frame (the slab's side at +Z, w pointing down into it).
        # The interface from below, in its flipped frame (the slab's side at +Z): w = flip(-up).
        r, wr, _, wt = _interface(coat, _flip(-up), ior, 1.0, rng)
        escaped += beta * wt
        beta = beta * wr
        wi_b = -_flip(r)  # flip(r) travels back down; the base's next light direction is its reverse
        if not np.any(beta > BETA_CUTOFF):
            break
    return escaped, nee


def _check(name, w):
    """The estimators' directions must be unit vectors strictly above the surface (the walk enters
    there; below it the layered BRDF is 0 by definition, not an estimate)."""
    w = np.asarray(w, dtype=np.float64)
    if w.shape != (3,) or not (w[2] > 0) or abs(float(np.linalg.norm(w)) - 1.0) > DIRECTION_TOL:
        raise PbrcheckError(f"layered: {name} must be a unit 3-vector above the surface (z > 0), got {w.tolist()}")
    return w


def _estimate(n, seed, fn):
    if int(n) < 2:
        raise PbrcheckError(f"layered: n (walks) must be at least 2 for a standard error, got {n}")
    rng = np.random.default_rng(seed)
    vals = []
    left = int(n)
    while left > 0:
        b = min(left, BATCH)
        vals.append(fn(b, rng))
        left -= b
    x = np.concatenate(vals)
    return float(np.mean(x)), float(np.std(x, ddof=1) / np.sqrt(x.size))


def layered_albedo(base: Base, coat: Coat, v, n=1 << 16, seed=0):
    """``(E, standard error)``: the directional albedo of the layered material at the view ``v`` (3,)
    (the coverage mix with the base's albedo :func:`base_albedo` at ``coat.weight < 1``)."""
    v = _check("v", v)
    e, se = _estimate(n, seed, lambda b, rng: _walk(base, coat, v, b, rng)[0])
    c = float(coat.weight)
    if c == 1.0:
        return e, se
    return (1.0 - c) * base_albedo(base, v) + c * e, c * se


def _top_lobe(coat, wi, wo):
    """The rough top's reflection ``F(i.h) D G1(i) G1(o) / (4 (n.i)(n.o))``; 0 for a smooth top."""
    if coat.smooth:
        return 0.0
    ggx = AnisotropicGGX(coat.roughness)
    wi, wo = np.asarray(wi, dtype=np.float64), np.asarray(wo, dtype=np.float64)
    h = (wi + wo) / np.linalg.norm(wi + wo)
    F = fresnel_exact(float(wi @ h), 1.0, float(coat.ior))
    return float(F * ggx.D(h) * ggx.G1(wi) * ggx.G1(wo) / (4.0 * wi[2] * wo[2]))


def layered_brdf(base: Base, coat: Coat, wi, wo, n=1 << 16, seed=0):
    """``(f(wi, wo), standard error)`` of the layered material (no cosine), ``wi``, ``wo`` (3,) above
    the surface; a smooth top's mirror delta is left out."""
    wi, wo = _check("wi", wi), _check("wo", wo)
    if coat.interface == "multiple" and not coat.smooth:
        # the top's own reflection would be the microsurface walk's all-order lobe, which needs its
        # evaluation estimator ([Heitz16] sec. 6: next-event estimation at each microsurface vertex),
        # not built: the multiple-scattering interface gives the albedo (layered_albedo) only
        raise PbrcheckError("layered: layered_brdf takes a single-scattering rough interface only "
                            "(coat interface 'multiple' has layered_albedo)")
    c = float(coat.weight)
    fb = float(base.f(wi[None], wo[None])[0])
    if c == 0.0:
        return fb, 0.0
    m, se = _estimate(n, seed, lambda b, rng: _walk(base, coat, wi, b, rng, exit_dir=wo)[1])
    m += _top_lobe(coat, wi, wo)
    return (1.0 - c) * fb + c * m, c * se


def base_albedo(base: Base, v, n=512):
    """The base's directional albedo at ``v`` by the midpoint rule on an n x n grid of the base's
    proposal's primary samples (deterministic; both branches of the mixture stratified; 512^2 agrees
    with 1024^2 to 2e-5 on the glTF base at roughness 0.5); a Lambertian's is its ``base_color``."""
    if base.lambert:
        return float(base.base_color)
    g = (np.arange(n) + 0.5) / n
    u = np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1).reshape(-1, 2)
    v3 = np.broadcast_to(np.asarray(v, dtype=np.float64), (u.shape[0], 3))
    total = 0.0
    for l, share in zip(base.proposals(v3, u), (BASE_COSINE_MIX, 1.0 - BASE_COSINE_MIX)):
        total += share * float(np.mean(base.weight(v3, l)))
    return total


def spec_albedo(base: Base, coat: Coat, v):
    """[Coat] "Layering"'s albedo: ``(1 - c Fc(n.v)) E_base(v) + c Fc(n.v) E_coat(v)`` (Schlick Fc at
    IOR 1.5, the coat's GGX albedo by quadrature; its mirror limit 1 at roughness 0)."""
    mu = float(np.asarray(v)[2])
    w = float(coat.weight) * float(fresnel_coat(mu, coat.ior))
    e_coat = 1.0 if coat.smooth else AnisotropicGGX(coat.roughness).albedo(mu)
    return (1.0 - w) * base_albedo(base, v) + w * e_coat


def spec_brdf(base: Base, coat: Coat, wi, wo):
    """[Coat] "Layering"'s BRDF at (light ``wi``, view ``wo``): ``(1 - c Fc(n.v)) f_base + c Fc(n.v)
    clearcoat_brdf``; the mirror coat's delta left out as in :func:`layered_brdf`."""
    wi, wo = np.asarray(wi, dtype=np.float64), np.asarray(wo, dtype=np.float64)
    w = float(coat.weight) * float(fresnel_coat(wo[2], coat.ior))
    fb = float(base.f(wi[None], wo[None])[0])
    fc = 0.0 if coat.smooth else float(AnisotropicGGX(coat.roughness).brdf(wo[None], wi[None])[0])
    return (1.0 - w) * fb + w * fc


@lru_cache(maxsize=8)
def internal_reflectance(ior=CLEARCOAT_IOR):
    """``Fbar = int_0^1 F(mu; ior -> 1) 2 mu dmu``: the slab's hemispherical reflectance from inside
    (Gauss-Legendre on the two panels either side of the critical cosine)."""
    mu_c = np.sqrt(max(1.0 - 1.0 / (ior * ior), 0.0))
    x, w = np.polynomial.legendre.leggauss(FBAR_NODES)
    total = 0.0
    for a, b in ((0.0, mu_c), (mu_c, 1.0)):
        mu = 0.5 * (b - a) * (x + 1.0) + a
        total += float(np.sum(0.5 * (b - a) * w * fresnel_exact(mu, ior, 1.0) * 2.0 * mu))
    return total


def smooth_lambert_brdf(rho, wi, wo, ior=CLEARCOAT_IOR):
    """The closed form of a smooth non-absorbing slab over a Lambertian base of albedo ``rho``:
    ``T(wi) T(wo) rho / (pi ior^2 (1 - rho Fbar))`` (the geometric series of internal bounces)."""
    T = [1.0 - float(fresnel_exact(float(np.asarray(w)[2]), 1.0, ior)) for w in (wi, wo)]
    return T[0] * T[1] * rho / (np.pi * ior * ior * (1.0 - rho * internal_reflectance(float(ior))))
