"""``pbrcheck fit-lobes``: inverse fits of the lobes' real-time forms against the truth (issue 36
item 5b).

Sheen albedo table
------------------
The truth is the spec's sheen directional albedo ``E(n.v, r) = int D_Charlie V_Charlie (n.l) dl``
by quadrature (:meth:`pbrcheck.lobes.SheenCharlie.albedo`, [Sheen] "Albedo-scaling technique"), the E
of the albedo scaling ``1 - max(sheenColor) E``. The real-time form fitted is a small table read as
the sheen LUT is read (:data:`realtime.lobes.SHEEN_LUT_CONVENTIONS`: texel centres at ``(i + 0.5)/N``,
bilinear between them, linear extrapolation within half a texel of 0 and 1:
:func:`realtime.lobes.lut_bilinear`), of :data:`SHEEN_TABLE_N` x :data:`SHEEN_TABLE_N` texels. The
objective, the squared error of the interpolated table against the quadrature on the training grid
(:data:`TRAIN_N`^2 points), is written in Dr.Jit (LLVM AD arrays: the table's bilinear read as the GLSL
hook does it, :func:`sheen_loss_and_grad`) and minimised by Adam on its ``dr.backward`` gradient from the
neutral table 0 (:func:`fit_sheen_table`, :data:`SHEEN_ADAM`). The objective is quadratic in the table
(the read is linear in it), so its minimiser is also the least-squares solution of the normal
equations (:func:`fit_sheen_table_lstsq`, ``numpy.linalg.lstsq``): kept as the check of the AD result
(within :data:`SHEEN_AD_TOL`), not as the product. "Before": the same table baked by point sampling at
the texel centres (what ``sheen_lut.comp`` does, at the same size), the engines' default 32 x 32 bake,
three.js's analytic ``DG / pi`` fit (:func:`realtime.lobes.sheen_dg_fit`), PlayCanvas's ``DG`` and
three.js's constant 0.157 of its albedo scaling. Errors on a held-out grid (:data:`HELD_N`^2 points
offset from the training grid). The fitted table is written as :mod:`realtime.fitted_lobes` (constants
+ the reader's conventions, a numpy reader and its GLSL), read by the registry member ``sheen_dfg =
fitted`` (:mod:`realtime.registry`).

Anisotropic bent-normal weight
------------------------------
The truth: the spec's anisotropic GGX (F = 1) against a seeded test environment (:func:`test_env`)
per view (:func:`aniso_truth`); the real-time form: the Sample Viewer-style bent normal's split-sum
lookup (:func:`aniso_realtime`, :func:`prefiltered`) with the weight ``w`` of ``mix((b x v) x b, n,
w)`` per (strength, roughness) node, fitted per node over training environments,
reported on held-out environments and nodes against the Sample Viewer's
``(1 - s (1 - r))^4`` (:func:`aniso_report`).
The fit is by AD (:func:`fit_aniso_table`): the objective of every free node written in Dr.Jit
(:func:`aniso_loss_and_grad`: bent normal, reflection, the prefilter's sum over the stratified grid,
the environment's lobes), Adam (:data:`ANISO_ADAM`) from :data:`ANISO_START`; the dense scan per node
(:func:`fit_aniso_table_scan`, :data:`ANISO_SCAN`) is the check (within :data:`ANISO_AD_TOL`, at no
higher training cost). The weights are written to :mod:`realtime.fitted_lobes`, read by the registry
member ``anisotropy_bend = fitted``.

API
---
:data:`ANISO_STRENGTH`, :data:`ANISO_ROUGHNESS`, :data:`ANISO_HELD_STRENGTH`, :data:`ANISO_HELD_ROUGHNESS`,
:data:`ANISO_TRAIN_ENVS`, :data:`ANISO_HELD_ENVS`, :data:`ENV_LOBES`, :data:`ENV_KAPPA`, :data:`ANISO_NU`,
:data:`ANISO_SCAN`, :data:`ANISO_ADAM`, :data:`ANISO_START`, :data:`ANISO_AD_TOL`, :func:`test_env`,
:func:`prefiltered`, :func:`aniso_views`, :func:`aniso_truth`, :func:`aniso_realtime`, :func:`sample_viewer_weight`,
:func:`aniso_loss_and_grad`, :func:`fit_aniso_table`, :func:`fit_aniso_table_scan`, :func:`aniso_node_costs`,
:func:`aniso_weight_table`, :func:`aniso_report`, :func:`aniso_table_markdown`, :func:`aniso_fit_line`;
:data:`SHEEN_TABLE_N`, :data:`TRAIN_N`, :data:`HELD_N`, :data:`NOV_MIN`, :data:`SHEEN_ADAM`, :data:`SHEEN_AD_TOL`,
:func:`sheen_truth`, :func:`bilinear_weights`, :func:`sheen_loss_and_grad`, :func:`fit_sheen_table`,
:func:`fit_sheen_table_lstsq`, :func:`bake_sheen_table`, :func:`sheen_report`, :func:`sheen_check_line`,
:func:`sheen_table_markdown`, :func:`module_text`, :func:`read_table`, :func:`table_coords`,
:data:`SHEEN_QUAD`, :data:`AXES`, :data:`NOV_REPORT`; the AD loop :func:`adam` (:data:`ADAM_BETAS`, :data:`ADAM_EPS`).

References
----------
[Sheen]  KHR_materials_sheen README, "Implementation Notes".
[EntPBR] Dassault Systemes Enterprise PBR 2022x, sheen albedo fit (three.js IBLSheenBRDF).
[Karis13] B. Karis, "Real Shading in Unreal Engine 4", SIGGRAPH 2013 course notes (the prefilter, n = v = r).
[McAuley15] S. McAuley, the bent normal (b x v) x b of the Sample Viewer's anisotropy.
[Adam]   D. P. Kingma, J. Ba, "Adam: A Method for Stochastic Optimization", ICLR 2015.


Frozen steps (issue 39): both objectives run their forward and backward pass through ``dr.freeze``
(:func:`frozen_loss_and_grad`: recorded on the first calls, replayed for every later Adam step; the
same numbers as traced within float64 rounding, tested). Measured on the CPU (2 threads, the whole
fit, wall): the sheen table's 3000 steps 1.08 s traced, 0.081 s frozen (13x: the step is a small
graph, tracing was the step); the bend weights' 100 steps 2.16 s traced, 1.65 s frozen (1.3x: its
1.2 M-lane kernels dominate).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from pbrcheck.lobes import SheenCharlie
from realtime import lobes as _rt

#: Texels per axis of the fitted sheen albedo table (64 floats: a uniform array or a tiny texture).
SHEEN_TABLE_N = 8
#: Training grid: TRAIN_N x TRAIN_N points, n.v in [NOV_MIN, 1], roughness in [0, 1].
TRAIN_N = 25
#: Held-out grid: HELD_N x HELD_N points at the midpoints of a grid offset from the training one.
HELD_N = 16
#: The smallest n.v of both grids: at n.v = 0 the Charlie visibility's 1 / (4 n.v) is unbounded
#: (the spec's E diverges towards grazing at low roughness: 1.6 at n.v 0.02, roughness 0.1).
NOV_MIN = 0.02


#: Adam's moment decays (Kingma & Ba 2015, their defaults) and its epsilon (as reference.normal_filter's).
ADAM_BETAS = (0.9, 0.999)
ADAM_EPS = 1e-8
#: The sheen table's Adam: (steps, learning rate, final learning rate). The objective is quadratic with a
#: well-conditioned read (cond(W) = 29 on the sqrt axis): from 0, 3000 steps decaying 0.2 -> 1e-6 end
#: within 1e-11 of the least-squares table (2000 steps at 0.1: 6e-3 off at the singular corner); ~1 s.
SHEEN_ADAM = (3000, 0.2, 1e-6)
#: The AD table against the least-squares one, per entry: below the module's printed 1e-6.
SHEEN_AD_TOL = 1e-7

#: Quadrature nodes (cos theta, phi) of the truth here: 96 x 48 agrees with the lobe's default 192 x 96
#: to 8e-5 over roughness 0.02-1, n.v 0.02-0.7 (4x faster; the fits' errors are > 1e-3).
SHEEN_QUAD = (96, 48)
#: The fitted table's axes (:func:`table_coords`): "nov" the sheen LUT's (column i at n.v = (i + 0.5)/N),
#: "sqrt_nov" column i at sqrt(n.v) = (i + 0.5)/N (more columns where E is steep: grazing views).
AXES = ("nov", "sqrt_nov")


def sheen_truth(nov, rough):
    """E at each (n.v, roughness) pair (flat arrays) by the spec lobe's quadrature."""
    return np.array([SheenCharlie(r).albedo(m, *SHEEN_QUAD) for m, r in zip(np.ravel(nov), np.ravel(rough))])


