"""Occlusion terms: GLSL (realtime/shaders/occlusion.glsl) against the numpy twins
(pbrcheck/occlusion.py) on grids including the extremes, and the occlusion texture in the raster
pipeline against its known answer."""

from __future__ import annotations

import numpy as np
import pytest

from pbrcheck.occlusion import (
    HORIZON_FADE,
    cone_cone_intersection,
    horizon_occlusion_marmoset,
    occlusion_from_texture,
    specular_occlusion_gtso,
    specular_occlusion_lagarde,
)
from realtime.dispatch import horizon_occlusion, specular_occlusion
from realtime.gl import is_software_renderer
from realtime.registry import HORIZON_OCCLUSIONS, SPECULAR_OCCLUSIONS
from realtime.glsl_harness import run_glsl

#: float32 GLSL against the float64 twins.
GLSL_ATOL = 2e-6
#: GTSO and its cap intersection: GLSL's acos (llvmpipe: within 1.6e-4 rad of float64, measured) through
#: the cap fractions (measured 2.4e-4 on the grid).
GTSO_ATOL_MESA = 5e-4
#: ... on NVIDIA's GL (H100): its acos is within 6.8e-5 rad of float64 (largest at 0, measured with a
#: harness probe), and the cap intersection's smoothstep moves by up to ~7 per radian of angle error
#: (n.v 0, ao 0.999, roughness 0.2: 0.00069 for 1e-4 rad); three acos calls: 3 x 6.8e-5 x 7 = 1.4e-3
#: (measured 9.7e-4 there).
GTSO_ATOL_GPU = 1.5e-3
GTSO_ATOL = GTSO_ATOL_MESA if is_software_renderer() else GTSO_ATOL_GPU

GRID = np.linspace(0.0, 1.0, 11)


def test_lagarde_glsl_matches_numpy_on_a_grid_with_extremes():
    NoV, ao, r = np.meshgrid(GRID, GRID, GRID, indexing="ij")
    g = run_glsl("specular_occlusion_lagarde(x0, x1, x2)", NoV, ao, r)
    assert np.allclose(g, specular_occlusion_lagarde(NoV, ao, r), atol=GLSL_ATOL, rtol=0)
    for name in SPECULAR_OCCLUSIONS.names:
        d = run_glsl("specular_occlusion(x0, x1, x2)", NoV, ao, r, defines=SPECULAR_OCCLUSIONS.select(name))
        atol = GTSO_ATOL if name == "gtso" else GLSL_ATOL
        assert np.allclose(d, specular_occlusion(NoV, ao, r, name), atol=atol, rtol=0), name


def test_lagarde_limits():
    """Unoccluded (ao = 1) gives 1; fully occluded (ao = 0) gives 0 at grazing n.v < 1, and the
    factor never exceeds 1 nor falls below 0."""
    r = GRID
    assert np.allclose(specular_occlusion_lagarde(0.7, 1.0, r), 1.0)
    assert np.allclose(specular_occlusion_lagarde(0.0, 0.0, r), 0.0)
    v = specular_occlusion_lagarde(*np.meshgrid(GRID, GRID, GRID))
    assert v.min() >= 0 and v.max() <= 1


def test_occlusion_from_texture_glsl_matches_numpy():
    t, s = np.meshgrid(GRID, np.array([0.0, 0.5, 1.0, 2.0]))
    g = run_glsl("occlusion_from_texture(x0, x1)", t, s)
    assert np.allclose(g, occlusion_from_texture(t, s), atol=GLSL_ATOL, rtol=0)
    assert np.allclose(occlusion_from_texture(0.25, 1.0), 0.25) and np.allclose(occlusion_from_texture(0.25, 0.0), 1.0)


def test_occlusion_texture_scales_the_diffuse_ibl(tmp_path):
    """A dielectric with F0 = 0 (KHR_materials_ior ior = 1) has only the diffuse image-based term:
    an occlusion texture of constant r scales it by 1 + strength (r - 1) exactly (up to RGBA16F and the
    split sum's bias term B, 1e-4 of the radiance here)."""
    from gltf_build import quad_asset, quad_scene
    from pbrcheck.scene import load_scene
    from realtime.render import render_realtime

    ao = np.full((4, 4, 3), 128, np.uint8)
    mat = {"pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 0.5},
           "occlusionTexture": {"index": 0, "strength": 0.5}, "extensions": {"KHR_materials_ior": {"ior": 1.0}}}
    q = quad_asset(tmp_path / "ao.gltf", mat, [(ao, None)])
    sc = load_scene(str(quad_scene(tmp_path, q, env="[0.5, 0.8, 1.0]")))
    small = {"cube_size": 32, "irradiance_source_size": 8, "irradiance_size": 8, "prefilter_levels": 4,
             "prefilter_samples": 64, "lut_size": 16, "lut_samples": 256, "supersample": 1}
    on = render_realtime(sc, "default", small, progress=False)
    off = render_realtime(sc, "default", {**small, "occlusion_texture": False}, progress=False)
    lag = render_realtime(sc, "default", {**small, "specular_occlusion": "lagarde"}, progress=False)
    m = on.channels["coverage"] == 1
    assert m.mean() > 0.3
    expect = 1.0 + 0.5 * (128 / 255 - 1.0)
    assert np.allclose(on.rgb[m] / off.rgb[m], expect, rtol=2e-3)
    # F0 = 0 leaves only the split sum's bias term B to occlude: lagarde removes a little light, never adds
    assert np.all(lag.rgb[m] <= on.rgb[m]) and np.allclose(lag.rgb[m], on.rgb[m], rtol=1e-3)
    assert np.any(lag.rgb[m] < on.rgb[m])


