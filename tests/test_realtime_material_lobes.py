"""The glTF PBR extensions' lobes in the real-time renderer's programs (realtime/material_lobes.py,
realtime/shaders/material_lobes.glsl): the material composition's own lobe terms against their numpy
twins (lobes_material.glsl) on grids with the extremes; the ``#define`` switches compiled only where a
scene's materials use a lobe (a lobe-free program's source is the one it had before the lobes, a
lobe program's is not); every built-in lobe scene changes its lobed objects' pixels against the same
scene at the lobe's neutral value, and leaves the neutral objects' bit for bit, in both pipelines;
two known answers under a uniform white environment over a black base (the coat's split-sum
directional albedo, the sheen's Charlie albedo E); the point lights' anisotropic GGX and thin film
(lobes_anisotropy.glsl, lobes_iridescence.glsl) against their twins on grids with the extremes and a lit
sphere against the truth's BRDF x cos x light, strength 0 / factor 0 bit for bit; the lobe textures of a glTF asset in the raster
pipeline (texture 0 = no lobe bit for bit, texture 1 = the factor, a KHR_texture_transform picking a
half of the texture)."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gltf_build import QUAD_UV, quad_asset, quad_scene
from pbrcheck import lobe_params as lp
from pbrcheck import lobes as truth
from pbrcheck.gltf_objects import AssetOptions
from pbrcheck.lights import DirectionalLight
from pbrcheck.scene import Environment, Material, Sphere, load_scene
from realtime import gl, lobes
from realtime import render as R
from realtime.glsl_harness import run_glsl
from realtime.material_lobes import lobe_defines, scene_lobes
from realtime.presets import OPTION_REGISTRIES, OPTIONS, PRESETS, resolve_options
from realtime.registry import LOBE_REGISTRIES
from realtime.render import render_realtime

pytestmark = pytest.mark.filterwarnings("ignore::RuntimeWarning")

SMALL = {"cube_size": 32, "irradiance_source_size": 8, "irradiance_size": 8, "prefilter_levels": 4,
         "prefilter_samples": 64, "lut_size": 16, "lut_samples": 256, "supersample": 1, "sheen_lut_size": 16,
         "sheen_lut_samples": 256, "charlie_size": 16, "charlie_levels": 4, "charlie_samples": 64}
# float32 terms against float64 twins (a few operations; normalize, cos and sin within a few ulp).
RTOL_F32 = 2e-5
ATOL_F32 = 1e-6
DIR_ATOL = 1e-5
# Known answers under a constant environment of radiance 1 (every prefiltered level and the Charlie
# cube's hold 1 to float rounding, so the pixel is the weight alone), over n.v >= KNOWN_MIN_NOV: the
# DFG LUT at 32 x 1024 samples against a 256^2 visible-normal quadrature measured within 0.26 %
# (roughness 0.3 and 0.7); the sheen LUT at 32 x 4096 against the 256 x 128 quadrature within 0.65 %.
# The engines' other forms miss these by 19 % to 370 % (coat) and 23 % to 58 % (sheen): docs/realtime.md.
KNOWN_RTOL = 0.01
# Pixels used for the known answers: n.v >= this (the silhouette's pixels mix the background, and
# the LUTs' extrapolation within half a texel of n.v = 0 is the least accurate there).
KNOWN_MIN_NOV = 0.2
# Nodes of the expected albedo's table over [KNOWN_MIN_NOV, 1], interpolated linearly at each pixel's n.v:
# the coat albedo's curvature at roughness 0.3 (0.25 -> 0.07 over n.v 0.2 -> 0.5) needs ~40 for 0.1 %.
KNOWN_NODES = 41
# A point light's lobe against the truth's float64 evaluation: a few dozen float32 operations (the Charlie
# Lambda's exp of a fit, pow(sin, 1/alpha)).
LIGHT_RTOL = 1e-4
# The Charlie cube (64^2 faces, 4 levels, 1024 samples a texel, each read at its density's level of a
# 64^2 source cube with box-filtered mips) against the quadrature of what it estimates on the sky's
# radiance function: measured within 4.4 % at levels 1-3 (the largest looking down, where the ground
# meets the horizon within a source texel's footprint; up to 1.3 % elsewhere). Level 0 (sheen
# roughness 0: the horizon ring) is not compared: the quadrature does not resolve its sliver.
CHARLIE_RTOL = 0.06
# A texture of 1 against its factor: RGBA16F holds 1 exactly; the lobe's uniforms are the same floats.
TEXTURE_ONE_RTOL = 1e-6
#: The identifiers of lobe code (material_lobes.glsl, lobes_*.glsl, the pipelines' lobe blocks).
LOBE_SYMBOLS = re.compile(r"\b(g_lobes|MaterialLobes|obj_lobes|lobe_p\d|tex_lobe|lobes_layer|coat_\w+|sheen_\w+|"
                          r"aniso_\w+|iridescence_\w+|charlie_\w+|specular_dielectric_f0|split_sum_albedo_f90)\b")


def f32(x):
    return np.asarray(x, np.float32).astype(np.float64)


def close(glsl, ref, rtol=RTOL_F32, atol=ATOL_F32):
    glsl, ref = np.asarray(glsl, np.float64), np.asarray(ref, np.float64)
    assert glsl.shape == ref.shape and glsl.size > 0, (glsl.shape, ref.shape)
    assert np.all(np.isfinite(glsl))
    bad = np.abs(glsl - ref) > atol + rtol * np.abs(ref)
    assert not bad.any(), f"{bad.sum()} mismatches, worst glsl={glsl[bad][:3]} ref={ref[bad][:3]}"


# ---- the material composition's lobe terms (lobes_material.glsl) against their twins ---------------

def test_specular_dielectric_f0_and_f90_twins():
    f0, fac, c = (g.ravel() for g in np.meshgrid(f32([0.0, 0.04, 0.5, 1.0]), f32([0.0, 0.3, 1.0]),
                                                  f32([0.0, 0.5, 1.0, 2.0, 30.0]), indexing="ij"))
    color = np.stack([c, 0.5 * c, np.ones_like(c)], axis=-1)
    g = run_glsl("specular_dielectric_f0(x0, x1, vec3(x2, x3, x4))", f0, fac, *color.T, components=3)
    want = lobes.specular_dielectric_f0(f0, fac, color)
    close(g, want)
    # the truth's equation (pbrcheck.lobes.specular_f0) is the same, and neutral factors give F0_ior exactly
    np.testing.assert_array_equal(want, truth.specular_f0(f0, fac, color))
    np.testing.assert_array_equal(lobes.specular_dielectric_f0(f0, 1.0, (1.0, 1.0, 1.0)), np.stack([f0] * 3, -1))
    f90, m = (g.ravel() for g in np.meshgrid(f32([0.0, 0.3, 1.0]), f32([0.0, 0.25, 0.5, 1.0]), indexing="ij"))
    close(run_glsl("specular_f90_blend(x0, x1)", f90, m), lobes.specular_f90_blend(f90, m))
    assert np.all(run_glsl("specular_f90_blend(1.0, x0)", m) == 1.0)   # F90 = 1 stays exactly 1


def test_split_sum_albedo_f90_twin():
    A, B, f90 = (g.ravel() for g in np.meshgrid(f32([0.0, 0.3, 1.0]), f32([0.0, 0.05, 0.5]), f32([0.0, 0.4, 1.0]),
                                                 indexing="ij"))
    F0 = np.stack([A * 0 + 0.04, A * 0 + 0.5, A * 0 + 1.0], axis=-1)
    g = run_glsl("split_sum_albedo_f90(vec3(x0, x1, x2), x3, x4, x5)", *F0.T, f90, A, B, components=3)
    close(g, lobes.split_sum_albedo_f90(F0, f90, A, B))


def test_aniso_direction_and_sphere_tangent_twins():
    rng = np.random.default_rng(3)
    n = lobes._normalize(rng.normal(size=(40, 3)))
    n = np.concatenate([n, [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
    n = f32(n)
    t = lobes.sphere_tangent(n)
    close(run_glsl("sphere_tangent(vec3(x0, x1, x2))", *n.T, components=3), t, atol=DIR_ATOL)
    np.testing.assert_array_equal(t[-4:-2], [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])   # the poles: +X
    assert np.allclose(np.sum(t * n, axis=-1), 0.0, atol=1e-7)                   # in the tangent plane
    t = f32(t)
    for rot in (0.0, 0.3, np.pi / 2, -np.pi, 2 * np.pi):
        r = np.full(len(n), rot)
        d = lobes.aniso_direction(t, n, r)
        close(run_glsl("aniso_direction(vec3(x0, x1, x2), vec3(x3, x4, x5), x6)", *t.T, *n.T, f32(r), components=3),
              d, atol=DIR_ATOL)
    # counter-clockwise from the tangent toward n x t: a quarter turn is the bitangent
    np.testing.assert_allclose(lobes.aniso_direction(t, n, np.full(len(n), np.pi / 2)), np.cross(n, t), atol=1e-12)


# ---- the direct lights' anisotropic GGX and thin film (lobes_anisotropy.glsl, lobes_iridescence.glsl) --

#: The terms' extremes: roughness 0 (alpha at the floor MIN_ALPHA) and 1, strength 0 and 1.
ALPHAS = (1e-7, 0.01, 0.09, 0.25, 1.0)
STRENGTHS = (0.0, 0.4, 1.0)
#: The terms at at = ab against the isotropic GGX (brdf.glsl D_GGX, G_SmithGGXCorrelated / (4 n.v n.l)): the
#: same function in another algebraic form, both float32: measured within 3.2e-6 (D at the alpha floor 10
#: degrees off its spike, D ~ 1e-12, where the float32 half vector's |h|^2 - 1 ~ 1e-7 weighs against D_GGX's
#: (1 - n.h)(1 + n.h)); within 2e-7 elsewhere. (The renders skip the terms at strength 0: bit for bit.)
ISO_RTOL = 1e-5
#: The truth's isotropic D at the alpha floor (pbrcheck.terms.GGX.eval: (n.h)^2 (alpha^2 - 1) + 1 cancels to
#: alpha^2 = 1e-14 in float64, keeping ~2 digits): measured 1.6e-3 from the twin's exact 1 / (pi alpha^2)
#: at the mirror's spike; every other roughness and strength agree to 1e-10.
TRUTH_FLOOR_RTOL = 2e-3


def _sph(theta, phi):
    return np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=-1)


def test_aniso_alpha_t_twin():
    a, s = (g.ravel() for g in np.meshgrid(f32(ALPHAS), f32(STRENGTHS + (0.7,)), indexing="ij"))
    close(run_glsl("aniso_alpha_t(x0, x1)", a, s), lobes.aniso_alpha_t(a, s))
    assert np.array_equal(run_glsl("aniso_alpha_t(x0, 0.0)", f32(ALPHAS)), f32(ALPHAS))   # strength 0: alpha
    assert np.all(run_glsl("aniso_alpha_t(x0, 1.0)", f32(ALPHAS)) == 1.0)                  # strength 1: 1


def test_D_and_V_GGX_anisotropic_twins_and_their_isotropic_limit():
    """On half vectors and directions from the normal to grazing (89.99 degrees), every azimuth, alpha
    from the floor to 1 on both axes; the truth's AnisotropicGGX (float64) equals the twins, and at
    at = ab = alpha the GLSL terms are the isotropic D_GGX and G_SmithGGXCorrelated / (4 n.v n.l)."""
    th = np.radians([0.0, 10.0, 45.0, 80.0, 89.99])
    ph = np.radians([0.0, 30.0, 90.0, 200.0])
    at_, ab_ = np.array(ALPHAS), np.array(ALPHAS)
    T, P, AT, AB = (g.ravel() for g in np.meshgrid(th, ph, at_, ab_, indexing="ij"))
    h = f32(_sph(T, P))
    AT, AB = f32(AT), f32(AB)
    g = run_glsl("D_GGX_anisotropic(x0, x1, x2, x3, x4)", h[:, 2], h[:, 0], h[:, 1], AT, AB)
    want = lobes.D_GGX_anisotropic(h[:, 2], h[:, 0], h[:, 1], AT, AB)
    close(g, want, rtol=1e-5, atol=0.0)
    assert np.all(run_glsl("D_GGX_anisotropic(x0, x1, x2, x3, x4)", -h[:, 2], h[:, 0], h[:, 1], AT, AB)[h[:, 2] > 0] == 0)
    # the isotropic limit, and the truth's D (1 / (pi at ab (...)^2) about t = +x) against the twin
    iso = AT == AB
    close(g[iso], run_glsl("D_GGX(x0, x1)", h[iso, 2], AT[iso]), rtol=ISO_RTOL, atol=0.0)
    for a_t, a_b in ((0.09, 0.09), (0.3, 0.09), (1.0, 0.0001)):
        ggx = truth.AnisotropicGGX(np.sqrt(a_b), np.sqrt((a_t - a_b) / (1.0 - a_b)))
        hh = _sph(T[:20], P[:20])
        np.testing.assert_allclose(lobes.D_GGX_anisotropic(hh[:, 2], hh[:, 0], hh[:, 1], ggx.at, ggx.ab), ggx.D(hh),
                                   rtol=1e-10)
    # V on pairs of directions (v, l), grazing included
    TV, PV, TL, PL, A = (g.ravel() for g in np.meshgrid(th, ph[:2], th, ph, np.array([1e-7, 0.09, 1.0]), indexing="ij"))
    v, l = f32(_sph(TV, PV)), f32(_sph(TL, PL))
    A = f32(A)
    for at in (A, np.ones_like(A), f32(0.5 * A + 0.5)):
        gv = run_glsl("V_GGX_anisotropic(x0, x1, x2, x3, x4, x5, x6, x7)", v[:, 2], l[:, 2], v[:, 0], v[:, 1], l[:, 0],
                      l[:, 1], at, A)
        close(gv, lobes.V_GGX_anisotropic(v[:, 2], l[:, 2], v[:, 0], v[:, 1], l[:, 0], l[:, 1], at, A), rtol=1e-5,
              atol=0.0)
    gv = run_glsl("V_GGX_anisotropic(x0, x1, x2, x3, x4, x5, x6, x6)", v[:, 2], l[:, 2], v[:, 0], v[:, 1], l[:, 0],
                  l[:, 1], A)
    giso = run_glsl("G_SmithGGXCorrelated(x0, x1, x2) / (4.0 * x0 * x1)", v[:, 2], l[:, 2], A)
    close(gv, giso, rtol=ISO_RTOL, atol=0.0)


def test_aniso_specular_dv_twin_is_the_truths_brdf():
    """aniso_specular_dv (n = +z, t at azimuth rot, b = n x t) against its twin on the grid of the
    extremes (grazing v and l, strength 0 and 1, roughness 0 and 1), and the twin against
    pbrcheck.lobes.AnisotropicGGX(roughness, strength, rot).brdf (the truth, float64) to 1e-10."""
    th = np.radians([0.0, 30.0, 70.0, 89.9])
    ph = np.radians([0.0, 50.0, 135.0, 260.0])
    R = np.array([0.0, 0.3, 1.0])
    TV, PV, TL, PL, RR, S, ROT = (g.ravel() for g in np.meshgrid(th, ph[:2], th, ph, R, np.array(STRENGTHS),
                                                                   np.array([0.0, 0.6]), indexing="ij"))
    TV, PV, TL, PL, ROT = (f32(x) for x in (TV, PV, TL, PL, ROT))
    alpha = f32(np.maximum(RR * RR, 1e-7))
    S64, S = S, f32(S)
    expr = ("aniso_specular_dv(vec3(0.0, 0.0, 1.0), vec3(cos(x6), sin(x6), 0.0), vec3(-sin(x6), cos(x6), 0.0), "
            "vec3(sin(x0) * cos(x1), sin(x0) * sin(x1), cos(x0)), vec3(sin(x2) * cos(x3), sin(x2) * sin(x3), cos(x2)), "
            "x4, x5)")
    g = run_glsl(expr, TV, PV, TL, PL, alpha, S, ROT)
    n = np.broadcast_to([0.0, 0.0, 1.0], (len(TV), 3))
    t = np.stack([np.cos(ROT), np.sin(ROT), 0 * ROT], -1)
    want = lobes.aniso_specular_dv(n, t, np.cross(n, t), _sph(TV, PV), _sph(TL, PL), alpha, S)
    assert np.all(want >= 0) and want.max() > 1e6   # the mirror's spike is in the grid
    close(g, want, rtol=1e-4, atol=1e-6)
    want = lobes.aniso_specular_dv(n, t, np.cross(n, t), _sph(TV, PV), _sph(TL, PL), np.maximum(RR * RR, 1e-7), S64)
    for r in R:
        for s_ in STRENGTHS:
            for rot in (0.0, 0.6):
                m = (RR == r) & (S64 == s_) & (ROT == f32(rot))
                ggx = truth.AnisotropicGGX(r, s_, float(f32(rot)))
                v, l = _sph(TV[m], PV[m]), _sph(TL[m], PL[m])
                tr = np.where((v[:, 2] > 0) & (l[:, 2] > 0), ggx.brdf(v, l), 0.0)
                np.testing.assert_allclose(want[m], tr, rtol=TRUTH_FLOOR_RTOL if (r == 0 and s_ == 0) else 1e-10,
                                           atol=1e-12)   # tails below 1e-12 (1e-18 off a mirror's spike) cancel


def test_iridescence_light_fresnel_twin_and_factor_zero():
    """On v.h from 0 (grazing) to 1, base F0 0 to 1, F90 0 and 1, film IOR 1 to 2, thickness 0 (no film)
    to 1200 nm, factor 0 to 1; at factor 0 the GLSL value is Schlick's (brdf.glsl F_Schlick) bit for bit."""
    VoH, F0, F90, IOR, D, K = (g.ravel() for g in np.meshgrid(f32([0.0, 1e-3, 0.2, 0.5, 1.0]), f32([0.0, 0.04, 0.5, 1.0]),
                                                              f32([0.0, 1.0]), f32([1.0, 1.3, 2.0]),
                                                              f32([0.0, 0.03, 300.0, 1200.0]), f32([0.0, 0.5, 1.0]),
                                                              indexing="ij"))
    f0 = np.stack([F0, 0.5 * F0, np.ones_like(F0)], -1)
    g = run_glsl("iridescence_light_fresnel(x0, vec3(x1, x2, x3), x4, x5, x6, x7)", VoH, *f0.T, F90, IOR, D, K,
                 components=3)
    close(g, lobes.iridescence_light_fresnel(VoH, f0, F90, IOR, D, K), rtol=1e-4, atol=2e-6)
    z = K == 0
    schlick = run_glsl("F_Schlick(x0, vec3(x1, x2, x3), x4)", VoH[z], *f0[z].T, F90[z], components=3)
    assert np.array_equal(g[z], schlick)
    # the film changes it where present (so the comparison above can fail)
    on = (K == 1) & (D == 300) & (IOR == f32(1.3))
    assert np.abs(g[on] - run_glsl("F_Schlick(x0, vec3(x1, x2, x3), x4)", VoH[on], *f0[on].T, F90[on],
                                   components=3)).max() > 0.05


