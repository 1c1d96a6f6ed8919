"""The physically layered coat (pbrcheck/layered.py, issue 36 item 5a): known answers."""

import numpy as np

from pbrcheck import layered as L
from pbrcheck.lobes import fresnel_coat

WI, WO = L.direction(0.8, 0.3), L.direction(0.4, 2.0)
N = 8192


def test_coat_weight_zero_is_the_base():
    b = L.Base()
    f, se = L.layered_brdf(b, L.Coat(0.5, weight=0.0), WI, WO, n=N)
    assert f == float(b.f(WI[None], WO[None])[0]) and se == 0.0


def test_ior_one_smooth_is_the_base():
    b = L.Base(0.7, roughness=0.3)
    f, se = L.layered_brdf(b, L.Coat(0.0, ior=1.0), WI, WO, n=N)
    assert abs(f - float(b.f(WI[None], WO[None])[0])) < 1e-12 and se < 1e-12
    e, se = L.layered_albedo(b, L.Coat(0.0, ior=1.0), WO, n=N)
    assert abs(e - L.base_albedo(b, WO)) < 4 * se + 2e-3


def test_white_lambert_under_smooth_coat_conserves_energy():
    white = L.Base(1.0, lambert=True)
    for mu in (1.0, 0.5, 0.2):
        e, se = L.layered_albedo(white, L.Coat(0.0), L.direction(mu), n=N)
        assert abs(e - 1.0) < 1e-9, (mu, e)
        # the spec's albedo scaling: (1 - Fc) * 1 + Fc * E_coat; E_coat = 1 for the mirror coat
        assert abs(L.spec_albedo(white, L.Coat(0.0), L.direction(mu)) - 1.0) < 1e-12


def test_spec_layering_known_value_rough_coat():
    white = L.Base(1.0, lambert=True)
    c = L.Coat(0.5)
    v = L.direction(0.5)
    from pbrcheck.lobes import AnisotropicGGX
    Fc = float(fresnel_coat(0.5))
    want = (1 - Fc) * L.base_albedo(white, v) + Fc * AnisotropicGGX(0.5).albedo(0.5)
    assert abs(L.spec_albedo(white, c, v) - want) < 1e-12
    assert abs(L.base_albedo(white, v) - 1.0) < 1e-12


def test_smooth_lambert_closed_form():
    for rho in (0.5, 1.0):
        f, se = L.layered_brdf(L.Base(rho, lambert=True), L.Coat(0.0), WI, WO, n=N)
        want = L.smooth_lambert_brdf(rho, WI, WO)
        assert abs(f - want) < 4 * se + 1e-4, (rho, f, want, se)
    # Fbar at IOR 1.5: the classic 0.596 (1 - (1 - F_outside_avg) / eta^2 with F_avg 0.092)
    assert abs(L.internal_reflectance(1.5) - 0.5963) < 1e-3


def test_reciprocity():
    for b, c in ((L.Base(), L.Coat(0.0)), (L.Base(roughness=0.3), L.Coat(0.5))):
        f1, s1 = L.layered_brdf(b, c, WI, WO, n=N, seed=1)
        f2, s2 = L.layered_brdf(b, c, WO, WI, n=N, seed=2)
        assert abs(f1 - f2) < 4 * np.hypot(s1, s2), (f1, f2, s1, s2)


def test_albedo_is_the_brdf_integral():
    """E(v) from the walk = int f(v, l) (n.l) dl from the NEE estimator (a smooth coat, Lambert
    base: f is the closed form, so the integral is a 1-D quadrature)."""
    rho = 0.5
    v = L.direction(0.6)
    x, w = np.polynomial.legendre.leggauss(64)
    mu = 0.5 * (x + 1)
    integral = sum(0.5 * wk * L.smooth_lambert_brdf(rho, L.direction(m), v) * m * 2 * np.pi for m, wk in zip(mu, w))
    e, se = L.layered_albedo(L.Base(rho, lambert=True), L.Coat(0.0), v, n=N)
    F = L.fresnel_exact(0.6, 1.0, 1.5)
    assert abs(e - (F + integral)) < 4 * se + 1e-4, (e, F + integral)


def test_seeded():
    a = L.layered_albedo(L.Base(), L.Coat(0.25), WO, n=2048, seed=7)
    b = L.layered_albedo(L.Base(), L.Coat(0.25), WO, n=2048, seed=7)
    assert a == b and a[1] > 0


