"""Dr.Jit microfacet terms shared by the BSDF (:mod:`reference.bsdf`) and the random walk
(:mod:`reference.multiscatter`), so both evaluate the very same functions. Local shading frame,
``n = +Z``; numpy twins of the same names in :mod:`pbrcheck.brdf`.

API: :data:`INV_PI`, :func:`D_GGX`, :func:`F_Schlick`, :func:`F_None`, :func:`fresnel_term`.
References: [Walter07] Walter et al., "Microfacet Models for Refraction through Rough Surfaces",
EGSR 2007 (eq. 33); [Schlick94] Schlick, "An Inexpensive BRDF Model for Physically-based
Rendering", CGF 1994 (eq. 15).
"""

from __future__ import annotations

import math

import pbrcheck  # noqa: F401  (sets DRJIT_LIBLLVM_PATH before drjit loads)

import drjit as dr
import mitsuba as mi

from pbrcheck.registry import FRESNELS

INV_PI = 1.0 / math.pi


def D_GGX(h, alpha):
    """GGX NDF [Walter07 eq. 33] in its stable form: with ``s = h.x^2 + h.y^2 = sin^2(theta_h)``,
    ``1 / (pi a^2 (s / a^2 + h.z^2)^2)`` (= ``a^2 / (pi (h.z^2 (a^2 - 1) + 1)^2)``): a narrow lobe
    stays accurate in float32, where ``1 - cos(theta_h)`` underflows and ``sin^2`` does not."""
    a2 = alpha * alpha
    s = h.x * h.x + h.y * h.y
    t = s / a2 + h.z * h.z
    return dr.select(h.z > 0, INV_PI / (a2 * t * t), 0.0)


def F_Schlick(c, F0):
    """[Schlick94 eq. 15] at the cosine ``c`` (clamped to [0, 1]): ``F0 + (1 - F0) (1 - c)^5``."""
    c = dr.clip(c, 0.0, 1.0)
    w = dr.square(dr.square(1.0 - c)) * (1.0 - c)
    return F0 + (1.0 - F0) * w


def F_None(c, F0):
    """No Fresnel factor: 1 (Color3f)."""
    return mi.Color3f(1.0)


def fresnel_term(fresnel, c, F0):
    """The registry's member ``fresnel`` (:data:`pbrcheck.registry.FRESNELS`): ``schlick``
    (:func:`F_Schlick`) or ``none`` (:func:`F_None`)."""
    return globals()[FRESNELS[fresnel].impl.drjit](c, F0)