# ---- the switches: compiled only where a scene's materials use a lobe -------------------------------

def test_every_lobe_option_is_a_registry_held_as_an_object():
    for define, (reg, *_rest) in LOBE_REGISTRIES.items():
        names = [k for k, v in OPTION_REGISTRIES.items() if v is reg]
        assert len(names) == 1, define
        assert PRESETS["default"][names[0]] in reg
    sv, fil = resolve_options("sample_viewer"), resolve_options("filament")
    assert (sv.coat_ibl, sv.sheen_dfg, sv.sheen_scaling, sv.sheen_cube, sv.anisotropy_bend) == (
        "filament", "lut_ibl_sampler_legacy", "lut", "charlie", "sample_viewer")  # the pinned 1.1.0
    assert (fil.coat_ibl, fil.sheen_dfg, fil.sheen_scaling, fil.sheen_cube, fil.anisotropy_bend, fil.iridescence) == (
        "filament", "lut_neubelt", "filament", "ggx", "filament", "none")


@pytest.mark.parametrize("name,ext,define", [("clearcoat", lp.CLEARCOAT, "LOBE_CLEARCOAT"),
                                             ("sheen", lp.SHEEN, "LOBE_SHEEN"),
                                             ("specular", lp.SPECULAR, "LOBE_SPECULAR"),
                                             ("anisotropy", lp.ANISOTROPY, "LOBE_ANISOTROPY"),
                                             ("iridescence", lp.IRIDESCENCE, "LOBE_IRIDESCENCE")])
