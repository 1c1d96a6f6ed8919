"""Roughness -> prefiltered-LOD mappings: the built-in ones (numpy twins of ``realtime/shaders/lod.glsl``)
and the fitted monotone mapping's file format (:class:`LodMapping`).

Built-in mappings (:data:`LOD_MAPPINGS`), each a pair of functions of the same
name as its GLSL twin, ``M`` the last level of the prefiltered chain and ``cube_log2`` log2 of the
cube's face size:

* ``lod_linear(r) = clamp(r, 0, 1) M``, inverse ``roughness_linear(lod) = lod / M``
  (article 000);
* ``lod_quadratic(r) = M x (2 - x)``, ``x = clamp(r, 0, 1)``, inverse
  ``roughness_quadratic(lod) = 1 - sqrt(max(1 - lod/M, 0))`` (Filament's perceptualRoughnessToLod);
* ``lod_log2(r) = clamp(cube_log2 - (1 - 1.2 log2 max(r, 1e-6)), 0, M)``, inverse
  ``roughness_log2(lod) = clamp(2^((lod - cube_log2 + 1)/1.2), 0, 1)`` (UE4's
  ComputeReflectionCaptureMipFromRoughness, quoted by article 002).

The fitted mapping (``pbrcheck fit-lod``) is

    lod(r) = sum_k c_k b_k(r),    c_k >= 0,    b_k in {r, r^2, r^3, r^4, sqrt(r), r (2 - r)}

Every basis function is increasing on [0, 1] with ``b_k(0) = 0``, so non-negative coefficients make
the mapping monotone non-decreasing with ``lod(0) = 0``; ``r (2 - r)`` makes both smooth built-in
mappings members of the family (``linear`` = M r, ``quadratic`` = M r (2 - r); their coefficients
are :data:`LOD_MAPPINGS`' ``basis``). It is clamped to ``[0, mip_count - 1]`` when
evaluated, as the GPU's ``textureLod`` does. It holds only for the cube size, mip count and
prefiltered chain it was measured with (``chain``: the built-in mapping whose inverse baked the
levels); all three are kept with the coefficients and checked when it is loaded.

API
---
:func:`lod_linear`, :func:`lod_quadratic`, :func:`lod_log2` and their inverses
:func:`roughness_linear`, :func:`roughness_quadratic`, :func:`roughness_log2`;
:data:`LOD_MAPPINGS` (the registry, a built-in mapping's entry holding its pair),
:data:`BUILTIN_LOD_MAPPINGS`, :func:`builtin_lod` (dispatch by name); :data:`BASIS_NAMES`, :func:`basis`,
:func:`basis_coefficients`; :class:`LodMapping` (``__call__``, ``to_json``, ``from_json``,
``load``, ``glsl_expr``, ``glsl``); :class:`LodFitError`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from .errors import PbrcheckError
from .jsonio import read_json
from .registry import Entry, Registry, role

#: log2's smallest roughness (log2 of 0 is -inf; 1e-6 is far below the first level's roughness).
LOG2_MIN_ROUGHNESS = 1e-6


def lod_linear(r, max_lod, cube_log2=None):
    """Article 000: ``lod = clamp(r, 0, 1) M``."""
    return np.clip(r, 0.0, 1.0) * max_lod


def roughness_linear(lod, max_lod, cube_log2=None):
    """Inverse of :func:`lod_linear`: ``r = lod / M``."""
    return np.asarray(lod, dtype=np.float64) / max_lod


def lod_quadratic(r, max_lod, cube_log2=None):
    """Filament's perceptualRoughnessToLod: ``lod = M x (2 - x)``, ``x = clamp(r, 0, 1)``."""
    x = np.clip(r, 0.0, 1.0)
    return max_lod * x * (2.0 - x)


def roughness_quadratic(lod, max_lod, cube_log2=None):
    """Inverse of :func:`lod_quadratic`: ``r = 1 - sqrt(max(1 - lod / M, 0))``."""
    return 1.0 - np.sqrt(np.maximum(1.0 - np.asarray(lod, dtype=np.float64) / max_lod, 0.0))


def lod_log2(r, max_lod, cube_log2):
    """UE4's ComputeReflectionCaptureMipFromRoughness: level from the 1x1 mip
    ``1 - 1.2 log2 r``, i.e. ``lod = clamp(cube_log2 - (1 - 1.2 log2 max(r, 1e-6)), 0, M)``."""
    level_from_1x1 = 1.0 - 1.2 * np.log2(np.maximum(r, LOG2_MIN_ROUGHNESS))
    return np.clip(cube_log2 - level_from_1x1, 0.0, max_lod)


def roughness_log2(lod, max_lod, cube_log2):
    """Inverse of :func:`lod_log2`: ``r = clamp(2^((lod - cube_log2 + 1) / 1.2), 0, 1)``."""
    return np.clip(np.exp2((np.asarray(lod, dtype=np.float64) - cube_log2 + 1.0) / 1.2), 0.0, 1.0)


