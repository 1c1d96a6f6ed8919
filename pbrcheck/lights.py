"""Punctual lights of a scene: point, spot and directional, with ``KHR_lights_punctual``'s semantics.

API
---
- :data:`LIGHT_TYPES` -- the closed list (``point``, ``spot``, ``directional``).
- :class:`PointLight`, :class:`SpotLight`, :class:`DirectionalLight` -- the scene's lights (frozen).
- :func:`glsl_light_constants` -- ``LIGHT_POINT`` ... as GLSL constants (the type's index).
- :func:`pack_lights` -- the real-time renderer's lights buffer (``realtime/shaders/lights.glsl``).
- :func:`spot_attenuation` -- glTF's angular attenuation of a spot light (the numpy twin of the GLSL
  term of the same name in ``realtime/shaders/lights.glsl``; the reference evaluates it too).

Conventions (README "Scene files"; docs/assets.md "Lights")
-----------------------------------------------------------
Units are radiometric with glTF's photometric numbers taken as they are (1 cd = 1 W/sr, 1 lux =
1 W/m^2, RGB per channel: ``intensity`` is glTF's ``color * intensity``):

* ``point``: ``position``; ``intensity`` I in W/sr. Irradiance at distance d: ``I cos / d^2``.
* ``spot``: ``position``, ``direction`` (where the cone points, the glTF node's -Z; unit after
  loading), ``inner_cone_angle`` and ``outer_cone_angle`` (radians from the axis, glTF's defaults 0
  and pi/4, ``0 <= inner < outer <= pi/2``); ``intensity`` I in W/sr on the axis. Irradiance: ``I cos
  / d^2 * spot_attenuation(dot(direction, -l), cos(outer), cos(inner))``.
* ``directional``: ``direction`` (where the light travels, the node's -Z; unit after loading);
  ``intensity`` E in W/m^2: the irradiance of a surface facing the light, ``E cos`` on any other.

``range`` is not modelled (pure inverse square, as for point lights: glTF's range is a cut-off
hint an engine may ignore). Both renderers and the export follow these definitions.

References: Khronos ``KHR_lights_punctual`` specification (2018), "Light Types", "Range Property"
and "Inner and Outer Cone Angles" (its recommended implementation of the angular attenuation).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

Vec3 = tuple[float, float, float]

#: The light types a scene (``[[lights]] type``) and a glTF asset may hold.
LIGHT_TYPES = ("point", "spot", "directional")
#: glTF's default cone angles of a spot light (radians).
DEFAULT_INNER_CONE = 0.0
DEFAULT_OUTER_CONE = math.pi / 4
#: The spec's floor of cos(inner) - cos(outer) in the attenuation's scale (its recommended code).
SPOT_MIN_COS_SPAN = 0.001


@dataclass(frozen=True)
class PointLight:
    """A point light: position (world units) and radiant intensity (W/sr, RGB)."""
    position: Vec3
    intensity: Vec3  # radiant intensity, W/sr: irradiance at distance d is I cos / d^2
    type: str = "point"


@dataclass(frozen=True)
class SpotLight:
    """A spot light (glTF ``spot``): a point light whose intensity is scaled by
    :func:`spot_attenuation` of the angle between ``direction`` (unit) and the direction to the
    shaded point. Cone angles in radians."""
    position: Vec3
    direction: Vec3
    intensity: Vec3  # W/sr on the axis
    inner_cone_angle: float = DEFAULT_INNER_CONE
    outer_cone_angle: float = DEFAULT_OUTER_CONE
    type: str = "spot"


@dataclass(frozen=True)
class DirectionalLight:
    """A directional light (glTF ``directional``): parallel rays travelling along ``direction`` (unit),
    irradiance ``intensity`` (W/m^2, RGB) on a surface facing the light."""
    direction: Vec3
    intensity: Vec3  # W/m^2
    type: str = "directional"


def spot_attenuation(cd, cos_outer, cos_inner, *, clip=np.clip):
    """glTF's spot attenuation (``KHR_lights_punctual``, "Inner and Outer Cone Angles"):
    ``saturate(cd * scale + offset)^2`` with ``scale = 1 / max(0.001, cos_inner - cos_outer)``,
    ``offset = -cos_outer * scale``; ``cd`` is the cosine between the spot's direction and the
    direction from the light to the point. 1 inside the inner cone, 0 beyond the outer. ``clip``:
    numpy's, or Dr.Jit's ``dr.clip`` for Dr.Jit arrays."""
    span = np.maximum(SPOT_MIN_COS_SPAN, np.subtract(cos_inner, cos_outer))
    scale = 1.0 / (span if np.ndim(span) else float(span))  # a Python float beside Dr.Jit arrays
    offset = -cos_outer * scale
    a = clip(cd * scale + offset, 0.0, 1.0)
    return a * a


def glsl_light_constants() -> dict[str, int]:
    """``{"LIGHT_POINT": 0, "LIGHT_SPOT": 1, "LIGHT_DIRECTIONAL": 2}``: the index in :data:`LIGHT_TYPES`."""
    return {f"LIGHT_{t.upper()}": i for i, t in enumerate(LIGHT_TYPES)}


def pack_lights(lights) -> np.ndarray:
    """float32 ``(max(n, 1), 12)``: per light ``position, type; intensity, cos(outer); direction,
    cos(inner)`` (``realtime/shaders/lights.glsl``); one zero row for no light."""
    rows = []
    for L in lights:
        code = float(LIGHT_TYPES.index(L.type))
        pos = getattr(L, "position", (0.0, 0.0, 0.0))
        d = getattr(L, "direction", (0.0, 0.0, 0.0))
        co = math.cos(L.outer_cone_angle) if L.type == "spot" else 0.0
        ci = math.cos(L.inner_cone_angle) if L.type == "spot" else 0.0
        rows.append([*pos, code, *L.intensity, co, *d, ci])
    return np.asarray(rows or [[0.0] * 12], np.float32)
