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
(:data:`TRAIN_N`^2 points), is quadratic in the table values (the read is linear in them), so its
minimiser is the least-squares solution of the normal equations, computed exactly
(``numpy.linalg.lstsq``): no automatic differentiation is needed, and none of gradient descent's
iterations. "Before": the same table baked by point sampling at the texel centres (what
``sheen_lut.comp`` does, at the same size), the engines' default 32 x 32 bake, three.js's analytic
``DG / pi`` fit (:func:`realtime.lobes.sheen_dg_fit`), PlayCanvas's ``DG`` and three.js's constant
0.157 of its albedo scaling. Errors on a held-out grid (:data:`HELD_N`^2 points offset from the
training grid). The fitted table is written as :mod:`realtime.fitted_lobes` (constants + the
reader's conventions, a registry-ready numpy reader and a GLSL hook).

Anisotropic bent-normal weight
------------------------------
The truth: the spec's anisotropic GGX (F = 1) against a seeded test environment (:func:`test_env`)
per view (:func:`aniso_truth`); the real-time form: the Sample Viewer-style bent normal's split-sum
lookup (:func:`aniso_realtime`, :func:`prefiltered`) with the weight ``w`` of ``mix((b x v) x b, n,
w)`` per (strength, roughness) node, fitted by a dense scan per node over training environments
(:func:`fit_aniso_table`), reported on held-out environments and nodes against the Sample Viewer's
``(1 - s (1 - r))^4`` (:func:`aniso_report`).

API
---
:data:`ANISO_STRENGTH`, :data:`ANISO_ROUGHNESS`, :data:`ANISO_HELD_STRENGTH`, :data:`ANISO_HELD_ROUGHNESS`,
:data:`ANISO_TRAIN_ENVS`, :data:`ANISO_HELD_ENVS`, :data:`ENV_LOBES`, :data:`ENV_KAPPA`, :data:`ANISO_NU`,
:data:`ANISO_SCAN`, :func:`test_env`, :func:`prefiltered`, :func:`aniso_views`, :func:`aniso_truth`,
:func:`aniso_realtime`, :func:`sample_viewer_weight`, :func:`fit_aniso_table`, :func:`aniso_weight_table`,
:func:`aniso_report`, :func:`aniso_table_markdown`;
:data:`SHEEN_TABLE_N`, :data:`TRAIN_N`, :data:`HELD_N`, :data:`NOV_MIN`, :func:`sheen_truth`,
:func:`bilinear_weights`, :func:`fit_sheen_table`, :func:`bake_sheen_table`, :func:`sheen_report`,
:func:`sheen_table_markdown`, :func:`module_text`, :func:`read_table`, :func:`table_coords`,
:data:`SHEEN_QUAD`, :data:`AXES`, :data:`NOV_REPORT`.

References
----------
[Sheen]  KHR_materials_sheen README, "Implementation Notes".
[EntPBR] Dassault Systemes Enterprise PBR 2022x, sheen albedo fit (three.js IBLSheenBRDF).
[Karis13] B. Karis, "Real Shading in Unreal Engine 4", SIGGRAPH 2013 course notes (the prefilter, n = v = r).
[McAuley15] S. McAuley, the bent normal (b x v) x b of the Sample Viewer's anisotropy.
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


def fit_sheen_table(n=SHEEN_TABLE_N, axis="sqrt_nov"):
    """The n x n table (rows roughness, columns n.v on ``axis``) minimising the squared error on the
    training grid."""
    nov, rough = train_grid()
    W = bilinear_weights(table_coords(nov, axis), rough, n)
    table, *_ = np.linalg.lstsq(W, sheen_truth(nov, rough), rcond=None)
    return table.reshape(n, n)


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
        f"fitted {n}x{n}, n.v axis (least squares)": read_table(fit_sheen_table(n, "nov"), nov, rough, "nov"),
        f"fitted {n}x{n}, sqrt(n.v) axis (least squares: realtime/fitted_lobes.py)": read_table(table, nov, rough),
    })
    return {k: _errors(v, truth, nov) for k, v in cands.items()}, table


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
#: The weights scanned per node (the objective is 1-D per node: a dense scan finds its minimum).
ANISO_SCAN = np.linspace(0.0, 1.0, 51)
_Z = np.array([0.0, 0.0, 1.0])
_B = np.array([0.0, 1.0, 0.0])  # the anisotropy bitangent n x t for the direction t = +X