def test_a_lobe_scene_compiles_its_lobe_alone(name, ext, define):
    scene = load_scene(name)
    assert scene_lobes(scene) == (ext,)
    d = lobe_defines(scene_lobes(scene), resolve_options("default"))
    assert d["MATERIAL_LOBES"] == 1 and d[define] == 1
    assert not {k for k in d if k.startswith("LOBE_")} - {define}
    # an article composition renders no lobe: its program stays the lobe-free one
    assert lobe_defines(scene_lobes(scene), resolve_options("analytic_mobile")) == {}


def test_lobe_switches_follow_the_options():
    o = resolve_options("sample_viewer")
    d = lobe_defines((lp.CLEARCOAT, lp.SHEEN, lp.ANISOTROPY), o)
    assert (d["COAT_IBL"], d["SHEEN_DFG"], d["SHEEN_RADIANCE"], d["ANISOTROPY_BEND"]) == (
        "COAT_IBL_FILAMENT", "SHEEN_DFG_LUT_IBL_SAMPLER_LEGACY", "SHEEN_RADIANCE_CHARLIE", "ANISOTROPY_BEND_SAMPLE_VIEWER")
    assert lobe_defines((lp.SHEEN,), resolve_options("filament"))["SHEEN_RADIANCE"] == "SHEEN_RADIANCE_GGX"
    assert lobe_defines((lp.SHEEN,), resolve_options("default", {"sheen_dfg": "threejs"}))["SHEEN_RADIANCE"] == \
        "SHEEN_RADIANCE_IRRADIANCE"
    assert lobe_defines((lp.SHEEN,), resolve_options("default", {"sheen_dfg": "playcanvas"}))["SHEEN_RADIANCE"] == \
        "SHEEN_RADIANCE_NORMAL_ROUGHEST"


