"""BRDF terms in numpy: normalization, bounds, reciprocity, energy, extremes."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pbrcheck import brdf
from pbrcheck.brdf import (D_Beckmann, D_BlinnPhong, D_GGX, F_Schlick, G1_SchlickGGX, G1_SmithGGX,
                           G_SchlickGGX, G_SmithGGX, G_SmithGGXCorrelated, alpha_from_roughness,
                           brdf_eval, diffuse_albedo, geometry_term, specular_albedo, specular_dfg)
from pbrcheck.scene import GEOMETRY_NAMES, NDF_NAMES

# The projected NDF integrates to 1; a piecewise Gauss-Legendre rule resolves every lobe to ~1e-9,
# so 1e-6 leaves room for float64 cancellation in 1 - cos^2 at the narrowest lobe (roughness 0.02).
NDF_NORMALIZATION_TOL = 1e-6
# Two independent quadratures of the directional albedo (half-vector rule vs a dense light-direction
# grid at moderate roughness) agree to this; the light-direction grid is the coarser (~1e-4).
ALBEDO_CROSSCHECK_TOL = 5e-4
# Energy: a white-furnace albedo may exceed 1 by no more than quadrature error.
ENERGY_TOL = 1e-6
ROUGHNESSES = [0.02, 0.05, 0.1, 0.25, 0.5, 0.75, 1.0]


def _projected_ndf_integral(ndf, alpha):
    """int D(h) cos(theta) dw over the hemisphere = int 2 pi D cos sin dtheta, split at the lobe's
    scale atan(alpha 2^k) so a narrow lobe is resolved as well as a wide one."""
    cuts = sorted({0.0, np.pi / 2} | {float(np.arctan(alpha * 2.0 ** k)) for k in range(-3, 40)
                                     if np.arctan(alpha * 2.0 ** k) < np.pi / 2 - 1e-9})
    x, w = np.polynomial.legendre.leggauss(40)
    total = 0.0
    for a, b in zip(cuts[:-1], cuts[1:]):
        t = 0.5 * (b - a) * (x + 1) + a
        total += np.sum(0.5 * (b - a) * w * 2 * np.pi * ndf(np.cos(t), alpha) * np.cos(t) * np.sin(t))
    return total


@pytest.mark.parametrize("ndf", [D_GGX, D_Beckmann, D_BlinnPhong])
@pytest.mark.parametrize("roughness", ROUGHNESSES)
def test_projected_ndf_integrates_to_one(ndf, roughness):
    alpha = float(alpha_from_roughness(roughness))
    assert _projected_ndf_integral(ndf, alpha) == pytest.approx(1.0, abs=NDF_NORMALIZATION_TOL)


cosines = st.floats(0.0, 1.0)
roughness_st = st.floats(0.0, 1.0)


@settings(max_examples=300, deadline=None)
@given(cosines, cosines, roughness_st)
def test_geometry_terms_in_unit_interval(nv, nl, r):
    for g in GEOMETRY_NAMES:
        v = float(geometry_term(g, nv, nl, r))
        assert 0.0 <= v <= 1.0 + 1e-12, (g, nv, nl, r, v)
    a = float(alpha_from_roughness(r))
    assert 0.0 <= float(G1_SmithGGX(nv, a)) <= 1.0 + 1e-12
    assert 0.0 <= float(G1_SchlickGGX(nv, brdf.k_schlick_direct(r))) <= 1.0 + 1e-12


def test_correlated_is_at_least_separable():
    """Heitz 2014 sec. 6: the height-correlated form is >= the separable product."""
    nv, nl, r = np.meshgrid(np.linspace(0.01, 1, 20), np.linspace(0.01, 1, 20), np.linspace(0.05, 1, 8))
    a = alpha_from_roughness(r)
    assert np.all(G_SmithGGXCorrelated(nv, nl, a) >= G_SmithGGX(nv, nl, a) - 1e-12)


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


@settings(max_examples=200, deadline=None)
@given(st.floats(0.01, 1.0), st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1),
       st.sampled_from(NDF_NAMES), st.sampled_from(GEOMETRY_NAMES))
def test_reciprocity(r, vx, vy, lx, ly, ndf, geometry):
    n = np.array([0.0, 0.0, 1.0])
    v = _unit([vx, vy, 0.5])
    l = _unit([lx, ly, 0.7])
    kw = dict(base_color=[0.8, 0.5, 0.2], metallic=0.3, roughness=r, specular=0.04, ndf=ndf, geometry=geometry)
    np.testing.assert_allclose(brdf_eval(n, v, l, **kw), brdf_eval(n, l, v, **kw), rtol=1e-10, atol=1e-12)


#: Beckmann's masking paired with another NDF is not energy-bounded (see below): not a furnace case.
MISMATCHED = {("ggx", "smith_beckmann_correlated"), ("blinn_phong", "smith_beckmann_correlated")}


@pytest.mark.parametrize("ndf, geometry", [(n, g) for g in GEOMETRY_NAMES for n in NDF_NAMES if (n, g) not in MISMATCHED])
def test_white_furnace_albedo_at_most_one(ndf, geometry):
    """White furnace of the specular lobe (metal, F0 = 1): directional albedo <= 1 everywhere, and
    of the whole dielectric BRDF (white base colour) near normal incidence. Beckmann's masking
    (smith_beckmann_correlated) only with Beckmann's D: its Lambda is far smaller than GGX's for
    grazing directions, so with GGX's long-tailed D (1.0035 at roughness 0.02, n.v = 0.001) or
    Blinn-Phong's (uniform at roughness 1: 1.76 at n.v = 0.001) the mismatched pair reflects more
    than it receives (a property of the combination, which a scene may still name; pinned by
    :func:`test_beckmann_masking_with_another_ndf_gains_energy`)."""
    for r in [0.0, 0.02, 0.3, 0.7, 1.0]:
        for nv in [1.0, 0.7, 0.3, 0.05, 1e-3]:
            assert specular_albedo(nv, r, 1.0, ndf=ndf, geometry=geometry) <= 1.0 + ENERGY_TOL
        for nv in [1.0, 0.9]:
            e = specular_albedo(nv, r, 0.04, ndf=ndf, geometry=geometry) + diffuse_albedo(nv, r, 0.04)
            assert e <= 1.0 + ENERGY_TOL


@pytest.mark.parametrize("ndf", sorted(n for n, _ in MISMATCHED))
def test_beckmann_masking_with_another_ndf_gains_energy(ndf):
    """The mismatched pairs excluded above do exceed 1 at grazing angles (so excluding them is a
    statement about the model, measured here, not a hidden failure)."""
    worst = max(specular_albedo(1e-3, r, 1.0, ndf=ndf, geometry="smith_beckmann_correlated")
                for r in (0.02, 0.3, 0.7, 1.0))
    assert worst > 1.0 + ENERGY_TOL


def test_dielectric_model_gains_energy_at_grazing_angles():
    """A documented property of the specified material model, not a bug of this code: the diffuse
    weight ``(1 - F(v.h))`` is taken per light direction, so it does not remove the energy the
    specular lobe reflects. A white dielectric's albedo exceeds 1 towards grazing view (~1.15 for a
    mirror at n.v = 0.3, ~1.9 at n.v = 0.001). If this test fails, the model changed: update the
    README's "Material model" section with it."""
    e = lambda nv, r: specular_albedo(nv, r, 0.04) + diffuse_albedo(nv, r, 0.04)
    assert e(0.3, 0.0) == pytest.approx(1.1509, abs=1e-3)
    assert e(1e-3, 0.0) > 1.9
    assert e(1.0, 0.0) == pytest.approx(1.0 - 0.04 + 0.04, abs=1e-3)


