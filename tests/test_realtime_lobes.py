"""The glTF PBR extensions' real-time approximations (realtime/shaders/lobes_*.glsl) against their numpy
twins of the same name (realtime/lobes.py) on grids with the extremes (n.v -> 0 and 1, roughness 0
and 1, strength 0 and 1, film thickness 0), each variant at its neutral parameters reducing to the
base, every registry member through its switch's GLSL dispatch, and the sheen LUT's texels against an
independent quadrature."""

from __future__ import annotations

import re

import numpy as np
import pytest

from realtime import lobe_luts, lobes
from realtime import registry as rt_registry
from realtime.gl import SHADER_DIR
from realtime.glsl_harness import run_glsl

pytestmark = pytest.mark.filterwarnings("ignore::RuntimeWarning")

# float32 arithmetic against float64: a few dozen operations and llvmpipe's exp/pow/sqrt within a
# few ulp (as tests/test_realtime_glsl.py).
RTOL_F32 = 2e-5
ATOL_F32 = 1e-6
# exp / pow amplify float32 rounding by the exponent's size |E|: relative error ~ EXP_ULP |E|
# (llvmpipe's exp2/log2 measured good to ~3e-6, tests/test_realtime_glsl.py).
EXP_ULP = 5e-6
# Directions: a normalize of float32 vectors and a cross product or two: ~1e-6 per component;
# reflect about a bent normal doubles it. Grazing views (sqrt(1 - x^2), x -> 1) keep sqrt(2 ulp).
DIR_ATOL = 5e-4
# The thin film's Fourier sensitivity: cos of arguments up to ~120 rad loses 120 x 6e-8 = 7e-6 of
# its phase in float32, times amplitudes <= ~3, summed over 2 orders and 3 channels.
IRI_ATOL = 1e-4
# The sheen LUT (SHEEN_LUT_SIZE x SHEEN_LUT_SAMPLES Charlie-sampled Hammersley points, texel centres)
# against the midpoint quadrature of lobes.sheen_albedo_quadrature: the sampler's error at 4096 points
# measured <= 0.4 % at moderate roughness; the 512 x 256 quadrature is good to ~1e-4 there.
SHEEN_LUT_RTOL = 1e-2
# At low sheen roughness away from grazing the albedo is ~1e-3 (the Charlie spike sin^(1/alpha) points
# its half vectors at the horizon): there both estimates agree to ~1e-4 absolute (measured 7e-5 at
# n.v 0.52, roughness 0.11), which a relative tolerance alone would not grant.
SHEEN_LUT_ATOL = 2e-4
# rgba16f against rgba32f: half precision keeps 11 significant bits (4.9e-4 relative).
F16_RTOL = 1e-3

COS = np.array([0.0, 1e-6, 1e-4, 0.01, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99, 0.9999, 1.0])
ROUGH = np.array([0.0, 1e-3, 0.01, 0.05, 0.1, 0.24, 0.25, 0.26, 0.5, 0.75, 1.0])


def f32(x):
    return np.asarray(x, np.float32).astype(np.float64)


def grid(*axes):
    return [g.ravel() for g in np.meshgrid(*[f32(a) for a in axes], indexing="ij")]


def close(glsl, ref, rtol=RTOL_F32, atol=ATOL_F32):
    glsl = np.asarray(glsl, np.float64)
    ref = np.asarray(ref, np.float64)
    assert glsl.shape == ref.shape, (glsl.shape, ref.shape)
    assert glsl.size > 0
    assert np.all(np.isfinite(glsl)), "GLSL produced NaN/Inf"
    err = np.abs(glsl - ref)
    bad = err > atol + rtol * np.abs(ref)
    assert not bad.any(), f"{bad.sum()} mismatches, worst glsl={glsl[bad][:3]} ref={ref[bad][:3]}"


# ---- the switches ----------------------------------------------------------------------------------

