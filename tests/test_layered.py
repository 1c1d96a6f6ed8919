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
