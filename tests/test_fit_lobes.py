"""The lobes' inverse fits by AD (compare/research/fit_lobes.py, realtime/fitted_lobes.py; issue 36 item 5b):
the sheen albedo table (checked against its closed least-squares solution) and the anisotropic bend weight
(checked against a dense scan), their held-out errors, the generated module and its GLSL."""

import numpy as np
import pytest

from compare.research import fit_lobes as F
from realtime import fitted_lobes
from realtime.lobes import lut_bilinear

#: The fitted table's stated tolerance against the quadrature on the held-out grid (docs/research.md):
#: rms 0.027 measured; max 0.103 for n.v >= 0.1 (the corner n.v, roughness -> 0 is singular).
SHEEN_TABLE_RMS_TOL = 0.03
SHEEN_TABLE_MAX_TOL = 0.11
#: The Dr.Jit loss against the numpy objective it transcribes (float64 both; sums in other orders).
LOSS_RTOL = 1e-10
#: Central differences of the aniso loss (step 1e-4) against dr.backward's gradient: the truncation
#: error h^2 |f'''| / 6 is ~1e-8 against gradients of order 0.1-10.
GRAD_RTOL = 1e-4
#: A frozen step (issue 39) against the traced one: the same float64 operations, sums maybe reduced in
#: another order (measured: 1e-16 on the sheen table after 3000 steps, 8e-16 on the bend weights).
FROZEN_RTOL = 1e-12


def test_sheen_ad_fit_is_the_least_squares_solution_fast():
    """The AD loop (Dr.Jit loss of the table's read, Adam from 0) ends at the closed least-squares
    solution on a synthetic target (a smooth function of the grid: no quadrature, fast)."""
    nov, r = F.train_grid()
    c = F.table_coords(nov, "sqrt_nov")
    target = np.exp(-3.0 * c) * (1.0 + r) + 0.2 * r * r
    f = F.sheen_loss_and_grad(F.SHEEN_TABLE_N, c, r, target)
    table, losses = F.adam(f, np.zeros(F.SHEEN_TABLE_N ** 2), *F.SHEEN_ADAM)
    W = F.bilinear_weights(c, r, F.SHEEN_TABLE_N)
    ls, *_ = np.linalg.lstsq(W, target, rcond=None)
    assert np.max(np.abs(table - ls)) < F.SHEEN_AD_TOL
    assert losses[0] == pytest.approx(np.mean(target ** 2), rel=1e-12)   # the neutral start: table 0
    assert losses[-1] == pytest.approx(np.mean((W @ ls - target) ** 2), rel=1e-6)


def test_sheen_ad_loss_and_gradient_are_the_reads():
    """The Dr.Jit loss is the numpy read's mean squared error, its gradient (2/P) W^T (W t - y)."""
    rng = np.random.default_rng(2)
    nov, r = F.train_grid()
    c = F.table_coords(nov, "sqrt_nov")
    y, t = rng.random(nov.size), rng.random(64)
    W = F.bilinear_weights(c, r, 8)
    loss, g = F.sheen_loss_and_grad(8, c, r, y)(t)
    assert loss == pytest.approx(np.mean((W @ t - y) ** 2), rel=LOSS_RTOL)
    np.testing.assert_allclose(g, 2.0 / y.size * W.T @ (W @ t - y), rtol=1e-9, atol=1e-14)


@pytest.mark.slow
def test_sheen_ad_fit_on_the_truth_is_the_least_squares_table():
    table = F.fit_sheen_table()
    assert np.max(np.abs(table - F.fit_sheen_table_lstsq())) < F.SHEEN_AD_TOL
    assert np.max(np.abs(table - fitted_lobes.SHEEN_ALBEDO_TABLE)) <= 5e-7   # the module holds it (6 decimals)


