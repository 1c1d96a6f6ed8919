"""The truth of light through a surface (pbrcheck/transmission.py; reference/transmission.py twins in
tests/test_reference_transmission.py; issue 37 item 1): each sampler's weight is eval / pdf, a binned
chi-square of each sampler against its pdf over the whole sphere, reciprocity (a BTDF between media:
``f(v, l) / eta_v^2 = f(l, v) / eta_l^2``), energy (a white rough dielectric interface reflects and
transmits at most what arrives; the smooth one exactly; the thin-walled sheet's R + T is the specular
lobe's albedo), Snell's law, Beer-Lambert through a slab of known thickness by a random walk of the
samplers along the path actually travelled, the IOR-1 thin sheet passing light straight, and the
dispersion's spectral weights."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from pbrcheck import lobes as L
from pbrcheck import transmission as T

#: Chi-square: samples, bins (cos theta in [-1, 1] x phi), smallest expected count a bin keeps (smaller
#: ones pooled, as Mitsuba's ChiSquareTest does), significance level (tests/test_lobes.py's values).
CHI2_SAMPLES = 200_000
CHI2_BINS = (40, 40)
CHI2_MIN_EXPECTED = 5.0
CHI2_SIGNIFICANCE = 0.01
#: Float64 identities (weight = eval / pdf, reciprocity): rounding only.
EXACT_RTOL = 1e-9
#: The energy quadrature (midpoint rule on 256^2 nodes of the sampler's u; its integrand eval/pdf is
#: smooth and <= 1): against 512^2 nodes it moves < 2e-4 (test_energy_quadrature_converged).
ENERGY_NODES = 256
ENERGY_QUAD_TOL = 1e-3
#: Random walks through the slab: paths, and the binomial tolerance (5 standard errors of a fraction
#: near 0.5 over that many paths).
SLAB_PATHS = 100_000
#: Bounces of a slab walk: the throughput left after k internal round trips is (R^2 a^2)^k, R = 0.04:
#: below 1e-11 after 4; the walk stops when no path is left inside.
SLAB_MAX_BOUNCES = 12
SLAB_TOL = 5.0 * 0.5 / np.sqrt(SLAB_PATHS)


def _dir(mu, phi=0.3):
    s = np.sqrt(1.0 - mu * mu)
    return np.array([s * np.cos(phi), s * np.sin(phi), mu])


def _sphere_dirs():
    """Directions on both sides, grazing (|cos| 1e-3) to the normal, several azimuths."""
    cs = np.array([1e-3, 0.05, 0.3, 0.6, 0.9, 1.0])
    cs = np.concatenate([-cs[::-1], cs])
    ph = np.linspace(0.0, 2 * np.pi, 5, endpoint=False) + 0.2
    c, p = np.meshgrid(cs, ph, indexing="ij")
    s = np.sqrt(1 - c * c)
    return np.stack([s * np.cos(p), s * np.sin(p), c], axis=-1).reshape(-1, 3)


def _pairs():
    d = _sphere_dirs()
    return np.repeat(d, len(d), axis=0), np.tile(d, (len(d), 1))


ROUGH = [(0.1, 1.5), (0.5, 1.5), (1.0, 1.5), (0.3, 1.33), (0.6, 2.4)]
LOBES = ([("dielectric", r, i) for r, i in ROUGH] + [("thin", 0.1, 1.5), ("thin", 0.5, 1.5), ("thin", 1.0, 1.0),
                                                   ("thin", 0.4, 2.0)] + [("diffuse", 1.0, 1.0)])


def make(kind, r, ior, mod=T):
    if kind == "dielectric":
        return mod.RoughDielectric(r, ior)
    if kind == "thin":
        return mod.ThinDielectric(r, ior)
    return mod.DiffuseBTDF()


@pytest.mark.parametrize("kind,r,ior", LOBES)
def test_sample_weight_is_eval_over_pdf_on_both_sides(kind, r, ior):
    lobe, rng = make(kind, r, ior), np.random.default_rng(3)
    for mu in (0.9, 0.2, -0.2, -0.9):
        v = _dir(mu)
        l, w, p, delta = lobe.sample(v, rng.random((20_000, 2)), rng.random(20_000))
        vv = np.broadcast_to(v, l.shape)
        e, pp = lobe.eval(vv, l), lobe.pdf(vv, l)
        ok = p > 0
        assert ok.mean() > 0.5 and not delta.any()
        np.testing.assert_allclose(pp[ok], p[ok], rtol=EXACT_RTOL)
        np.testing.assert_allclose(w[ok], e[ok] / p[ok], rtol=EXACT_RTOL)
        assert np.all(w[~ok] == 0.0)   # a sample the pdf does not cover carries nothing
        assert np.allclose(np.linalg.norm(l[ok], axis=-1), 1.0)


# ---- chi-square over the sphere -------------------------------------------------------------------

def _chi2(lobe, v, seed=11):
    rng = np.random.default_rng(seed)
    l, _, p, _ = lobe.sample(v, rng.random((CHI2_SAMPLES, 2)), rng.random(CHI2_SAMPLES))
    l = l[p > 0]
    nt, nphi = CHI2_BINS
    ti = np.clip(((l[:, 2] + 1.0) * 0.5 * nt).astype(int), 0, nt - 1)
    pi = np.minimum(((np.arctan2(l[:, 1], l[:, 0]) % (2 * np.pi)) / (2 * np.pi) * nphi).astype(int), nphi - 1)
    obs = np.bincount(ti * nphi + pi, minlength=nt * nphi).astype(float)
    k = 12
    sub = (np.arange(k) + 0.5) / k
    ct = ((np.arange(nt)[:, None] + sub[None]) / nt * 2.0 - 1.0).ravel()
    ph = ((np.arange(nphi)[:, None] + sub[None]) / nphi * 2 * np.pi).ravel()
    C, P = np.meshgrid(ct, ph, indexing="ij")
    S = np.sqrt(1 - C * C)
    d = np.stack([S * np.cos(P), S * np.sin(P), C], -1).reshape(-1, 3)
    dens = lobe.pdf(np.broadcast_to(v, d.shape), d).reshape(nt, k, nphi, k)
    exp = dens.mean(axis=(1, 3)).ravel() * (2.0 / nt) * (2 * np.pi / nphi) * CHI2_SAMPLES
    keep = exp >= CHI2_MIN_EXPECTED
    o = np.append(obs[keep], obs[~keep].sum())
    e = np.append(exp[keep], exp[~keep].sum())
    if e[-1] < CHI2_MIN_EXPECTED:
        o[-2] += o[-1]
        e[-2] += e[-1]
        o, e = o[:-1], e[:-1]
    return stats.chi2.sf(np.sum((o - e) ** 2 / e), len(o) - 1), len(o)


CHI2_CASES = [("dielectric", 0.5, 1.5, 0.7), ("dielectric", 0.3, 1.5, -0.6), ("dielectric", 0.8, 1.33, 0.2),
              ("dielectric", 0.4, 2.4, -0.95), ("thin", 0.5, 1.5, 0.6), ("thin", 0.3, 1.5, -0.8),
              ("diffuse", 1.0, 1.0, 0.5)]


@pytest.mark.parametrize("kind,r,ior,mu", CHI2_CASES, ids=[f"{c[0]} r{c[1]} ior{c[2]} mu{c[3]}" for c in CHI2_CASES])
def test_chi2_over_the_sphere(kind, r, ior, mu):
    p, bins = _chi2(make(kind, r, ior), _dir(mu))
    print(f"chi2 {kind} r{r} ior{ior} mu{mu}: p = {p:.4f} over {bins} bins")
    assert p > CHI2_SIGNIFICANCE and bins > 50


def test_chi2_detects_a_wrong_pdf():
    """The test can fail: the dielectric's pdf with the refraction Jacobian's eta_l^2 left out."""

    class Wrong(T.RoughDielectric):
        def pdf(self, v, l):
            p = super().pdf(v, l)
            eta_v, eta_l = self._etas(v)
            return np.where(v[..., 2] * l[..., 2] < 0, p / eta_l ** 2, p)

    p, _ = _chi2(Wrong(0.5, 1.5), _dir(0.7))
    assert p < 1e-6


# ---- reciprocity ------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind,r,ior", LOBES)
def test_reciprocity(kind, r, ior):
    """``f = eval / |n.l|``: ``f(v, l) / eta_v^2 = f(l, v) / eta_l^2`` (radiance transport between media,
    [Walter07] sec. 5.1 / Veach 1997 5.2); a thin surface and the diffuse BTDF are symmetric."""
    lobe = make(kind, r, ior)
    v, l = _pairs()
    f_vl = lobe.eval(v, l) / np.abs(l[:, 2])
    f_lv = lobe.eval(l, v) / np.abs(v[:, 2])
    if kind == "dielectric":
        ev, el = np.where(v[:, 2] > 0, 1.0, ior), np.where(l[:, 2] > 0, 1.0, ior)
        f_vl, f_lv = f_vl / ev ** 2, f_lv / el ** 2
    assert np.count_nonzero(f_vl) > len(v) // 8
    np.testing.assert_allclose(f_vl, f_lv, rtol=1e-7, atol=1e-12 * np.max(f_vl))


# ---- energy -------------------------------------------------------------------------------------------

def _energy(lobe, v, n=ENERGY_NODES):
    """``int (f_r + f_t (eta_l / eta_v)^2) |n.l| dl`` (the flux albedo; radiance weights carry
    ``(eta_v / eta_l)^2``) by the midpoint rule over the visible normals, both branches at each normal
    weighted by their probabilities F, 1 - F (deterministic: no lobe-choice noise)."""
    g = (np.arange(n) + 0.5) / n
    u = np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1).reshape(-1, 2)
    _, wr, pr, _ = lobe.sample(v, u, np.zeros(len(u)))
    lt, wt, pt, _ = lobe.sample(v, u, np.nextafter(np.ones(len(u)), 0))
    h = lobe.ggx.sample_h(v, u)
    vh = h @ v
    if isinstance(lobe, T.RoughDielectric):
        F = T.fresnel_dielectric(vh, lobe.eta, lobe.f0)
        eta_v, eta_l = (1.0, lobe.eta) if v[2] > 0 else (lobe.eta, 1.0)
        wt = wt * (eta_l / eta_v) ** 2
    else:
        F = L.schlick(vh, lobe.f0)
    return float(np.mean(F * wr + (1.0 - F) * wt))


@pytest.mark.parametrize("r", [0.05, 0.3, pytest.param(0.6, marks=pytest.mark.slow), pytest.param(1.0, marks=pytest.mark.slow)])
def test_white_rough_dielectric_interface_energy_at_most_one(r):
    for ior in (1.33, 1.5, 2.4):
        lobe = T.RoughDielectric(r, ior)
        for mu in (1.0, 0.3, 0.05, -0.05, -0.5, -1.0):
            E = _energy(lobe, _dir(mu))
            assert E <= 1.0 + ENERGY_QUAD_TOL, (r, ior, mu, E)
            if r <= 0.05:      # nearly smooth: nothing is lost to the single-scattering microfacets
                assert E == pytest.approx(1.0, abs=2e-2), (r, ior, mu, E)
    if r == 1.0:   # the energy the single-scattering microfacets lose (docs/reference.md)
        print("rough dielectric flux albedo, ior 1.5, roughness 1:",
              {mu: round(_energy(T.RoughDielectric(1.0, 1.5), _dir(mu)), 4) for mu in (1.0, 0.5, 0.1, -0.5)})


def test_energy_quadrature_converged():
    lobe = T.RoughDielectric(0.3, 1.5)
    for mu in (0.9, -0.4):
        assert _energy(lobe, _dir(mu)) == pytest.approx(_energy(lobe, _dir(mu), 2 * ENERGY_NODES), abs=2e-4)


def test_smooth_dielectric_is_exact_and_obeys_snell():
    """Roughness 0: delta reflection (weight 1) with probability F and refraction (weight (eta_v /
    eta_l)^2) with 1 - F: R + T = 1 in flux; the refracted direction obeys Snell's law."""
    lobe = T.RoughDielectric(0.0, 1.5)
    assert lobe.ggx.smooth and np.all(lobe.eval(*_pairs()) == 0.0)
    v = _dir(0.6)
    u = np.full((2, 2), 0.5)
    l, w, p, delta = lobe.sample(v, u, np.array([0.0, 0.999999]))
    assert delta.all() and np.all(p == 0.0)
    F = T.fresnel_dielectric(0.6, 1.5, lobe.f0)
    np.testing.assert_allclose(l[0], [-v[0], -v[1], v[2]])          # mirror
    sin_i, sin_t = np.hypot(v[0], v[1]), np.hypot(l[1, 0], l[1, 1])
    assert sin_i == pytest.approx(1.5 * sin_t) and l[1, 2] < 0          # Snell: sin_i = eta sin_t
    assert w[1] == pytest.approx(1 / 1.5 ** 2) and w[0] == 1.0
    assert F * 1.0 + (1 - F) * w[1] * 1.5 ** 2 == pytest.approx(1.0)
    # from inside past the critical angle (sin > 1 / 1.5): everything reflects
    vi = _dir(-0.5)
    assert T.fresnel_dielectric(-0.5, 1.5, lobe.f0) == 1.0
    l2, w2, _, _ = lobe.sample(vi, u, np.array([0.999, 0.999]))
    assert np.all(l2[:, 2] < 0) and np.all(w2 == 1.0)


