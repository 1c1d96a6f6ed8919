"""Statistics of an environment map that the error of a real-time approximation depends on.

API
---
- :func:`environment_stats` -- resolution, luminance range and concentration of an
  :class:`~pbrcheck.environment.EnvMap` (a plain dict, the ``env_*`` columns of a corpus row).
- :func:`thumbnail` -- a small tone-mapped sRGB uint8 picture of the map for the report.
- :data:`STAT_COLUMNS` -- the statistics' names, in table order.

Definitions (``Y`` = Rec.709 luminance of a texel times the map's ``scale``; texel ``(r, c)`` of an
H x W map sits at ``theta = pi r / (H - 1)`` and covers the solid angle
``dw = sin(theta) (pi / (H - 1)) (2 pi / W)``: the equirectangular Jacobian, so the pole rows, which
span almost no solid angle, weigh almost nothing):

* ``env_width``, ``env_height``, ``env_texels`` -- the resolution (what prefiltering and spherical
  harmonics see; users report brightness changing with it).
* ``env_max_luminance``, ``env_mean_luminance`` -- the maximum of ``Y`` and its solid-angle
  weighted mean (``sum Y dw / 4 pi``).
* ``env_dynamic_range`` -- ``log10(max Y / Y_p1)`` in decades, ``Y_p1`` the 1st percentile of ``Y``
  over texels, floored at :data:`DYNAMIC_RANGE_FLOOR` times the maximum (a black texel would make
  the range infinite and say nothing more).
* ``env_top1_energy`` -- the fraction of the incident energy ``sum Y dw`` carried by the brightest
  1 % of texels, counted by solid angle: texels sorted by ``Y`` are taken, brightest first, until
  they cover 1 % of the sphere (the last one in part). Counting texels by number instead would
  favour the tiny texels next to the poles; by solid angle the figure does not depend on the
  resolution and is exactly 0.01 for a uniform environment and close to 1 for a small sun.

References: Debevec 1998 (light probes and their dynamic range); Karis 2013, "Real Shading in Unreal
Engine 4" (prefiltered environment maps break down under small bright sources).
"""

from __future__ import annotations

import math

import numpy as np

from ..maps import tonemap

#: Rec.709 luminance weights.
LUMA = np.array([0.2126, 0.7152, 0.0722])
#: Solid-angle fraction of the "brightest texels" whose energy share is ``env_top1_energy`` (1 %).
TOP_FRACTION = 0.01
#: Percentile of luminance taken as the dark end of the dynamic range.
DARK_PERCENTILE = 1.0
#: Floor of the dark end relative to the maximum (caps the dynamic range at 12 decades).
DYNAMIC_RANGE_FLOOR = 1e-12
#: Thumbnail size (width, height) in pixels: 2:1 like the map.
THUMB_SIZE = (128, 64)

STAT_COLUMNS = ("env_width", "env_height", "env_texels", "env_max_luminance", "env_mean_luminance",
                "env_dynamic_range", "env_top1_energy")


def _solid_angles(height: int, width: int) -> np.ndarray:
    """(H,) solid angle of one texel per row (see the module docstring)."""
    theta = np.pi * np.arange(height) / (height - 1)
    return np.sin(theta) * (np.pi / (height - 1)) * (2 * np.pi / width)


def environment_stats(env) -> dict:
    """The statistics of :data:`STAT_COLUMNS` of ``env`` (an :class:`~pbrcheck.environment.EnvMap`).

    Parameters
    ----------
    env : EnvMap
        A validated environment (finite, non-negative, at least 2 x 3 texels).

    Returns
    -------
    dict
        ``env_*`` name -> value (ints for the resolution, floats otherwise).
    """
    data = np.asarray(env.data, dtype=np.float64)
    H, W = data.shape[:2]
    y = (data @ LUMA) * float(env.scale)
    w = np.broadcast_to(_solid_angles(H, W)[:, None], (H, W)).ravel()
    flat = y.ravel()
    e = flat * w
    total = float(e.sum())
    ymax = float(y.max())
    order = np.argsort(-flat, kind="stable")
    cum_w = np.cumsum(w[order])
    target = TOP_FRACTION * cum_w[-1]
    k = int(np.searchsorted(cum_w, target))          # texels 0..k-1 cover less than the target
    before = float(cum_w[k - 1]) if k > 0 else 0.0
    part = (target - before) / w[order[k]] if w[order[k]] > 0 else 0.0
    top_e = float(e[order[:k]].sum()) + part * float(e[order[k]])
    top1 = float(top_e / total) if total > 0 else float("nan")
    if ymax > 0:
        dark = max(float(np.percentile(flat, DARK_PERCENTILE)), DYNAMIC_RANGE_FLOOR * ymax)
        dyn = math.log10(ymax / dark)
    else:
        dyn = 0.0
    return {"env_width": int(W), "env_height": int(H), "env_texels": int(W * H),
            "env_max_luminance": ymax, "env_mean_luminance": total / (4 * math.pi),
            "env_dynamic_range": dyn, "env_top1_energy": top1}


def thumbnail(env, size: tuple[int, int] = THUMB_SIZE) -> np.ndarray:
    """A (h, w, 3) uint8 sRGB picture of ``env``: box-downsampled (nearest rows and columns
    averaged), exposed so the mean luminance maps to 0.18, then the report's filmic curve."""
    data = np.asarray(env.data, dtype=np.float64) * float(env.scale)
    H, W = data.shape[:2]
    tw, th = min(size[0], W), min(size[1], H)
    rows = np.minimum((np.arange(th + 1) * H) // th, H)
    cols = np.minimum((np.arange(tw + 1) * W) // tw, W)
    # Box filter: the mean of each block (a prefix-sum table keeps it O(H W)).
    c = np.zeros((H + 1, W + 1, 3))
    c[1:, 1:] = data.cumsum(0).cumsum(1)
    r0, r1, c0, c1 = rows[:-1, None], rows[1:, None], cols[None, :-1], cols[None, 1:]
    area = ((r1 - r0) * (c1 - c0))[..., None]
    small = (c[r1, c1] - c[r0, c1] - c[r1, c0] + c[r0, c0]) / np.maximum(area, 1)
    mean_y = float((small @ LUMA).mean())
    exposure = 0.18 / mean_y if mean_y > 0 else 1.0
    return np.round(np.clip(tonemap(small, exposure), 0, 1) * 255).astype(np.uint8)