def test_aniso_ad_loss_and_gradient_are_the_numpy_objective(monkeypatch):
    """On one training environment: the Dr.Jit objective per node is the numpy form's
    (aniso_realtime, _rel_err), and dr.backward's gradient its central differences."""
    monkeypatch.setattr(F, "ANISO_TRAIN_ENVS", (0,))
    f = F.aniso_loss_and_grad()
    nodes, v, env = F._free_nodes(), F.aniso_views(), F.test_env(0)
    w = np.linspace(0.1, 0.9, len(nodes))
    loss, g, per = f(w)
    want = [F._rel_err(F.aniso_realtime(env, v, r, wk), F.aniso_truth(env, v, r, s)) for (r, s), wk in zip(nodes, w)]
    np.testing.assert_allclose(per, want, rtol=LOSS_RTOL)
    assert loss == pytest.approx(sum(want), rel=LOSS_RTOL)
    h = 1e-4
    fd = [(f(w + h * e)[0] - f(w - h * e)[0]) / (2 * h) for e in np.eye(len(w))[:3]]
    np.testing.assert_allclose(g[:3], fd, rtol=GRAD_RTOL)


def test_bilinear_weights_are_the_readers():
    rng = np.random.default_rng(0)
    t = rng.random((5, 5)) + 0.5  # positive: the reader's clamp at 0 does not act
    x, y = rng.random(200), rng.random(200)
    W = F.bilinear_weights(x, y, 5)
    assert np.allclose(W @ t.ravel(), lut_bilinear(t[..., None], x, y)[..., 0], atol=1e-12)
    assert np.allclose(W.sum(axis=1), 1.0)


def test_fitted_module_reader_is_the_fit_read():
    nov, r = np.linspace(0.02, 1, 9), np.linspace(0, 1, 9)
    np.testing.assert_allclose(fitted_lobes.sheen_albedo_fitted(nov, r),
                               F.read_table(fitted_lobes.SHEEN_ALBEDO_TABLE, nov, r, "sqrt_nov"), rtol=1e-14, atol=1e-15)


def test_fitted_table_close_to_quadrature_fast():
    nov = np.array([0.15, 0.3, 0.55, 0.8, 1.0, 0.25])
    r = np.array([0.2, 0.45, 0.7, 0.95, 0.35, 0.85])
    assert np.max(np.abs(fitted_lobes.sheen_albedo_fitted(nov, r) - F.sheen_truth(nov, r))) < SHEEN_TABLE_MAX_TOL


@pytest.mark.slow
def test_fitted_table_within_tolerance_and_better_than_the_bake_held_out():
    errors, _ = F.sheen_report(fitted_lobes.SHEEN_ALBEDO_TABLE, baked32=False)
    fitted = errors[[k for k in errors if "sqrt" in k][0]]
    baked = errors[[k for k in errors if k.startswith("baked 8x8")][0]]
    assert fitted["rms"] < SHEEN_TABLE_RMS_TOL and fitted["max_abs_above"] < SHEEN_TABLE_MAX_TOL
    # the fit reduces the held-out error of the same-size bake (rms 0.035 -> 0.027, max 0.46 -> 0.10)
    assert fitted["rms"] < 0.85 * baked["rms"] and fitted["max_abs_above"] < 0.5 * baked["max_abs_above"]
    # and every engine's analytic form is far worse (rms >= 0.24)
    assert min(e["rms"] for k, e in errors.items() if "DG" in k or "0.157" in k) > 5 * fitted["rms"]


def test_aniso_module_reader_is_the_fit_read_and_pinned():
    rng = np.random.default_rng(1)
    for s, r in zip(rng.random(20), 0.1 + 0.9 * rng.random(20)):
        assert abs(float(fitted_lobes.aniso_bend_weight_fitted(s, r))
                   - F.aniso_weight_table(fitted_lobes.ANISO_BEND_WEIGHT_TABLE, s, r)) < 1e-12
    # isotropic where the spec's lobe is: strength 0, roughness 1 (alpha_t = mix(1, 1, s^2))
    assert np.all(fitted_lobes.aniso_bend_weight_fitted(0.0, np.linspace(0, 1, 5)) == 1.0)
    assert np.all(fitted_lobes.aniso_bend_weight_fitted(np.linspace(0, 1, 5), 1.0) == 1.0)
    assert fitted_lobes.ANISO_STRENGTH == F.ANISO_STRENGTH and fitted_lobes.ANISO_ROUGHNESS == F.ANISO_ROUGHNESS


