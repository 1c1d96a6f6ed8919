"""Fitting a smooth monotone roughness -> prefiltered-LOD mapping to measured optima.

Given per-roughness optimal LODs ``lod_i`` (the continuous mip level that minimizes the real-time
specular error against the reference), fit

    lod(r) = sum_k c_k b_k(r),    c_k >= 0,    b_k in {r, r^2, r^3, r^4, sqrt(r)}

Every basis function is increasing on [0, 1] with ``b_k(0) = 0``, so non-negative coefficients make
the mapping monotone non-decreasing with ``lod(0) = 0`` (roughness 0 samples the base level), and
the fit is a non-negative least-squares problem (Lawson & Hanson 1974, ``scipy.optimize.nnls``),
optionally weighted. The result is clamped to ``[0, mip_count - 1]`` when evaluated, as the GPU's
``textureLod`` does.

The fitted mapping only holds for the cube size and mip count it was measured with; both are kept
with the coefficients and checked when it is loaded.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from pbrcheck.errors import PbrcheckError

BASIS_NAMES = ("r", "r^2", "r^3", "r^4", "sqrt(r)")


def _basis(r: np.ndarray) -> np.ndarray:
    r = np.clip(np.asarray(r, dtype=np.float64), 0.0, 1.0)
    return np.stack([r, r * r, r ** 3, r ** 4, np.sqrt(r)], axis=-1)


class LodFitError(PbrcheckError):
    pass


@dataclass(frozen=True)
class LodMapping:
    coefficients: tuple[float, ...]
    cube_size: int
    mip_count: int

    def __call__(self, roughness) -> np.ndarray:
        lod = _basis(roughness) @ np.asarray(self.coefficients)
        return np.clip(lod, 0.0, self.mip_count - 1)

    def to_json(self) -> dict:
        return {"basis": list(BASIS_NAMES), **asdict(self)}

    @classmethod
    def from_json(cls, d: dict, source: str = "<fit>") -> "LodMapping":
        try:
            c = tuple(float(x) for x in d["coefficients"])
            m = cls(c, int(d["cube_size"]), int(d["mip_count"]))
        except (KeyError, TypeError, ValueError) as e:
            raise LodFitError(f"{source}: not a fitted LOD mapping ({e})") from None
        if len(c) != len(BASIS_NAMES) or any(x < 0 or not np.isfinite(x) for x in c):
            raise LodFitError(f"{source}: coefficients: expected {len(BASIS_NAMES)} finite non-negative numbers, found {list(c)}")
        return m

    @classmethod
    def load(cls, path: str | Path) -> "LodMapping":
        p = Path(path)
        try:
            d = json.loads(p.read_text())
        except (OSError, json.JSONDecodeError) as e:
            raise LodFitError(f"{p}: cannot read fitted LOD mapping ({e})") from None
        return cls.from_json(d.get("mappings", {}).get("fitted", d), str(p))

    def glsl(self, name: str = "roughnessToLodFitted") -> str:
        """The mapping as a GLSL function (same clamp as :meth:`__call__`)."""
        c = [f"{x:.9g}" for x in self.coefficients]
        return (
            f"// Fitted roughness -> LOD mapping (pbrcheck fit-lod), valid for a {self.cube_size}^2 cube\n"
            f"// with {self.mip_count} mips: lod = sum c_k b_k(r), b = (r, r^2, r^3, r^4, sqrt(r)), c_k >= 0.\n"
            f"float {name}(float r) {{\n"
            f"    r = clamp(r, 0.0, 1.0);\n"
            f"    float lod = r * ({c[0]} + r * ({c[1]} + r * ({c[2]} + r * {c[3]}))) + {c[4]} * sqrt(r);\n"
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