def table_coords(nov, axis):
    """The table's column coordinate of n.v (:data:`AXES`)."""
    return np.sqrt(nov) if axis == "sqrt_nov" else np.asarray(nov, np.float64)


def _grid(n, offset):
    t = (np.arange(n) + offset) / (n - 1 + 2 * offset) if offset else np.linspace(0.0, 1.0, n)
    nov = NOV_MIN + (1.0 - NOV_MIN) * t
    N, R = np.meshgrid(nov, t, indexing="ij")
    return N.ravel(), R.ravel()


def train_grid():
    return _grid(TRAIN_N, 0.0)


@lru_cache(maxsize=1)
def _train_truth():
    """The quadrature on the training grid (625 albedos, the fits' slow part: computed once)."""
    t = sheen_truth(*train_grid())
    t.flags.writeable = False
    return t


def held_grid():
    return _grid(HELD_N, 0.5)


def bilinear_weights(nov, rough, n):
    """The weights (P, n*n) of :func:`realtime.lobes.lut_bilinear`'s read of an n x n table (index
    ``j * n + i``: row j roughness, column i n.v) before its final clamp at 0: ``W @ table.ravel()``."""
    x = np.clip(np.asarray(nov, np.float64), 0, 1) * n - 0.5
    y = np.clip(np.asarray(rough, np.float64), 0, 1) * n - 0.5
    i0 = np.clip(np.floor(x).astype(int), 0, n - 2)
    j0 = np.clip(np.floor(y).astype(int), 0, n - 2)
    fx, fy = x - i0, y - j0
    W = np.zeros((x.size, n * n))
    rows = np.arange(x.size)
    for dj, wy in ((0, 1.0 - fy), (1, fy)):
        for di, wx in ((0, 1.0 - fx), (1, fx)):
            np.add.at(W, (rows, (j0 + dj) * n + i0 + di), wy * wx)
    return W


def fit_sheen_table_lstsq(n=SHEEN_TABLE_N, axis="sqrt_nov"):
    """The closed-form minimiser of :func:`fit_sheen_table`'s objective (the read is linear in the table,
    so the objective is quadratic: ``numpy.linalg.lstsq`` of the reader's weights against the
    quadrature on the training grid). Kept as the check of the AD fit (``tests/test_fit_lobes.py``), not
    the product."""
    nov, rough = train_grid()
    W = bilinear_weights(table_coords(nov, axis), rough, n)
    table, *_ = np.linalg.lstsq(W, _train_truth(), rcond=None)
    return table.reshape(n, n)


def _dr():
    """Dr.Jit and its LLVM AD arrays (``pbrcheck`` first: it sets DRJIT_LIBLLVM_PATH before drjit loads)."""
    import pbrcheck  # noqa: F401
    import drjit as dr
    from drjit.llvm.ad import Float64, UInt32
    return dr, Float64, UInt32