def test_aniso_truth_is_isotropic_lookup_at_roughness_one():
    """At roughness 1 strength changes nothing in the spec (the truth), so the pinned weight is right."""
    env, v = F.test_env(0), F.aniso_views()
    assert np.allclose(F.aniso_truth(env, v, 1.0, 0.0), F.aniso_truth(env, v, 1.0, 0.9), rtol=1e-12)


@pytest.mark.slow
def test_aniso_ad_fit_is_the_scan_and_the_module_and_reduces_held_out_error():
    """The AD weights: the module's (4 decimals); within the scan's step of the dense scan's (the
    check), at a training cost per node no higher than the scan's (up to Adam's last steps); and
    they cut the held-out error of the Sample Viewer's weight."""
    table, losses = F.fit_aniso_table(return_losses=True)
    assert np.allclose(table, fitted_lobes.ANISO_BEND_WEIGHT_TABLE, atol=5e-5)
    scan = F.fit_aniso_table_scan()
    assert np.max(np.abs(table - scan)) <= F.ANISO_AD_TOL
    assert np.all(F.aniso_node_costs(table) <= F.aniso_node_costs(scan) + 1e-4)
    assert losses[-1] < 0.7 * losses[0]
    e = F.aniso_report(table)
    # held-out environments and nodes: mean 0.210 -> 0.072, max 1.62 -> 0.43 (docs/research.md)
    assert e["fitted"]["mean"] < 0.5 * e["sample_viewer"]["mean"]
    assert e["fitted"]["max"] < 0.5 * e["sample_viewer"]["max"]


def test_glsl_hooks_are_the_numpy_readers():
    """Both GLSL hooks through the GLSL harness (appended as a hook file whose hook_dfg returns them),
    against their numpy twins."""
    import types

    pytest.importorskip("moderngl")
    from realtime.glsl_harness import run_glsl
    text = (fitted_lobes.SHEEN_ALBEDO_GLSL + fitted_lobes.ANISO_BEND_WEIGHT_GLSL
            + "\nvec2 hook_dfg(float NoV, float roughness) {\n"
              "    return vec2(sheen_albedo_fitted(NoV, roughness), aniso_bend_weight_fitted(NoV, roughness));\n}\n")
    hook = types.SimpleNamespace(path="fitted_lobes.glsl", text=text, defines={"HOOK_DFG": 1})
    x, r = np.linspace(0.0, 1.0, 13), np.linspace(0.0, 1.0, 9)[:, None]
    got = run_glsl("hook_dfg(x0, x1)", x, r, components=2, hook=hook)
    assert np.allclose(got[..., 0], fitted_lobes.sheen_albedo_fitted(x, r), atol=2e-6)
    assert np.allclose(got[..., 1], fitted_lobes.aniso_bend_weight_fitted(x, r), atol=2e-6)


def test_frozen_loss_and_gradient_steps_equal_the_traced_ones(monkeypatch):
    """frozen_loss_and_grad (issue 39): the sheen and anisotropy objectives replayed by dr.freeze give
    the traced loss, gradient (and per-node losses) for every new parameter vector, recording at most
    twice; a frozen sheen fit ends at the traced fit's table."""
    monkeypatch.setattr(F, "ANISO_TRAIN_ENVS", (0,))
    rng = np.random.default_rng(3)
    nov, r = F.train_grid()
    c = F.table_coords(nov, "sqrt_nov")
    y = rng.random(nov.size)
    cases = [(F.sheen_loss_and_grad(8, c, r, y, freeze=False), F.sheen_loss_and_grad(8, c, r, y), 64),
             (F.aniso_loss_and_grad(freeze=False), F.aniso_loss_and_grad(), len(F._free_nodes()))]
    for traced, frozen, n in cases:
        for _ in range(5):
            x = rng.random(n)
            for a, b in zip(traced(x), frozen(x)):
                np.testing.assert_allclose(b, a, rtol=FROZEN_RTOL, atol=1e-300)
        assert 1 <= frozen.frozen.n_recordings <= 2
        assert traced.frozen is None
    target = np.exp(-3.0 * c) * (1.0 + r)
    fits = [F.adam(F.sheen_loss_and_grad(8, c, r, target, freeze=fr), np.zeros(64), 200, 0.2, 1e-3)[0] for fr in (False, True)]
    np.testing.assert_allclose(fits[1], fits[0], rtol=FROZEN_RTOL, atol=1e-15)