def _preprocessed(entry: str, defines: dict) -> str:
    """The assembled source of ``entry`` through the C preprocessor (``#version`` dropped): what the GLSL
    compiler sees of it."""
    src = "\n".join(line for line in gl.assemble(entry, defines).text.splitlines() if not line.startswith("#version"))
    out = subprocess.run(["cpp", "-P", "-undef", "-w"], input=src, capture_output=True, text=True, check=True).stdout
    return re.sub(r"\s+", " ", out)


@pytest.mark.skipif(shutil.which("cpp") is None, reason="needs the C preprocessor (cpp) to see past #ifdef")
@pytest.mark.parametrize("preset", ["default", "filament", "sample_viewer", "runtime_is20"])
def test_a_lobe_free_program_has_no_lobe_code(preset):
    """The spheres scene's frame programs (ray-cast and raster) preprocess to sources that name no lobe
    symbol; the same programs with a lobe scene's switches do (so the check can fail). Checked once by
    hand against the sources before the lobes existed (main at 2e96e1f): the preprocessed texts of
    every preset's render.comp and raster.frag are identical."""
    o = resolve_options(preset)
    scene = load_scene("spheres")
    assert lobe_defines(scene_lobes(scene), o) == {}
    terms = {**R.resolved_terms(scene, o), "energy_compensation": R.resolved_energy_compensation(scene, o)}
    base = R.frame_defines(o, terms)
    every = lobe_defines(tuple(lp.LOBE_EXTENSIONS), resolve_options("default"))
    for entry, extra in (("render.comp", {}), ("raster.frag", {"AOV_PASS": 0})):
        assert not LOBE_SYMBOLS.search(_preprocessed(entry, {**base, **extra}))
        lobed = _preprocessed(entry, {**base, **extra, **every})
        assert {m.group(1) for m in LOBE_SYMBOLS.finditer(lobed)} >= {"g_lobes", "lobes_layer", "coat_attenuation",
                                                                      "sheen_dfg", "aniso_reflection",
                                                                      "iridescence_fresnel"}


# ---- renders: the lobed objects change, the neutral ones stay bit for bit ---------------------------

NEUTRAL = {"clearcoat": dict(clearcoat=0.0), "sheen": dict(sheen_color=(0.0, 0.0, 0.0)),
           "specular": dict(specular_factor=1.0, specular_color=(1.0, 1.0, 1.0)),
           "anisotropy": dict(anisotropy_strength=0.0), "iridescence": dict(iridescence=0.0)}


def _neutralized(scene, name):
    return replace(scene, objects=tuple(replace(o, material=replace(o.material, **NEUTRAL[name])) for o in scene.objects))


@pytest.mark.parametrize("pipeline", ["raycast", pytest.param("raster", marks=pytest.mark.slow)])
@pytest.mark.parametrize("name", list(NEUTRAL))
def test_a_built_in_lobe_scene_changes_its_lobed_objects_alone(name, pipeline):
    """With a directional light added (the lobes' point-light terms) and glTF's metallic blend."""
    scene = load_scene(name).with_camera(width=40, height=40)
    scene = replace(scene, lights=(DirectionalLight(direction=(-0.3, -0.5, -0.8), intensity=(2.0, 2.0, 2.0)),),
                    brdf=replace(scene.brdf, metallic_blend="gltf"))
    neutral = _neutralized(scene, name)
    a = render_realtime(scene, "default", {**SMALL, "pipeline": pipeline}, progress=False)
    b = render_realtime(neutral, "default", {**SMALL, "pipeline": pipeline}, progress=False)
    assert "lobes" in a.meta and "lobes" not in b.meta
    obj = a.channels["object"]
    assert np.array_equal(obj, b.channels["object"])
    changed = same = 0
    for o, o0 in zip(scene.objects, neutral.objects):
        m = obj == o.id
        assert m.sum() > 10
        if o.material == o0.material:   # at the neutral value inside a lobe program: the lobe-free pixels
            assert np.array_equal(a.rgb[m], b.rgb[m]), o.name
            same += 1
        else:
            assert np.abs(a.rgb[m] - b.rgb[m]).max() > 1e-3, o.name
            changed += 1
    assert same >= 1 and changed >= 15   # each grid holds its neutral value (a row, or one sphere), the rest not


LOBE_OPTIONS = ("coat_ibl", "coat_attenuation", "sheen_dfg", "sheen_scaling", "sheen_cube", "anisotropy_bend",
                "iridescence")


def _every_lobe_scene():
    """Six small spheres: one per lobe and one with all five, a directional light (the point-light terms)."""
    scene = load_scene("clearcoat").with_camera(width=48, height=32)
    lobes_of = [dict(clearcoat=1.0, clearcoat_roughness=0.3), dict(sheen_color=(1.0, 0.6, 0.3), sheen_roughness=0.5),
                dict(specular_factor=0.5, specular_color=(1.0, 0.5, 0.2)), dict(anisotropy_strength=0.8, anisotropy_rotation=0.5),
                dict(iridescence=1.0, iridescence_thickness=300.0)]
    lobes_of.append({k: v for d in lobes_of for k, v in d.items()})
    objs = tuple(Sphere(id=i, center=(-2.5 + 1.0 * i, 0.0, 0.0), radius=0.45,
                        material=Material(base_color=(0.5, 0.3, 0.2), metallic=0.3, roughness=0.4, **d))
                 for i, d in enumerate(lobes_of))
    return replace(scene, objects=objs, lights=(DirectionalLight(direction=(-0.3, -0.5, -0.8), intensity=(2.0, 2.0, 2.0)),))