def adam(loss_and_grad, x0, iterations, lr, lr_final, lo=None, hi=None):
    """Adam (Kingma & Ba 2015, :data:`ADAM_BETAS`, :data:`ADAM_EPS`) on ``loss_and_grad(x) -> (loss,
    grad)`` from ``x0``, the learning rate decaying geometrically from ``lr`` to ``lr_final``, ``x``
    clipped to [lo, hi] after each step. Returns ``(x, losses)`` (the loss before each step)."""
    x = np.asarray(x0, np.float64).copy()
    m1, m2 = np.zeros_like(x), np.zeros_like(x)
    b1, b2 = ADAM_BETAS
    losses = []
    for it in range(iterations):
        step = lr * (lr_final / lr) ** (it / max(iterations - 1, 1))
        loss, g = loss_and_grad(x)
        m1 = b1 * m1 + (1 - b1) * g
        m2 = b2 * m2 + (1 - b2) * g * g
        x = x - step * (m1 / (1 - b1 ** (it + 1))) / (np.sqrt(m2 / (1 - b2 ** (it + 1))) + ADAM_EPS)
        if lo is not None or hi is not None:
            x = np.clip(x, lo, hi)
        losses.append(float(loss))
    return x, losses


def frozen_loss_and_grad(body, consts: dict, freeze: bool = True):
    """``f(x) -> (loss, gradient, *extras)`` (numpy) of ``body(p, consts) -> (loss, *extras)`` (Dr.Jit,
    ``p`` the float64 parameters with gradients enabled, ``consts`` a dict of the Dr.Jit arrays every
    step reads), the gradient by ``dr.backward``. With ``freeze`` (issue 39) the forward and backward
    pass run through ``dr.freeze``: recorded on the first calls, replayed for every later step without
    tracing (an Adam fit calls it once a step with new values of the same size). ``consts`` are passed
    as the frozen function's inputs (a frozen function must be given every variable it reads; one
    captured by a closure is not found). The same numbers as traced: ``tests/test_fit_lobes.py``."""
    dr, Float, _ = _dr()

    def g(p, consts):
        out = body(p, consts)
        dr.backward(out[0])
        return (out[0], dr.grad(p), *out[1:])

    fn = dr.freeze(g) if freeze else g

    def f(x):
        p = Float(np.ravel(np.asarray(x, np.float64)))
        dr.enable_grad(p)
        loss, grad, *rest = fn(p, consts)
        return (float(loss[0]), np.array(grad, np.float64), *rest)
    f.frozen = fn if freeze else None
    return f


def sheen_loss_and_grad(n, coords, rough, truth, freeze: bool = True):
    """``f(table) -> (loss, gradient)``: the mean squared error of the table's read (the GLSL hook's
    bilinear read, before its clamp at 0, written in Dr.Jit) at ``(coords, rough)`` against ``truth``,
    the gradient by ``dr.backward`` (:func:`frozen_loss_and_grad`: ``freeze``)."""
    dr, Float, UInt = _dr()
    C, R, T = Float(coords), Float(rough), Float(truth)
    x, y = dr.clip(C, 0.0, 1.0) * n - 0.5, dr.clip(R, 0.0, 1.0) * n - 0.5
    i0, j0 = dr.clip(dr.floor(x), 0, n - 2), dr.clip(dr.floor(y), 0, n - 2)
    fx, fy = x - i0, y - j0
    i, j = UInt(i0), UInt(j0)
    consts = {"fx": fx, "fy": fy, "i": i, "j": j, "T": T}
    dr.eval(consts)   # the same for every step: evaluated once

    def body(t, k):
        def at(jj, ii):
            return dr.gather(Float, t, jj * n + ii)

        fx, fy, i, j = k["fx"], k["fy"], k["i"], k["j"]
        pred = (1 - fy) * ((1 - fx) * at(j, i) + fx * at(j, i + 1)) + fy * ((1 - fx) * at(j + 1, i) + fx * at(j + 1, i + 1))
        return (dr.sum(dr.square(pred - k["T"])) / len(truth),)
    return frozen_loss_and_grad(body, consts, freeze)


def fit_sheen_table(n=SHEEN_TABLE_N, axis="sqrt_nov", return_losses=False):
    """The n x n table (rows roughness, columns n.v on ``axis``) minimising the squared error of its read
    on the training grid, by AD: the loss in Dr.Jit (:func:`sheen_loss_and_grad`), Adam
    (:data:`SHEEN_ADAM`) from the neutral table 0 (no sheen albedo). The objective is quadratic: the
    result equals :func:`fit_sheen_table_lstsq` (within :data:`SHEEN_AD_TOL`, tested)."""
    nov, rough = train_grid()
    f = sheen_loss_and_grad(n, table_coords(nov, axis), rough, _train_truth())
    table, losses = adam(f, np.zeros(n * n), *SHEEN_ADAM)
    table = table.reshape(n, n)
    return (table, losses) if return_losses else table


def bake_sheen_table(n):
    """The table by point sampling the quadrature at the texel centres (a bake's way; n.v >= NOV_MIN)."""
    c = (np.arange(n) + 0.5) / n
    R, N = np.meshgrid(c, np.maximum(c, NOV_MIN), indexing="ij")
    return sheen_truth(N.ravel(), R.ravel()).reshape(n, n)


def read_table(table, nov, rough, axis="sqrt_nov"):
    """The table's value at (n.v, roughness): :func:`realtime.lobes.lut_bilinear` on its axes."""
    return _rt.lut_bilinear(np.asarray(table)[..., None], table_coords(nov, axis), rough)[..., 0]


#: The n.v above which the report also gives the max error (the corner n.v -> 0, roughness -> 0,
#: where the spec's E is singular, dominates the plain max).
NOV_REPORT = 0.1


def _errors(pred, truth, nov):
    e = pred - truth
    return {"max_abs": float(np.max(np.abs(e))), "max_abs_above": float(np.max(np.abs(e[nov >= NOV_REPORT]))),
            "rms": float(np.sqrt(np.mean(e * e))), "mean": float(np.mean(e))}