@pytest.mark.parametrize("define", list(rt_registry.LOBE_REGISTRIES))
def test_lobe_switch_constants_are_the_registry_members(define):
    """Each lobe file's #define constants are its registry's members by index (Registry.constants),
    its default member is the registry's, and each member's role functions exist in that file."""
    reg, include, default, roles = rt_registry.LOBE_REGISTRIES[define]
    text = (SHADER_DIR / include).read_text()
    found = {m.group(1): int(m.group(2)) for m in re.finditer(rf"#define ({define}_[A-Z0-9_]+) (\d+)", text)}
    assert found == reg.constants()
    assert re.search(rf"#ifndef {define}\n#define {define} {reg.constant(default)}\n", text)
    for e in reg:
        for name, r in e.roles.items():
            assert name in roles
            assert re.search(rf"\b{r.glsl}\(", text), r.glsl
            assert r.numpy is getattr(lobes, r.glsl)


# ---- coat ------------------------------------------------------------------------------------------

COAT = np.array([0.0, 0.5, 1.0])
F0S = np.array([0.0, 0.04, 0.5, 1.0])


def test_coat_small_terms():
    ior = f32([1.0, 1.3, 1.5, 2.0, 3.0])
    close(run_glsl("coat_f0(x0)", ior), lobes.coat_f0(ior))
    assert lobes.coat_f0(1.5) == pytest.approx(0.04)
    c, f0 = grid(COS, F0S)
    close(run_glsl("coat_fresnel(x0, x1)", c, f0), lobes.coat_fresnel(c, f0))


@pytest.mark.parametrize("entry", list(rt_registry.COAT_ATTENUATIONS), ids=rt_registry.COAT_ATTENUATIONS.names)
def test_coat_attenuation_twins(entry):
    nv, vh, coat, f0 = grid(COS, COS[::3], COAT, F0S)
    fn = entry.roles["coat_attenuation"]
    want = fn.numpy(nv, vh, coat, f0)
    close(run_glsl(f"{fn.glsl}(x0, x1, x2, x3)", nv, vh, coat, f0), want)
    close(run_glsl("coat_attenuation(x0, x1, x2, x3)", nv, vh, coat, f0,
                   defines=rt_registry.COAT_ATTENUATIONS.select(entry.name)), want)
    # neutral: no coat leaves the base as it is
    assert np.all(want[coat == 0] == 1.0)
    # a full coat at grazing (its Fresnel 1) removes the base entirely
    key = vh if entry.name == "voh" else nv
    assert np.allclose(want[(coat == 1) & (key == 0)], 0.0)


@pytest.mark.parametrize("entry", list(rt_registry.COAT_IBLS), ids=rt_registry.COAT_IBLS.names)
def test_coat_ibl_weight_twins(entry):
    nv, r, coat, f0, A = grid(COS, ROUGH[::2], COAT, F0S[:3], [0.0, 0.3, 1.0])
    B = f32(0.05 + 0.1 * A)
    fn = entry.roles["coat_ibl_weight"]
    want = fn.numpy(nv, r, coat, f0, A, B)
    close(run_glsl(f"{fn.glsl}(x0, x1, x2, x3, x4, x5)", nv, r, coat, f0, A, B), want, rtol=1e-4, atol=1e-6)
    close(run_glsl("coat_ibl_weight(x0, x1, x2, x3, x4, x5)", nv, r, coat, f0, A, B,
                   defines=rt_registry.COAT_IBLS.select(entry.name)), want, rtol=1e-4, atol=1e-6)
    assert np.all(want[coat == 0] == 0.0)  # neutral: no coat lobe
    assert want[coat == 1].max() > 0.5  # and a real one at grazing


