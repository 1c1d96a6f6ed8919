"""The DFG LUT against the exact quadrature (pbrcheck.brdf), its sampling strategies (GLSL,
numpy and Dr.Jit twins of pbrcheck.registry.LUT_SAMPLINGS) and the whole bake against its numpy and
Dr.Jit twins, the Kd LUT, and the `lut` command."""

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


# Sampled directions: float32 GLSL / Dr.Jit against float64 numpy through sqrt of a cancellation
# (as tests/test_realtime_glsl.SQRT_ULP_DIR); weights and texels: float32 sums of <= 64 terms.
DIR_ATOL = 5e-4
DIR_RTOL = 1e-4
WEIGHT_RTOL = 2e-5
TEXEL_ATOL = 2e-6
STRATEGY_PAIRS = [(e.name, r) for e in registry.LUT_SAMPLINGS for r in e.roles]


def _strategy_grid():
    """u (incl. 0 and 0.999), view cosines 1e-4 .. 1, alpha MIN_ALPHA .. 1, broadcast flat."""
    rng = np.random.default_rng(5)
    u = rng.random((24, 2))
    u[0], u[1] = (0.0, 0.0), (0.999, 0.999)
    nov = np.array([1e-4, 0.05, 0.5, 0.9, 1.0])
    alpha = np.array([1e-7, 1e-3, 0.1, 0.5, 1.0])
    U, NV, AL = np.broadcast_arrays(u[:, None, None, :], nov[None, :, None, None], alpha[None, None, :, None])
    u, nov, alpha = U.reshape(-1, 2), NV[..., 0].ravel(), AL[..., 0].ravel()
    v = np.stack([np.sqrt(1.0 - nov * nov), np.zeros_like(nov), nov], -1)
    return u, v, alpha


@pytest.mark.parametrize("name, role", STRATEGY_PAIRS)
def test_strategy_twins(name, role):
    """Each strategy's half vector and weight: GLSL and Dr.Jit against the numpy twin of the same
    name, for every NDF the strategy applies to (the GLSL NDF switch, numpy / Dr.Jit's argument)."""
    from reference.variant import ensure_variant
    ensure_variant()
    import mitsuba as mi

    from realtime.glsl_harness import run_glsl
    from reference import dfg
    fn = registry.LUT_SAMPLINGS[name].roles[role].glsl
    u, v, alpha = _strategy_grid()
    mv = mi.Vector3f(*[mi.Float(v[:, k]) for k in range(3)])
    for ndf in registry.LUT_SAMPLINGS[name].extra["ndfs"] or registry.NDFS.names:
        if role == "lut_half_vector":
            want = getattr(sampling, fn)(u, v, alpha, ndf)
            got = run_glsl(f"{fn}(vec2(x0, x1), vec3(x2, 0.0, x3), x4)", u[:, 0], u[:, 1], v[:, 0], v[:, 2], alpha,
                           components=3, defines=registry.NDFS.select(ndf))
            np.testing.assert_allclose(got, want, rtol=DIR_RTOL, atol=DIR_ATOL, err_msg=f"{fn} {ndf} GLSL")
            h = getattr(dfg, fn)(mi.Point2f(mi.Float(u[:, 0]), mi.Float(u[:, 1])), mv, mi.Float(alpha), ndf)
            np.testing.assert_allclose(np.array(h).T, want, rtol=DIR_RTOL, atol=DIR_ATOL, err_msg=f"{fn} {ndf} Dr.Jit")
        else:
            h = sampling.lut_half_vector(u, v, alpha, name, ndf)
            G = brdf.G_SmithGGXCorrelated(v[:, 2], np.clip(2.0 * np.sum(v * h, -1) * h[:, 2] - v[:, 2], 0.0, 1.0), alpha)
            want = getattr(sampling, fn)(G, v, h, alpha)
            got = run_glsl(f"{fn}(x0, vec3(x1, 0.0, x2), vec3(x3, x4, x5), x6)", G, v[:, 0], v[:, 2], h[:, 0], h[:, 1],
                           h[:, 2], alpha)
            np.testing.assert_allclose(got, want, rtol=WEIGHT_RTOL, atol=TEXEL_ATOL, err_msg=f"{fn} GLSL")
            mh = mi.Vector3f(*[mi.Float(h[:, k]) for k in range(3)])
            got = getattr(dfg, fn)(mi.Float(G), mv, mh, mi.Float(alpha))
            np.testing.assert_allclose(np.array(got), want, rtol=WEIGHT_RTOL, atol=TEXEL_ATOL, err_msg=f"{fn} Dr.Jit")


@pytest.mark.parametrize("ndf", registry.NDFS.names)
def test_bake_is_its_numpy_and_drjit_twins(ndf):
    """dfg_lut.comp's texels equal pbrcheck.sampling.dfg_lut_texel and reference.dfg.dfg_lut (same
    points, same strategy, same estimator) for every strategy, incl. the smoothest and roughest rows."""
    from reference.variant import ensure_variant
    ensure_variant()
    from reference import dfg
    N, S, geometry = 6, 32, "schlick_ggx_direct" if ndf == "ggx" else "smith_ggx_correlated"
    for strategy in registry.LUT_SAMPLINGS.names:
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
