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

API
---
:data:`SHEEN_TABLE_N`, :data:`TRAIN_N`, :data:`HELD_N`, :data:`NOV_MIN`, :func:`sheen_truth`,
:func:`bilinear_weights`, :func:`fit_sheen_table`, :func:`bake_sheen_table`, :func:`sheen_report`,
:func:`sheen_table_markdown`, :func:`module_text`, :func:`read_table`, :func:`table_coords`,
:data:`SHEEN_QUAD`, :data:`AXES`, :data:`NOV_REPORT`.

References
----------
[Sheen]  KHR_materials_sheen README, "Implementation Notes".
[EntPBR] Dassault Systemes Enterprise PBR 2022x, sheen albedo fit (three.js IBLSheenBRDF).
"""

from __future__ import annotations

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


def module_text(table) -> str:
    """The source of :mod:`realtime.fitted_lobes` holding ``table`` (on the "sqrt_nov" axis)."""
    t = np.asarray(table, np.float64)
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

API: :data:`SHEEN_ALBEDO_TABLE`, :data:`SHEEN_ALBEDO_TABLE_CONVENTIONS`, :func:`sheen_albedo_fitted`,
:data:`SHEEN_ALBEDO_GLSL`.
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
'''
