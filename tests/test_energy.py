"""Energy compensation of the real-time specular lobe: GLSL terms (realtime/shaders/energy.glsl)
and Dr.Jit terms (reference/energy.py) against their numpy twins (pbrcheck/energy.py), each registry
member's role functions and the dispatch, the Kulla-Conty E_avg table, the white furnace."""

from __future__ import annotations

import numpy as np
import pytest

from pbrcheck import brdf, energy, registry
from realtime import dispatch
from realtime import registry as rt_registry
from realtime.glsl_harness import run_glsl

# float32 GLSL against float64 numpy.
RTOL_F32 = 2e-5
ATOL_F32 = 2e-6
FMS_ATOL_F32 = 2e-5
# The committed E_avg table against a fresh bake (the bake's quadrature is deterministic).
EAVG_ATOL = 1e-6

F0S = np.array([0.0, 0.02, 0.04, 0.3, 0.7, 0.95, 1.0])
ROUGH = np.array([0.0, 1e-4, 0.05, 0.2, 0.5, 0.8, 1.0])
NOV = np.array([1e-4, 0.05, 0.3, 0.7, 1.0])


def _grid():
    F0, r, mu = np.meshgrid(F0S, ROUGH, NOV, indexing="ij")
    F0, r, mu = F0.ravel(), r.ravel(), mu.ravel()
    AB = np.array([brdf.specular_dfg(m, x) for m, x in zip(mu, r)])
    return F0, r, mu, AB[:, 0], AB[:, 1]


GRID = _grid()


def _close(g, ref):
    np.testing.assert_allclose(g, ref, rtol=RTOL_F32, atol=ATOL_F32)


def test_twins_same_grid():
    F0, r, mu, A, B = GRID
    E = A + B
    _close(run_glsl("F_avg_Schlick(vec3(x0)).x", F0), energy.F_avg_Schlick(F0))
    _close(run_glsl("energy_filament(vec3(x0), x1).x", F0, E), energy.energy_filament(F0, E))
    _close(run_glsl("ms_fdez_aguera(vec3(x0), x1, x2).x", F0, A, B), energy.ms_fdez_aguera(F0, A, B))
    Eavg = energy.kc_eavg(r)
    _close(run_glsl("ms_kulla_conty(vec3(x0), x1, x2).x", F0, E, Eavg), energy.ms_kulla_conty(F0, E, Eavg))
    El = E.reshape(-1, NOV.size)[:, ::-1].ravel()  # E at another n.v, same roughness
    # f_ms divides two float32 cancellations (1 - E)(1 - El) / (1 - Eavg) near roughness 0: absolute
    # tolerance FMS_ATOL_F32 there (the values are ~1e-4).
    np.testing.assert_allclose(run_glsl("f_ms_kulla_conty(vec3(x0), x1, x2, x3).x", F0, E, El, Eavg),
                               energy.f_ms_kulla_conty(F0, E, El, Eavg), rtol=RTOL_F32, atol=FMS_ATOL_F32)
    rr = np.linspace(0.0, 1.0, 101)
    _close(run_glsl("kc_eavg(x0)", rr), energy.kc_eavg(rr))


@pytest.mark.parametrize("name", rt_registry.ENERGY_COMPENSATIONS.names)
def test_dispatch_twins(name):
    F0, r, mu, A, B = GRID
    d = rt_registry.ENERGY_COMPENSATIONS.select(name)
    _close(run_glsl("energy_scale(vec3(x0), x1, x2).x", F0, A, B, defines=d), dispatch.energy_scale(F0, A, B, name))
    _close(run_glsl("energy_ms(vec3(x0), x1, x2, x3).x", F0, A, B, r, defines=d),
           dispatch.energy_ms(F0, A, B, r, name))
    fs = np.linspace(0.0, 3.0, F0.size)
    El = (A + B).reshape(-1, NOV.size)[:, ::-1].ravel()
    np.testing.assert_allclose(
        run_glsl("energy_direct(vec3(x4), vec3(x0), x1, x2, x5, x3).x", F0, A, B, r, fs, El, defines=d),
        dispatch.energy_direct(fs, F0, A, B, El, r, name), rtol=RTOL_F32, atol=FMS_ATOL_F32)


