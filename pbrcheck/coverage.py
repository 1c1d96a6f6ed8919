"""Alpha-to-coverage of glTF MASK materials in the raster pipeline: the numpy twin of
``realtime/shaders/coverage.glsl`` (same name; compared by the GLSL harness in
``tests/test_specular_aa.py``).

API
---
- :func:`alpha_to_coverage_sharpen` -- Golus 2017, "Anti-aliased Alpha Test: The Esoteric Alpha To
  Coverage": ``clip((alpha - cutoff) / max(width, 1e-4) + 0.5, 0, 1)`` with ``width = fwidth(alpha)``
  (the alpha test's step spread over one pixel: coverage 1/2 at the cutoff, 0 or 1 a pixel away).

Conventions: ``alpha`` the base colour's alpha (factor x texture x COLOR_0), ``cutoff`` glTF's
``alphaCutoff``, ``width = |d alpha/dx| + |d alpha/dy|`` in pixels of the colour pass.
"""

from __future__ import annotations

import numpy as np


def alpha_to_coverage_sharpen(alpha, cutoff, width):
    """[Golus17]: ``clip((alpha - cutoff) / max(width, 1e-4) + 0.5, 0, 1)``."""
    a, c, w = (np.asarray(x, np.float64) for x in (alpha, cutoff, width))
    return np.clip((a - c) / np.maximum(w, 1e-4) + 0.5, 0.0, 1.0)
