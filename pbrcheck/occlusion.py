"""Ambient and specular occlusion of the real-time image-based lighting: the numpy twins of
``realtime/shaders/occlusion.glsl`` (same names; compared by the GLSL harness in
``tests/test_occlusion.py``).

API
---
- :func:`occlusion_from_texture` -- glTF 2.0's occlusion: ``1 + strength (texel.r - 1)`` (spec 3.9.4,
  ``occlusionTexture.strength``); it scales the indirect (image-based) diffuse light.
- :func:`specular_occlusion_lagarde` -- Lagarde & de Rousiers 2014, "Moving Frostbite to PBR",
  section 4.10.2, listing 26: ``saturate((n.v + ao)^exp2(-16 alpha - 1) - 1 + ao)`` with ``alpha`` the
  GGX width (perceptual roughness squared, Frostbite's ``roughness``; Filament's
  ``computeSpecularAO`` passes the same).
- :func:`specular_occlusion` -- the dispatch over :data:`pbrcheck.registry.SPECULAR_OCCLUSIONS`.

Conventions: ``ao`` in [0, 1] (1: unoccluded), ``NoV`` in [0, 1], ``roughness`` perceptual in [0, 1].
"""

from __future__ import annotations

import numpy as np

from .registry import SPECULAR_OCCLUSIONS


def occlusion_from_texture(texel_r, strength):
    """glTF 2.0 (spec 3.9.4): ``1 + strength (texel_r - 1)``."""
    return 1.0 + np.asarray(strength, np.float64) * (np.asarray(texel_r, np.float64) - 1.0)


def specular_occlusion_lagarde(NoV, ao, roughness):
    """[Lagarde14] listing 26: ``clip((n.v + ao)^exp2(-16 alpha - 1) - 1 + ao, 0, 1)``, alpha = roughness^2."""
    NoV, ao, r = (np.asarray(x, np.float64) for x in (NoV, ao, roughness))
    alpha = r * r
    return np.clip(np.power(NoV + ao, np.exp2(-16.0 * alpha - 1.0)) - 1.0 + ao, 0.0, 1.0)


def specular_occlusion(NoV, ao, roughness, method: str):
    """The specular occlusion factor of ``method`` (a member of ``SPECULAR_OCCLUSIONS``)."""
    if method not in SPECULAR_OCCLUSIONS:
        raise KeyError(f"unknown specular occlusion {method!r}; known: {', '.join(SPECULAR_OCCLUSIONS.names)}")
    if method == "none":
        return np.ones(np.broadcast(np.asarray(NoV), np.asarray(ao), np.asarray(roughness)).shape)
    return specular_occlusion_lagarde(NoV, ao, roughness)
