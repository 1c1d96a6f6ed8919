"""The LOD fit recovers a known mapping from synthetic optima, stays monotone, emits valid GLSL."""

from __future__ import annotations

import json

import numpy as np
import pytest

from compare.lodfit import LodFitError, LodMapping, fit_lod_mapping

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
    p.write_text(json.dumps({"coefficients": [-1, 0, 0, 0, 0], "cube_size": 64, "mip_count": 7}))
    with pytest.raises(LodFitError, match="non-negative"):
        LodMapping.load(p)
    with pytest.raises(LodFitError, match="cannot read"):
        LodMapping.load(tmp_path / "missing.json")


def test_glsl_matches_python():
    """Evaluate the emitted GLSL expression with Python semantics on a grid."""
    m = LodMapping((1.5, 2.0, 0.25, 0.1, 0.7), 256, 9)
    src = m.glsl()
    assert "float roughnessToLodFitted(float r)" in src
    expr = src.split("float lod = ")[1].split(";")[0]
    for r in np.linspace(0, 1, 11):
        lod = eval(expr, {"r": r, "sqrt": np.sqrt})
        assert min(max(lod, 0), 8) == pytest.approx(float(m(r)), abs=1e-6)