def test_thin_sheet_energy_is_the_specular_lobes_albedo():
    """[Trans]: reflection F and transmission 1 - F of the one specular lobe (mirrored): R + T is the
    lobe's albedo without Fresnel, :meth:`pbrcheck.lobes.AnisotropicGGX.albedo` (<= 1)."""
    for r in (0.2, 0.6, 1.0):
        lobe = T.ThinDielectric(r, 1.5)
        for mu in (0.9, 0.4):
            E = _energy(lobe, _dir(mu, 0.0))
            assert E == pytest.approx(L.AnisotropicGGX(r).albedo(mu), abs=2e-3) and E <= 1.0 + ENERGY_QUAD_TOL
            assert _energy(lobe, _dir(-mu, 0.0)) == pytest.approx(E, abs=1e-9)   # two-sided


def test_ior_one_thin_sheet_passes_light_straight():
    """Transmission 1, IOR 1, roughness 0: f0 = 0, the sheet transmits ``1 - (1 - |n.v|)^5`` straight
    on (weight 1) and mirrors the rest; at normal incidence it is not there."""
    lobe = T.ThinDielectric(0.0, 1.0)
    for mu in (1.0, 0.8, -0.5):
        v = _dir(mu)
        l, w, _, delta = lobe.sample(v, np.full((1, 2), 0.5), np.array([0.999999]))
        assert delta.all() and w[0] == 1.0
        np.testing.assert_allclose(l[0], -v, atol=1e-15)
    assert L.schlick(1.0, lobe.f0) == 0.0
    # the volume interface at IOR 1 refracts straight as well (a delta at any roughness)
    d = T.RoughDielectric(0.5, 1.0)
    v = _dir(0.7)
    l, w, p, delta = d.sample(v, np.full((1, 2), 0.3), np.array([0.999999]))
    np.testing.assert_allclose(l[0], -v, atol=1e-15)
    assert delta[0] and w[0] == 1.0 and p[0] == 0.0