ROLE_PAIRS = [(e.name, r) for e in rt_registry.ENERGY_COMPENSATIONS for r in e.roles]


def _role_args(role):
    """The role's arguments on GRID (F0 0..1, roughness 0..1, n.v 1e-4..1): El is E at another n.v
    of the same roughness, f_spec spans 0..3."""
    F0, r, mu, A, B = GRID
    El = (A + B).reshape(-1, NOV.size)[:, ::-1].ravel()
    fs = np.linspace(0.0, 3.0, F0.size)
    return {"energy_scale": (F0, A, B), "energy_ms": (F0, A, B, r),
            "energy_direct": (fs, F0, A, B, El, r)}[role]


def _glsl_call(fn, role):
    vec = {"energy_scale": (0,), "energy_ms": (0,), "energy_direct": (0, 1)}[role]
    n = len(_role_args(role))
    return f"{fn}({', '.join(f'vec3(x{k})' if k in vec else f'x{k}' for k in range(n))}).x"


@pytest.mark.parametrize("name, role", ROLE_PAIRS)
def test_role_twins(name, role):
    """Each member's role function: GLSL and Dr.Jit against the numpy twin of the same name."""
    from reference.variant import ensure_variant
    ensure_variant()
    import mitsuba as mi

    from reference import energy as drjit_energy
    fn = rt_registry.ENERGY_COMPENSATIONS[name].roles[role].glsl
    args = _role_args(role)
    want = getattr(energy, fn)(*args)
    atol = FMS_ATOL_F32 if role == "energy_direct" else ATOL_F32  # f_ms's float32 cancellations
    np.testing.assert_allclose(run_glsl(_glsl_call(fn, role), *args), want, rtol=RTOL_F32, atol=atol)
    got = getattr(drjit_energy, fn)(*[mi.Float(a) for a in args])
    np.testing.assert_allclose(np.array(got), want, rtol=RTOL_F32, atol=atol)


@pytest.mark.parametrize("name", rt_registry.ENERGY_COMPENSATIONS.names)
def test_drjit_dispatch_matches_numpy(name):
    """reference.energy's dispatch loops the registry as pbrcheck.energy's does (identity included),
    on Color3f F0 as the reference would pass it."""
    from reference.variant import ensure_variant
    ensure_variant()
    import mitsuba as mi

    from reference import energy as drjit_energy
    F0, r, mu, A, B = GRID
    El = (A + B).reshape(-1, NOV.size)[:, ::-1].ravel()
    c3 = mi.Color3f(mi.Float(F0), mi.Float(F0), mi.Float(F0))
    f = [mi.Float(x) for x in (A, B, r, El)]
    close = dict(rtol=RTOL_F32, atol=FMS_ATOL_F32)
    np.testing.assert_allclose(np.array(drjit_energy.energy_scale(c3, f[0], f[1], name))[0],
                               dispatch.energy_scale(F0, A, B, name), **close)
    np.testing.assert_allclose(np.array(drjit_energy.energy_ms(c3, f[0], f[1], f[2], name))[0],
                               dispatch.energy_ms(F0, A, B, r, name), **close)
    np.testing.assert_allclose(np.array(drjit_energy.energy_direct(c3, c3, f[0], f[1], f[3], f[2], name))[0],
                               dispatch.energy_direct(F0, F0, A, B, El, r, name), **close)
    np.testing.assert_allclose(np.array(drjit_energy.specular_albedo_compensated(c3, f[0], f[1], f[2], name))[0],
                               dispatch.specular_albedo_compensated(F0, A, B, r, name), **close)
    with pytest.raises(ValueError, match="unknown energy compensation 'nope'"):
        drjit_energy.energy_scale(c3, f[0], f[1], "nope")
    with pytest.raises(ValueError, match="unknown energy compensation 'nope'"):
        dispatch.energy_ms(F0, A, B, r, "nope")