def sheen_report(table=None, baked32=True):
    """Held-out errors of every candidate: ``{name: {max_abs, rms, mean}}`` (and the fitted table, on
    the "sqrt_nov" axis). ``baked32`` False skips the 32 x 32 bake (1024 quadratures)."""
    nov, rough = held_grid()
    truth = sheen_truth(nov, rough)
    table = fit_sheen_table() if table is None else np.asarray(table)
    n = table.shape[0]
    cands = {f"baked {n}x{n} (point samples at texel centres)": read_table(bake_sheen_table(n), nov, rough, "nov")}
    if baked32:
        cands["baked 32x32 (the engines' LUT size)"] = read_table(bake_sheen_table(32), nov, rough, "nov")
    cands.update({
        "three.js DG / pi (EntPBR fit)": _rt.sheen_dg_fit(nov, rough) / np.pi,
        "PlayCanvas DG (no 1 / pi)": _rt.sheen_dg_fit(nov, rough),
        "three.js constant 0.157": np.full_like(truth, _rt.THREEJS_SHEEN_ALBEDO),
        f"fitted {n}x{n}, n.v axis (AD)": read_table(fit_sheen_table(n, "nov"), nov, rough, "nov"),
        f"fitted {n}x{n}, sqrt(n.v) axis (AD: realtime/fitted_lobes.py)": read_table(table, nov, rough),
    })
    return {k: _errors(v, truth, nov) for k, v in cands.items()}, table


def sheen_check_line(table) -> str:
    """The AD table's distance to the closed least-squares solution (the check) and its Adam loss."""
    d = float(np.max(np.abs(np.asarray(table) - fit_sheen_table_lstsq(np.asarray(table).shape[0]))))
    return (f"sheen table: AD (Dr.Jit loss, {SHEEN_ADAM[0]} Adam steps from 0) vs the least-squares solution: "
            f"max |difference| {d:.1e} (tolerance {SHEEN_AD_TOL:g})")


def sheen_table_markdown(errors) -> str:
    lines = [f"| sheen albedo E(n.v, r) | max abs error | max abs, n.v >= {NOV_REPORT:g} | rms | mean signed |",
             "|---|---|---|---|---|"]
    for k, e in errors.items():
        lines.append(f"| {k} | {e['max_abs']:.4f} | {e['max_abs_above']:.4f} | {e['rms']:.4f} | {e['mean']:+.4f} |")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------------------------------------
# Anisotropy: the blend weight of the Sample Viewer-style bent normal
# ------------------------------------------------------------------------------------------------

#: The fitted weight table's nodes: anisotropy strength (columns) and roughness (rows). Below
#: roughness 0.2 the prefiltered lookup's own quadrature (:data:`ANISO_NU`^2 samples) does not
#: resolve the test environment's lobes. The weight is pinned to 1 where the spec's lobe is
#: isotropic, at strength 0 and at roughness 1 (``alpha_t = mix(1, 1, s^2)``): there the bend must
#: not absorb the split sum's own error (a free fit picks 0.445 at roughness 1).
ANISO_STRENGTH = (0.0, 0.25, 0.5, 0.75, 1.0)
ANISO_ROUGHNESS = (0.2, 0.4, 0.6, 0.8, 1.0)
#: Held-out nodes (midpoints) and environments (seeds) of the report.
ANISO_HELD_STRENGTH = (0.125, 0.375, 0.625, 0.875)
ANISO_HELD_ROUGHNESS = (0.3, 0.5, 0.7, 0.9)
ANISO_TRAIN_ENVS = (0, 1, 2, 3, 4, 5)
ANISO_HELD_ENVS = (10, 11, 12, 13)
#: The test environment: a constant 0.05 plus ENV_LOBES von Mises-Fisher lobes of sharpness
#: ENV_KAPPA (~7 degrees wide) above the horizon, weights in [0.5, 1.5], placed by the seed.
ENV_LOBES = 3
ENV_KAPPA = 60.0
#: Stratified samples per axis of the truth's and the prefilter's integrals (deterministic).
ANISO_NU = 32
#: The weights scanned per node by the check (:func:`fit_aniso_table_scan`; the objective is 1-D per
#: node: a dense scan finds its global minimum, to its step 0.02).
ANISO_SCAN = np.linspace(0.0, 1.0, 51)
#: The AD fit's Adam: (steps, learning rate, final learning rate); ~0.1 s a step (1.2 M lanes).
#: 100 steps decaying 0.05 -> 0.001 move no weight by more than 0.003 in their last 50.
ANISO_ADAM = (100, 0.05, 0.001)
#: The AD fit's start: 0.5 for every free node, the middle of the weight's range [0, 1]. The objective
#: has local minima (the environments' sharp lobes): from 1 (the unbent normal) node (roughness 0.2,
#: strength 0.5) stops at 0.97 (training cost +0.125 over the scan's 0.66), from 0 the whole roughness
#: 0.2 row stays near 0.07 (cost +3.7 to +4.9 a node); from 0.5 every node ends in the scan's basin.
ANISO_START = 0.5
#: The AD weights against the scan's, per node: the scan's step (0.02); measured 0.011 at most.
ANISO_AD_TOL = 0.02
_Z = np.array([0.0, 0.0, 1.0])
_B = np.array([0.0, 1.0, 0.0])  # the anisotropy bitangent n x t for the direction t = +X


def _u_grid(n=ANISO_NU):
    g = (np.arange(n) + 0.5) / n
    return np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1).reshape(-1, 2)


def _env_params(seed):
    """The lobes of :func:`test_env`'s environment: directions (ENV_LOBES, 3) and weights (ENV_LOBES,)."""
    rng = np.random.default_rng(seed)
    z, ph = rng.uniform(0.2, 0.9, ENV_LOBES), rng.uniform(0.0, 2.0 * np.pi, ENV_LOBES)
    sz = np.sqrt(1.0 - z * z)
    return np.stack([sz * np.cos(ph), sz * np.sin(ph), z], axis=-1), rng.uniform(0.5, 1.5, ENV_LOBES)