def test_albedo_crosscheck_against_light_direction_grid():
    """The half-vector quadrature vs brute force over a dense (theta_l, phi_l) grid of brdf_eval."""
    n = np.array([0.0, 0.0, 1.0])
    th, wt = np.polynomial.legendre.leggauss(400)
    th = 0.25 * np.pi * (th + 1)
    wt = 0.25 * np.pi * wt
    ph, wp = np.polynomial.legendre.leggauss(400)
    ph = 0.5 * np.pi * (ph + 1)          # [0, pi], doubled by symmetry
    wp = 0.5 * np.pi * wp * 2
    T, P = np.meshgrid(th, ph, indexing="ij")
    l = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1)
    W = (wt[:, None] * wp[None, :]) * np.sin(T) * np.cos(T)
    for geometry in GEOMETRY_NAMES:
        for r, nv in [(0.5, 0.8), (0.7, 0.3), (1.0, 0.1)]:
            v = np.array([np.sqrt(1 - nv * nv), 0.0, nv])
            f = brdf_eval(n, v, l, base_color=[1, 1, 1], metallic=1.0, roughness=r, specular=0.0, geometry=geometry)
            brute = float(np.sum(f[..., 0] * W))
            assert specular_albedo(nv, r, 1.0, geometry=geometry) == pytest.approx(brute, abs=ALBEDO_CROSSCHECK_TOL)


def test_dfg_known_values():
    # roughness 0: the mirror limit, A + B = 1 and B = (1 - n.v)^5 (Schlick)
    A, B = specular_dfg(0.5, 0.0)
    assert (A, B) == pytest.approx((1 - 0.5 ** 5, 0.5 ** 5), abs=1e-12)
    # ... and the quadrature tends to it, for every geometry term (schlick_ggx_direct keeps
    # k = 1/8 at roughness 0, so its limit is G1(n.v, 1/8)^2, not 1)
    # A lobe this narrow (alpha 1.2e-4) is a mirror weighted by G(v, v) at its own roughness.
    for geometry in GEOMETRY_NAMES:
        A2, B2 = specular_dfg(0.5, 0.011, geometry=geometry)
        g = float(geometry_term(geometry, 0.5, 0.5, 0.011))
        assert (A2, B2) == pytest.approx((g * A, g * B), abs=1e-5)
    g = (0.5 / (0.5 * (1 - 1 / 8) + 1 / 8)) ** 2
    assert sum(specular_dfg(0.5, 0.0, geometry="schlick_ggx_direct")) == pytest.approx(g, abs=1e-12)
    # roughness 1, n.v = 1, separable Smith with GGX: a closed form is not simple, but the
    # correlated and separable forms coincide at n.v = 1 only through G1(v) = 1 -> both equal
    assert sum(specular_dfg(1.0, 1.0, geometry="smith_ggx")) == pytest.approx(
        sum(specular_dfg(1.0, 1.0, geometry="smith_ggx_correlated")), rel=0.2)


