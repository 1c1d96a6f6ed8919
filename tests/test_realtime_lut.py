"""The DFG LUT against the exact quadrature (pbrcheck.brdf) and the whole bake against its numpy
and Dr.Jit twins for every sampling strategy (the strategies' functions: tests/test_realtime_sampling.py),
the Kd LUT, and the `lut` command."""

from __future__ import annotations

import numpy as np
import pytest

from pbrcheck import brdf, registry, sampling
from pbrcheck.exr import read_exr
from realtime.presets import resolve_options
from realtime.render import dfg_lut, read_lut

# The accuracy goal for the default LUT at f32, for every geometry variant.
GOAL_MAX_ABS = 1e-3
GOAL_MEAN_ABS = 2e-4
# Rows checked: the reference costs ~2 ms per texel; all of them fit the test budget.

LUT_GEOMETRIES = ("smith_ggx_correlated", "smith_ggx", "schlick_ggx_ibl", "schlick_ggx_direct")

_ref_cache: dict = {}


def _reference(geometry, N, rows):
    key = (geometry, N, tuple(rows))
    if key not in _ref_cache:
        c = (np.arange(N) + 0.5) / N
        _ref_cache[key] = np.array([[brdf.specular_dfg(nv, c[j], geometry=geometry) for nv in c]
                                    for j in rows])
    return _ref_cache[key]


def _rows(N):
    return list(range(N))


# The bake's texels: float32 sums of <= 32 terms (GLSL, Dr.Jit) against float64 numpy.
TEXEL_ATOL = 2e-6


@pytest.mark.parametrize("ndf", registry.NDFS.names)
def test_bake_is_its_numpy_and_drjit_twins(ndf):
    """dfg_lut.comp's texels equal pbrcheck.sampling.dfg_lut_texel and reference.sampling.dfg_lut (same
    points, same strategy, same estimator) for every strategy, incl. the smoothest and roughest rows."""
    from reference.variant import ensure_variant
    ensure_variant()
    from reference import sampling as dfg
    N, S, geometry = 6, 32, "schlick_ggx_direct" if ndf == "ggx" else "smith_ggx_correlated"
    for strategy in sampling.LUT_SAMPLINGS.names:
        lut = read_lut(dfg_lut(N, S, "f32", geometry, ndf, strategy))
        want = np.array([[sampling.dfg_lut_texel((i + 0.5) / N, (j + 0.5) / N, S, geometry, ndf, strategy)
                          for i in range(N)] for j in range(N)])
        np.testing.assert_allclose(lut, want, rtol=0, atol=TEXEL_ATOL, err_msg=f"GLSL {strategy}")
        np.testing.assert_allclose(dfg.dfg_lut(N, S, geometry, ndf, strategy), want, rtol=0, atol=TEXEL_ATOL,
                                   err_msg=f"Dr.Jit {strategy}")


@pytest.mark.slow
@pytest.mark.parametrize("geometry", LUT_GEOMETRIES)
def test_default_lut_meets_the_accuracy_goal(geometry):
    o = resolve_options("default")
    assert o["lut_format"] == "f32"
    N = o["lut_size"]
    lut = read_lut(dfg_lut(N, o["lut_samples"], "f32", geometry, "ggx", o["lut_sampling"]))
    rows = _rows(N)
    err = np.abs(lut[rows] - _reference(geometry, N, rows))
    assert err.max() <= GOAL_MAX_ABS, f"max {err.max():.2e} at {np.unravel_index(err.argmax(), err.shape)}"
    assert err.mean() <= GOAL_MEAN_ABS, f"mean {err.mean():.2e}"


def test_article000_lut_misses_the_goal_at_grazing_angles():
    """1024 GGX half-vector samples (article 000's LUT): several times the goal at grazing n.v."""
    o = resolve_options("splitsum_basic")
    N = 64
    lut = read_lut(dfg_lut(N, o["lut_samples"], "f32", "schlick_ggx_direct", "ggx", o["lut_sampling"]))
    rows = _rows(N)
    err = np.abs(lut[rows] - _reference("schlick_ggx_direct", N, rows))
    assert err.max() > 2 * GOAL_MAX_ABS


def test_lut_axes_and_f16():
    """Row 0 smoothest (A + B ~ 1 at n.v ~ 1), columns increasing n.v; f16 within its precision."""
    lut32 = read_lut(dfg_lut(16, 1024, "f32", "smith_ggx_correlated"))
    lut16 = read_lut(dfg_lut(16, 1024, "f16", "smith_ggx_correlated"))
    s = lut32.sum(-1)
    assert s[0, -1] > 0.99 and s[-1, -1] < 0.9          # smooth row holds energy, rough row loses some
    assert np.all(np.diff(lut32[0, :, 0]) > 0)           # A grows with n.v on the smooth row
    # half floats: 11 significant bits -> relative 2^-11 = 4.9e-4 on values <= 1
    assert np.abs(lut16 - lut32).max() <= 2.0 ** -11
    assert np.all(np.isfinite(lut32)) and np.all(np.isfinite(lut16))


def test_kd_lut_matches_diffuse_albedo():
    from realtime.render import kd_lut
    from realtime.gl import get_context

    N = 32
    tex = kd_lut(N, {})
    kd = np.frombuffer(tex.read(), np.float32)
    c = (np.arange(N) + 0.5) / N
    ref = np.array([brdf.diffuse_albedo(x, 0.5, 0.0) for x in c])
    # 4096 stratified cosine samples of a smooth integrand: < 1e-3
    assert np.abs(kd - ref).max() < 1e-3
    assert get_context() is not None


def test_envbrdf_approx_is_rough_but_bounded():
    """Karis's fit vs the exact DFG: far from LUT accuracy (measured worst 0.31, at grazing n.v and
    roughness 0.9, where the fit's B stays high); bounded so a broken fit (e.g. swapped A/B) fails."""
    c = (np.arange(8) + 0.5) / 8
    worst = 0.0
    for r in (0.1, 0.5, 0.9):
        ex = np.array([brdf.specular_dfg(x, r) for x in c])
        worst = max(worst, np.abs(brdf.EnvBRDFApprox(c, r) - ex).max())
    assert 1e-2 < worst < 0.4


def test_lut_command_writes_channels_A_and_B(tmp_path):
    from pbrcheck.cli import main

    out = tmp_path / "lut.exr"
    assert main(["lut", "--size", "8", "--samples", "256", "--format", "f16", "--out", str(out)]) == 0
    img = read_exr(out, require=("A", "B"))
    assert img.shape == (8, 8)
    assert img.channels["A"][0, -1] > 0.9            # row 0 smoothest, last column n.v ~ 1
    assert main(["lut", "--size", "8", "--format", "f64", "--out", str(out)]) == 2