def test_env(seed):
    """The environment ``L(l)`` of the seed (module constants; its lobes :func:`_env_params`)."""
    mu, c = _env_params(seed)
    return lambda l: 0.05 + np.exp(ENV_KAPPA * (l @ mu.T - 1.0)) @ c


def _basis(n):
    sign = np.where(n[:, 2] >= 0, 1.0, -1.0)
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    return (np.stack([1.0 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]], axis=-1),
            np.stack([b, sign + n[:, 1] ** 2 * a, -n[:, 1]], axis=-1))


def prefiltered(env, R, roughness):
    """The split sum's prefiltered radiance at directions R (k, 3): Karis's estimator with n = v = R
    (half vectors of density D (n.h), weights n.l), on the stratified grid."""
    from pbrcheck.lobes import AnisotropicGGX
    h = AnisotropicGGX(roughness).sample_h(_Z, _u_grid())
    l = 2.0 * h[:, 2:3] * h - _Z
    w = np.maximum(l[:, 2], 0.0)
    t, s = _basis(R)
    L = l[None, :, 0:1] * t[:, None] + l[None, :, 1:2] * s[:, None] + l[None, :, 2:3] * R[:, None]
    return (env(L.reshape(-1, 3)).reshape(len(R), -1) @ w) / w.sum()


def aniso_views():
    """The views of the fit: 20, 45, 70 degrees from n x azimuths 0, 45, 90, 135 from the direction."""
    th, ph = np.radians([20.0, 45.0, 70.0]), np.radians([0.0, 45.0, 90.0, 135.0])
    T, P = (a.ravel() for a in np.meshgrid(th, ph, indexing="ij"))
    return np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], axis=-1)


def aniso_truth(env, v, roughness, strength):
    """``int L(l) f(v, l) (n.l) dl`` of the spec's anisotropic GGX (F = 1) per view: the visible
    normals' estimator on the stratified grid."""
    from pbrcheck.lobes import AnisotropicGGX
    ggx, out = AnisotropicGGX(roughness, strength), []
    for vi in v:
        l, pdf = ggx.sample(vi, _u_grid())
        f = ggx.eval(vi[None], l)
        out.append(np.mean(np.where(pdf > 0, env(l) * f / np.maximum(pdf, 1e-300), 0.0)))
    return np.array(out)


def aniso_realtime(env, v, roughness, weight):
    """The bent-normal lookup: ``prefiltered(reflect(-v, normalize(mix((b x v) x b, n, weight)))) E(n.v)``
    with E the isotropic GGX albedo (the DFG with F = 1) at the material's roughness."""
    from pbrcheck.lobes import AnisotropicGGX
    m = np.cross(np.cross(_B, v), _B)
    bn = m * (1.0 - weight) + _Z * weight
    bn = bn / np.linalg.norm(bn, axis=-1, keepdims=True)
    R = 2.0 * np.sum(v * bn, axis=-1, keepdims=True) * bn - v
    return prefiltered(env, R, roughness) * _iso_albedo(roughness, tuple(map(tuple, v)))


@lru_cache(maxsize=64)
def _iso_albedo(roughness, v):
    from pbrcheck.lobes import AnisotropicGGX
    return np.array([AnisotropicGGX(roughness).albedo(vi[2], n=64) for vi in v])


def sample_viewer_weight(strength, roughness):
    """The Sample Viewer's (and three.js's) ``(1 - s (1 - r))^4``."""
    return (1.0 - np.asarray(strength) * (1.0 - np.asarray(roughness))) ** 4


def _rel_err(pred, truth):
    return float(np.sum((pred - truth) ** 2) / np.sum(truth ** 2))


def _aniso_cases(envs, strengths, roughs):
    v = aniso_views()
    return [(e, r, s, aniso_truth(test_env(e), v, r, s)) for e in envs for r in roughs for s in strengths]


def fit_aniso_table_scan():
    """The weight per (roughness row, strength column) minimising the relative squared error summed
    over the training environments and views (strength 0 and roughness 1 pinned to 1); a dense scan
    of :data:`ANISO_SCAN` per node: the objective is 1-D per node, so the scan finds its global
    minimum (to the scan's step). Kept as the check of the AD fit (:func:`fit_aniso_table`)."""
    v = aniso_views()
    cases = _aniso_cases(ANISO_TRAIN_ENVS, ANISO_STRENGTH[1:], ANISO_ROUGHNESS[:-1])
    table = np.ones((len(ANISO_ROUGHNESS), len(ANISO_STRENGTH)))
    for j, r in enumerate(ANISO_ROUGHNESS[:-1]):
        for i, s in enumerate(ANISO_STRENGTH[1:], start=1):
            mine = [c for c in cases if c[1] == r and c[2] == s]
            cost = [sum(_rel_err(aniso_realtime(test_env(e), v, r, w), L) for e, _, _, L in mine) for w in ANISO_SCAN]
            table[j, i] = ANISO_SCAN[int(np.argmin(cost))]
    return table


def _free_nodes():
    """The fitted (not pinned) nodes (roughness, strength), row-major in the table's interior."""
    return [(r, s) for r in ANISO_ROUGHNESS[:-1] for s in ANISO_STRENGTH[1:]]