@pytest.fixture(scope="module")
def every_lobe_default():
    return render_realtime(_every_lobe_scene(), "default", SMALL, progress=False)


@pytest.mark.parametrize("option,value", [(o, v) for o in LOBE_OPTIONS for v in OPTIONS[o].choices
                                          if v != PRESETS["default"][o]])
def test_every_lobe_form_renders_and_changes_the_image(option, value, every_lobe_default):
    assert all((every_lobe_default.channels["object"] == i).sum() > 10 for i in range(6))   # every sphere in view
    img = render_realtime(_every_lobe_scene(), "default", {**SMALL, option: value}, progress=False)
    assert np.all(np.isfinite(img.rgb))
    assert np.abs(img.rgb - every_lobe_default.rgb).max() > 1e-4, (option, value)


def test_an_article_composition_renders_no_lobe_and_says_so():
    scene = load_scene("clearcoat").with_camera(width=16, height=16)
    img = render_realtime(scene, "analytic_mobile", SMALL, progress=False)
    assert "lobes" not in img.meta
    assert "lobes_ignored" in img.meta["warnings"] and lp.CLEARCOAT in img.meta["warnings"]


# ---- known answers: a black base under a uniform white environment -----------------------------------

def _one_sphere(material: Material, width: int = 48):
    scene = load_scene("clearcoat").with_camera(width=width, height=width)
    return replace(scene, objects=(Sphere(id=0, center=(0.0, 0.0, 0.0), radius=2.0, material=material),),
                   environment=Environment(type="constant", radiance=(1.0, 1.0, 1.0)))


# a base that reflects nothing: black, and KHR_materials_specular's factor 0 (F0 = F90 = 0)
BLACK = dict(base_color=(0.0, 0.0, 0.0), metallic=0.0, specular_factor=0.0)


def _coat_albedo(mu: float, roughness: float, n: int = 256) -> float:
    """int Fc(v.h) D G2 / (4 n.v) dl, Fc Schlick with F0 0.04 (the split sum's own integrand), by the
    visible-normal quadrature of pbrcheck.lobes.AnisotropicGGX.albedo with the Fresnel inside."""
    ggx = truth.AnisotropicGGX(roughness)
    g = (np.arange(n) + 0.5) / n
    u = np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1).reshape(-1, 2)
    v = np.array([np.sqrt(1 - mu * mu), 0.0, mu])
    l, pdf = ggx.sample(v, u)
    h = lobes._normalize(l + v)
    F = truth.schlick(np.clip(np.sum(h * v, axis=-1), 0, 1), truth.f0_from_ior(1.5))
    f = ggx.eval(v[None], l) * F
    return float(np.mean(np.where(pdf > 0, f / np.maximum(pdf, 1e-300), 0.0)))


def _check_known(img, expected_of_mu):
    nov = img.channels["NdotV"]
    m = (img.channels["object"] == 0) & (nov >= KNOWN_MIN_NOV)
    assert m.sum() > 200
    mus = np.linspace(KNOWN_MIN_NOV, 1.0, KNOWN_NODES)
    table = np.array([expected_of_mu(mu) for mu in mus])
    want = np.interp(nov[m], mus, table)
    got = img.rgb[m]
    assert np.allclose(got, want[:, None], rtol=KNOWN_RTOL, atol=0), (float(np.abs(got / want[:, None] - 1).max()))


@pytest.mark.parametrize("roughness", [0.3, 0.7])
def test_clearcoat_over_black_is_the_coat_albedo(roughness):
    """coat_ibl = splitsum: clearcoat 1 over a base that reflects nothing, in a uniform white environment,
    is the coat's directional albedo int Fc(v.h) f cos (the split sum's F0 A + B at the coat's roughness)."""
    scene = _one_sphere(Material(**BLACK, clearcoat=1.0, clearcoat_roughness=roughness))
    img = render_realtime(scene, "default", {**SMALL, "lut_size": 32, "lut_samples": 1024}, progress=False)
    _check_known(img, lambda mu: _coat_albedo(mu, roughness))


def test_sheen_over_black_is_the_charlie_albedo():
    """sheen_dfg = lut_charlie: sheenColor 1 over a base that reflects nothing, in a uniform white
    environment, is the spec's sheen albedo E(n.v, r) = int D_Charlie V_Charlie n.l dl."""
    r = 0.5
    scene = _one_sphere(Material(**BLACK, sheen_color=(1.0, 1.0, 1.0), sheen_roughness=r))
    img = render_realtime(scene, "default", {**SMALL, "sheen_lut_size": 32, "sheen_lut_samples": 4096},
                          progress=False)
    _check_known(img, lambda mu: lobes.sheen_albedo_quadrature(mu, r, 256, 128)[0])


@pytest.mark.parametrize("lobe", ["clearcoat", "sheen"])
def test_a_directional_light_adds_the_specs_lobe(lobe):
    """Over a base that reflects nothing, with no environment, a directional light at 40 degrees: the
    sphere's centre pixel (n = v = +z) is the truth's lobe (pbrcheck.lobes: clearcoat Fc(n.v) times
    ClearcoatLobe.eval; sheenColor times SheenCharlie.eval) times the light's irradiance."""
    th = np.radians(40.0)
    l = np.array([np.sin(th), 0.0, np.cos(th)])
    mat = Material(**BLACK, **({"clearcoat": 1.0, "clearcoat_roughness": 0.4} if lobe == "clearcoat" else
                               {"sheen_color": (1.0, 0.5, 0.25), "sheen_roughness": 0.5}))
    scene = _one_sphere(mat, 49)
    scene = replace(scene, environment=Environment(type="constant", radiance=(0.0, 0.0, 0.0)),
                    lights=(DirectionalLight(direction=tuple(-l), intensity=(3.0, 3.0, 3.0)),))
    img = render_realtime(scene, "default", SMALL, progress=False)
    got = img.rgb[24, 24]
    v = np.array([0.0, 0.0, 1.0])
    if lobe == "clearcoat":
        want = 3.0 * truth.fresnel_coat(1.0) * truth.ClearcoatLobe(0.4).eval(v, l) * np.ones(3)
    else:
        want = 3.0 * truth.SheenCharlie(0.5).eval(v, l) * np.array([1.0, 0.5, 0.25])
    assert float(np.min(want)) > 1e-3
    np.testing.assert_allclose(got, want, rtol=LIGHT_RTOL)


#: The lit sphere's pixels compared: n.v and n.l at least this, and the sphere's tangent (-n.y, n.x) at least
#: this long (at the pole on the view axis the tangent turns a full circle within a pixel).
LIT_MIN_COS = 0.2
LIT_MIN_TANGENT = 0.1
LIT_LIGHT = (0.3, 0.5, 0.8)
LIT_E = 2.5
LIT_LOBES = {"anisotropy": dict(anisotropy_strength=0.7, anisotropy_rotation=0.5),
             "iridescence": dict(iridescence=0.8, iridescence_thickness=400.0, iridescence_ior=1.3),
             "both": dict(anisotropy_strength=1.0, anisotropy_rotation=-1.0, iridescence=1.0,
                          iridescence_thickness=250.0, iridescence_ior=1.8)}


