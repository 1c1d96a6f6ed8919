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
- :func:`cone_cone_intersection` -- Oat & Sander 2007, "Ambient Aperture Lighting" (the approximation
  Jimenez et al. 2016 use): the fraction of spherical cap 2 (cosine ``cos_cap2``) that lies inside cap 1,
  caps ``acos(cos_distance)`` apart, with a smoothstep between the contained and the disjoint cases.
- :func:`specular_occlusion_gtso` -- Jimenez, Wu, Pesce, Jarabo 2016, "Practical Realtime Strategies
  for Accurate Indirect Occlusion" (GTSO), section 6: the specular cone (``cos = exp2(-3.321928
  alpha^2)``, Filament's ``SpecularAO_Cones`` fit of the GGX lobe's aperture) intersected with the
  visibility cone around the (bent) normal (``cos = sqrt(1 - ao)``), the reflection ``acos(n.v)`` from
  the normal (no bent normals in glTF: the bent normal is the shading normal). Divided by the same
  intersection with the unoccluded hemisphere (ao = 1), so that full visibility gives exactly 1: the
  split sum already integrates the lobe over the hemisphere, and the horizon is
  :func:`horizon_occlusion`'s (the published form, and Filament's, darken unoccluded grazing views).
  Filament's artistic fade to 1 for alpha > 0.09 is not applied.
- :func:`horizon_occlusion_marmoset` -- Russell 2015 (Marmoset Toolbag), "Horizon Occlusion for Normal
  Mapped Reflections", the form Jimenez et al. 2016 also use: ``saturate(1 + HORIZON_FADE r.n_g)^2``
  with ``n_g`` the geometric (interpolated vertex) normal: a normal map's reflection below the
  surface's horizon fades out; 1 wherever r is above it.
The registries :data:`realtime.registry.SPECULAR_OCCLUSIONS` / ``HORIZON_OCCLUSIONS`` hold these
functions; their dispatch by name is :func:`realtime.dispatch.specular_occlusion` / ``horizon_occlusion``.

Conventions: ``ao`` in [0, 1] (1: unoccluded), ``NoV`` in [0, 1], ``roughness`` perceptual in [0, 1],
``alpha = roughness^2``; ``RoNg`` the cosine between the reflection and the geometric normal.
"""

from __future__ import annotations

import numpy as np


#: Marmoset's horizon fade (Russell 2015): the reflection fades out over the 1 / 1.3 of r.n_g below 0.
HORIZON_FADE = 1.3
#: ln(10) / ln(2): Jimenez et al.'s specular cone aperture cos = 10^(-alpha^2) = exp2(-3.321928 alpha^2).
GTSO_APERTURE = 3.321928


def occlusion_from_texture(texel_r, strength):
    """glTF 2.0 (spec 3.9.4): ``1 + strength (texel_r - 1)``."""
    return 1.0 + np.asarray(strength, np.float64) * (np.asarray(texel_r, np.float64) - 1.0)


def specular_occlusion_lagarde(NoV, ao, roughness):
    """[Lagarde14] listing 26: ``clip((n.v + ao)^exp2(-16 alpha - 1) - 1 + ao, 0, 1)``, alpha = roughness^2."""
    NoV, ao, r = (np.asarray(x, np.float64) for x in (NoV, ao, roughness))
    alpha = r * r
    return np.clip(np.power(NoV + ao, np.exp2(-16.0 * alpha - 1.0)) - 1.0 + ao, 0.0, 1.0)


def cone_cone_intersection(cos_cap1, cos_cap2, cos_distance):
    """[OatSander07] as [Jimenez16] use it: the fraction of cap 2 inside cap 1 (apertures ``acos(cos_cap1)``,
    ``acos(cos_cap2)``, axes ``acos(cos_distance)`` apart): ``min(1, (1 - c1) / (1 - c2))`` when the smaller
    cap lies inside the larger, 0 when they are disjoint, else that times ``smoothstep(x)``,
    ``x = 1 - (d - |r1 - r2|) / (r1 + r2 - |r1 - r2|)``."""
    c1, c2, cd = (np.asarray(x, np.float64) for x in (cos_cap1, cos_cap2, cos_distance))
    r1, r2, d = np.arccos(np.clip(c1, -1, 1)), np.arccos(np.clip(c2, -1, 1)), np.arccos(np.clip(cd, -1, 1))
    # the area of the smaller cap over cap 2's: 1 when cap 2 is the smaller one
    # (min, not a branch on c2 >= c1: two caps of zero size, c1 = c2 = 1, overlap by 0)
    ratio = np.minimum(1.0, (1.0 - c1) / np.maximum(1.0 - c2, 1e-30))
    delta = np.abs(r1 - r2)
    x = 1.0 - np.clip((d - delta) / np.maximum(r1 + r2 - delta, 1e-4), 0.0, 1.0)
    smooth = x * x * (3.0 - 2.0 * x)
    return ratio * np.where(np.minimum(r1, r2) <= np.maximum(r1, r2) - d, 1.0, np.where(r1 + r2 <= d, 0.0, smooth))


def specular_occlusion_gtso(NoV, ao, roughness):
    """[Jimenez16] sec. 6 (module docstring): ``I(sqrt(1 - ao)) / I(0)``, ``I(c) =
    cone_cone_intersection(c, exp2(-GTSO_APERTURE alpha^2), n.v)``, clipped to [0, 1]."""
    NoV, ao, r = (np.asarray(x, np.float64) for x in (NoV, ao, roughness))
    alpha = r * r
    cos_s = np.exp2(-GTSO_APERTURE * alpha * alpha)
    occluded = cone_cone_intersection(np.sqrt(np.maximum(1.0 - ao, 0.0)), cos_s, NoV)
    free = cone_cone_intersection(0.0, cos_s, NoV)
    return np.where(occluded >= free, 1.0, np.clip(occluded / np.maximum(free, 1e-6), 0.0, 1.0))


def horizon_occlusion_marmoset(RoNg):
    """[Russell15]: ``clip(1 + HORIZON_FADE r.n_g, 0, 1)^2``."""
    h = np.clip(1.0 + HORIZON_FADE * np.asarray(RoNg, np.float64), 0.0, 1.0)
    return h * h
