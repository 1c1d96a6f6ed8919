"""The LOD fit recovers a known mapping from synthetic optima, stays monotone, emits valid GLSL."""

from __future__ import annotations

import json

import numpy as np
import pytest

from compare.research.monotone_fit import fit_lod_mapping
from pbrcheck.lodmap import LodFitError, LodMapping

# Synthetic optima carry +-0.05 LOD of noise (a dense LOD scan's step); the fit must come back
# within twice that everywhere on [0, 1].
RECOVERY_TOL = 0.1


@pytest.mark.parametrize("truth", [
    lambda r: 8 * r,                          # linear
    lambda r: 8 * (0.2 * r + 0.8 * r * r),    # mostly quadratic
    lambda r: 6 * np.sqrt(r),                 # steep start
])
def test_recovers_known_mapping(truth):
    rng = np.random.default_rng(0)
    r = np.linspace(0, 1, 16)
    y = truth(r) + rng.uniform(-0.05, 0.05, r.size)
    m = fit_lod_mapping(r, y, cube_size=256, mip_count=9)
    grid = np.linspace(0, 1, 101)
    assert np.max(np.abs(m(grid) - np.clip(truth(grid), 0, 8))) < RECOVERY_TOL
    assert np.all(np.diff(m(grid)) >= -1e-12)  # monotone


def test_noisy_non_monotone_optima_give_a_monotone_fit():
    r = np.linspace(0, 1, 16)
    y = 7 * r + np.where(np.arange(16) % 2 == 0, 0.6, -0.6)
    m = fit_lod_mapping(r, y, cube_size=128, mip_count=8)
    assert np.all(np.diff(m(np.linspace(0, 1, 200))) >= -1e-12)
    assert m(0.0) == 0.0 and m(1.0) <= 7.0


def test_json_round_trip_and_validation(tmp_path):
    m = fit_lod_mapping(np.linspace(0, 1, 8), 5 * np.linspace(0, 1, 8) ** 2, cube_size=64, mip_count=7)
    p = tmp_path / "fit.json"
    p.write_text(json.dumps({"mappings": {"fitted": m.to_json()}}))
    assert LodMapping.load(p) == m
    p.write_text(json.dumps({"coefficients": [-1, 0, 0, 0, 0, 0], "cube_size": 64, "mip_count": 7}))
    with pytest.raises(LodFitError, match="non-negative"):
        LodMapping.load(p)
    with pytest.raises(LodFitError, match="cannot read"):
        LodMapping.load(tmp_path / "missing.json")


def test_glsl_matches_python():
    """Evaluate the emitted GLSL expression with Python semantics on a grid."""
    m = LodMapping((1.5, 2.0, 0.25, 0.1, 0.7, 0.4), 256, 9)
    src = m.glsl()
    assert "float roughnessToLodFitted(float r)" in src
    expr = src.split("float lod = ")[1].split(";")[0]
    for r in np.linspace(0, 1, 11):
        lod = eval("(" + expr + ")", {"r": r, "sqrt": np.sqrt})
        assert min(max(lod, 0), 8) == pytest.approx(float(m(r)), abs=1e-6)


def test_builtin_smooth_mappings_are_members_of_the_family():
    """linear = M r and quadratic = M r (2 - r) (realtime/shaders/lod.glsl) are exact members, so a
    fit started from either cannot end worse than it."""
    from pbrcheck.lodmap import basis_coefficients, builtin_lod

    r = np.linspace(0, 1, 33)
    for name in ("linear", "quadratic"):
        m = LodMapping(tuple(basis_coefficients(name, 8.0)), 256, 9)
        assert np.max(np.abs(m(r) - builtin_lod(name, r, 8.0, 8.0))) < 1e-12


def test_error_fit_never_worse_than_its_starts():
    """On bumpy measured-like curves (optimum on a noisy quadratic, a bump at an integer level) the
    error objective ends at or below every start it was given, as predicted by the same scan."""
    from compare.research.monotone_fit import fit_lod_to_error, predicted_error

    rng = np.random.default_rng(3)
    r = np.linspace(0, 1, 6)
    grid = np.arange(0, 5.001, 0.25)
    opt = 5 * r * (2 - r) + rng.uniform(-0.4, 0.4, r.size)
    err = 0.1 * np.abs(grid[None, :] - opt[:, None]) ** 1.5 + 0.05 * (np.abs(grid - 3.0) < 0.3)[None, :]
    quad = [0, 0, 0, 0, 0, 5.0]
    lin = [5.0, 0, 0, 0, 0, 0]
    m = fit_lod_to_error(r, grid, err, cube_size=32, mip_count=6, starts=[quad, lin])
    got = predicted_error(m(r), grid, err)
    for c in (quad, lin):
        assert got <= predicted_error(LodMapping(tuple(c), 32, 6)(r), grid, err) + 1e-12