def aniso_loss_and_grad(freeze: bool = True):
    """``f(weights) -> (loss, gradient, per-node loss)``: the training objective of every free node
    (:func:`_free_nodes`; the sum over nodes of each node's relative squared error summed over the
    training environments, :func:`_rel_err`), the real-time form :func:`aniso_realtime` written in
    Dr.Jit (bent normal, reflection, :func:`_basis`, Karis's prefilter on the stratified grid, the
    environment's lobes, times the isotropic albedo), gradient by ``dr.backward``. One lane per (node,
    environment, view, prefilter sample), the prefilter's sum a block sum; the truth (numpy) is constant."""
    from pbrcheck.lobes import AnisotropicGGX
    dr, Float, UInt = _dr()
    v, nodes, envs = aniso_views(), _free_nodes(), ANISO_TRAIN_ENVS
    cases = {(r, s, e): L for e, r, s, L in _aniso_cases(envs, ANISO_STRENGTH[1:], ANISO_ROUGHNESS[:-1])}
    truth = np.array([[cases[(r, s, e)] for e in envs] for r, s in nodes])        # (K, E, V)
    K, E, V = truth.shape
    ls = []
    for r, _ in nodes:                                                              # the prefilter's l, weight n.l
        h = AnisotropicGGX(r).sample_h(_Z, _u_grid())
        ls.append(2.0 * h[:, 2:3] * h - _Z)
    ls = np.array(ls)                                                               # (K, NS, 3)
    NS = ls.shape[1]
    wl = np.maximum(ls[..., 2], 0.0)
    scale = np.array([_iso_albedo(r, tuple(map(tuple, v))) for r, _ in nodes]) / wl.sum(axis=1)[:, None]  # (K, V)
    mus, cs = (np.array(a) for a in zip(*[_env_params(e) for e in envs]))          # (E, J, 3), (E, J)
    kk, ee, vv, ss = (a.ravel() for a in np.meshgrid(np.arange(K), np.arange(E), np.arange(V), np.arange(NS),
                                                      indexing="ij"))

    def vec(a):
        return [Float(np.ascontiguousarray(a[:, c])) for c in range(3)]

    m = vec(np.cross(np.cross(_B, v), _B)[vv])
    vw, lw = vec(v[vv]), vec(ls[kk, ss])
    WL = Float(wl[kk, ss])
    mu = [vec(mus[ee, j]) for j in range(mus.shape[1])]
    c = [Float(cs[ee, j]) for j in range(cs.shape[1])]
    node = UInt(kk)
    SC = Float(scale[kk[::NS], vv[::NS]])
    T = Float(truth.ravel())
    DEN = Float(np.sum(truth ** 2, axis=2).ravel())

    def dot(a, b):
        return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]

    consts = {"m": m, "vw": vw, "lw": lw, "WL": WL, "mu": mu, "c": c, "node": node, "SC": SC, "T": T, "DEN": DEN}
    dr.eval(consts)

    def body(p, k):
        m, vw, lw, WL, mu, c, node, SC, T, DEN = (k[x] for x in ("m", "vw", "lw", "WL", "mu", "c", "node", "SC", "T", "DEN"))
        w = dr.gather(Float, p, node)
        bn = [m[0] * (1.0 - w), m[1] * (1.0 - w), m[2] * (1.0 - w) + w]
        inv = dr.rsqrt(dot(bn, bn))
        bn = [x * inv for x in bn]
        d = 2.0 * dot(vw, bn)
        R = [d * bn[i] - vw[i] for i in range(3)]
        sign = dr.select(R[2] >= 0, 1.0, -1.0)                                      # _basis, Duff et al. 2017
        a = -1.0 / (sign + R[2])
        b = R[0] * R[1] * a
        t = [1.0 + sign * R[0] * R[0] * a, sign * b, -sign * R[0]]
        s = [b, sign + R[1] * R[1] * a, -R[1]]
        L = [lw[0] * t[i] + lw[1] * s[i] + lw[2] * R[i] for i in range(3)]
        env = Float(0.05)
        for muj, cj in zip(mu, c):
            env = env + cj * dr.exp(ENV_KAPPA * (dot(L, muj) - 1.0))
        pred = dr.block_sum(env * WL, NS) * SC
        per = dr.block_sum(dr.square(pred - T), V) / DEN                            # (K E)
        return dr.sum(per), dr.detach(per)

    g = frozen_loss_and_grad(body, consts, freeze)

    def f(weights):
        loss, grad, per = g(weights)
        return loss, grad, np.array(per).reshape(K, E).sum(axis=1)
    f.frozen = g.frozen
    return f


def fit_aniso_table(return_losses=False):
    """The weight per (roughness row, strength column) minimising the relative squared error summed over
    the training environments and views, by AD (:func:`aniso_loss_and_grad`, Adam :data:`ANISO_ADAM`
    from :data:`ANISO_START`, weights kept in [0, 1]); strength 0 and roughness 1 pinned to 1. Checked
    against the scan (:func:`fit_aniso_table_scan`, tested: within :data:`ANISO_AD_TOL` of it, at no
    higher training cost)."""
    f = aniso_loss_and_grad()
    w, losses = adam(lambda x: f(x)[:2], np.full(len(_free_nodes()), ANISO_START), *ANISO_ADAM, lo=0.0, hi=1.0)
    table = np.ones((len(ANISO_ROUGHNESS), len(ANISO_STRENGTH)))
    table[:-1, 1:] = w.reshape(len(ANISO_ROUGHNESS) - 1, len(ANISO_STRENGTH) - 1)
    return (table, losses) if return_losses else table


def aniso_fit_line(losses, table=None) -> str:
    """The AD fit's training loss before and after; with ``table``, its check against the scan."""
    line = (f"bend weights: AD (Dr.Jit loss, {len(losses)} Adam steps from {ANISO_START:g}): training loss "
            f"{losses[0]:.4f} -> {losses[-1]:.4f}")
    if table is not None:
        scan = fit_aniso_table_scan()
        d = float(np.max(np.abs(np.asarray(table) - scan)))
        extra = float(np.max(aniso_node_costs(table) - aniso_node_costs(scan)))
        line += (f"; vs the dense scan: max |difference| {d:.4f} (tolerance {ANISO_AD_TOL:g}), the largest node "
                 f"cost above the scan's {extra:+.1e}")
    return line


def aniso_node_costs(table):
    """Each free node's training objective (:func:`aniso_loss_and_grad`) at ``table``'s weights."""
    return aniso_loss_and_grad()(np.asarray(table)[:-1, 1:].ravel())[2]