def _lit_sphere(lobe: str, blend: str, **lobe_fields):
    mat = Material(base_color=(0.9, 0.6, 0.3), metallic=0.5, roughness=0.4, **lobe_fields)
    scene = _one_sphere(mat, 49)
    l = np.asarray(LIT_LIGHT) / np.linalg.norm(LIT_LIGHT)
    return replace(scene, environment=Environment(type="constant", radiance=(0.0, 0.0, 0.0)),
                   lights=(DirectionalLight(direction=tuple(-l), intensity=(LIT_E,) * 3),),
                   brdf=replace(scene.brdf, metallic_blend=blend)), mat, l


def _lit_truth(img, scene, mat, l):
    """Per pixel: the truth's base BRDF times n.l times the light (reference.lobe_bsdf's material: the
    anisotropic GGX of pbrcheck.lobes.AnisotropicGGX about the README's direction in the sphere's frame
    (realtime.lobes.sphere_tangent = Mitsuba's sh_frame.s, tests/test_aniso_convention.py), the Fresnel
    F_d, F_m each mixed with the film at v.h over its own F0 (here the real-time RGB film, the twin
    realtime.lobes.iridescence_light_fresnel: the truth's film is spectral), the diffuse under 1 - F (blend
    f0) or 1 - max3 F_d (gltf)); and the mask of the pixels compared."""
    n = np.stack([img.channels[c] for c in ("N.X", "N.Y", "N.Z")], -1).astype(np.float64)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    v = lobes._normalize(np.asarray(scene.camera.origin) - 2.0 * n)
    T = lobes.sphere_tangent(n)
    NoV, NoL = np.sum(n * v, -1), n @ l
    mask = ((img.channels["object"] == 0) & (NoV >= LIT_MIN_COS) & (NoL >= LIT_MIN_COS)
            & (np.hypot(n[..., 0], n[..., 1]) >= LIT_MIN_TANGENT))
    return _lit_brdf_cos(n[mask], v[mask], T[mask], l, mat, scene.brdf.metallic_blend), mask


def _lit_brdf_cos(n, v, T, l, mat, blend):
    """The truth's base BRDF x n.l x LIT_E at unit normals n, view directions v and tangents T (arrays (N, 3))
    for the light direction l (_lit_truth's docstring)."""
    B = np.cross(n, T)
    local = lambda w: np.stack([np.sum(w * T, -1), np.sum(w * B, -1), np.sum(w * n, -1)], -1)  # noqa: E731
    vl, ll = local(v), local(np.broadcast_to(l, v.shape))
    VoH = np.sum(vl * lobes._normalize(vl + ll), -1)
    ggx = truth.AnisotropicGGX(mat.roughness, mat.anisotropy_strength, mat.anisotropy_rotation)
    spec = ggx.brdf(vl, ll)
    base, m, f0 = np.asarray(mat.base_color), mat.metallic, np.full(3, mat.specular)
    k = mat.iridescence if mat.iridescence_thickness > 0 else 0.0
    Fd = lobes.iridescence_light_fresnel(VoH, np.broadcast_to(f0, vl.shape), 1.0, mat.iridescence_ior,
                                         mat.iridescence_thickness, np.full(len(VoH), k))
    Fm = lobes.iridescence_light_fresnel(VoH, np.broadcast_to(base, vl.shape), 1.0, mat.iridescence_ior,
                                         mat.iridescence_thickness, np.full(len(VoH), k))
    F = Fd * (1.0 - m) + Fm * m
    Fdiff = np.max(Fd, -1, keepdims=True) if blend == "gltf" else F
    f = (1.0 - Fdiff) * (1.0 - m) * base / np.pi + F * spec[:, None]
    return f * (ll[:, 2] * LIT_E)[:, None]


@pytest.mark.parametrize("lobe,blend", [("anisotropy", "f0"), ("iridescence", "f0"), ("both", "gltf")])
def test_a_directional_light_on_the_anisotropic_iridescent_base_is_the_truths_brdf(lobe, blend):
    """A sphere under one directional light, no environment: every pixel (away from the silhouette and
    the tangent's pole) is the truth's base BRDF x n.l x the light's irradiance to LIGHT_RTOL: the
    README's anisotropic GGX (D and the height-correlated V at alpha_t = mix(alpha, 1, s^2) along the
    rotated tangent) and the thin film at v.h in the Fresnel. The isotropic, film-free BRDF misses it."""
    scene, mat, l = _lit_sphere(lobe, blend, **LIT_LOBES[lobe])
    img = render_realtime(scene, "default", SMALL, progress=False)
    want, mask = _lit_truth(img, scene, mat, l)
    assert mask.sum() > 300
    got = img.rgb[mask].astype(np.float64)
    np.testing.assert_allclose(got, want, rtol=LIGHT_RTOL, atol=LIGHT_RTOL * float(want.max()))
    plain = _lit_truth(img, scene, replace(mat, anisotropy_strength=0.0, iridescence=0.0), l)[0]
    assert np.abs(plain - got).max() > 0.05 * float(want.max())


def test_a_directional_light_on_a_brushed_iridescent_gltf_quad_is_the_truths_brdf(tmp_path):
    """The raster pipeline: a glTF quad facing +z (TANGENT +x, w = 1) with KHR_materials_anisotropy (strength
    0.7, rotation 0.5: the direction TBN (cos, sin, 0)) and KHR_materials_iridescence (factor 0.8, no
    thickness texture: iridescenceThicknessMaximum 400 nm, IOR 1.3), glTF's metallic blend, one directional
    light and no environment: each covered pixel is the truth's base BRDF x n.l x E to LIGHT_RTOL, v the
    camera's ray through the pixel centre (pbrcheck.camera.primary_rays)."""
    from pbrcheck.camera import primary_rays

    gmat = {"pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.6, 0.3, 1.0], "metallicFactor": 0.5,
                                     "roughnessFactor": 0.4},
            "extensions": {lp.ANISOTROPY: {"anisotropyStrength": 0.7, "anisotropyRotation": 0.5},
                           lp.IRIDESCENCE: {"iridescenceFactor": 0.8, "iridescenceIor": 1.3}}}
    asset = quad_asset(tmp_path / "lit.gltf", gmat)
    scene = load_scene(str(quad_scene(tmp_path, asset, size=(32, 32), name="lit.toml")))
    l = np.asarray(LIT_LIGHT) / np.linalg.norm(LIT_LIGHT)
    scene = replace(scene, environment=Environment(type="constant", radiance=(0.0, 0.0, 0.0)),
                    lights=(DirectionalLight(direction=tuple(-l), intensity=(LIT_E,) * 3),))
    assert scene.brdf.metallic_blend == "gltf"
    img = render_realtime(scene, "default", SMALL, progress=False)
    assert img.meta["pipeline"] == "raster" and {"LOBE_ANISOTROPY", "LOBE_IRIDESCENCE"} <= set(json.loads(img.meta["lobes"]))
    m = img.channels["coverage"] == 1
    assert m.sum() > 300
    _, d = primary_rays(scene.camera)
    v = -d[m]
    n = np.broadcast_to([0.0, 0.0, 1.0], v.shape)
    T = np.broadcast_to([1.0, 0.0, 0.0], v.shape)
    mat = Material(base_color=(0.9, 0.6, 0.3), metallic=0.5, roughness=0.4, anisotropy_strength=0.7,
                   anisotropy_rotation=0.5, iridescence=0.8, iridescence_ior=1.3, iridescence_thickness=400.0)
    want = _lit_brdf_cos(n, v, T, l, mat, "gltf")
    np.testing.assert_allclose(img.rgb[m].astype(np.float64), want, rtol=LIGHT_RTOL, atol=LIGHT_RTOL * float(want.max()))