def test_coat_forms_agree_where_they_should():
    """At roughness 0 the DFG LUT holds a mirror's (A, B) = (1 - Fc, Fc), Fc = (1 - n.v)^5, so the split sum
    F0 A + B (splitsum) is Schlick's Fresnel: Filament's Fc-only weight is then exact. The Sample Viewer's k_S
    (Fdez-Aguera's roughness-dependent F0) is already Schlick's at roughness 0, and k_S A + B applies the
    grazing term twice: its smooth coat is brighter than Schlick's between normal and grazing incidence
    (a finding, docs/realtime.md). The two attenuations agree where v.h = n.v."""
    nv = f32(COS)
    fc = (1 - nv) ** 5
    A, B = 1 - fc, fc
    fil = lobes.coat_ibl_weight_filament(nv, 0.0, 1.0, 0.04, A, B)
    np.testing.assert_allclose(lobes.coat_ibl_weight_splitsum(nv, 0.0, 1.0, 0.04, A, B), fil, rtol=1e-12)
    sv = lobes.coat_ibl_weight_sample_viewer(nv, 0.0, 1.0, 0.04, A, B)
    np.testing.assert_allclose(sv - fil, (0.96 * fc) * (1 - fc), atol=1e-12)
    assert (sv - fil).max() > 0.2  # at n.v = 0.1: 0.84 against Schlick's 0.61
    np.testing.assert_allclose(lobes.coat_attenuation_nov(nv, nv, 0.7, 0.04), lobes.coat_attenuation_voh(nv, nv, 0.7, 0.04))


# ---- sheen -----------------------------------------------------------------------------------------

def test_charlie_d_twin():
    c, r = grid(COS, ROUGH)
    a = f32(r * r)
    g = run_glsl("D_Charlie(x0, x1)", c, a)
    want = lobes.D_Charlie(c, a)
    aa = np.maximum(a, lobes.SHEEN_MIN_ALPHA)
    E = 0.5 / aa * np.abs(np.log(np.maximum((1 - c) * (1 + c), 1e-30)))
    close(g, want, rtol=1e-4 + EXP_ULP * E, atol=1e-6)
    # normalization: int D (n.h) dh = 1 over the hemisphere (midpoint rule in theta)
    th = (np.arange(20000) + 0.5) * (np.pi / 2 / 20000)
    for alpha in (0.01, 0.25, 1.0):
        total = np.sum(lobes.D_Charlie(np.cos(th), alpha) * np.cos(th) * np.sin(th)) * 2 * np.pi * (np.pi / 2 / 20000)
        assert total == pytest.approx(1.0, rel=1e-4)


def test_charlie_visibility_twins():
    c, r = grid(COS, ROUGH)
    a = f32(r * r)
    close(run_glsl("charlie_L(x0, x1)", c, a), lobes._charlie_L(c, a), rtol=1e-5, atol=2e-5)
    close(run_glsl("charlie_lambda(x0, x1)", c, a), lobes.charlie_lambda(c, a), rtol=1e-4)
    v, l, r2 = grid(COS, COS, ROUGH[::2])
    a2 = f32(r2 * r2)
    ok = (v > 0) & (l > 0)  # at a cosine 0 both sides are the guard's 1 / COS_EPS
    close(run_glsl("V_Charlie(x0, x1, x2)", v, l, a2)[ok], lobes.V_Charlie(v, l, a2)[ok], rtol=2e-4)
    close(run_glsl("V_Neubelt(x0, x1)", v, l), lobes.V_Neubelt(v, l), rtol=1e-5)
    # Lambda's two branches meet at cos = 0.5
    for alpha in (0.001, 0.3, 1.0):
        assert lobes.charlie_lambda(0.5 - 1e-9, alpha) == pytest.approx(lobes.charlie_lambda(0.5, alpha), rel=1e-6)