def test_glsl_table_is_the_numpy_table():
    src = (registry.__file__.rsplit("/", 2)[0] + "/realtime/shaders/energy.glsl")
    text = open(src).read()
    body = text.split("const float KC_EAVG[17] = float[17](")[1].split(");")[0]
    np.testing.assert_allclose([float(x) for x in body.replace("\n", " ").split(",")], energy.KC_EAVG, atol=0)
    assert f"KC_EAVG_SIZE = {energy.KC_EAVG_SIZE};" in text


@pytest.mark.slow
def test_eavg_table_rebakes():
    np.testing.assert_allclose(energy.bake_kc_eavg(), energy.KC_EAVG, atol=EAVG_ATOL)


@pytest.mark.parametrize("name", ("filament", "fdez_aguera", "kulla_conty"))
def test_white_metal_furnace_is_one(name):
    """F0 = 1 under a white furnace: every compensation restores the albedo to 1 (by construction;
    Kulla-Conty through its table's E_avg only at F0 < 1)."""
    F0, r, mu, A, B = GRID
    got = dispatch.specular_albedo_compensated(np.ones_like(A), A, B, r, name)
    np.testing.assert_allclose(got, 1.0, atol=1e-9)


def test_none_is_single_scattering_and_compensations_add_energy():
    F0, r, mu, A, B = GRID
    ss = F0 * A + B
    np.testing.assert_allclose(dispatch.specular_albedo_compensated(F0, A, B, r, "none"), ss)
    for name in ("filament", "fdez_aguera", "kulla_conty"):
        got = dispatch.specular_albedo_compensated(F0, A, B, r, name)
        assert np.all(got >= ss - 1e-12) and np.all(got <= 1.0 + 1e-9), name


def test_presets_offer_the_compensations():
    from realtime.presets import OPTIONS, PRESETS, resolve_options

    assert OPTIONS["energy_compensation"].choices == ("scene", *rt_registry.ENERGY_COMPENSATIONS.names)
    assert set(energy.SCENE_COMPENSATION) == set(registry.MULTISCATTERS.names)
    assert energy.SCENE_COMPENSATION["none"] == "none"
    assert PRESETS["default"]["energy_compensation"] == "scene"
    f = resolve_options("filament")
    assert f["energy_compensation"] == "filament" and f["irradiance"] == "sh9" and f["lod_mapping"] == "quadratic"
    assert "energy_compensation" in PRESETS["default"]


def test_default_preset_compensates_exactly_for_random_walk_scenes():
    from dataclasses import replace

    from pbrcheck.scene import load_scene
    from realtime.presets import resolve_options
    from realtime.render import resolved_energy_compensation

    s = load_scene("furnace")
    o = resolve_options("default")
    assert resolved_energy_compensation(s, o) == "none"
    s_rw = replace(s, brdf=replace(s.brdf, multiscatter="random_walk"))
    assert resolved_energy_compensation(s_rw, o) == energy.SCENE_COMPENSATION["random_walk"] == "filament"
    assert resolved_energy_compensation(s_rw, resolve_options("default", {"energy_compensation": "none"})) == "none"


def test_compensation_needs_the_material_split_sum():
    from realtime.presets import OptionError, resolve_options

    with pytest.raises(OptionError, match="energy_compensation"):
        resolve_options("default", {"energy_compensation": "filament", "ibl": "runtime"})
    with pytest.raises(OptionError, match="energy_compensation"):
        resolve_options("splitsum_basic", {"energy_compensation": "kulla_conty"})
    for p in ("splitsum_basic", "runtime_is20", "runtime_is256", "analytic_mobile"):
        assert resolve_options(p)["energy_compensation"] == "none"