# ---- Beer-Lambert through a slab --------------------------------------------------------------------

def _walk_slab(lobe, v0, sigma_t, thickness, rng, n=SLAB_PATHS, max_bounces=SLAB_MAX_BOUNCES):
    """Random walks of the sampler through a slab 0 > z > -thickness (smooth faces, normal +Z on top,
    -Z below): each path starts above going along -v0, each face samples reflection / refraction,
    each crossing of the slab attenuates by ``exp(-sigma_t d)`` over its length ``d = thickness /
    |cos|``; returns the mean throughput (flux units) leaving through the bottom."""
    v = np.broadcast_to(v0, (n, 3)).copy()
    w = np.ones(n)
    alive = np.ones(n, bool)
    out = np.zeros(n)
    top = np.ones(n, bool)            # the face the path is at; the local frame of the bottom face is flipped
    for _ in range(max_bounces):
        vl = np.where(top[:, None], v, v * np.array([1.0, 1.0, -1.0]))   # the bottom face's frame: z -> -z
        l, wt, _, _ = lobe.sample(vl, rng.random((n, 2)), rng.random(n))
        inside = l[:, 2] < 0
        eta_v = np.where(vl[:, 2] > 0, 1.0, lobe.eta)
        eta_l = np.where(inside, lobe.eta, 1.0)
        w = w * wt * (eta_l / eta_v) ** 2                  # flux: undo the radiance scaling
        leave = alive & ~inside
        out += np.where(leave & ~top, w, 0.0)              # out of the bottom face
        alive &= inside
        if not alive.any():
            break
        d = thickness / np.maximum(np.abs(l[:, 2]), 1e-12)
        w = w * np.exp(-sigma_t * d)
        lw = np.where(top[:, None], l, l * np.array([1.0, 1.0, -1.0]))   # back to world
        v = -lw
        top = ~top
    return float(out.mean())