#: Roughness -> prefiltered mip level. ``extra["basis"]``: the mapping as coefficients of
#: :data:`pbrcheck.lodmap.BASIS_NAMES` times the last level ``M`` (None: not a member of the fit's
#: family); ``extra["builtin"]``: bakes a prefiltered chain (``fitted`` reads a built-in chain);
#: a built-in mapping's roles: its ``lod`` of roughness and its inverse ``roughness`` of the level.
LOD_MAPPINGS = Registry("LOD_MAPPING", applies_to=(
    "the real-time renderer's prefiltered chain only (the reference has none): a built-in mapping's roles lod and "
    "roughness (numpy here, GLSL twins of the same names in lod.glsl)"), entries=[
    Entry("linear", "article 000: lod = r M", extra={"builtin": True, "basis": (1, 0, 0, 0, 0, 0)},
          roles={"lod": role(lod_linear), "roughness": role(roughness_linear)}),
    Entry("quadratic", "Filament's perceptualRoughnessToLod: lod = M r (2 - r)",
          extra={"builtin": True, "basis": (0, 0, 0, 0, 0, 1)},
          roles={"lod": role(lod_quadratic), "roughness": role(roughness_quadratic)}),
    Entry("log2", "UE4's ComputeReflectionCaptureMipFromRoughness (article 002): "
                  "lod = log2(size) - (1 - 1.2 log2 r)", extra={"builtin": True, "basis": None},
          roles={"lod": role(lod_log2), "roughness": role(roughness_log2)}),
    Entry("fitted", "pbrcheck fit-lod's fitted monotone mapping (lod_mapping=fitted:FILE)",
          extra={"builtin": False, "basis": None}),
])

#: The built-in mappings (each bakes its own prefiltered chain).
BUILTIN_LOD_MAPPINGS = tuple(e.name for e in LOD_MAPPINGS if e.extra["builtin"])


def builtin_lod(name: str, r, max_lod: float, cube_log2: float) -> np.ndarray:
    """The built-in mapping ``name``'s LOD of roughness ``r``.

    Parameters
    ----------
    name : str
        A built-in member of :data:`LOD_MAPPINGS`.
    r : array_like
        Perceptual roughness in [0, 1].
    max_lod : float
        Last level of the prefiltered chain (``prefilter_levels - 1``).
    cube_log2 : float
        log2 of the cube's face size (the log2 mapping counts from the 1x1 level).

    Returns
    -------
    numpy.ndarray
        The level, float64.

    Raises
    ------
    LodFitError
        ``name`` is not a built-in mapping.
    """
    if name not in BUILTIN_LOD_MAPPINGS:
        raise LodFitError(f"lod_mapping: expected one of {', '.join(BUILTIN_LOD_MAPPINGS)}, found {name!r}")
    lod = LOD_MAPPINGS[name].roles["lod"].numpy
    return np.asarray(lod(np.asarray(r, dtype=np.float64), max_lod, cube_log2), np.float64)


def basis_coefficients(name: str, max_lod: float) -> list[float] | None:
    """A built-in mapping as coefficients of :data:`BASIS_NAMES` (None when it is no member)."""
    b = LOD_MAPPINGS[name].extra["basis"]
    return None if b is None else [float(max_lod) * c for c in b]


BASIS_NAMES = ("r", "r^2", "r^3", "r^4", "sqrt(r)", "r(2-r)")
#: Built-in mappings a prefiltered chain can be baked with (realtime/shaders/lod.glsl).
CHAINS = BUILTIN_LOD_MAPPINGS


def basis(r: np.ndarray) -> np.ndarray:
    """The fit's basis functions :data:`BASIS_NAMES` at roughness ``r`` (clamped to [0, 1]): (..., 6)."""
    r = np.clip(np.asarray(r, dtype=np.float64), 0.0, 1.0)
    return np.stack([r, r * r, r ** 3, r ** 4, np.sqrt(r), r * (2.0 - r)], axis=-1)


class LodFitError(PbrcheckError):
    """A fitted LOD mapping that cannot be read or fitted; names the file and field."""


@dataclass(frozen=True)
class LodMapping:
    """A fitted monotone roughness -> LOD mapping: coefficients of :data:`BASIS_NAMES`, valid for a
    ``cube_size``^2 cube with ``mip_count`` levels baked with the ``chain`` mapping."""
    coefficients: tuple[float, ...]
    cube_size: int
    mip_count: int
    chain: str = "quadratic"

    def __call__(self, roughness) -> np.ndarray:
        lod = basis(roughness) @ np.asarray(self.coefficients)
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
        d = read_json(path, LodFitError, "fitted LOD mapping")
        return cls.from_json(d.get("mappings", {}).get("fitted", d), str(path))

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