def test_charlie_sampler_twin_and_density():
    rng = np.random.default_rng(3)
    u = f32(rng.random((256, 2)))
    u[0], u[1] = (0.0, 0.0), (0.999, 0.999)
    for r in (0.0, 0.05, 0.5, 1.0):
        a = float(np.float32(r * r))
        g = run_glsl("sample_Charlie(vec2(x0, x1), x2)", u[:, 0], u[:, 1], a, components=3)
        close(g, lobes.sample_Charlie(u, a), rtol=1e-4, atol=DIR_ATOL)
    # the sampled sin theta's CDF is the density's: P(sin < s) = s^(2 + 1/alpha)
    n = 4096
    uu = np.stack([np.zeros(n), (np.arange(n) + 0.5) / n], axis=-1)
    for alpha in (0.04, 0.25, 1.0):
        s = np.linalg.norm(lobes.sample_Charlie(uu, alpha)[:, :2], axis=-1)
        for s0 in (0.3, 0.6, 0.9):
            assert np.mean(s < s0) == pytest.approx(s0 ** (2 + 1 / alpha), abs=1.0 / n)
    c, r = grid(COS, ROUGH[3:])
    a = f32(r * r)
    close(run_glsl("charlie_prefilter_pdf(x0, x1)", c, a), lobes.charlie_prefilter_pdf(c, a), rtol=2e-3, atol=1e-6)


def test_sheen_dg_fit_twin():
    c, r = grid(COS, ROUGH)
    # exp(a n.v + b) with |a n.v + b| up to ~25: EXP_ULP x 25
    close(run_glsl("sheen_dg_fit(x0, x1)", c, r), lobes.sheen_dg_fit(c, r), rtol=2e-4)


@pytest.mark.parametrize("entry", list(rt_registry.SHEEN_DFGS), ids=rt_registry.SHEEN_DFGS.names)
def test_sheen_dfg_twins(entry):
    c, r, e0 = grid(COS, ROUGH, [0.0, 0.2, 0.9])
    E = np.stack([e0, f32(0.5 * e0 + 0.01), f32(0.25 * e0 + 0.02)], axis=-1)
    fn = entry.roles["sheen_dfg"]
    want = fn.numpy(c, r, E)
    assert want.shape == c.shape
    sel = rt_registry.SHEEN_DFGS.select(entry.name)   # a member's own GLSL (extra["glsl"]) is compiled where selected
    close(run_glsl(f"{fn.glsl}(x0, x1, vec3(x2, x3, x4))", c, r, E[:, 0], E[:, 1], E[:, 2], defines=sel), want, rtol=2e-4)
    close(run_glsl("sheen_dfg(x0, x1, vec3(x2, x3, x4))", c, r, E[:, 0], E[:, 1], E[:, 2], defines=sel), want, rtol=2e-4)


@pytest.mark.parametrize("entry", list(rt_registry.SHEEN_SCALINGS), ids=rt_registry.SHEEN_SCALINGS.names)
def test_sheen_scaling_twins(entry):
    col = f32([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [0.2, 0.9, 0.5], [1.0, 0.0, 0.0]])
    e = f32([0.0, 0.3, 1.0])
    ci, ei = np.meshgrid(np.arange(len(col)), np.arange(len(e)), indexing="ij")
    C, ee = col[ci.ravel()], e[ei.ravel()]
    E = np.stack([ee, 0.8 * ee, 0.6 * ee], axis=-1)
    fn = entry.roles["sheen_scaling"]
    want = fn.numpy(C, E)
    args = (C[:, 0], C[:, 1], C[:, 2], E[:, 0], E[:, 1], E[:, 2])
    close(run_glsl(f"{fn.glsl}(vec3(x0, x1, x2), vec3(x3, x4, x5))", *args), want)
    close(run_glsl("sheen_scaling(vec3(x0, x1, x2), vec3(x3, x4, x5))", *args,
                   defines=rt_registry.SHEEN_SCALINGS.select(entry.name)), want)
    assert np.all(want[np.all(C == 0, axis=-1)] == 1.0)  # neutral: no sheen leaves the base as it is
    assert want.min() < 0.9  # and a white sheen takes energy from it


