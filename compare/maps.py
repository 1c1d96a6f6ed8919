"""Error maps and display images: false-colour PNGs, tone-mapped PNGs, signed-difference EXRs.

Figures are written with matplotlib's Agg backend (no display needed), images (display images, error
maps) with Pillow alone (:func:`png_bytes`: no figure, no pyplot import). Pixels outside the valid mask
are drawn in :data:`MASKED_GREY` so that excluded background and silhouettes are obvious. Display
images apply a renderer's own display transform where it has one (:func:`display_rgb`); metrics
never see it.

API
---
:func:`write_maps`, :func:`write_rel_png`, :func:`write_flip_png`, :func:`write_diff_exr`,
:func:`write_tonemapped`, :func:`display_rgb`, :func:`tonemap`, :func:`tonemap_aces`,
:func:`srgb_oetf`, :func:`false_colour`, :func:`pyplot`, :func:`save_figure`, :func:`png_bytes`, :func:`safe_name` (a
renderer's, scene's or check's name as a file or folder name: the gate's and the report's).
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from pbrcheck.atomic import staged_folder, write_bytes_atomic
from pbrcheck.exr import Image, write_exr

from .worktime import work

#: Relative error |t - r| / (r + 0.01) mapped to the full colour range (values above saturate).
REL_MAP_MAX = 1.0
#: Grey (sRGB, 0..1) for pixels outside the valid mask.
MASKED_GREY = (0.35, 0.35, 0.35)
#: The resolution a PNG records (pyplot.imsave's default).
PNG_DPI = 100
#: Exposure of the tone-mapped display images: scales linear radiance before the curve.
DISPLAY_EXPOSURE = 1.0


def _mpl():
    """matplotlib with the Agg backend, imported on first use (a heavy import most commands skip)."""
    import matplotlib  # local: heavy, and the backend must be chosen before pyplot is imported

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return matplotlib, plt


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend (no display needed)."""
    return _mpl()[1]


def safe_name(name: str) -> str:
    """``name`` as a file or folder name: every character but letters, digits and ``-_.`` becomes
    ``_``, and ``.`` or ``..`` all ``_`` (the gate's :func:`~compare.gate.load_budget` refuses two
    checks whose folders would be one)."""
    safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in name)
    return "_" * len(safe) if safe in (".", "..") else safe


def save_figure(fig, path: Path, dpi: int = 80) -> str:
    """Lay out ``fig``, write it to ``path`` (PNG, atomically), close it; returns the file name."""
    plt = pyplot()
    with work("plots"):
        fig.tight_layout()
        buf = io.BytesIO()
        try:
            fig.savefig(buf, dpi=dpi, format="png")
        finally:
            plt.close(fig)
        write_bytes_atomic(path, buf.getvalue())
    return Path(path).name


def png_bytes(rgb: np.ndarray) -> bytes:
    """``rgb`` (H, W, 3) in [0, 1] as PNG bytes, without matplotlib (an image needs no figure, and
    pyplot's import is most of a small plot's cost): Pillow, RGBA, 8 bits, the values truncated as
    ``matplotlib.pyplot.imsave`` does (``uint8(255 x)``), so the pixels are the ones it wrote (tested)."""
    from PIL import Image as PILImage  # local: only PNG writers need it (a matplotlib dependency)

    a = np.clip(np.asarray(rgb, dtype=np.float64), 0.0, 1.0)
    rgba = np.empty(a.shape[:2] + (4,), dtype=np.uint8)
    rgba[..., :3] = (a[..., :3] * 255).astype(np.uint8)
    rgba[..., 3] = 255
    buf = io.BytesIO()
    PILImage.fromarray(rgba, "RGBA").save(buf, format="png", dpi=(PNG_DPI, PNG_DPI))
    return buf.getvalue()


def _save_rgb(path: Path, rgb: np.ndarray) -> Path:
    """``rgb`` in [0, 1] as a PNG at ``path`` (:func:`png_bytes`), encoded in memory and written atomically."""
    with work("plots"):
        return write_bytes_atomic(path, png_bytes(rgb))


