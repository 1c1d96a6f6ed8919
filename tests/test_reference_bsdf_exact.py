"""Lobe-selection probabilities are exact at their ends, whatever the division's rounding.

On cuda_ad_rgb, ``s / s`` is an approximate reciprocal times ``s``, so a white metal (no diffuse lobe)
got ``P_spec = 1 - 1e-7`` and its delta-only BSDF an ``eval_pdf`` of 1.9e-11 ... 1.8e-8 instead of 0
(``test_mirror_limit_is_a_finite_delta`` failed on an H100). These tests emulate that rounding on the
CPU through the ``reference.bsdf._divide`` seam, so the guard is tested without CUDA.
"""

from __future__ import annotations

import numpy as np
import pytest

import pbrcheck  # noqa: F401
from pbrcheck.scene import GEOMETRY_NAMES
from reference.variant import ensure_variant

ensure_variant()
import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402

from reference import bsdf as rb  # noqa: E402

# CUDA's div.approx.f32 is within 2 ulp; emulate a quotient one part in 2^22 off, both ways.
ROUNDING = (1.0 - 2.0 ** -22, 1.0 + 2.0 ** -22)


def _mat(**kw):
    ensure_variant()  # another test module may have switched Mitsuba's variant in this process
    d = {"type": "pbr_material", "base_color": [0.9, 0.6, 0.3], "metallic": 1.0, "roughness": 0.0,
         "specular": 0.04, "ndf": "ggx", "geometry": "smith_ggx_correlated", "fresnel": "schlick"}
    d.update(kw)
    return mi.load_dict(d)


def _si(n=64):
    cos = np.linspace(0.001, 1.0, n)
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = mi.Vector3f(np.sqrt(1 - cos**2), 0.0, cos)
    return si


@pytest.mark.parametrize("factor", ROUNDING)
@pytest.mark.parametrize("geometry", GEOMETRY_NAMES)
@pytest.mark.parametrize("rough", [0.0, 1e-4])
def test_delta_only_metal_pdf_is_exactly_zero_under_inexact_division(monkeypatch, factor, geometry, rough):
    monkeypatch.setattr(rb, "_divide", lambda a, b: (a / b) * factor)
    b = _mat(geometry=geometry, roughness=rough)
    si = _si()
    ctx = mi.BSDFContext()
    bs, w = b.sample(ctx, si, mi.Float(np.full(64, 0.999999)), mi.Point2f(0.3, 0.7))
    assert np.all(np.array(bs.pdf) == 1.0)  # the discrete probability of the only lobe
    assert np.all(np.array(bs.sampled_type) == int(mi.BSDFFlags.DeltaReflection))
    f, pdf = b.eval_pdf(ctx, si, bs.wo)
    assert np.all(np.array(f) == 0) and np.all(np.array(pdf) == 0)
    # any other direction too
    wo = dr.normalize(mi.Vector3f(0.3, 0.2, 0.9))
    assert np.all(np.array(b.pdf(ctx, si, wo)) == 0)


@pytest.mark.parametrize("factor", ROUNDING)
def test_black_specular_never_picks_the_specular_lobe(monkeypatch, factor):
    """The other end: no specular albedo (specular 0, dielectric, no Fresnel rise at n.v = 1)."""
    monkeypatch.setattr(rb, "_divide", lambda a, b: (a / b) * factor)
    b = _mat(metallic=0.0, specular=0.0, roughness=0.5)
    si = dr.zeros(mi.SurfaceInteraction3f, 1)
    si.wi = mi.Vector3f(0.0, 0.0, 1.0)
    p = np.array(b._p_spec(mi.Float(1.0), b._f0()))
    assert np.all(p == 0.0)


def test_the_seam_is_used():
    """Guard against a refactor that bypasses ``_divide`` (which would make the tests above vacuous)."""
    calls = []

    def spy(a, b):
        calls.append(1)
        return a / b

    orig = rb._divide
    rb._divide = spy
    try:
        b = _mat(metallic=0.5, roughness=0.5)
        b.eval_pdf(mi.BSDFContext(), _si(4), mi.Vector3f(0.0, 0.0, 1.0))
    finally:
        rb._divide = orig
    assert calls
