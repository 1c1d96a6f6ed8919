"""Specular anti-aliasing / normal-map filtering and alpha-to-coverage terms: GLSL
(realtime/shaders/specular_aa.glsl, coverage.glsl) against the numpy twins (pbrcheck/specular_aa.py,
pbrcheck/coverage.py) on grids including the extremes, the known answers of each term, and the
prefiltered bake (slope variance per mip)."""

from __future__ import annotations

import numpy as np

from pbrcheck.coverage import alpha_to_coverage_sharpen
from pbrcheck.specular_aa import (
    SCREEN_SPACE_THRESHOLD,
    slope_variance_mips,
    specular_aa_prefiltered,
    specular_aa_screen_space,
    specular_aa_toksvig,
    specular_aa_widen,
)
from realtime.dispatch import specular_aa
from realtime.registry import SPECULAR_AAS
from realtime.glsl_harness import run_glsl

#: float32 GLSL (two square roots of alpha^2 + v) against the float64 twins.
GLSL_ATOL = 2e-6

ROUGH = np.array([0.0, 1e-4, 0.05, 0.1, 0.25, 0.5, 0.75, 0.9, 1.0])
LENGTHS = np.array([1e-4, 0.01, 0.3, 0.5, 0.8, 0.95, 0.999, 1.0, 1.001, 1.5])
VARIANCES = np.array([0.0, 1e-8, 1e-4, 0.01, 0.1, 0.5, 1.0, 4.0])


def test_twins_on_grids_with_extremes():
    r, L = np.meshgrid(ROUGH, LENGTHS, indexing="ij")
    assert np.allclose(run_glsl("specular_aa_toksvig(x0, x1)", r, L), specular_aa_toksvig(r, L), atol=GLSL_ATOL, rtol=0)
    r, v = np.meshgrid(ROUGH, VARIANCES, indexing="ij")
    assert np.allclose(run_glsl("specular_aa_widen(x0, x1)", r, v), specular_aa_widen(r, v), atol=GLSL_ATOL, rtol=0)
    assert np.allclose(run_glsl("specular_aa_screen_space(x0, x1)", r, v), specular_aa_screen_space(r, v),
                       atol=GLSL_ATOL, rtol=0)
    assert np.allclose(run_glsl("specular_aa_prefiltered(x0, x1)", r, v), specular_aa_prefiltered(r, v),
                       atol=GLSL_ATOL, rtol=0)
    r, L, v, d = np.meshgrid(ROUGH, LENGTHS[::3], VARIANCES[::2], VARIANCES[1::2], indexing="ij")
    for name in SPECULAR_AAS.names:
        g = run_glsl("specular_aa(x0, x1, x2, x3)", r, L, v, d, defines=SPECULAR_AAS.select(name))
        assert np.allclose(g, specular_aa(r, L, v, d, name), atol=GLSL_ATOL, rtol=0), name


def test_known_answers():
    """No variance, no change (to the bit, GLSL too): a unit-length (or longer, unnormalised 8-bit)
    normal for toksvig, zero derivatives for screen_space, zero baked variance for prefiltered.
    Otherwise the roughness only grows, screen_space by at most the threshold, and stays <= 1."""
    r = ROUGH.astype(np.float32)
    for expr in ("specular_aa_toksvig(x0, 1.0)", "specular_aa_toksvig(x0, 1.0000154)",
                 "specular_aa_screen_space(x0, 0.0)", "specular_aa_prefiltered(x0, 0.0)"):
        assert np.array_equal(run_glsl(expr, r), r), expr
    assert np.array_equal(specular_aa_toksvig(ROUGH, 1.0), ROUGH)
    assert np.array_equal(specular_aa_screen_space(ROUGH, 0.0), ROUGH)
    r, L = np.meshgrid(ROUGH, LENGTHS, indexing="ij")
    t = specular_aa_toksvig(r, L)
    assert np.all(t >= r) and np.all(t <= 1.0)
    # Toksvig's sigma^2 = (1 - L) / L: L = 0.5 gives alpha^2 + 2
    assert np.allclose(specular_aa_toksvig(0.5, 0.5), 1.0)
    s = specular_aa_screen_space(0.0, np.array([1e3, 1e9]))
    assert np.allclose(s, SCREEN_SPACE_THRESHOLD ** 0.25)


def test_alpha_to_coverage_twin_and_known_answers():
    a, c, w = np.meshgrid(np.linspace(0, 1, 11), np.array([0.0, 0.5, 1.0]), np.array([0.0, 1e-5, 0.1, 1.0, 4.0]),
                          indexing="ij")
    assert np.allclose(run_glsl("alpha_to_coverage_sharpen(x0, x1, x2)", a, c, w), alpha_to_coverage_sharpen(a, c, w),
                       atol=GLSL_ATOL, rtol=0)
    assert alpha_to_coverage_sharpen(0.5, 0.5, 0.1) == 0.5          # the cutoff: half the samples
    assert alpha_to_coverage_sharpen(0.6, 0.5, 0.1) == 1.0 and alpha_to_coverage_sharpen(0.4, 0.5, 0.1) == 0.0
    assert alpha_to_coverage_sharpen(0.51, 0.5, 0.0) == 1.0         # constant alpha: the alpha test


def test_slope_variance_mips():
    """Level sizes follow GL's mips; a flat (or any constant) map has zero variance on every level; a
    map of two slopes +-s in a checker has variance s^2 per axis from level 1 on (0 at level 0)."""
    flat = np.zeros((8, 4, 3))
    flat[...] = (0.5, 0.5, 1.0)
    tilted = np.zeros((8, 4, 3))
    tilted[...] = (0.7, 0.4, 0.9)
    for tex in (flat, tilted):
        mips = slope_variance_mips(tex, 4)
        assert [m.shape for m in mips] == [(8, 4), (4, 2), (2, 1), (1, 1)]
        assert all(np.all(m == 0.0) for m in mips)
    s = 0.3
    n = np.array([s, 0.0, 1.0]) / np.hypot(s, 1.0)
    check = np.indices((8, 8)).sum(0) % 2
    tex = np.where(check[..., None] > 0, n * [1, 1, 1], n * [-1, 1, 1]) * 0.5 + 0.5
    mips = slope_variance_mips(tex, 4)
    assert np.all(mips[0] == 0.0)
    for m in mips[1:]:
        assert np.allclose(m, s * s, rtol=1e-6)