@pytest.mark.parametrize("lobe", ["anisotropy", "iridescence"])
@pytest.mark.parametrize("specular", [False, True])
def test_strength_and_factor_zero_under_a_light_are_the_plain_base_bit_for_bit(lobe, specular):
    """Anisotropy strength 0 (any rotation) and iridescence factor 0 (any film), in a program that compiles
    the lobe (a second, far sphere uses it), with and without KHR_materials_specular's lobe compiled
    (lobes_brdf_eval or brdf_eval for the light): the lit sphere's pixels are the lobe-free program's."""
    neutral = {"anisotropy": dict(anisotropy_strength=0.0, anisotropy_rotation=0.9),
               "iridescence": dict(iridescence=0.0, iridescence_thickness=400.0, iridescence_ior=1.8)}[lobe]
    spec = dict(specular_color=(1.0, 1.0, 0.999)) if specular else {}
    plain, mat, _ = _lit_sphere(lobe, "gltf", **spec)
    lobed, _, _ = _lit_sphere(lobe, "gltf", **neutral, **spec)
    far = Sphere(id=1, center=(0.0, 0.0, -50.0), radius=0.1, material=replace(mat, **LIT_LOBES[lobe]))
    lobed = replace(lobed, objects=(*lobed.objects, far))
    a = render_realtime(plain, "default", SMALL, progress=False)
    b = render_realtime(lobed, "default", SMALL, progress=False)
    assert ("LOBE_ANISOTROPY" if lobe == "anisotropy" else "LOBE_IRIDESCENCE") in b.meta["lobes"]
    m = a.channels["object"] == 0
    assert m.sum() > 300 and float(a.rgb[m].max()) > 0.1
    ch = slice(0, 2) if specular else slice(0, 3)   # specular_color 0.999 moves blue alone
    assert np.array_equal(a.rgb[m][:, ch], b.rgb[m][:, ch])


def test_sheen_colour_zero_is_the_base_bit_for_bit():
    base = Material(base_color=(0.6, 0.3, 0.2), roughness=0.4)
    a = render_realtime(_one_sphere(base, 24), "default", SMALL, progress=False)
    # a lobe program (the specular lobe keeps it compiled) with sheen at colour 0 and any roughness
    lobed = _one_sphere(replace(base, sheen_color=(0.0, 0.0, 0.0), sheen_roughness=0.7, specular_color=(1.0, 1.0, 0.999)), 24)
    two = replace(lobed, objects=(*lobed.objects, Sphere(id=1, center=(0.0, 0.0, -50.0), radius=0.1,
                                                         material=replace(base, sheen_color=(1.0, 1.0, 1.0)))))
    b = render_realtime(two, "default", SMALL, progress=False)
    assert "LOBE_SHEEN" in b.meta["lobes"]
    m = a.channels["object"] == 0
    # specular_color 0.999 in blue alone moves blue: red and green are the base's bits
    assert np.array_equal(a.rgb[m][:, :2], b.rgb[m][:, :2])


# ---- the Charlie-prefiltered cube ---------------------------------------------------------------------

def _charlie_numpy(env, n, roughness, n_theta=256, n_phi=512):
    """What charlie_prefilter.comp estimates, by a midpoint quadrature over the hemisphere about n in
    float64 on the environment's radiance function: int L(l) D(h) (n.l) dl / int D(h) (n.l) dl, h the
    half vector of l and v = n (the density of l is D(n.h) / 4 there)."""
    ct = (np.arange(n_theta) + 0.5) / n_theta                  # cos theta_l, uniform: dl = dcos dphi
    ph = (np.arange(n_phi) + 0.5) * 2.0 * np.pi / n_phi
    C, P = np.meshgrid(ct, ph, indexing="ij")
    S = np.sqrt(1.0 - C * C)
    t = np.cross([0.0, 0.0, 1.0] if abs(n[2]) < 0.999 else [1.0, 0.0, 0.0], n)
    t /= np.linalg.norm(t)
    b = np.cross(n, t)
    l = (S * np.cos(P))[..., None] * t + (S * np.sin(P))[..., None] * b + C[..., None] * n
    NoH = np.sqrt((1.0 + C) / 2.0)                             # h = normalize(n + l)
    w = lobes.D_Charlie(NoH, roughness * roughness) * C
    return (env.radiance(l.reshape(-1, 3)).astype(np.float64) * w.reshape(-1, 1)).sum(0) / w.sum()


def test_charlie_cube_levels_hold_the_charlie_filtered_environment():
    """Level L of the Charlie cube (charlie_levels 4: sheen roughness L / 3) along n against the
    quadrature of what it estimates on the environment's radiance function (a sunless sky: smooth, so
    the source levels' box filter and the density's level choice cost little)."""
    scene = replace(load_scene("sheen"), environment=replace(load_scene("sheen").environment, sun_radiance=(0.0, 0.0, 0.0)))
    env = R.environment_of(scene)
    o = resolve_options("default", {"charlie_size": 64, "charlie_levels": 4, "charlie_samples": 1024, "cube_size": 64})
    cube = R.env_cube(env, o.cube_size, "f32", {})
    tex = R.charlie_cube(env, cube, o, "f32", {})
    dirs = lobes._normalize(np.array([[0.0, 1.0, 0.0], [0.3, 0.2, 0.9], [-0.7, -0.1, 0.2], [0.1, -1.0, 0.05]]))
    for level in (1, 2, 3):
        got = R.sample_cube(tex, dirs, float(level))
        want = np.array([_charlie_numpy(env, d, level / 3.0) for d in dirs])
        np.testing.assert_allclose(got, want, rtol=CHARLIE_RTOL)


# ---- the lobe textures of a glTF asset (raster) -----------------------------------------------------

def _quad(tmp_path, name, ext: dict, images=(), sky: bool = False, **kw):
    mat = {"pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.1, 0.1, 1.0], "metallicFactor": 0.0,
                                    "roughnessFactor": 0.6}}
    if ext:
        mat["extensions"] = ext
    asset = quad_asset(tmp_path / f"{name}.gltf", mat, images, **kw)
    scene = load_scene(str(quad_scene(tmp_path, asset, env="[0.5, 0.8, 1.0]", name=f"{name}.toml")))
    if sky:   # a direction-dependent environment (the anisotropic lookup's direction shows)
        scene = replace(scene, environment=load_scene("anisotropy").environment)
    return render_realtime(scene, "default", SMALL, progress=False)


