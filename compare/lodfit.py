"""Fitting a smooth monotone roughness -> prefiltered-LOD mapping to measured optima.

Given per-roughness optimal LODs ``lod_i`` (the continuous mip level that minimizes the real-time
specular error against the reference), fit

    lod(r) = sum_k c_k b_k(r),    c_k >= 0,    b_k in {r, r^2, r^3, r^4, sqrt(r), r (2 - r)}

Every basis function is increasing on [0, 1] with ``b_k(0) = 0``, so non-negative coefficients make
the mapping monotone non-decreasing with ``lod(0) = 0`` (roughness 0 samples the base level), and
the fit is a non-negative least-squares problem (Lawson & Hanson 1974, ``scipy.optimize.nnls``),
optionally weighted. ``r (2 - r)`` is there so that both smooth built-in mappings are members of
the family (``linear`` = M r, ``quadratic`` = M r (2 - r)): a fit started from a built-in can only
improve on it. The result is clamped to ``[0, mip_count - 1]`` when evaluated, as the GPU's
``textureLod`` does.

The fitted mapping only holds for the cube size and mip count it was measured with; both are kept
with the coefficients and checked when it is loaded. It also holds only for the prefiltered chain it
was measured on: ``chain`` names the built-in mapping whose inverse baked the levels (level L holds
``roughness_from_lod(L)`` of that mapping); ``lod_mapping=fitted:FILE`` bakes that chain and looks it
up with the fitted function.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from pbrcheck.errors import PbrcheckError

BASIS_NAMES = ("r", "r^2", "r^3", "r^4", "sqrt(r)", "r(2-r)")
#: Built-in mappings a prefiltered chain can be baked with (realtime/shaders/ibl.glsl).
CHAINS = ("linear", "quadratic", "log2")


def _basis(r: np.ndarray) -> np.ndarray:
    r = np.clip(np.asarray(r, dtype=np.float64), 0.0, 1.0)
    return np.stack([r, r * r, r ** 3, r ** 4, np.sqrt(r), r * (2.0 - r)], axis=-1)


class LodFitError(PbrcheckError):
    pass


@dataclass(frozen=True)
class LodMapping:
    coefficients: tuple[float, ...]
    cube_size: int
    mip_count: int
    chain: str = "quadratic"

    def __call__(self, roughness) -> np.ndarray:
        lod = _basis(roughness) @ np.asarray(self.coefficients)
        return np.clip(lod, 0.0, self.mip_count - 1)

    def to_json(self) -> dict:
        return {"basis": list(BASIS_NAMES), **asdict(self)}

    @classmethod
    def from_json(cls, d: dict, source: str = "<fit>") -> "LodMapping":
        try:
            c = tuple(float(x) for x in d["coefficients"])
            m = cls(c, int(d["cube_size"]), int(d["mip_count"]), str(d.get("chain", "quadratic")))
        except (KeyError, TypeError, ValueError) as e:
            raise LodFitError(f"{source}: not a fitted LOD mapping ({e})") from None
        if len(c) != len(BASIS_NAMES) or any(x < 0 or not np.isfinite(x) for x in c):
            raise LodFitError(f"{source}: coefficients: expected {len(BASIS_NAMES)} finite non-negative numbers, found {list(c)}")
        if m.chain not in CHAINS:
            raise LodFitError(f"{source}: chain: expected one of {', '.join(CHAINS)}, found {m.chain!r}")
        return m

    @classmethod
    def load(cls, path: str | Path) -> "LodMapping":
        p = Path(path)
        try:
            d = json.loads(p.read_text())
        except (OSError, json.JSONDecodeError) as e:
            raise LodFitError(f"{p}: cannot read fitted LOD mapping ({e})") from None
        return cls.from_json(d.get("mappings", {}).get("fitted", d), str(p))

    def glsl_expr(self, var: str = "r") -> str:
        """One GLSL expression of ``var`` (clamped as :meth:`__call__`), for a ``#define``."""
        c = [f"{x:.9g}" for x in self.coefficients]
        x = f"clamp({var}, 0.0, 1.0)"
        return (f"clamp({x} * ({c[0]} + {x} * ({c[1]} + {x} * ({c[2]} + {x} * {c[3]}))) + {c[4]} * sqrt({x}) "
                f"+ {c[5]} * {x} * (2.0 - {x}), 0.0, {float(self.mip_count - 1):.1f})")

    def glsl(self, name: str = "roughnessToLodFitted") -> str:
        """The mapping as a GLSL function (same clamp as :meth:`__call__`)."""
        c = [f"{x:.9g}" for x in self.coefficients]
        return (
            f"// Fitted roughness -> LOD mapping (pbrcheck fit-lod), valid for a {self.cube_size}^2 cube\n"
            f"// with {self.mip_count} mips, on a chain baked with the {self.chain} mapping: lod = sum c_k b_k(r),\n"
            f"// b = (r, r^2, r^3, r^4, sqrt(r), r (2 - r)), c_k >= 0 (monotone, lod(0) = 0).\n"
            f"float {name}(float r) {{\n"
            f"    r = clamp(r, 0.0, 1.0);\n"
            f"    float lod = r * ({c[0]} + r * ({c[1]} + r * ({c[2]} + r * {c[3]}))) + {c[4]} * sqrt(r)\n"
            f"              + {c[5]} * r * (2.0 - r);\n"
            f"    return clamp(lod, 0.0, {float(self.mip_count - 1):.1f});\n"
            f"}}\n"
        )


def fit_lod_mapping(roughness, lod, *, cube_size: int, mip_count: int, weights=None) -> LodMapping:
    """Non-negative least squares of the monotone basis to (roughness, lod) samples."""
    from scipy.optimize import nnls

    r = np.asarray(roughness, dtype=np.float64)
    y = np.asarray(lod, dtype=np.float64)
    if r.shape != y.shape or r.size < 2 or not (np.all(np.isfinite(r)) and np.all(np.isfinite(y))):
        raise LodFitError(f"fit-lod: need >= 2 finite (roughness, lod) pairs, found {r.size}")
    w = np.ones_like(r) if weights is None else np.sqrt(np.asarray(weights, dtype=np.float64))
    A = _basis(r) * w[:, None]
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
    from scipy.optimize import minimize

    r = np.asarray(roughness, dtype=np.float64)
    g = np.asarray(lod_grid, dtype=np.float64)
    e = np.asarray(errors, dtype=np.float64)
    if e.shape != (r.size, g.size) or not np.all(np.isfinite(e)):
        raise LodFitError(f"fit-lod: errors must be a finite {r.size} x {g.size} table, found shape {e.shape}")
    B = _basis(r)
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
