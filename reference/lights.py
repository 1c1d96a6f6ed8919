"""The scene's punctual lights as Mitsuba 3 emitters (:mod:`pbrcheck.lights` has the conventions).

* ``point``: Mitsuba's ``point`` (``intensity`` W/sr): ``I / d^2``.
* ``directional``: Mitsuba's ``directional`` (``irradiance`` E in W/m^2 on a surface facing the light,
  ``direction`` where the light travels): a delta direction whose ``sample_direction`` returns E.
* ``spot``: ``gltf_spot``, a delta-position emitter written here, **not** Mitsuba's ``spot``: Mitsuba's
  falloff is linear in the angle between ``beam_width`` and ``cutoff_angle``, glTF's is
  ``saturate(cd scale + offset)^2`` in the cosine (:func:`pbrcheck.lights.spot_attenuation`, the
  same function the tests and the GLSL twin use). ``sample_direction`` returns
  ``I spot_attenuation(dot(axis, -l)) / d^2`` with ``pdf = 1`` and ``delta = True``, like ``point``.

Both integrator modes take these as they take point lights: ``local`` adds every delta emitter's
``sample_direction`` at the first hit without a shadow ray, ``path`` (Mitsuba's ``path``) casts one;
derivatives flow through the BSDF value, as for point lights (the emitters hold no parameter).

API: :data:`SPOT_PLUGIN`, :class:`GltfSpot`, :func:`register`, :func:`emitter_dict`.
References: Khronos ``KHR_lights_punctual`` ("Inner and Outer Cone Angles"); Mitsuba 3 plugin
documentation (``point``, ``directional``, ``spot``: its ``falloff_curve``).
"""

from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi

from pbrcheck.lights import spot_attenuation

SPOT_PLUGIN = "gltf_spot"
_REGISTERED: set[str] = set()


class GltfSpot(mi.Emitter):
    """glTF's spot light: ``position``, ``direction`` (the cone's axis, unit), ``intensity`` (rgb,
    W/sr on the axis), ``inner_cone_angle`` / ``outer_cone_angle`` (radians)."""

    def __init__(self, props):
        mi.Emitter.__init__(self, props)
        self.m_flags = mi.EmitterFlags.DeltaPosition
        self.position = mi.ScalarPoint3f(props.get("position"))
        self.axis = dr.normalize(mi.ScalarVector3f(props.get("direction")))
        self.intensity = mi.ScalarColor3f(props.get("intensity"))
        self.cos_outer = math.cos(float(props.get("outer_cone_angle")))
        self.cos_inner = math.cos(float(props.get("inner_cone_angle")))

    def _radiant(self, to_point, d2):
        """Intensity towards the unit direction ``to_point`` (light -> point) over ``d2``."""
        cd = dr.dot(mi.Vector3f(self.axis), to_point)
        att = spot_attenuation(cd, self.cos_outer, self.cos_inner, clip=dr.clip)
        return mi.Color3f(self.intensity) * (att / d2)

    def sample_direction(self, it, sample, active=True):
        ds = dr.zeros(mi.DirectionSample3f)
        ds.p = mi.Point3f(self.position)
        ds.time = it.time
        ds.pdf = mi.Float(1.0)
        ds.delta = mi.Bool(True)
        ds.emitter = mi.EmitterPtr(self)
        v = ds.p - it.p
        d2 = dr.squared_norm(v)
        ds.dist = dr.sqrt(d2)
        ds.d = v / ds.dist
        return ds, dr.select(active, self._radiant(-ds.d, d2), 0.0)

    def pdf_direction(self, it, ds, active=True):
        return mi.Float(0.0)  # a delta position: no density (as Mitsuba's point)

    def eval_direction(self, it, ds, active=True):
        d2 = dr.squared_norm(mi.Point3f(self.position) - it.p)
        return dr.select(active, self._radiant(-ds.d, d2), 0.0)

    def eval(self, si, active=True):
        return mi.Color3f(0.0)  # not hit by rays

    def bbox(self):
        return mi.ScalarBoundingBox3f(self.position)

    def traverse(self, callback):
        pass  # no differentiable parameter

    def to_string(self):
        return (f"GltfSpot[position={list(self.position)}, direction={list(self.axis)}, "
                f"intensity={list(self.intensity)}, cos_inner={self.cos_inner}, cos_outer={self.cos_outer}]")


def register() -> None:
    """Register ``gltf_spot`` for the current Mitsuba variant (idempotent)."""
    v = mi.variant()
    if v not in _REGISTERED:
        mi.register_emitter(SPOT_PLUGIN, lambda props: GltfSpot(props))
        _REGISTERED.add(v)


def emitter_dict(light) -> dict:
    """The Mitsuba dict of a :mod:`pbrcheck.lights` light."""
    rgb = {"type": "rgb", "value": list(light.intensity)}
    if light.type == "point":
        return {"type": "point", "position": list(light.position), "intensity": rgb}
    if light.type == "directional":
        return {"type": "directional", "direction": list(light.direction), "irradiance": rgb}
    return {"type": SPOT_PLUGIN, "position": list(light.position), "direction": list(light.direction),
            "intensity": list(light.intensity), "inner_cone_angle": float(light.inner_cone_angle),
            "outer_cone_angle": float(light.outer_cone_angle)}
