"""Error maps and display images: false-colour PNGs, tone-mapped PNGs, signed-difference EXRs.

PNGs are written with matplotlib's Agg backend (no display needed). Pixels outside the valid mask
are drawn in :data:`MASKED_GREY` so that excluded background and silhouettes are obvious.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pbrcheck.exr import Image, write_exr

#: Relative error |t - r| / (r + 0.01) mapped to the full colour range (values above saturate).
REL_MAP_MAX = 1.0
#: Grey (sRGB, 0..1) for pixels outside the valid mask.
MASKED_GREY = (0.35, 0.35, 0.35)
#: Exposure of the tone-mapped display images: scales linear radiance before the curve.
DISPLAY_EXPOSURE = 1.0


def _mpl():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return matplotlib, plt


def _save_rgb(path: Path, rgb: np.ndarray) -> Path:
    _, plt = _mpl()
    path.parent.mkdir(parents=True, exist_ok=True)
    plt.imsave(str(path), np.clip(rgb, 0.0, 1.0))
    return path


def false_colour(values: np.ndarray, vmax: float, cmap: str, mask: np.ndarray | None = None) -> np.ndarray:
    """(H, W) values to (H, W, 3) colours of ``cmap`` over [0, vmax]; masked-out pixels grey."""
    matplotlib, _ = _mpl()
    cm = matplotlib.colormaps[cmap]
    rgb = cm(np.clip(values / vmax, 0.0, 1.0))[..., :3]
    if mask is not None:
        rgb[~mask] = MASKED_GREY
    return rgb


def tonemap(rgb: np.ndarray, exposure: float = DISPLAY_EXPOSURE) -> np.ndarray:
    """Display version of linear radiance: ACES filmic fit (Narkowicz 2015) then the sRGB OETF."""
    x = np.clip(rgb.astype(np.float64) * exposure, 0.0, None)
    y = np.clip((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0)
    return np.where(y <= 0.0031308, 12.92 * y, 1.055 * np.power(y, 1 / 2.4) - 0.055)


def write_tonemapped(path: Path, rgb: np.ndarray) -> Path:
    return _save_rgb(Path(path), tonemap(rgb))


def write_rel_png(path: Path, comparison) -> Path:
    """Relative error, max over RGB, magma-free 'inferno' scale [0, REL_MAP_MAX]."""
    rel = comparison.maps.rel.max(axis=-1)
    return _save_rgb(Path(path), false_colour(rel, REL_MAP_MAX, "inferno", comparison.valid))


def write_flip_png(path: Path, comparison) -> Path:
    """HDR-FLIP error map with FLIP's customary magma scale [0, 1]."""
    return _save_rgb(Path(path), false_colour(comparison.maps.flip, 1.0, "magma", comparison.valid))


def write_diff_exr(path: Path, comparison) -> Path:
    """Signed difference t - r per channel (R, G, B), plus ``valid`` (1/0) as a channel."""
    d = comparison.maps.diff.astype(np.float32)
    return write_exr(path, Image.from_rgb(d, {"kind": "signed difference test - reference"},
                                          valid=comparison.valid.astype(np.float32)))


def write_maps(out_dir: Path, comparison, prefix: str = "") -> dict[str, Path]:
    """The three maps of ``compare --maps``: ``rel_error.png``, ``flip.png``, ``diff.exr``."""
    out_dir = Path(out_dir)
    return {
        "rel_error": write_rel_png(out_dir / f"{prefix}rel_error.png", comparison),
        "flip": write_flip_png(out_dir / f"{prefix}flip.png", comparison),
        "diff": write_diff_exr(out_dir / f"{prefix}diff.exr", comparison),
    }