def _u_grid(n=ANISO_NU):
    g = (np.arange(n) + 0.5) / n
    return np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1).reshape(-1, 2)


def test_env(seed):
    """The environment ``L(l)`` of the seed (module constants)."""
    rng = np.random.default_rng(seed)
    z, ph = rng.uniform(0.2, 0.9, ENV_LOBES), rng.uniform(0.0, 2.0 * np.pi, ENV_LOBES)
    sz = np.sqrt(1.0 - z * z)
    mu = np.stack([sz * np.cos(ph), sz * np.sin(ph), z], axis=-1)
    c = rng.uniform(0.5, 1.5, ENV_LOBES)
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


def fit_aniso_table():
    """The weight per (roughness row, strength column) minimising the relative squared error summed
    over the training environments and views (strength 0 and roughness 1 pinned to 1); a dense scan
    of :data:`ANISO_SCAN` per node (no AD: the objective is 1-D per node)."""
    v = aniso_views()
    cases = _aniso_cases(ANISO_TRAIN_ENVS, ANISO_STRENGTH[1:], ANISO_ROUGHNESS[:-1])
    table = np.ones((len(ANISO_ROUGHNESS), len(ANISO_STRENGTH)))
    for j, r in enumerate(ANISO_ROUGHNESS[:-1]):
        for i, s in enumerate(ANISO_STRENGTH[1:], start=1):
            mine = [c for c in cases if c[1] == r and c[2] == s]
            cost = [sum(_rel_err(aniso_realtime(test_env(e), v, r, w), L) for e, _, _, L in mine) for w in ANISO_SCAN]
            table[j, i] = ANISO_SCAN[int(np.argmin(cost))]
    return table


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
    and the bent-normal weights ``aniso_table``."""
    t = np.asarray(table, np.float64)
    at = np.asarray(aniso_table, np.float64)
    arows = ",\n".join("    (" + ", ".join(f"{x:.4f}" for x in row) + ")" for row in at)
    aflat = ", ".join(f"{x:.4f}" for x in at.ravel())
    ns, nr = len(ANISO_STRENGTH), len(ANISO_ROUGHNESS)
    n = t.shape[0]
    rows = ",\n".join("    (" + ", ".join(f"{x:.6f}" for x in row) + ")" for row in t)
    flat = ",\n        ".join(", ".join(f"{x:.6f}" for x in row) for row in t)
    return f'''"""Fitted real-time lobe tables (issue 36 item 5b), written by ``pbrcheck fit-lobes --module``
(:mod:`compare.research.fit_lobes`; do not edit by hand).