def _grey(v: int, w: int = 8, h: int = 8) -> np.ndarray:
    px = np.full((h, w, 4), 255, np.uint8)
    px[..., :3] = v
    return px


def test_clearcoat_texture_scales_the_factor(tmp_path):
    none = _quad(tmp_path, "none", {})
    fac = _quad(tmp_path, "fac", {lp.CLEARCOAT: {"clearcoatFactor": 1.0, "clearcoatRoughnessFactor": 0.2}})
    black = _quad(tmp_path, "black", {lp.CLEARCOAT: {"clearcoatFactor": 1.0, "clearcoatRoughnessFactor": 0.2,
                                                    "clearcoatTexture": {"index": 0}}}, [(_grey(0), None)])
    white = _quad(tmp_path, "white", {lp.CLEARCOAT: {"clearcoatFactor": 1.0, "clearcoatRoughnessFactor": 0.2,
                                                    "clearcoatTexture": {"index": 0}}}, [(_grey(255), None)])
    m = none.channels["coverage"] == 1
    assert m.mean() > 0.3 and "lobes" in fac.meta and "lobes" not in none.meta
    assert np.abs(fac.rgb[m] - none.rgb[m]).max() > 1e-3          # the coat shows
    assert np.array_equal(black.rgb[m], none.rgb[m])              # texture 0: no coat, bit for bit
    assert np.allclose(white.rgb[m], fac.rgb[m], rtol=TEXTURE_ONE_RTOL, atol=0)


def test_a_lobe_texture_reads_its_texcoord_and_transform(tmp_path):
    """A sheen colour texture white on its left half and black on its right, on TEXCOORD_1, through
    KHR_texture_transform scale (0.25, 1) (u in [0, 0.25]: the white half only; clamped, no wrap to
    the black edge): the image is the untextured sheen's; without the transform, the quad's right
    half is the unsheened base."""
    px = np.full((1, 8, 4), 255, np.uint8)
    px[:, 4:, :3] = 0
    clamp = {"wrapS": 33071, "wrapT": 33071}
    sheen = {"sheenColorFactor": [1.0, 1.0, 1.0], "sheenRoughnessFactor": 0.5}
    fac = _quad(tmp_path, "fac", {lp.SHEEN: sheen})
    none = _quad(tmp_path, "none", {})
    xf = _quad(tmp_path, "xf", {lp.SHEEN: {**sheen, "sheenColorTexture": {
        "index": 0, "texCoord": 1, "extensions": {"KHR_texture_transform": {"scale": [0.25, 1.0]}}}}}, [(px, clamp)],
        uv0=np.zeros((4, 2), np.float32) + 0.9, uv1=QUAD_UV)   # TEXCOORD_0 on the black half: read set 1
    half = _quad(tmp_path, "half", {lp.SHEEN: {**sheen, "sheenColorTexture": {"index": 0}}}, [(px, clamp)])
    m = none.channels["coverage"] == 1
    assert np.allclose(xf.rgb[m], fac.rgb[m], rtol=TEXTURE_ONE_RTOL, atol=0)
    W = m.shape[1]
    right = m & (np.arange(W)[None, :] > W * 0.7)
    left = m & (np.arange(W)[None, :] < W * 0.3)
    assert np.array_equal(half.rgb[right], none.rgb[right])      # black texels: no sheen
    assert np.allclose(half.rgb[left], fac.rgb[left], rtol=TEXTURE_ONE_RTOL, atol=0)


def _channels(zero: str, w: int = 8, h: int = 8) -> np.ndarray:
    """An RGBA8 image whose channels are 255 but ``zero`` (one of RGBA), which is 0."""
    px = np.full((h, w, 4), 255, np.uint8)
    px[..., "RGBA".index(zero)] = 0
    return px


@pytest.mark.parametrize("ext,fields,slot,channel", [
    (lp.SHEEN, {"sheenColorFactor": [1.0, 0.8, 0.6], "sheenRoughnessFactor": 0.5}, "sheenColorTexture", None),
    (lp.ANISOTROPY, {"anisotropyStrength": 1.0, "anisotropyRotation": 0.4}, "anisotropyTexture", "B"),
    (lp.IRIDESCENCE, {"iridescenceFactor": 1.0}, "iridescenceTexture", "R"),
    (lp.IRIDESCENCE, {"iridescenceFactor": 1.0, "iridescenceThicknessMinimum": 0.0}, "iridescenceThicknessTexture", "G"),
    (lp.CLEARCOAT, {"clearcoatFactor": 1.0}, "clearcoatTexture", "R"),
], ids=["sheenColor", "anisotropy.B", "iridescence.R", "iridescenceThickness.G", "clearcoat.R"])
def test_a_lobe_texture_reads_its_channel(tmp_path, ext, fields, slot, channel):
    """A texture whose read channel is 0 and every other channel 1 turns the lobe off: the quad is the
    one without the extension, bit for bit (a lobe at zero strength, factor or film thickness is skipped;
    reading any other channel would leave it on). sheenColor reads RGB: all three at 0, alpha 1."""
    px = np.zeros((8, 8, 4), np.uint8) if channel is None else _channels(channel)
    if channel is None:
        px[..., 3] = 255
    sky = ext == lp.ANISOTROPY
    none = _quad(tmp_path, "none", {}, sky=sky)
    on = _quad(tmp_path, "on", {ext: fields}, sky=sky)
    off = _quad(tmp_path, "off", {ext: {**fields, slot: {"index": 0}}}, [(px, None)], sky=sky)
    m = none.channels["coverage"] == 1
    assert "lobes" in on.meta and "lobes" in off.meta
    assert np.abs(on.rgb[m] - none.rgb[m]).max() > 1e-4                # the lobe shows without its texture
    assert np.array_equal(off.rgb[m], none.rgb[m])


# ---- the shared Khronos extension assets (skip cleanly where ../shared is absent) --------------------

KHRONOS = Path(__file__).resolve().parents[2] / "shared" / "assets" / "khronos"


@pytest.mark.slow
@pytest.mark.parametrize("name,define", [("ClearCoatTest", "LOBE_CLEARCOAT"), ("SheenCloth", "LOBE_SHEEN"),
                                         ("SpecularTest", "LOBE_SPECULAR"), ("AnisotropyStrengthTest", "LOBE_ANISOTROPY"),
                                         ("AnisotropyRotationTest", "LOBE_ANISOTROPY"),
                                         ("IridescenceSuzanne", "LOBE_IRIDESCENCE")])
def test_a_khronos_extension_asset_renders_its_lobe(name, define):
    p = KHRONOS / name / f"{name}.gltf"
    if not p.is_file():
        pytest.skip(f"{p} is absent (the real assets live in ../shared/assets)")
    scene = load_scene(str(p), AssetOptions(size=(48, 48)))
    img = render_realtime(scene, "default", SMALL, progress=False)
    assert img.meta["pipeline"] == "raster" and define in json.loads(img.meta["lobes"])
    assert np.all(np.isfinite(img.rgb)) and (img.channels["coverage"] > 0).mean() > 0.05