def test_sheen_lut_against_quadrature_and_its_reader():
    """The sheen LUT's texels (rgba32f) against the midpoint quadrature within SHEEN_LUT_RTOL at a few
    texel centres; GLSL sheen_lut_lookup on it = numpy sheen_lut_lookup on its read-back (the conventions at both
    ends); rgba16f = rgba32f to half precision."""
    n = lobes.SHEEN_LUT_SIZE
    tex = lobe_luts.sheen_lut()
    L = lobe_luts.read_sheen_lut(tex)
    assert L.shape == (n, n, 3)
    for i, j in [(4, 8), (16, 16), (28, 28), (8, 24), (30, 12), (2, 2), (1, 30), (16, 3)]:
        nv, r = (i + 0.5) / n, (j + 0.5) / n
        np.testing.assert_allclose(L[j, i], lobes.sheen_albedo_quadrature(nv, r), rtol=SHEEN_LUT_RTOL,
                                   atol=SHEEN_LUT_ATOL)
    # the conventions differ where they should: the older IBL sampler's alpha = roughness (not squared)
    # makes its smooth sheen far brighter (row 3, n.v 0.52: 0.147 against the spec's 0.0012)
    assert L[3, 16, 2] > 50 * L[3, 16, 0]
    c, r = grid(COS, ROUGH)
    want = lobes.sheen_lut_lookup(L, c, r)
    got = run_glsl("sheen_lut_lookup(x0, x1)", c, r, components=3, textures={"sheen_lut": tex})
    close(got, want, rtol=1e-5, atol=1e-6)
    L16 = lobe_luts.read_sheen_lut(lobe_luts.sheen_lut(fmt="f16"))
    np.testing.assert_allclose(L16, L, rtol=F16_RTOL, atol=1e-6)


# ---- anisotropy ------------------------------------------------------------------------------------

def _frames(k=64, seed=4):
    """Shading frames (n, t, b = n x t) and views v with n.v from 1 (v = n) down to grazing."""
    rng = np.random.default_rng(seed)
    n = rng.normal(size=(k, 3))
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    t = np.cross(n, rng.normal(size=(k, 3)))
    t /= np.linalg.norm(t, axis=-1, keepdims=True)
    b = np.cross(n, t)
    cv = np.resize(np.array([1.0, 0.9999, 0.9, 0.5, 0.1, 1e-3]), k)
    phi = rng.random(k) * 2 * np.pi
    sv = np.sqrt(1 - cv * cv)
    v = cv[:, None] * n + sv[:, None] * (np.cos(phi)[:, None] * t + np.sin(phi)[:, None] * b)
    return f32(n), f32(t), f32(b), f32(v / np.linalg.norm(v, axis=-1, keepdims=True))


def _aniso_args(n, t, b, v, s, r):
    return (n[:, 0], n[:, 1], n[:, 2], t[:, 0], t[:, 1], t[:, 2], v[:, 0], v[:, 1])


ANISO_EXPR = "{fn}(vec3(x0, x1, x2), vec3(x3, x4, x5), cross(vec3(x0, x1, x2), vec3(x3, x4, x5)), " \
             "vec3(x6, x7, sqrt(max(1.0 - x6 * x6 - x7 * x7, 0.0)) * SIGN), {s}, {r})"


#: The defines a function of lobes_anisotropy.glsl needs: the fitted member's are compiled only where selected.
ANISO_DEFINES = {**{e.roles["aniso_reflection"].glsl: rt_registry.ANISOTROPY_BENDS.select(e.name)
                    for e in rt_registry.ANISOTROPY_BENDS},
                 "aniso_bent_normal_fitted": rt_registry.ANISOTROPY_BENDS.select("fitted")}


def _run_aniso(fn, n, t, v, s, r):
    """GLSL ``fn`` on frames whose v.z is rebuilt from (v.x, v.y) with v's sign (8 harness inputs)."""
    out = np.zeros_like(n)
    for sign in (1.0, -1.0):
        m = (v[:, 2] >= 0) if sign > 0 else (v[:, 2] < 0)
        if not m.any():
            continue
        expr = ANISO_EXPR.format(fn=fn, s=f"{s:.6f}", r=f"{r:.6f}").replace("SIGN", f"{sign:.1f}")
        out[m] = run_glsl(expr, n[m, 0], n[m, 1], n[m, 2], t[m, 0], t[m, 1], t[m, 2], v[m, 0], v[m, 1], components=3,
                          defines=ANISO_DEFINES.get(fn))
    return out