@pytest.mark.parametrize("mu,sigma_t", [(1.0, 0.0), (1.0, 0.7), (0.5, 0.7), (0.9, 2.0)])
def test_beer_lambert_through_a_slab_along_the_path_travelled(mu, sigma_t):
    """A smooth slab of thickness 1.5, ior 1.5: the walk's transmittance equals the closed form of
    all internal bounces, ``(1 - R)(1 - R') a / (1 - R R' a^2)``, with ``a = exp(-sigma_t d /
    cos theta_t)`` along the refracted path (at normal incidence :func:`slab_transmittance`)."""
    thickness, ior = 1.5, 1.5
    lobe = T.RoughDielectric(0.0, ior)
    rng = np.random.default_rng(5)
    got = _walk_slab(lobe, _dir(mu), sigma_t, thickness, rng)
    R = float(T.fresnel_dielectric(mu, ior, lobe.f0))
    sin_t = np.sqrt(1 - mu * mu) / ior
    cos_t = np.sqrt(1 - sin_t ** 2)
    R2 = float(T.fresnel_dielectric(-cos_t, ior, lobe.f0))           # the same Schlick cosine: R2 = R
    assert R2 == pytest.approx(R)
    a = np.exp(-sigma_t * thickness / cos_t)
    want = (1 - R) * (1 - R2) * a / (1 - R * R2 * a * a)
    if mu == 1.0:
        assert want == pytest.approx(T.slab_transmittance(ior, sigma_t, thickness))
    assert got == pytest.approx(want, abs=SLAB_TOL), (got, want)


