"""Roughness added per normal-map mip level: the table ``pbrcheck fit-normal-roughness`` fits, its file
format and GLSL hook, and the closed forms it is compared with.

The table holds one GGX ``alpha^2`` increment per level of the normal map's mip chain; a fragment
reading the normal map at (fractional) level ``lod`` gets

    alpha'^2 = min(alpha^2 + v(lod), 1),   v(lod) = (1 - f) t[k] + f t[k + 1],   k = floor(lod), f = lod - k

(``alpha = roughness^2``, perceptual roughness in and out; ``lod`` clamped to the table), the same
widening as :func:`pbrcheck.specular_aa.specular_aa_widen`, interpolated between levels as trilinear
filtering interpolates the normal map itself. Written as GLSL it is a ``hook_specular_aa``
(:mod:`realtime.hooks`, docs/hooks.md): ``--shader FILE.glsl`` or the option ``shader=FILE.glsl``
renders with it (raster pipeline; the hook is called on normal-mapped fragments only). :meth:`NormalRoughnessTable.__call__`
is its numpy twin, compared with the written GLSL by the GLSL harness (``realtime.glsl_harness.run_glsl(...,
hook=...)``) in ``tests/test_fit_normal_roughness.py``.

Closed forms per level (means over the level's texels of a normal map, :func:`level_closed_forms`):
``toksvig``: ``2 (1 - L) / L`` of the box-filtered normal's length L (Toksvig 2005, "Mipmapping Normal
Maps", JGT 10(3), with ``s = 2 / alpha^2``: :func:`pbrcheck.specular_aa.specular_aa_toksvig`);
``lean``: ``var(s_x) + var(s_y)`` of the level-0 slopes under each texel (Olano & Baker 2010,
:func:`pbrcheck.specular_aa.slope_variance_mips`).

API
---
:class:`NormalRoughnessTable` (``__call__``, ``to_json``, ``from_json``, ``load``, ``glsl``);
:func:`level_closed_forms`; :func:`box_mips`; :class:`NormalRoughnessError`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import PbrcheckError
from .jsonio import read_json
from .specular_aa import slope_variance_mips, specular_aa_widen


class NormalRoughnessError(PbrcheckError):
    """A per-level roughness table that cannot be read or fitted; names the file and field."""


@dataclass(frozen=True)
class NormalRoughnessTable:
    """``alpha^2`` increments, one per normal-map mip level (level 0 first), non-negative."""
    increments: tuple[float, ...]

    def variance(self, lod) -> np.ndarray:
        """``v(lod)``: the table linearly interpolated at ``lod`` (clamped to its levels)."""
        t = np.asarray(self.increments, np.float64)
        x = np.clip(np.asarray(lod, np.float64), 0.0, len(t) - 1)
        return np.interp(x, np.arange(len(t)), t)

    def __call__(self, roughness, lod) -> np.ndarray:
        """The widened perceptual roughness (numpy twin of :meth:`glsl`'s ``hook_specular_aa``)."""
        return specular_aa_widen(roughness, self.variance(lod))

    def to_json(self) -> dict:
        return {"convention": "alpha^2 increment per normal-map mip level (level 0 first), "
                              "alpha = roughness^2, linear between levels",
                "increments": [float(x) for x in self.increments]}

    @classmethod
    def from_json(cls, d: dict, source: str = "<fit>") -> "NormalRoughnessTable":
        try:
            t = tuple(float(x) for x in d["increments"])
        except (KeyError, TypeError, ValueError) as e:
            raise NormalRoughnessError(f"{source}: increments: not a per-level roughness table ({e})") from None
        if not t or any(x < 0 or not np.isfinite(x) for x in t):
            raise NormalRoughnessError(f"{source}: increments: expected finite non-negative numbers, found {list(t)}")
        return cls(t)

    @classmethod
    def load(cls, path: str | Path) -> "NormalRoughnessTable":
        d = read_json(path, NormalRoughnessError, "a per-level roughness table")
        return cls.from_json(d.get("fitted", d), str(path))

    def glsl(self, source: str = "pbrcheck fit-normal-roughness") -> str:
        """The table as a ``hook_specular_aa`` file (self-contained: the raster pass and the compute
        frame pass both compile it)."""
        n = len(self.increments)
        vals = ", ".join(f"{x:.9g}" for x in self.increments)
        return (
            f"// Roughness added per normal-map mip level ({source}): hook_specular_aa (docs/hooks.md).\n"
            f"// Equation: alpha'^2 = min(alpha^2 + v(lod), 1), alpha = roughness^2 (perceptual in and out),\n"
            f"// v linear between the {n} levels' alpha^2 increments below (level 0 first), lod clamped.\n"
            f"const float NR_INCREMENTS[{n}] = float[{n}]({vals});\n"
            f"float hook_specular_aa(float roughness, float normal_length, float normal_lod) {{\n"
            f"    float x = clamp(normal_lod, 0.0, {float(n - 1):.1f});\n"
            f"    int k = int(floor(x));\n"
            f"    float v = mix(NR_INCREMENTS[k], NR_INCREMENTS[min(k + 1, {n - 1})], x - float(k));\n"
            f"    float a = roughness * roughness;\n"
            f"    return v > 0.0 ? sqrt(sqrt(clamp(a * a + v, 0.0, 1.0))) : roughness;\n"
            f"}}\n"
            f"// End of the table: {n} levels, alpha^2 increments (pbrcheck.normal_roughness).\n"
        )


def level_closed_forms(texels: np.ndarray, levels: int | None = None) -> dict[str, list[float]]:
    """Per mip level, the mean over its texels of Toksvig's ``2 (1 - L) / L`` and of LEAN's slope
    variance, for the normal map ``texels`` (H, W, >=3) in [0, 1] as uploaded (normal ``2 t - 1``).
    Box mips (an odd row or column dropped at each halving), as :func:`pbrcheck.specular_aa.slope_variance_mips`;
    ``levels`` default: the full chain."""
    t = np.asarray(texels, np.float64)[..., :3]
    h, w = t.shape[:2]
    levels = max(h, w).bit_length() if levels is None else int(levels)
    tok = []
    for mip in box_mips(t, levels):
        L = np.clip(np.linalg.norm(2.0 * mip - 1.0, axis=-1), 1e-4, 1.0)
        tok.append(float(np.mean(2.0 * (1.0 - L) / L)))
    lean = [float(np.mean(m)) for m in slope_variance_mips(t, levels)]
    return {"toksvig": tok, "lean": lean}


def box_mips(texels: np.ndarray, levels: int | None = None) -> list[np.ndarray]:
    """The box mip chain of ``texels`` (H, W, C), unnormalised: level ``k``'s texel is the mean of a
    ``2^k x 2^k`` block of level 0 (each axis's block at most its size; an odd row or column dropped at
    each halving), as ``glGenerateMipmap``'s box filter makes it of the uploaded texels (decoding
    ``2 t - 1`` is linear: the mean of the decoded normals). Level 0 is ``texels`` itself;
    ``levels`` default: the full chain (``max(H, W).bit_length()``)."""
    t = np.asarray(texels)
    h, w = t.shape[:2]
    levels = max(h, w).bit_length() if levels is None else int(levels)
    out = []
    for k in range(levels):
        bh, bw = 1 << min(k, h.bit_length() - 1), 1 << min(k, w.bit_length() - 1)
        m = t[:h - h % bh, :w - w % bw].reshape(h // bh, bh, w // bw, bw, t.shape[2]).mean(axis=(1, 3))
        out.append(m.astype(t.dtype, copy=False))
    return out