ANISO_FUNCS = ["aniso_bent_normal_sample_viewer", "aniso_bent_normal_threejs", "aniso_bent_normal_filament",
               "aniso_bent_normal_babylon", "aniso_bent_normal_fitted"]


@pytest.mark.parametrize("fn", ANISO_FUNCS + [e.roles["aniso_reflection"].glsl for e in rt_registry.ANISOTROPY_BENDS])
def test_anisotropy_twins(fn):
    n, t, b, v = _frames()
    v = f32(np.concatenate([v[:, :2], np.sign(v[:, 2:]) * np.sqrt(np.maximum(1 - v[:, 0:1] ** 2 - v[:, 1:2] ** 2, 0))], -1))
    for s in (0.0, 0.5, 1.0, -0.5):
        if s < 0 and ("sample_viewer" in fn or "threejs" in fn or "fitted" in fn):
            continue  # the strength of KHR_materials_anisotropy is in [0, 1]; only Filament / Babylon sign it
        for r in (0.0, 0.5, 1.0):
            g = _run_aniso(fn, n, t, v, s, r)
            want = getattr(lobes, fn)(n, t, np.cross(n, t), v, np.full(len(n), s), np.full(len(n), r))
            close(g, want, rtol=0, atol=DIR_ATOL)


@pytest.mark.parametrize("entry", list(rt_registry.ANISOTROPY_BENDS), ids=rt_registry.ANISOTROPY_BENDS.names)
def test_anisotropy_neutral_and_dispatch(entry):
    """Strength 0 is the isotropic lookup: reflect(-v, n) (three.js: its own isotropic lean); the
    dispatch on ANISOTROPY_BEND selects the member; strength 1 bends (the lookup moves)."""
    n, t, b, v = _frames(seed=5)
    fn = entry.roles["aniso_reflection"]
    k = len(n)
    for r in (0.0, 0.5, 1.0):
        got = fn.numpy(n, t, b, v, np.zeros(k), np.full(k, r))
        if entry.name == "threejs":
            base = lobes.threejs_reflection(n, v, np.full(k, r))
        else:
            base = 2 * np.sum(v * n, -1, keepdims=True) * n - v
        # the frames are float32-rounded (|n| = 1 +- 1e-7): normalizations move them by that much
        np.testing.assert_allclose(got, base, atol=1e-6)
    moved = np.linalg.norm(fn.numpy(n, t, b, v, np.ones(k), np.full(k, 0.5)) - fn.numpy(n, t, b, v, np.zeros(k), np.full(k, 0.5)), axis=-1)
    assert moved.max() > 0.1
    m = v[:, 2] >= 0
    expr = "aniso_reflection(vec3(x0, x1, x2), vec3(x3, x4, x5), cross(vec3(x0, x1, x2), vec3(x3, x4, x5)), " \
           "vec3(x6, x7, sqrt(max(1.0 - x6 * x6 - x7 * x7, 0.0))), 1.0, 0.5)"
    g = run_glsl(expr, n[m, 0], n[m, 1], n[m, 2], t[m, 0], t[m, 1], t[m, 2], v[m, 0], v[m, 1], components=3,
                 defines=rt_registry.ANISOTROPY_BENDS.select(entry.name))
    vv = v[m].copy()
    vv[:, 2] = np.sqrt(np.maximum(1 - vv[:, 0] ** 2 - vv[:, 1] ** 2, 0))
    close(g, fn.numpy(n[m], t[m], b[m], vv, np.ones(m.sum()), np.full(m.sum(), 0.5)), rtol=0, atol=DIR_ATOL)