def aniso_weight_table(table, strength, roughness):
    """The fitted weight at (strength, roughness): bilinear on the nodes, clamped to them."""
    s = np.interp(strength, ANISO_STRENGTH, np.arange(len(ANISO_STRENGTH)))
    r = np.interp(roughness, ANISO_ROUGHNESS, np.arange(len(ANISO_ROUGHNESS)))
    i0, j0 = min(int(s), len(ANISO_STRENGTH) - 2), min(int(r), len(ANISO_ROUGHNESS) - 2)
    fx, fy = s - i0, r - j0
    t = np.asarray(table)
    return float((1 - fy) * ((1 - fx) * t[j0, i0] + fx * t[j0, i0 + 1]) + fy * ((1 - fx) * t[j0 + 1, i0] + fx * t[j0 + 1, i0 + 1]))


def aniso_report(table):
    """Held-out (environments :data:`ANISO_HELD_ENVS`, nodes at the midpoints) relative squared error
    of the Sample Viewer's weight, the fitted table and the unbent normal (weight 1): mean and max."""
    v = aniso_views()
    res = {"sample_viewer": [], "fitted": [], "unbent (weight 1)": []}
    for e, r, s, L in _aniso_cases(ANISO_HELD_ENVS, ANISO_HELD_STRENGTH, ANISO_HELD_ROUGHNESS):
        env = test_env(e)
        for k, w in (("sample_viewer", sample_viewer_weight(s, r)), ("fitted", aniso_weight_table(table, s, r)),
                     ("unbent (weight 1)", 1.0)):
            res[k].append(_rel_err(aniso_realtime(env, v, r, w), L))
    return {k: {"mean": float(np.mean(x)), "max": float(np.max(x))} for k, x in res.items()}


def aniso_table_markdown(errors, table) -> str:
    lines = ["| bent-normal weight | held-out rel. sq. error, mean | max |", "|---|---|---|"]
    for k, e in errors.items():
        lines.append(f"| {k} | {e['mean']:.4f} | {e['max']:.4f} |")
    lines += ["", "| fitted weight: roughness \\ strength | " + " | ".join(f"{s:g}" for s in ANISO_STRENGTH) + " |",
              "|---|" + "---|" * len(ANISO_STRENGTH)]
    for r, row in zip(ANISO_ROUGHNESS, np.asarray(table)):
        sv = " | ".join(f"{w:.3f} ({sample_viewer_weight(s, r):.3f})" for s, w in zip(ANISO_STRENGTH, row))
        lines.append(f"| {r:g} | {sv} |")
    return "\n".join(lines) + "\n"