def test_quadrature_converges():
    for ndf in NDF_NAMES:
        for r, nv in [(0.5, 1.0), (0.1, 1e-3), (1.0, 1e-3), (0.05, 0.3)]:
            a = specular_dfg(nv, r, ndf=ndf)
            b = specular_dfg(nv, r, ndf=ndf, n_theta=96, n_phi=160)
            assert a == pytest.approx(b, abs=1e-7)


@pytest.mark.parametrize("r", [0.0, 1e-4, 1.0])
@pytest.mark.parametrize("nv", [1.0, 1e-6, 0.0])
@pytest.mark.parametrize("nl", [1.0, 1e-6, 0.0])
def test_finite_at_extremes(r, nv, nl):
    a = alpha_from_roughness(r)
    for f in (D_GGX, D_Beckmann, D_BlinnPhong):
        for noh in (0.0, 1e-6, 0.5, 1.0):
            assert np.isfinite(f(noh, a)) and f(noh, a) >= 0
    for g in GEOMETRY_NAMES:
        assert np.isfinite(geometry_term(g, nv, nl, r))
    assert np.isfinite(G_SchlickGGX(nv, nl, 0.0))
    n = np.array([0.0, 0.0, 1.0])
    v = np.array([np.sqrt(1 - nv * nv), 0.0, nv])
    l = np.array([-np.sqrt(1 - nl * nl), 0.0, nl])
    for ndf in NDF_NAMES:
        for geo in GEOMETRY_NAMES:
            assert np.all(np.isfinite(brdf_eval(n, v, l, [1, 1, 1], 0.5, r, 0.04, ndf=ndf, geometry=geo)))
    assert all(np.isfinite(specular_dfg(max(nv, 0.0), r)))


def test_fresnel_schlick_endpoints():
    assert F_Schlick(1.0, 0.04) == pytest.approx(0.04)
    assert F_Schlick(0.0, 0.04) == pytest.approx(1.0)
    np.testing.assert_allclose(F_Schlick(np.array([0.5])[..., None], np.array([0.1, 0.5, 1.0])),
                               [[0.1 + 0.9 / 32, 0.5 + 0.5 / 32, 1.0]])


def test_fresnel_none_removes_diffuse():
    n = np.array([0.0, 0.0, 1.0])
    v = _unit([0.3, 0.0, 1.0])
    l = _unit([-0.2, 0.1, 1.0])
    f = brdf_eval(n, v, l, [1, 1, 1], 0.0, 1.0, 0.04, fresnel="none")
    spec_only = brdf_eval(n, v, l, [1, 1, 1], 1.0, 1.0, 1.0, fresnel="schlick")  # F0 = 1 -> F = 1
    np.testing.assert_allclose(f, spec_only, rtol=1e-12)


#: 4096 Hammersley points estimate the lobe's albedo to well within this (measured: < 0.03% for each NDF).
LOBE_MC_RTOL = 1e-2


@pytest.mark.parametrize("ndf", NDF_NAMES)
def test_specular_lobe_sample_pdf_and_eval_agree_with_its_albedo(ndf):
    """The lobe object's importance-sampling estimate of ``int f cos dl`` (its sample, pdf and eval
    on 4096 Hammersley points) equals its quadrature albedo within LOBE_MC_RTOL; the diffuse lobe's
    pdf integrates to 1 over the hemisphere (midpoints in cos theta: exact)."""
    from pbrcheck import sampling
    lobe = brdf.SpecularLobe(ndf, "smith_ggx_correlated", "none")
    NoV, r, n = 0.6, 0.5, 4096
    v = np.array([np.sqrt(1.0 - NoV * NoV), 0.0, NoV])
    h = lobe.sample(sampling.hammersley(np.arange(n), n), r)
    VoH = h @ v
    l = 2.0 * VoH[:, None] * h - v
    ok = (l[:, 2] > 0) & (VoH > 0)
    f = lobe.eval(np.full(n, NoV), l[:, 2], h[:, 2], np.ones((n, 3)), r)[:, 0]
    est = np.sum(np.where(ok, f * l[:, 2] / lobe.pdf(h[:, 2], VoH, r), 0.0)) / n
    assert est == pytest.approx(lobe.albedo(NoV, r), rel=LOBE_MC_RTOL)
    c = (np.arange(n) + 0.5) / n  # uniform hemisphere directions: d omega = 2 pi dc
    assert 2.0 * np.pi * np.mean(brdf.DiffuseLobe.pdf(c)) == pytest.approx(1.0, rel=1e-12)