# ---- the fitted members (pbrcheck fit-lobes: realtime/fitted_lobes.py) ------------------------------

#: Strengths and roughnesses of the fitted bend's weight table: its extremes, its nodes and between them
#: (below its first roughness node 0.2 the table holds its first row).
FIT_S = np.array([0.0, 0.1, 0.25, 0.37, 0.5, 0.9, 1.0])
FIT_R = np.array([0.0, 0.1, 0.2, 0.33, 0.6, 0.71, 0.95, 1.0])


@pytest.mark.parametrize("define, member, reader", [("SHEEN_DFG", "fitted", "sheen_albedo_fitted"),
                                                    ("ANISOTROPY_BEND", "fitted", "aniso_bend_weight_fitted")])
def test_fitted_members_hold_their_glsl_and_compile_it_only_where_selected(define, member, reader):
    """The entry holds the generated module's GLSL as an object (extra["glsl"]), realtime.generated writes
    it into the lobe file's members include under #if on the switch: a program selecting another member
    has no such function (the reader is undefined there), one selecting it has; the reader's GLSL equals
    its numpy twin on a grid with the extremes."""
    from pbrcheck.errors import ShaderCompileError
    from realtime import fitted_lobes
    from realtime.generated import glsl_generated, lobe_members_include

    reg, include, default, _ = rt_registry.LOBE_REGISTRIES[define]
    entry = reg[member]
    held = {"sheen_albedo_fitted": fitted_lobes.SHEEN_ALBEDO_GLSL, "aniso_bend_weight_fitted": fitted_lobes.ANISO_BEND_WEIGHT_GLSL}
    assert entry.extra["glsl"] is held[reader]
    generated = glsl_generated()[lobe_members_include(include)]
    assert f"#if {define} == {reg.constant(member)}\n" + entry.extra["glsl"].strip("\n") + "\n#endif" in generated
    assert f'#include "{lobe_members_include(include)}"' in (SHADER_DIR / include).read_text()
    x, y = grid(COS if define == "SHEEN_DFG" else FIT_S, ROUGH if define == "SHEEN_DFG" else FIT_R)
    with pytest.raises(ShaderCompileError):
        run_glsl(f"{reader}(x0, x1)", x, y, defines=reg.select(default))
    close(run_glsl(f"{reader}(x0, x1)", x, y, defines=reg.select(member)), getattr(fitted_lobes, reader)(x, y), rtol=1e-5)


def test_fitted_bend_twin_between_the_nodes():
    """aniso_reflection_fitted's GLSL = numpy at strengths and roughnesses between the weight table's nodes
    (the twin test above reads the nodes 0, 0.5, 1), and at strength 0 it is the unbent reflection."""
    n, t, b, v = _frames(k=32, seed=7)
    v = f32(np.concatenate([v[:, :2], np.sign(v[:, 2:]) * np.sqrt(np.maximum(1 - v[:, 0:1] ** 2 - v[:, 1:2] ** 2, 0))], -1))
    for s, r in ((0.37, 0.33), (0.9, 0.71), (0.1, 0.1), (1.0, 0.95)):
        k = len(n)
        want = lobes.aniso_reflection_fitted(n, t, np.cross(n, t), v, np.full(k, s), np.full(k, r))
        close(_run_aniso("aniso_reflection_fitted", n, t, v, s, r), want, rtol=0, atol=DIR_ATOL)
    w = lobes.aniso_bend_weight_fitted(0.37, 0.33)
    np.testing.assert_allclose(lobes.aniso_bent_normal_fitted(n, t, b, v, 0.37, 0.33),
                               lobes._normalize(lobes._mix(lobes._mcauley_normal(b, v), n, w)), atol=1e-12)
    assert 0.5 < w < 1.0   # the fitted table's weight there (the Sample Viewer's: 0.44)


# ---- iridescence -----------------------------------------------------------------------------------

