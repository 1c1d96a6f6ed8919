"""GLSL terms (realtime/shaders) against their numpy twins of the same name (pbrcheck.brdf,
pbrcheck.sampling, pbrcheck.environment), on grids including roughness 0 and 1 and cosines -> 0."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from pbrcheck import brdf, registry, sampling
from pbrcheck.environment import EnvMap
from realtime.gl import SHADER_DIR
from realtime.glsl_harness import run_glsl

pytestmark = pytest.mark.filterwarnings("ignore::RuntimeWarning")

# float32 arithmetic against float64: ~1e-7 relative per operation, a few dozen operations, and
# exp/pow/sqrt of llvmpipe within a few ulp: 2e-5 relative.
RTOL_F32 = 2e-5
# Values that are 0 in exact arithmetic come out as float32 rounding noise of O(1) terms.
ATOL_F32 = 1e-6
# numpy's D_GGX forms d = (n.h)^2 (alpha^2 - 1) + 1, which cancels catastrophically for alpha^2 <
# 1e-8 near n.h = 1 (float64 keeps ~16 - 8 digits); the GLSL form is exact there. Below ALPHA_SMALL
# the two agree to the float64 cancellation error only.
ALPHA_SMALL = 1e-4
RTOL_CANCEL = 1e-2
EXP_ULP = 5e-6
LOG_ABS_ERR = 6e-8  # one ulp of 1.0
# Directions built as sqrt(1 - x^2) with x -> 1 keep only sqrt(2 ulp) = 3.5e-4 in float32.
SQRT_ULP_DIR = 5e-4
# llvmpipe's float32 atan/acos: acos near +-1 alone loses sqrt(2 ulp) = 3.5e-4 rad; a direction
# error of TRIG_RAD moves a bilinear lookup by at most TRIG_RAD x the map's gradient per radian.
TRIG_RAD = 4e-4

COS = np.array([0.0, 1e-6, 1e-4, 0.01, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99, 0.9999, 1.0])
ROUGH = np.array([0.0, 1e-3, 0.01, 0.05, 0.1, 0.25, 0.5, 0.75, 1.0])


def f32(x):
    return np.asarray(x, np.float32).astype(np.float64)


def grid2(a, b):
    A, B = np.meshgrid(f32(a), f32(b), indexing="ij")
    return A.ravel(), B.ravel()


def close(glsl, ref, rtol=RTOL_F32, atol=ATOL_F32):
    glsl = np.asarray(glsl, np.float64)
    ref = np.asarray(ref, np.float64)
    assert np.all(np.isfinite(glsl)), "GLSL produced NaN/Inf"
    err = np.abs(glsl - ref)
    bad = err > atol + rtol * np.abs(ref)
    assert not bad.any(), f"{bad.sum()} mismatches, worst glsl={glsl[bad][:3]} ref={ref[bad][:3]}"


# The term twins loop over the registry's entries (tests/test_registry.py checks every entry's three
# implementations exist and that these loops cover them).
@pytest.mark.parametrize("entry", list(registry.NDFS), ids=registry.NDFS.names)
def test_ndf_twins(entry):
    c, r = grid2(COS, ROUGH)
    alpha = f32(brdf.alpha_from_roughness(r))
    name = entry.term.glsl
    g = run_glsl(f"{name}(x0, x1)", c, alpha)
    ref = entry.term.eval(c, alpha)
    small = alpha < ALPHA_SMALL
    # exp(E) / pow(x, n) amplify float32 rounding by the exponent's size |E| (its condition number):
    # relative error ~ EXP_ULP |E|: llvmpipe's exp2/log2 measured good to ~3e-6.
    a2 = alpha ** 2
    if name == "D_Beckmann":
        E = (1 - c * c) / np.maximum(c * c, 1e-8) / a2
    elif name == "D_BlinnPhong":
        E = brdf.blinn_phong_exponent(alpha) * np.abs(np.log(np.maximum(c, 1e-30)))
    else:
        E = np.zeros_like(c)
    tol = 1e-4 + EXP_ULP * np.abs(E)
    if name == "D_BlinnPhong":
        # pow(x, n) = exp2(n log2 x): log2 near x = 1 carries an absolute error ~LOG_ABS_ERR, times n.
        tol = tol + LOG_ABS_ERR * brdf.blinn_phong_exponent(alpha) * (c < 1)
    close(g[~small], ref[~small], rtol=tol[~small])
    close(g[small], ref[small], rtol=np.maximum(RTOL_CANCEL, tol[small]))


@pytest.mark.parametrize("name", ["G1_SmithGGX", "Lambda_GGX"])
def test_g1_twins(name):
    c, r = grid2(COS, ROUGH)
    alpha = f32(brdf.alpha_from_roughness(r))
    ok = c > 0 if name == "Lambda_GGX" else np.ones_like(c, bool)  # Lambda at c = 0 is 1/COS_EPS-sized
    close(run_glsl(f"{name}(x0, x1)", c, alpha)[ok], getattr(brdf, name)(c, alpha)[ok], rtol=1e-4)


@pytest.mark.parametrize("entry", list(registry.GEOMETRIES), ids=registry.GEOMETRIES.names)
def test_g2_twins(entry):
    """Each G term at its width (alpha, or Schlick's k) of every roughness of the grid."""
    v, l = grid2(COS, COS)
    for r in ROUGH:
        w = float(np.float32(entry.term.width(r)))
        close(run_glsl(f"{entry.term.glsl}(x0, x1, x2)", v, l, w), entry.term.eval(v, l, w))


@pytest.mark.parametrize("entry", list(registry.FRESNELS), ids=registry.FRESNELS.names)
def test_fresnel_twins(entry):
    c, F0 = grid2(COS, np.linspace(0.0, 1.0, 6))
    close(run_glsl(f"{entry.term.glsl}(x0, vec3(x1)).x", c, F0), entry.term.eval(c, F0))


def test_lambda_beckmann_twins():
    """Beckmann's Lambda (GLSL: erfcx by Numerical Recipes' fit; numpy: exact erfc): relative 1e-4
    where Lambda is not negligible, absolute 1e-6 where it vanishes (near-normal directions)."""
    c, r = grid2(COS, ROUGH)
    alpha = f32(brdf.alpha_from_roughness(r))
    ok = c > 0  # Lambda at c = 0 is 1/COS_EPS-sized
    close(run_glsl("Lambda_Beckmann(x0, x1)", c, alpha)[ok], brdf.Lambda_Beckmann(c, alpha)[ok], rtol=1e-4,
          atol=1e-6)
    z = f32(np.concatenate([np.linspace(0.0, 8.0, 33), [20.0, 1e3, 1e6]]))
    close(run_glsl("erfcx_nr(x0)", z), brdf.erfcx_nr(z), rtol=1e-5)


def test_the_one_erfc_fit():
    """brdf.glsl's erfcx_nr holds pbrcheck.terms.ERFCC_COEFFS, the fit numpy and Dr.Jit evaluate
    (terms.erfcx_fit), in the same Horner order; numpy's is within the fit's 1.2e-7 of math.erfc."""
    from pbrcheck import terms
    body = re.search(r"float erfcx_nr\(float z\) \{(.*?)\n\}", (SHADER_DIR / "brdf.glsl").read_text(), re.S).group(1)
    coeffs = [float(x) for x in re.findall(r"-?\d+\.\d+", body.split("float p =")[1].split(";")[0])]
    assert tuple(coeffs) == terms.ERFCC_COEFFS
    z = np.linspace(0.0, 6.0, 61)
    want = np.array([math.exp(x * x) * math.erfc(x) for x in z])
    np.testing.assert_allclose(terms.erfcx_nr(z), want, rtol=1.2e-7)


@pytest.mark.parametrize("kname", ["k_schlick_ibl", "k_schlick_direct"])
def test_schlick_twins(kname):
    r = f32(ROUGH)
    close(run_glsl(f"{kname}(x0)", r), getattr(brdf, kname)(r))
    v, l = grid2(COS, COS)
    for rr in ROUGH:
        k = float(np.float32(getattr(brdf, kname)(rr)))
        close(run_glsl("G_SchlickGGX(x0, x1, x2)", v, l, k), brdf.G_SchlickGGX(v, l, k))
        close(run_glsl("G1_SchlickGGX(x0, x1)", v, k), brdf.G1_SchlickGGX(v, k))


def test_small_terms():
    r = f32(ROUGH)
    close(run_glsl("alpha_from_roughness(x0)", r), brdf.alpha_from_roughness(r))
    close(run_glsl("blinn_phong_exponent(x0)", f32(brdf.alpha_from_roughness(r))),
          brdf.blinn_phong_exponent(f32(brdf.alpha_from_roughness(r))), rtol=1e-4)
    c = f32(COS)
    for F0 in (0.0, 0.04, 0.5, 1.0):
        close(run_glsl("F_Schlick(x0, x1, 1.0)", c, F0), brdf.F_Schlick(c, F0))
    close(run_glsl("Fd_Lambert()", c), np.full_like(c, brdf.Fd_Lambert()))


def test_env_brdf_approx_twin():
    c, r = grid2(COS, ROUGH)
    close(run_glsl("EnvBRDFApprox(x0, x1)", c, r, components=2), brdf.EnvBRDFApprox(c, r), rtol=1e-4, atol=1e-6)


def test_brdf_eval_twin():
    rng = np.random.default_rng(1)
    n = np.array([0.0, 0.0, 1.0])
    v = rng.normal(size=(400, 3))
    l = rng.normal(size=(400, 3))
    v[:, 2] = np.abs(v[:, 2])
    l[:, 2] = np.abs(l[:, 2])
    v[:5, 2] = 1e-4  # grazing
    v, l = f32(v / np.linalg.norm(v, axis=1, keepdims=True)), f32(l / np.linalg.norm(l, axis=1, keepdims=True))
    rough = f32(np.resize(ROUGH[1:], 400))  # roughness 0's delta peak is a point: left to the D tests
    base = (0.9, 0.6, 0.3)
    for metallic in (0.0, 1.0):
        g = run_glsl(f"brdf_eval(vec3(0,0,1), vec3(x0,x1,x2), vec3(x3,x4,x5), vec3{base}, {metallic:.1f}, x6, 0.04)",
                     v[:, 0], v[:, 1], v[:, 2], l[:, 0], l[:, 1], l[:, 2], rough, components=3)
        ref = brdf.brdf_eval(n, v, l, base, metallic, rough, 0.04)
        close(g, ref, rtol=2e-4, atol=1e-5)


def test_sampling_twins():
    rng = np.random.default_rng(2)
    u = f32(rng.random((256, 2)))
    u[0] = (0.0, 0.0)
    u[1] = (0.999, 0.999)
    for a in (1e-7, 1e-3, 0.1, 0.5, 1.0):
        for name in ("sample_GGX", "sample_Beckmann", "sample_BlinnPhong"):
            g = run_glsl(f"{name}(vec2(x0, x1), x2)", u[:, 0], u[:, 1], a, components=3)
            close(g, getattr(sampling, name)(u, a), rtol=1e-4, atol=SQRT_ULP_DIR)
        v = f32(np.array([0.6, 0.0, 0.8]))
        g = run_glsl("sample_GGX_VNDF(vec2(x0, x1), vec3(0.6, 0.0, 0.8), x2)", u[:, 0], u[:, 1], a, components=3)
        close(g, sampling.sample_GGX_VNDF(u, v, a), rtol=1e-4, atol=SQRT_ULP_DIR)
    close(run_glsl("sample_cosine(vec2(x0, x1))", u[:, 0], u[:, 1], components=3), sampling.sample_cosine(u),
          rtol=1e-4, atol=2e-5)


def test_hammersley_twin():
    i = np.arange(1024)
    g = run_glsl("hammersley(uint(x0), 1024u)", i, components=2)
    close(g, sampling.hammersley(i, 1024), rtol=0, atol=1e-7)
    # the radical inverse is a permutation of the 1024 strata
    assert len(np.unique(np.floor(sampling.hammersley(i, 1024)[:, 1] * 1024))) == 1024


def test_env_radiance_twin():
    """env.glsl's env_radiance is EnvMap.radiance (Mitsuba's convention), rotation and scale included."""
    from realtime.render import env_texture

    rng = np.random.default_rng(3)
    env = EnvMap(rng.random((9, 16, 3)).astype(np.float32), scale=2.0, rotation=33.0)
    d = rng.normal(size=(500, 3))
    d[:4] = [[0, 1, 0], [0, -1, 0], [0, 0, -1], [1e-9, 0.3, -1]]  # poles and the u seam
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    tex = env_texture(env)
    g = run_glsl("env_radiance(vec3(x0, x1, x2))", d[:, 0], d[:, 1], d[:, 2], components=3,
                 uniforms={"env_size": (env.width, env.height), "env_scale": 2.0,
                           "env_rot0": tuple(env.to_world()[:, 0]), "env_rot1": tuple(env.to_world()[:, 1]),
                           "env_rot2": tuple(env.to_world()[:, 2])},
                 textures={"env_equirect": tex})
    jump = max(np.abs(np.diff(env.data, axis=0)).max(), np.abs(np.diff(env.data, axis=1)).max())
    grad = env.scale * jump * max(env.width / (2 * np.pi), (env.height - 1) / np.pi)
    close(g, env.radiance(d), rtol=0, atol=TRIG_RAD * grad)



def test_spot_attenuation_twin():
    """glTF's spot attenuation (lights.glsl) against pbrcheck.lights.spot_attenuation: cosines at the
    inner and the outer cone, beyond both, between, and cones whose span hits the spec's 0.001 floor."""
    from pbrcheck.lights import spot_attenuation
    cones = [(0.0, np.pi / 4), (0.2, 0.5), (0.0, np.pi / 2), (np.pi / 2 - 0.01, np.pi / 2), (0.3, 0.3005)]
    for inner, outer in cones:
        ci, co = f32(np.cos(inner)), f32(np.cos(outer))
        cd = f32(np.concatenate([[-1.0, 0.0, co, ci, 1.0, co - 1e-3, ci + 1e-3, np.nextafter(np.float32(co), 2)],
                                 np.linspace(co, ci, 9)]))
        got = run_glsl("spot_attenuation(x0, x1, x2)", cd, co, ci)
        ref = spot_attenuation(cd, co, ci)
        # cd scale + offset cancels: float32 rounding of ~scale ulp(1) (scale <= 1 / 0.001)
        scale = 1.0 / max(1e-3, ci - co)
        close(got, ref, atol=ATOL_F32 * scale)
        assert ref[cd <= co].max() == 0.0
        if ci - co >= 1e-3:  # a narrower span is floored: the falloff then reaches 1 past the inner cone
            assert ref[cd >= ci].min() == 1.0
