"""The fit's maths of ``pbrcheck fit-lod``: a smooth monotone roughness -> LOD mapping fitted to
measured optima (:func:`fit_lod_mapping`, non-negative least squares, Lawson & Hanson 1974,
``scipy.optimize.nnls``) or to a measured error table (:func:`fit_lod_to_error`, bounded Powell on
the predicted error, :func:`predicted_error`). The family and the file format are
:mod:`pbrcheck.lodmap` (:class:`~pbrcheck.lodmap.LodMapping`).

API
---
:func:`fit_lod_mapping`, :func:`predicted_error`, :func:`fit_lod_to_error`.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize, nnls

from pbrcheck.lodmap import BASIS_NAMES, LodFitError, LodMapping, basis


def fit_lod_mapping(roughness, lod, *, cube_size: int, mip_count: int, weights=None) -> LodMapping:
    """Non-negative least squares of the monotone basis to (roughness, lod) samples."""
    r = np.asarray(roughness, dtype=np.float64)
    y = np.asarray(lod, dtype=np.float64)
    if r.shape != y.shape or r.size < 2 or not (np.all(np.isfinite(r)) and np.all(np.isfinite(y))):
        raise LodFitError(f"fit-lod: need >= 2 finite (roughness, lod) pairs, found {r.size}")
    w = np.ones_like(r) if weights is None else np.sqrt(np.asarray(weights, dtype=np.float64))
    A = basis(r) * w[:, None]
    coef, _ = nnls(A, y * w)
    return LodMapping(tuple(float(x) for x in coef), int(cube_size), int(mip_count))


def predicted_error(lod, lod_grid, errors, weights=None) -> float:
    """The scene error a scan predicts for reading roughness ``i`` at ``lod[i]``:
    ``sum_i w_i errors_i(lod_i) / sum_i w_i``, each measured curve ``errors[i]`` (on ``lod_grid``)
    interpolated linearly. With ``w_i`` the pixel count of roughness ``i`` this is the relmse over
    the scene's pixels (relmse is a per-pixel mean)."""
    e = np.asarray(errors, dtype=np.float64)
    lod = np.asarray(lod, dtype=np.float64)
    w = np.ones(e.shape[0]) if weights is None else np.asarray(weights, dtype=np.float64)
    w = w / w.sum()
    return float(sum(wi * np.interp(li, lod_grid, ei) for wi, li, ei in zip(w, lod, e)))


def fit_lod_to_error(roughness, lod_grid, errors, *, cube_size: int, mip_count: int, weights=None,
                     starts=()) -> LodMapping:
    """The monotone mapping (same basis, c_k >= 0) minimizing the *predicted error* rather than the
    distance to the per-roughness optima.

    ``errors[i, j]`` is the measured error of roughness ``roughness[i]`` read at LOD ``lod_grid[j]``
    (a dense scan); the predicted error of a mapping is ``sum_i w_i errors_i(lod(r_i))`` with linear
    interpolation along the scan. Noisy or multi-modal curves make the optima a poor target (the
    closest smooth curve can pass through high-error regions); this minimizes what is measured.
    Bounded Powell from the NNLS fit to the optima and from each of ``starts`` (further coefficient
    vectors); the best result wins.
    """
    r = np.asarray(roughness, dtype=np.float64)
    g = np.asarray(lod_grid, dtype=np.float64)
    e = np.asarray(errors, dtype=np.float64)
    if e.shape != (r.size, g.size) or not np.all(np.isfinite(e)):
        raise LodFitError(f"fit-lod: errors must be a finite {r.size} x {g.size} table, found shape {e.shape}")
    B = basis(r)
    top = float(mip_count - 1)

    def predicted(c):
        return predicted_error(np.clip(B @ np.maximum(c, 0.0), 0.0, top), g, e, weights)

    opt_lod = g[np.argmin(e, axis=1)]
    x0s = [np.asarray(fit_lod_mapping(r, opt_lod, cube_size=cube_size, mip_count=mip_count).coefficients)]
    x0s += [np.maximum(np.asarray(s, dtype=np.float64), 0.0) for s in starts]
    best = min(x0s, key=predicted)
    for x0 in x0s:
        res = minimize(predicted, x0, method="Powell", bounds=[(0.0, 4.0 * top + 1.0)] * len(BASIS_NAMES),
                       options={"xtol": 1e-4, "ftol": 1e-10, "maxfev": 4000})
        if predicted(res.x) < predicted(best):
            best = np.maximum(res.x, 0.0)
    return LodMapping(tuple(float(x) for x in best), int(cube_size), int(mip_count))