def test_iridescence_sensitivity_twin():
    opd, sh = grid([0.0, 50.0, 200.0, 800.0, 2000.0, 8000.0], [0.0, np.pi, 2 * np.pi])
    g = run_glsl("iridescence_sensitivity(x0, vec3(x1, x1 * 0.5, 0.0))", opd, sh, components=3)
    shift = np.stack([sh, sh * 0.5, np.zeros_like(sh)], -1)
    close(g, lobes.iridescence_sensitivity(opd, shift), rtol=1e-4, atol=IRI_ATOL)
    # S(0) with no shift is the fit's equal-energy white: XYZ = (1, 1, 1) to the fit's 0.2 %
    xyz = np.linalg.solve(lobes.XYZ_TO_REC709, lobes.iridescence_sensitivity(0.0, np.zeros(3)))
    np.testing.assert_allclose(xyz, 1.0, atol=2e-3)


@pytest.mark.parametrize("film_ior", [1.0, 1.3, 1.8, 0.8])
def test_iridescence_fresnel_twin(film_ior):
    c, d, f = grid(COS, [0.0, 1e-3, 0.02, 100.0, 400.0, 1200.0], [0.0, 0.04, 0.5, 0.9999, 1.0])
    base = np.stack([f, f32(0.5 * f + 0.02), f32(np.full_like(f, 0.04))], -1)
    g = run_glsl(f"iridescence_fresnel(1.0, {film_ior:.2f}, x0, x1, vec3(x2, x3, x4))", c, d, base[:, 0], base[:, 1],
                 base[:, 2], components=3)
    want = lobes.iridescence_fresnel(1.0, film_ior, c, d, base)
    close(g, want, rtol=1e-4, atol=IRI_ATOL)


def test_iridescence_neutral():
    """Thickness 0 switches iridescence off (iridescence_factor -> 0, so the mix leaves the base's F); the
    zero-thickness film's own Fresnel is the base's at normal incidence but not at grazing (Schlick's
    matched interface keeps F90 = 1: the reason the factor must go to 0); a factor 0 leaves F; total
    internal reflection (a denser outside) reflects everything; a real film colours the reflection."""
    d = f32([0.0, 0.0, 1e-3, 400.0])
    k = f32([1.0, 0.5, 1.0, 0.7])
    want_k = np.where(d > 0, k, 0.0)
    np.testing.assert_array_equal(lobes.iridescence_factor(k, d), want_k)
    close(run_glsl("iridescence_factor(x0, x1)", k, d), want_k, rtol=0, atol=0)
    c, f = grid(COS, [0.0, 0.04, 0.5, 0.95])
    base = np.stack([f, f, f], -1)
    schlick = np.repeat(f[:, None] + (1 - f[:, None]) * (1 - c[:, None]) ** 5, 3, axis=1)
    film0 = lobes.iridescence_fresnel(1.0, 1.3, c, 0.0, base)
    np.testing.assert_allclose(film0[c == 1], schlick[c == 1], atol=1e-15)
    assert np.abs(film0 - schlick)[c == f32(0.3)].max() > 0.3
    close(run_glsl("iridescence_fresnel(1.0, 1.3, x0, 0.0, vec3(x1))", c, f, components=3), film0, rtol=1e-4,
          atol=IRI_ATOL)
    F = np.stack([c, f, 1 - c], -1)
    np.testing.assert_allclose(lobes.iridescence_mix(F, film0, lobes.iridescence_factor(np.ones(len(c)), 0.0)), F)
    close(run_glsl("iridescence_mix(vec3(x0, x1, 0.2), vec3(0.9), iridescence_factor(1.0, 0.0))", c, f, components=3),
          np.stack([c, f, np.full_like(c, 0.2)], -1))
    assert np.all(lobes.iridescence_fresnel(1.5, 1.0, f32([0.01, 0.3]), 300.0, np.full((2, 3), 0.04)) == 1.0)
    rgb = lobes.iridescence_fresnel(1.0, 1.3, 0.9, 400.0, np.full(3, 0.04))
    assert np.ptp(rgb) > 0.02