:data:`SHEEN_ALBEDO_TABLE`: the sheen directional albedo ``E(n.v, sheenRoughness)`` of the spec's
Charlie lobe (KHR_materials_sheen, ``int D_Charlie V_Charlie n.l dl``), {n} x {n}, fitted by least squares
to the quadrature so that its bilinear read matches it (docs/research.md, "pbrcheck fit-lobes"); the E
of the albedo scaling ``1 - max(sheenColor) E(n.v)``. Conventions (:data:`SHEEN_ALBEDO_TABLE_CONVENTIONS`):
row j at sheen roughness (j + 0.5)/{n} (row 0 smoothest), column i at sqrt(n.v) = (i + 0.5)/{n}; read
bilinearly between texel centres with linear extrapolation within half a texel of 0 and 1 and a
clamp at 0 (:func:`realtime.lobes.lut_bilinear`'s rule). :func:`sheen_albedo_fitted` is the numpy
reader, :data:`SHEEN_ALBEDO_GLSL` the same read as a GLSL hook (``float sheen_albedo_fitted(float NoV,
float roughness)``), registry-ready for ``SHEEN_SCALING`` as ``1 - max3(color) sheen_albedo_fitted``.


:data:`ANISO_BEND_WEIGHT_TABLE`: the weight ``w`` of the Sample Viewer-style bent normal
``normalize(mix((b x v) x b, n, w))`` (b the anisotropy bitangent), in place of its ``(1 - s (1 -
r))^4``, fitted against the spec's anisotropic GGX integral under test environments (docs/research.md);
rows roughness :data:`ANISO_ROUGHNESS`, columns strength :data:`ANISO_STRENGTH`, read bilinearly
between the nodes and clamped to them (below roughness {ANISO_ROUGHNESS[0]:g}: its first row);
:func:`aniso_bend_weight_fitted` the numpy reader, :data:`ANISO_BEND_WEIGHT_GLSL` the GLSL hook
``float aniso_bend_weight_fitted(float anisotropy, float roughness)``, registry-ready for
``ANISOTROPY_BEND`` as the Sample Viewer's bend with this weight.

API: :data:`SHEEN_ALBEDO_TABLE`, :data:`SHEEN_ALBEDO_TABLE_CONVENTIONS`, :func:`sheen_albedo_fitted`,
:data:`SHEEN_ALBEDO_GLSL`, :data:`ANISO_STRENGTH`, :data:`ANISO_ROUGHNESS`, :data:`ANISO_BEND_WEIGHT_TABLE`,
:func:`aniso_bend_weight_fitted`, :data:`ANISO_BEND_WEIGHT_GLSL`.
"""

import numpy as np

from realtime.lobes import lut_bilinear

SHEEN_ALBEDO_TABLE = np.array((
{rows}))

SHEEN_ALBEDO_TABLE_CONVENTIONS = {{
    "axes": "row j: sheen roughness = (j + 0.5)/{n}, row 0 smoothest; column i: sqrt(n.v) = (i + 0.5)/{n}",
    "read": "bilinear between texel centres, linear extrapolation within half a texel of 0 and 1, clamped at 0",
    "value": "E = int D_Charlie V_Charlie n.l dl (KHR_materials_sheen), fitted by least squares on a "
             "{TRAIN_N} x {TRAIN_N} grid of n.v in [{NOV_MIN}, 1] x roughness in [0, 1]",
}}


def sheen_albedo_fitted(NoV, roughness):
    """E at (n.v, sheen roughness) from :data:`SHEEN_ALBEDO_TABLE` (numpy twin of the GLSL hook)."""
    return lut_bilinear(SHEEN_ALBEDO_TABLE[..., None], np.sqrt(np.clip(NoV, 0.0, 1.0)), roughness)[..., 0]


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
    """The fitted weight at (strength, roughness) (numpy twin of the GLSL hook; uniform node spacing)."""
    x = np.clip((np.asarray(anisotropy, np.float64) - {ANISO_STRENGTH[0]!r}) / {ANISO_STRENGTH[1] - ANISO_STRENGTH[0]!r}, 0.0, {ns - 1}.0)
    y = np.clip((np.asarray(roughness, np.float64) - {ANISO_ROUGHNESS[0]!r}) / {ANISO_ROUGHNESS[1] - ANISO_ROUGHNESS[0]!r}, 0.0, {nr - 1}.0)
    i0, j0 = np.minimum(np.floor(x).astype(int), {ns - 2}), np.minimum(np.floor(y).astype(int), {nr - 2})
    fx, fy = x - i0, y - j0
    t = ANISO_BEND_WEIGHT_TABLE
    return ((1 - fy) * ((1 - fx) * t[j0, i0] + fx * t[j0, i0 + 1])
            + fy * ((1 - fx) * t[j0 + 1, i0] + fx * t[j0 + 1, i0 + 1]))


ANISO_BEND_WEIGHT_GLSL = """
const float ANISO_BEND_WEIGHT_TABLE[{ns * nr}] = float[]({aflat});

float aniso_bend_weight_fitted(float anisotropy, float roughness) {{
    float x = clamp((anisotropy - {ANISO_STRENGTH[0]:.6f}) / {ANISO_STRENGTH[1] - ANISO_STRENGTH[0]:.6f}, 0.0, {ns - 1}.0);
    float y = clamp((roughness - {ANISO_ROUGHNESS[0]:.6f}) / {ANISO_ROUGHNESS[1] - ANISO_ROUGHNESS[0]:.6f}, 0.0, {nr - 1}.0);
    int i0 = min(int(floor(x)), {ns - 2});
    int j0 = min(int(floor(y)), {nr - 2});
    float fx = x - float(i0), fy = y - float(j0);
    float v0 = mix(ANISO_BEND_WEIGHT_TABLE[j0 * {ns} + i0], ANISO_BEND_WEIGHT_TABLE[j0 * {ns} + i0 + 1], fx);
    float v1 = mix(ANISO_BEND_WEIGHT_TABLE[(j0 + 1) * {ns} + i0], ANISO_BEND_WEIGHT_TABLE[(j0 + 1) * {ns} + i0 + 1], fx);
    return mix(v0, v1, fy);
}}
"""
'''
