"""``KHR_materials_unlit`` in the reference: the surface's radiance is its base colour, unshaded.

The extension (KhronosGroup/glTF, extensions/2.0/Khronos/KHR_materials_unlit): an unlit material
shows its base colour (``baseColorFactor`` x ``baseColorTexture`` x ``COLOR_0``) whatever the
lighting; alpha (MASK, BLEND) and ``doubleSided`` still apply; the other properties (metallic,
roughness, normal, occlusion, emissive) are ignored. The reference models it as a surface that
reflects nothing (:class:`reference.textured.TexturedMaterial` with ``unlit``: zero BSDF, its null
pass-through for alpha and culled back faces kept) and emits the base colour
(:class:`UnlitEmitter`, the shape's area emitter): the ``local`` estimator adds it at the first hit
exactly as an emissive surface, so a camera ray that hits it returns the base colour; ``path`` sees
it directly and in reflections (BSDF-sampled rays; the emitter is never sampled by next-event
estimation: its ``sample_direction`` weight and ``pdf_direction`` are 0, so a BSDF sample that hits
it keeps MIS weight 1 and the estimate stays unbiased).

API: :class:`UnlitEmitter`, :func:`unlit_emitter`.
"""

from __future__ import annotations

import pbrcheck  # noqa: F401  (sets DRJIT_LIBLLVM_PATH before drjit loads)

import drjit as dr
import mitsuba as mi


class UnlitEmitter(mi.Emitter):
    """The base colour of an unlit :class:`~reference.textured.TexturedMaterial` as a surface
    emitter (module docstring): ``eval`` = the material's base colour at the hit (its textures and
    vertex colour, the lit path's lookup), on the front side, and the back side where double-sided."""

    def __init__(self, props):
        mi.Emitter.__init__(self, props)
        self.m_flags = mi.EmitterFlags.Surface
        self.material = None   # the TexturedMaterial (set by unlit_emitter)

    def eval(self, si, active=True):
        m = self.material
        view, _ = m._view(si, active)
        front = mi.Bool(m.double_sided) | (mi.Frame3f.cos_theta(si.wi) > 0)
        return dr.select(mi.Bool(active) & front, mi.Spectrum(view.base_color), 0.0)

    def sample_direction(self, it, sample, active=True):
        ds = dr.zeros(mi.DirectionSample3f)
        return ds, mi.Spectrum(0.0)

    def pdf_direction(self, it, ds, active=True):
        return mi.Float(0.0)

    def eval_direction(self, it, ds, active=True):
        return mi.Spectrum(0.0)

    def sample_position(self, time, sample, active=True):
        return dr.zeros(mi.PositionSample3f), mi.Float(0.0)

    def sample_ray(self, time, sample1, sample2, sample3, active=True):
        return dr.zeros(mi.Ray3f), mi.Spectrum(0.0)

    def sample_wavelengths(self, si, sample, active=True):
        return dr.zeros(mi.Wavelength), mi.Spectrum(0.0)

    def traverse(self, callback):
        pass

    def to_string(self):
        return "UnlitEmitter[]"


def unlit_emitter(material) -> UnlitEmitter:
    """The emitter of an unlit ``TexturedMaterial`` ``material`` (its base colour)."""
    e = UnlitEmitter(mi.Properties())
    e.material = material
    return e