def test_gtso_glsl_matches_numpy_on_a_grid_with_extremes():
    g = np.concatenate([GRID, [1e-4, 0.999]])
    NoV, ao, r = np.meshgrid(g, g, g, indexing="ij")
    d = run_glsl("specular_occlusion_gtso(x0, x1, x2)", NoV, ao, r)
    assert np.allclose(d, specular_occlusion_gtso(NoV, ao, r), atol=GTSO_ATOL, rtol=0)
    c1, c2, cd = np.meshgrid(np.linspace(-1, 1, 9), g, g, indexing="ij")
    d = run_glsl("cone_cone_intersection(x0, x1, x2)", c1, c2, cd)
    assert np.allclose(d, cone_cone_intersection(c1, c2, cd), atol=GTSO_ATOL, rtol=0)
    d = run_glsl("specular_occlusion(x0, x1, x2)", NoV, ao, r, defines=SPECULAR_OCCLUSIONS.select("gtso"))
    assert np.allclose(d, specular_occlusion(NoV, ao, r, "gtso"), atol=GTSO_ATOL, rtol=0)


def test_gtso_known_answers():
    """Full visibility gives exactly 1 (on every n.v and roughness, GLSL too); no visibility 0; the
    factor falls with ao; a mirror reflection inside the visibility cone is unoccluded, outside it occluded."""
    NoV, r = np.meshgrid(np.concatenate([GRID, [1e-4]]), GRID, indexing="ij")
    assert np.array_equal(specular_occlusion_gtso(NoV, 1.0, r), np.ones_like(NoV))
    assert np.array_equal(run_glsl("specular_occlusion_gtso(x0, 1.0, x1)", NoV, r), np.ones(NoV.shape, np.float32))
    assert np.allclose(specular_occlusion_gtso(NoV, 0.0, r)[:-1, 1:], 0.0)
    ao = np.linspace(0, 1, 21)
    assert np.all(np.diff(specular_occlusion_gtso(0.6, ao, 0.5)) >= 0)
    # ao = 0.75: visibility cone of 60 degrees; the mirror direction at 0 degrees / 80 degrees from n
    assert specular_occlusion_gtso(1.0, 0.75, 0.0) == 1.0 and specular_occlusion_gtso(np.cos(1.4), 0.75, 0.0) == 0.0
    assert np.allclose(cone_cone_intersection(0.5, 0.9, 1.0), 1.0)    # cap 2 inside cap 1
    # no visibility against a mirror lobe is 0, also where cos_s rounds to 1 in float32 (r = 1e-4:
    # two caps of zero size, which the GLSL once read as "cap 2 inside cap 1", fully visible)
    for r in (0.0, 1e-4):
        assert specular_occlusion_gtso(np.array([1.0, 0.5]), 0.0, r).max() == 0.0
        assert run_glsl("specular_occlusion_gtso(x0, x1, x2)", np.array([1.0, 0.5]), np.zeros(2), np.full(2, r)).max() == 0.0
    assert np.allclose(cone_cone_intersection(0.9, 0.5, 1.0), 0.1 / 0.5)  # cap 1 (smaller) inside cap 2


def test_horizon_occlusion_glsl_matches_numpy_and_known_answers():
    RoNg = np.concatenate([np.linspace(-1.0, 1.0, 41), [-1 / HORIZON_FADE, -1e-6, 0.0, 1e-6]])
    g = run_glsl("horizon_occlusion_marmoset(x0)", RoNg)
    assert np.allclose(g, horizon_occlusion_marmoset(RoNg), atol=GLSL_ATOL, rtol=0)
    for name in HORIZON_OCCLUSIONS.names:
        d = run_glsl("horizon_occlusion(x0)", RoNg, defines=HORIZON_OCCLUSIONS.select(name))
        assert np.allclose(d, horizon_occlusion(RoNg, name), atol=GLSL_ATOL, rtol=0), name
    above = RoNg >= 0
    assert np.all(horizon_occlusion_marmoset(RoNg[above]) == 1.0)       # r above the horizon: 1
    assert np.all(horizon_occlusion_marmoset(RoNg[RoNg <= -1 / HORIZON_FADE]) == 0.0)
    assert np.all(np.diff(horizon_occlusion_marmoset(np.linspace(-1, 0, 11))) >= 0)
