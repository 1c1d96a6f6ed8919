"""Specular anti-aliasing and normal-map filtering: the roughness widened by the variance of the
normals a pixel covers. Numpy twins of ``realtime/shaders/specular_aa.glsl`` (same names; compared
by the GLSL harness in ``tests/test_specular_aa.py``), plus :func:`slope_variance_mips`, the bake
of the ``prefiltered`` method (run by :mod:`realtime.raster` beside the normal map's mip chain).

Every method adds a variance to the GGX width squared, ``alpha'^2 = min(alpha^2 + v, 1)``
(``alpha = roughness^2``, roughness perceptual), and returns the perceptual roughness
``alpha'^(1/2)``. The variance is the one of the NDF's slopes: an isotropic Beckmann / GGX lobe of
width alpha has slope variance alpha^2 / 2 per axis, so convolving it with normals of per-axis slope
variances ``s_x^2, s_y^2`` widens alpha^2 by ``s_x^2 + s_y^2`` [Olano & Baker 2010, sec. 3].

API
---
- :func:`specular_aa_toksvig` -- Toksvig 2005, "Mipmapping Normal Maps", JGT 10(3): the mip-filtered
  normal's length ``L`` gives the variance ``sigma^2 = (1 - L) / L`` (his eq. for ``f_t = 1 / (1 + s
  sigma^2)``, Blinn-Phong exponent ``s``); with ``s = 2 / alpha^2`` (Walter et al. 2007's Phong-Beckmann
  correspondence) ``1 / s' = 1 / s + sigma^2`` is ``alpha'^2 = alpha^2 + 2 sigma^2``. ``L >= 1``: no change.
- :func:`specular_aa_screen_space` -- Kaplanyan, Hill, Patney, Lefohn 2016, "Filtering Distributions
  of Normals for Shading Antialiasing"; Tokuyoshi & Kaplanyan 2019, "Improved Geometric Specular
  Antialiasing", as Filament ships it (``normalFiltering``, material parameters
  ``specularAntiAliasingVariance`` = :data:`SCREEN_SPACE_VARIANCE`, ``specularAntiAliasingThreshold`` =
  :data:`SCREEN_SPACE_THRESHOLD`): ``alpha^2 + min(2 SCREEN_SPACE_VARIANCE (|dn/dx|^2 + |dn/dy|^2),
  SCREEN_SPACE_THRESHOLD)`` from the screen derivatives of the geometric normal (Filament's and
  three.js's choice: not the normal-mapped one). ``dn2`` is ``|dn/dx|^2 + |dn/dy|^2``.
- :func:`specular_aa_prefiltered` -- ``alpha^2 + variance``, ``variance`` read from the texture that
  :func:`slope_variance_mips` bakes (LEAN mapping's second moments, Olano & Baker 2010, "LEAN Mapping",
  I3D: per texel of mip k, ``var(s_x) + var(s_y)`` of the slopes ``s = (n_x, n_y) / n_z`` of the unit
  level-0 normals it covers), times ``normal_scale^2``.
- :func:`specular_aa_widen` -- ``min(alpha^2 + v, 1)^(1/4)``, the roughness itself where ``v = 0``.
The registry :data:`realtime.registry.SPECULAR_AAS` holds these functions; its dispatch by name is
:func:`realtime.dispatch.specular_aa`.

Conventions: roughness perceptual in [0, 1]; ``normal_length`` the length of the tangent-space
normal ``2 t - 1`` read through the mip chain before its normalisation (and before ``normal_scale``).
"""

from __future__ import annotations

import numpy as np


#: Filament's ``specularAntiAliasingVariance`` default (screen-space variance of the normal's kernel).
SCREEN_SPACE_VARIANCE = 0.15
#: Filament's ``specularAntiAliasingThreshold`` default (cap on the added alpha^2).
SCREEN_SPACE_THRESHOLD = 0.2
#: Smallest n_z of a normal-map texel whose slope the bake takes (steeper texels are clamped).
MIN_SLOPE_NZ = 1e-2


def specular_aa_widen(roughness, variance):
    """``min(alpha^2 + variance, 1)^(1/4)``, ``alpha = roughness^2``; ``roughness`` itself where the
    variance is 0 (a flat normal map, a plane's zero derivatives: exactly no change)."""
    r, v = np.asarray(roughness, np.float64), np.maximum(np.asarray(variance, np.float64), 0.0)
    return np.where(v > 0.0, np.sqrt(np.sqrt(np.clip(r ** 4 + v, 0.0, 1.0))), r)


def specular_aa_toksvig(roughness, normal_length):
    """[Toksvig05]: ``alpha'^2 = alpha^2 + 2 (1 - L) / L``, ``L = min(normal_length, 1)``."""
    L = np.clip(np.asarray(normal_length, np.float64), 1e-4, 1.0)
    return specular_aa_widen(roughness, 2.0 * (1.0 - L) / L)


def specular_aa_screen_space(roughness, dn2):
    """[Kaplanyan16, Tokuyoshi19] as Filament: ``alpha^2 + min(2 x 0.15 dn2, 0.2)``."""
    dn2 = np.asarray(dn2, np.float64)
    return specular_aa_widen(roughness, np.minimum(2.0 * SCREEN_SPACE_VARIANCE * dn2, SCREEN_SPACE_THRESHOLD))


def specular_aa_prefiltered(roughness, variance):
    """[Olano10]: ``alpha'^2 = alpha^2 + variance`` (the baked slope variance)."""
    return specular_aa_widen(roughness, variance)


def slope_variance_mips(texels: np.ndarray, levels: int) -> list[np.ndarray]:
    """The ``prefiltered`` bake: ``levels`` float32 images, level k of size ``max(1, size >> k)`` (GL's
    mip sizes), each texel ``var(s_x) + var(s_y)`` of the level-0 slopes under it. ``texels`` (H, W, >=3)
    in [0, 1] (the normal map as uploaded, ``t``; the normal is ``2 t - 1``, normalised here). Moments
    are box-reduced 2 x 2 per level (an odd row or column is dropped, as GL's box mips of odd sizes
    approximate); level 0 is 0."""
    n = 2.0 * np.asarray(texels, np.float64)[..., :3] - 1.0
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
    nz = np.maximum(n[..., 2], MIN_SLOPE_NZ)
    s = n[..., :2] / nz[..., None]
    m = np.concatenate([s, s * s], axis=-1)   # E[s_x], E[s_y], E[s_x^2], E[s_y^2]
    out = []
    for k in range(levels):
        if k:
            h, w = m.shape[:2]
            if h > 1:
                m = 0.5 * (m[0:h - h % 2:2] + m[1:h - h % 2:2])
            if w > 1:
                m = 0.5 * (m[:, 0:w - w % 2:2] + m[:, 1:w - w % 2:2])
        var = (m[..., 2] - m[..., 0] ** 2) + (m[..., 3] - m[..., 1] ** 2)
        out.append(np.maximum(var, 0.0).astype(np.float32))
    return out