def false_colour(values: np.ndarray, vmax: float, cmap: str, mask: np.ndarray | None = None) -> np.ndarray:
    """(H, W) values to (H, W, 3) colours of ``cmap`` over [0, vmax]; masked-out pixels grey."""
    from matplotlib import colormaps  # local: the colour maps alone, not pyplot (heavy)

    cm = colormaps[cmap]
    rgb = cm(np.clip(values / vmax, 0.0, 1.0))[..., :3]
    if mask is not None:
        rgb[~mask] = MASKED_GREY
    return rgb


def srgb_oetf(y: np.ndarray) -> np.ndarray:
    """The sRGB transfer function (IEC 61966-2-1) of display-linear values in [0, 1]."""
    return np.where(y <= 0.0031308, 12.92 * y, 1.055 * np.power(y, 1 / 2.4) - 0.055)


def tonemap(rgb: np.ndarray, exposure: float = DISPLAY_EXPOSURE) -> np.ndarray:
    """Display version of linear radiance: ACES filmic fit (Narkowicz 2015) then the sRGB OETF."""
    x = np.clip(rgb.astype(np.float64) * exposure, 0.0, None)
    y = np.clip((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0)
    return srgb_oetf(y)


# Article 002's fitted ACES (Hill's RRT+ODT fit, via MJP's BakingLab).
_ACES_IN = np.array([[0.59719, 0.35458, 0.04823], [0.07600, 0.90834, 0.01566], [0.02840, 0.13383, 0.83777]])
_ACES_OUT = np.array([[1.60475, -0.53108, -0.07367], [-0.10208, 1.10813, -0.00605], [-0.00327, -0.07276, 1.07602]])


def tonemap_aces(rgb: np.ndarray) -> np.ndarray:
    """Article 002's toneMapACES: input matrix, RRTAndODTFit, output matrix, saturate (display-linear)."""
    c = rgb @ _ACES_IN.T
    a = c * (c + 0.0245786) - 0.000090537
    b = c * (0.983729 * c + 0.4329510) + 0.238081
    return np.clip((a / b) @ _ACES_OUT.T, 0.0, 1.0)


def display_rgb(rgb: np.ndarray, options: dict | None = None) -> np.ndarray:
    """The sRGB display image of linear radiance ``rgb`` under a renderer's display options.

    A real-time preset's ``exposure`` multiplies the radiance and its ``tonemap`` picks the curve:
    ``aces`` is article 002's fitted ACES (:func:`tonemap_aces`); ``none`` (and images without
    options: the reference) use the report's filmic curve (:func:`tonemap`). Display only: every
    metric is computed on the linear radiance.

    Parameters
    ----------
    rgb : numpy.ndarray
        (H, W, 3) linear radiance.
    options : dict, optional
        The renderer's options (``tonemap``, ``exposure``); None for the reference.

    Returns
    -------
    numpy.ndarray
        (H, W, 3) sRGB-encoded values in [0, 1].
    """
    o = options or {}
    exposure = float(o.get("exposure", 1.0))
    if o.get("tonemap") == "aces":
        return srgb_oetf(tonemap_aces(np.clip(rgb.astype(np.float64) * exposure, 0.0, None)))
    return tonemap(rgb, DISPLAY_EXPOSURE * exposure)


def write_tonemapped(path: Path, rgb: np.ndarray, options: dict | None = None) -> Path:
    """Write :func:`display_rgb` of ``rgb`` as a PNG."""
    return _save_rgb(Path(path), display_rgb(rgb, options))


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
    """The three maps of ``compare --maps``: ``rel_error.png``, ``flip.png``, ``diff.exr``, staged in
    a sibling temporary folder and moved into ``out_dir`` together (all three or none)."""
    out_dir = Path(out_dir)
    names = {"rel_error": f"{prefix}rel_error.png", "flip": f"{prefix}flip.png", "diff": f"{prefix}diff.exr"}
    with staged_folder(out_dir) as stage:
        write_rel_png(stage / names["rel_error"], comparison)
        write_flip_png(stage / names["flip"], comparison)
        write_diff_exr(stage / names["diff"], comparison)
    return {k: out_dir / n for k, n in names.items()}