def test_beer_lambert_and_sigma_t_of_the_volume_parameters():
    from pbrcheck.transmission_params import Volume

    vol = Volume(thickness=1.0, attenuation_distance=2.0, attenuation_color=(0.5, 0.25, 1.0))
    # white light turns into attenuationColor after attenuationDistance ([Volume])
    np.testing.assert_allclose(T.beer_lambert(vol.sigma_t, 2.0), [0.5, 0.25, 1.0])
    np.testing.assert_allclose(T.beer_lambert(vol.sigma_t, 4.0), [0.25, 0.0625, 1.0])


# ---- dispersion -------------------------------------------------------------------------------------

def test_spectral_weights_integrate_to_white_and_dispersion_spreads_the_ior():
    lam = np.linspace(*T.SPECTRAL_RANGE_NM, 40001)
    w = T.spectral_rgb_weights(lam)
    np.testing.assert_allclose(np.trapezoid(w, lam, axis=0), [1.0, 1.0, 1.0], rtol=1e-6)
    # the green weight peaks near 550 nm, the red one at longer wavelengths than the blue one
    assert lam[np.argmax(w[:, 0])] > lam[np.argmax(w[:, 1])] > lam[np.argmax(w[:, 2])]
    n = T.dispersion_iors(1.5, 1.0, [450.0, 587.6, 650.0])
    assert n[0] > n[1] > n[2] and n[1] == pytest.approx(1.5, abs=2e-4)
    np.testing.assert_array_equal(T.dispersion_iors(1.5, 0.0, [450.0, 650.0]), [1.5, 1.5])
    # the reference's channels: C, d, F lines; the Abbe number of the three is the one asked for
    nR, nG, nB = T.channel_iors(1.5, 0.36)
    assert (nG - 1.0) / (nB - nR) == pytest.approx(20.0 / 0.36, rel=1e-3) and nG == pytest.approx(1.5, abs=1e-4)
    assert T.channel_iors(1.5, 0.0) == (1.5, 1.5, 1.5)