def test_layered_coat_command(tmp_path, capsys):
    import json

    import pbrcheck_cli as cli
    from compare.research import layered_coat

    rows = layered_coat.run_layered_coat(samples=512, roughness=(0.0,), nov=(1.0,))
    r = rows[0]
    # the smooth coat over the grey base: the spec's layering is brighter than the walk (finding in
    # docs/research.md: ~1.59x at n.v 1); the white furnace under a smooth coat is 1
    assert 1.4 < r.albedo_spec / r.albedo < 1.8 and abs(r.furnace - 1.0) < 1e-9
    assert len(r.brdf) == len(layered_coat.LIGHTS)
    out = tmp_path / "lc.json"
    assert cli.main(["layered-coat", "--samples", "256", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert text.count("\n| ") == len(layered_coat.ROUGHNESS) * len(layered_coat.NOV)  # rows after the header
    data = json.loads(out.read_text())
    assert [d["roughness"] for d in data[::3]] == list(layered_coat.ROUGHNESS)


def test_bad_directions_are_typed_errors():
    import pytest

    from pbrcheck.errors import PbrcheckError
    with pytest.raises(PbrcheckError, match="wo must be a unit 3-vector above"):
        L.layered_brdf(L.Base(), L.Coat(), WI, np.array([0.0, 0.0, -1.0]), n=16)
    with pytest.raises(PbrcheckError, match="v must be a unit"):
        L.layered_albedo(L.Base(), L.Coat(), np.array([0.0, 0.0, 2.0]), n=16)
    with pytest.raises(PbrcheckError, match="at least 2"):
        L.layered_albedo(L.Base(), L.Coat(), WI, n=1)


# --- the multiple-scattering interface: a random walk on the coat's Smith microsurface [Heitz16] ----

#: Standard errors within which a Monte Carlo estimate must meet its known answer.
MS_SIGMAS = 5.0


def _ms_walks(alpha, mu, n, seed):
    """n walks of the bare interface (IOR 1.5 below) entered at cosine ``mu``: (reflected weight,
    transmitted weight, exit directions, event counts)."""
    w = np.broadcast_to(L.direction(mu), (n, 3)).copy()
    ev = np.zeros(n, dtype=np.int64)
    r, wr, t, wt = L._interface_ms(alpha, w, 1.5, np.random.default_rng(seed), events=ev)
    return wr, wt, np.where((wr == 1.0)[:, None], r, t), ev


def test_ms_interface_first_order_is_the_height_correlated_microfacet_reflection():
    """[Heitz16]: the walk's single-scattering part is the classic microfacet BRDF with the
    height-correlated masking-shadowing G2 = 1 / (1 + L(i) + L(o)): the share of walks reflected
    after exactly one event = E over visible normals of F(i.h) G2 / G1(i)."""
    from pbrcheck.lobes import AnisotropicGGX, fresnel_exact

    n = 200_000
    for rough, mu in ((0.5, 0.9), (1.0, 0.4)):
        wr, _, _, ev = _ms_walks(rough ** 2, mu, n, seed=3)
        first = ((wr == 1.0) & (ev == 1)).astype(float)
        g = AnisotropicGGX(rough)
        w = np.broadcast_to(L.direction(mu), (n, 3))
        h = g.sample_h(w, np.random.default_rng(4).random((n, 2)))
        c = np.sum(w * h, axis=-1)
        o = 2.0 * c[:, None] * h - w
        up = o[:, 2] > 0
        lo = g.Lambda(np.where(up[:, None], o, L._UP))
        ss = np.where(up, fresnel_exact(c, 1.0, 1.5) * (1.0 + g.Lambda(w)) / (1.0 + g.Lambda(w) + lo), 0.0)
        se = np.hypot(first.std(), ss.std()) / np.sqrt(n)
        assert abs(first.mean() - ss.mean()) < MS_SIGMAS * se, (rough, mu, first.mean(), ss.mean(), se)
        # higher orders add reflection (the single-scattering interface's loss, returned): most at
        # roughness 1 and grazing (0.0335 against 0.0283 measured)
        assert wr.mean() > first.mean() + (10 * se if rough == 1.0 else 0.0)


def test_ms_interface_conserves_energy_and_no_walk_is_cut():
    """Every walk leaves the interface above or below (weights 1, never both, never neither), with
    exit directions on the side it left; none reaches MS_MAX_EVENTS."""
    for rough in (0.25, 1.0):
        wr, wt, d, ev = _ms_walks(rough ** 2, 0.2, 50_000, seed=5)
        assert np.array_equal(wr + wt, np.ones_like(wr))
        assert np.all(d[wr == 1.0, 2] > 0) and np.all(d[wt == 1.0, 2] < 0)
        assert ev.max() < L.MS_MAX_EVENTS and ev.min() >= 1


def test_ms_coat_white_furnace_is_one_where_the_single_scattering_coat_loses_energy():
    white = L.Base(1.0, lambert=True)
    for rough, mu in ((0.5, 0.5), (1.0, 0.2)):
        v = L.direction(mu)
        e_ms, _ = L.layered_albedo(white, L.Coat(rough, interface="multiple"), v, n=2048, seed=1)
        e_ss, _ = L.layered_albedo(white, L.Coat(rough), v, n=2048, seed=1)
        assert abs(e_ms - 1.0) < 1e-12 and e_ss < 0.8


def test_ms_coat_tends_to_the_smooth_coat():
    """At coat roughness 0.02 the walk on the microsurface gives the smooth coat's albedo over the grey
    base (the exact smooth walk) within the combined standard errors."""
    base = L.Base(0.5, 0.0, 0.5, 0.04)
    for mu in (1.0, 0.5):
        v = L.direction(mu)
        a, sa = L.layered_albedo(base, L.Coat(0.02, interface="multiple"), v, n=8192, seed=2)
        b, sb = L.layered_albedo(base, L.Coat(0.0), v, n=8192, seed=3)
        assert abs(a - b) < MS_SIGMAS * np.hypot(sa, sb), (mu, a, b)


def test_ms_interface_typed_errors():
    import pytest

    from pbrcheck.errors import PbrcheckError
    with pytest.raises(PbrcheckError, match="interface must be one of single, multiple"):
        L.Coat(0.5, interface="double")
    with pytest.raises(PbrcheckError, match="single-scattering rough interface only"):
        L.layered_brdf(L.Base(), L.Coat(0.5, interface="multiple"), WI, WI, n=16)