def module_text(table, aniso_table) -> str:
    """The source of :mod:`realtime.fitted_lobes` holding the sheen ``table`` (on the "sqrt_nov" axis)
    and the bent-normal weights ``aniso_table`` (deterministic: fixed decimals, no date)."""
    t = np.asarray(table, np.float64)
    at = np.asarray(aniso_table, np.float64)
    arows = ",\n".join("    (" + ", ".join(f"{x:.4f}" for x in row) + ")" for row in at)
    aflat = ", ".join(f"{x:.4f}" for x in at.ravel())
    ns, nr = len(ANISO_STRENGTH), len(ANISO_ROUGHNESS)
    n = t.shape[0]
    rows = ",\n".join("    (" + ", ".join(f"{x:.6f}" for x in row) + ")" for row in t)
    flat = ",\n        ".join(", ".join(f"{x:.6f}" for x in row) for row in t)
    s0, ds = ANISO_STRENGTH[0], ANISO_STRENGTH[1] - ANISO_STRENGTH[0]
    r0, dr_ = ANISO_ROUGHNESS[0], ANISO_ROUGHNESS[1] - ANISO_ROUGHNESS[0]
    return f'''"""Fitted real-time lobe tables (issue 36 item 5b), written by ``pbrcheck fit-lobes --module``
(:mod:`compare.research.fit_lobes`; do not edit by hand). The registry members that read them:
``sheen_dfg = fitted`` and ``anisotropy_bend = fitted`` (:mod:`realtime.registry`, whose entries hold
the GLSL below; :func:`realtime.lobes.sheen_dfg_fitted`, :func:`realtime.lobes.aniso_reflection_fitted`).

:data:`SHEEN_ALBEDO_TABLE`: the sheen directional albedo ``E(n.v, sheenRoughness)`` of the spec's
Charlie lobe (KHR_materials_sheen, ``int D_Charlie V_Charlie n.l dl``), {n} x {n}, fitted by AD (Dr.Jit,
Adam from 0) to the quadrature so that its bilinear read matches it (docs/research.md, "pbrcheck
fit-lobes"; equal to the least-squares table, the check); the E of the albedo scaling ``1 - max(sheenColor)
E(n.v)``. Conventions (:data:`SHEEN_ALBEDO_TABLE_CONVENTIONS`): row j at sheen roughness (j + 0.5)/{n} (row 0
smoothest), column i at sqrt(n.v) = (i + 0.5)/{n}; read bilinearly between texel centres with linear
extrapolation within half a texel of 0 and 1 and a clamp at 0 (:func:`realtime.lobes.lut_bilinear`'s
rule, written out here so that this module imports nothing of the renderer). :func:`sheen_albedo_fitted`
is the numpy reader, :data:`SHEEN_ALBEDO_GLSL` the same read in GLSL (``float sheen_albedo_fitted(float
NoV, float roughness)``).

:data:`ANISO_BEND_WEIGHT_TABLE`: the weight ``w`` of the Sample Viewer-style bent normal
``normalize(mix((b x v) x b, n, w))`` (b the anisotropy bitangent), in place of its ``(1 - s (1 -
r))^4``, fitted by AD (Dr.Jit, Adam from 0.5) against the spec's anisotropic GGX integral under test
environments (docs/research.md; within the scan's step of the scan's weights, the check); rows roughness
:data:`ANISO_ROUGHNESS`, columns strength :data:`ANISO_STRENGTH`, read bilinearly between the nodes and
clamped to them (below roughness {ANISO_ROUGHNESS[0]:g}: its first row); :func:`aniso_bend_weight_fitted`
the numpy reader, :data:`ANISO_BEND_WEIGHT_GLSL` the GLSL ``float aniso_bend_weight_fitted(float
anisotropy, float roughness)``.

API: :data:`SHEEN_ALBEDO_TABLE`, :data:`SHEEN_ALBEDO_TABLE_CONVENTIONS`, :func:`sheen_albedo_fitted`,
:data:`SHEEN_ALBEDO_GLSL`, :data:`ANISO_STRENGTH`, :data:`ANISO_ROUGHNESS`, :data:`ANISO_BEND_WEIGHT_TABLE`,
:func:`aniso_bend_weight_fitted`, :data:`ANISO_BEND_WEIGHT_GLSL`.
"""

import numpy as np

SHEEN_ALBEDO_TABLE = np.array((
{rows}))

SHEEN_ALBEDO_TABLE_CONVENTIONS = {{
    "axes": "row j: sheen roughness = (j + 0.5)/{n}, row 0 smoothest; column i: sqrt(n.v) = (i + 0.5)/{n}",
    "read": "bilinear between texel centres, linear extrapolation within half a texel of 0 and 1, clamped at 0",
    "value": "E = int D_Charlie V_Charlie n.l dl (KHR_materials_sheen), fitted by AD (Adam) on a "
             "{TRAIN_N} x {TRAIN_N} grid of n.v in [{NOV_MIN}, 1] x roughness in [0, 1]",
}}


def sheen_albedo_fitted(NoV, roughness):
    """E at (n.v, sheen roughness) from :data:`SHEEN_ALBEDO_TABLE` (numpy twin of the GLSL reader)."""
    x = np.sqrt(np.clip(np.asarray(NoV, np.float64), 0.0, 1.0)) * {n} - 0.5
    y = np.clip(np.asarray(roughness, np.float64), 0.0, 1.0) * {n} - 0.5
    i0, j0 = np.clip(np.floor(x).astype(int), 0, {n - 2}), np.clip(np.floor(y).astype(int), 0, {n - 2})
    fx, fy = x - i0, y - j0
    t = SHEEN_ALBEDO_TABLE
    v0 = t[j0, i0] + (t[j0, i0 + 1] - t[j0, i0]) * fx
    v1 = t[j0 + 1, i0] + (t[j0 + 1, i0 + 1] - t[j0 + 1, i0]) * fx
    return np.maximum(v0 + (v1 - v0) * fy, 0.0)


SHEEN_ALBEDO_GLSL = """
const float SHEEN_ALBEDO_TABLE[{n * n}] = float[](
        {flat});

float sheen_albedo_fitted(float NoV, float roughness) {{
    float x = sqrt(clamp(NoV, 0.0, 1.0)) * {n}.0 - 0.5;
    float y = clamp(roughness, 0.0, 1.0) * {n}.0 - 0.5;
    int i0 = clamp(int(floor(x)), 0, {n - 2});
    int j0 = clamp(int(floor(y)), 0, {n - 2});
    float fx = x - float(i0), fy = y - float(j0);
    float v0 = mix(SHEEN_ALBEDO_TABLE[j0 * {n} + i0], SHEEN_ALBEDO_TABLE[j0 * {n} + i0 + 1], fx);
    float v1 = mix(SHEEN_ALBEDO_TABLE[(j0 + 1) * {n} + i0], SHEEN_ALBEDO_TABLE[(j0 + 1) * {n} + i0 + 1], fx);
    return max(mix(v0, v1, fy), 0.0);
}}
"""

ANISO_STRENGTH = {tuple(ANISO_STRENGTH)!r}
ANISO_ROUGHNESS = {tuple(ANISO_ROUGHNESS)!r}
ANISO_BEND_WEIGHT_TABLE = np.array((
{arows}))


def aniso_bend_weight_fitted(anisotropy, roughness):
    """The fitted weight at (strength, roughness) (numpy twin of the GLSL reader; uniform node spacing)."""
    x = np.clip((np.asarray(anisotropy, np.float64) - {s0!r}) / {ds!r}, 0.0, {ns - 1}.0)
    y = np.clip((np.asarray(roughness, np.float64) - {r0!r}) / {dr_!r}, 0.0, {nr - 1}.0)
    i0, j0 = np.minimum(np.floor(x).astype(int), {ns - 2}), np.minimum(np.floor(y).astype(int), {nr - 2})
    fx, fy = x - i0, y - j0
    t = ANISO_BEND_WEIGHT_TABLE
    return ((1 - fy) * ((1 - fx) * t[j0, i0] + fx * t[j0, i0 + 1])
            + fy * ((1 - fx) * t[j0 + 1, i0] + fx * t[j0 + 1, i0 + 1]))


ANISO_BEND_WEIGHT_GLSL = """
const float ANISO_BEND_WEIGHT_TABLE[{ns * nr}] = float[]({aflat});

float aniso_bend_weight_fitted(float anisotropy, float roughness) {{
    float x = clamp((anisotropy - {s0:.6f}) / {ds:.6f}, 0.0, {ns - 1}.0);
    float y = clamp((roughness - {r0:.6f}) / {dr_:.6f}, 0.0, {nr - 1}.0);
    int i0 = min(int(floor(x)), {ns - 2});
    int j0 = min(int(floor(y)), {nr - 2});
    float fx = x - float(i0), fy = y - float(j0);
    float v0 = mix(ANISO_BEND_WEIGHT_TABLE[j0 * {ns} + i0], ANISO_BEND_WEIGHT_TABLE[j0 * {ns} + i0 + 1], fx);
    float v1 = mix(ANISO_BEND_WEIGHT_TABLE[(j0 + 1) * {ns} + i0], ANISO_BEND_WEIGHT_TABLE[(j0 + 1) * {ns} + i0 + 1], fx);
    return mix(v0, v1, fy);
}}
"""
'''
