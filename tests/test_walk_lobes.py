"""The random walk (``[brdf] multiscatter = "random_walk"``) under the glTF lobes (issue 40):
reference/lobe_bsdf.py adds the walk's orders >= 2 to the base's specular (Schlick F0 / F90 per
bounce) and layers the coat and sheen on it as the spec does; anisotropy and iridescence stay refused
with the walk (typed). Known answers: a white metal's furnace at 1 with clearcoat 0 (the walk's
energy), at most 1 with clearcoat 1 (the coat's convex layering); neutral lobes = the walk alone; the
report's model-matched reference and diagnose's hypothesis for lobe scenes."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pbrcheck.errors import SceneError
from pbrcheck.scene import load_scene
from reference.render import ensure_variant

ensure_variant()
import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402

from reference import lobe_bsdf as LB  # noqa: E402
from reference import multiscatter as ms  # noqa: E402
from test_lobes import _pairs  # noqa: E402  (n.v and n.l from 1e-3 to 1)
from test_lobes_reference import NEUTRAL_ATOL, NEUTRAL_RTOL, _mat, _np, _si, _v3  # noqa: E402
from test_multiscatter import N_SIGMA, _eval_integral, _sample_mean  # noqa: E402

#: Samples of each furnace (the lobe path's sampler: the specular VNDF, the walk in eval).
N_WALK_FURNACE = 1 << 16
#: A white metal (F0 = 1) with the walk reflects 1 within this and N_SIGMA standard errors
#: (test_multiscatter's FURNACE_RTOL is 3e-3 at 2^16 of the walk's own sampler; here the walk's
#: eval estimator is divided by the VNDF density, a heavier tail: 1 %).
WALK_FURNACE_RTOL = 1e-2
#: The coat's layering bound: ``(1 - c Fc) A + c Fc A_coat <= 1`` for A = 1 (the walk) and A_coat <= 1.
LAYERING_BOUND = 1.0
WALK = dict(multiscatter="random_walk", multiscatter_seed=3)
WHITE_METAL = dict(base_color=[1.0, 1.0, 1.0], metallic=1.0, roughness=1.0)


def _sampled(d, mu):
    return _sample_mean(mi.load_dict(d), mu, N_WALK_FURNACE, seed=int(100 * mu))


@pytest.mark.parametrize("mu", [1.0, 0.5, 0.2])
def test_white_metal_walk_clearcoat_0_furnace_is_1(mu):
    """Clearcoat 0 (the lobe path traced): the walk's energy, 1 (single scattering alone: 0.55-0.7)."""
    mean, se = _sampled(_mat(**WHITE_METAL, **WALK, clearcoat=0.0, clearcoat_roughness=0.3), mu)
    err = np.abs(mean - 1.0)
    assert np.all(err <= np.maximum(N_SIGMA * se, WALK_FURNACE_RTOL)), (mu, mean, se)
    single, _ = _sampled(_mat(**WHITE_METAL, clearcoat=0.0, clearcoat_roughness=0.3), mu)
    assert np.all(single < 0.8), single   # without the walk the furnace loses energy: the test can fail


@pytest.mark.parametrize("mu", [1.0, 0.5, 0.2])
def test_white_metal_walk_clearcoat_1_furnace_at_most_1(mu):
    """Clearcoat 1 over the walking white metal: ``(1 - Fc) 1 + Fc A_coat`` (A_coat the coat GGX's
    albedo, <= 1): at most 1, and above 1 - Fc (the base's share)."""
    from pbrcheck import lobes as N

    mean, se = _sampled(_mat(**WHITE_METAL, **WALK, clearcoat=1.0, clearcoat_roughness=0.3), mu)
    fc = float(N.fresnel_coat(mu))
    want = (1.0 - fc) + fc * N.AnisotropicGGX(0.3).albedo(mu)
    assert np.all(mean <= LAYERING_BOUND + N_SIGMA * se), (mu, mean, se)
    assert np.all(np.abs(mean - want) <= np.maximum(N_SIGMA * se, WALK_FURNACE_RTOL)), (mu, mean, want, se)


def test_white_metal_walk_eval_furnace_with_coat_0():
    """The eval side (the walk's estimator integrated against a known density) is 1 too."""
    b = mi.load_dict(_mat(**WHITE_METAL, **WALK, clearcoat=0.0))
    assert b.lobes is not None
    mean, se = _eval_integral(b, 0.5, 1.0, 1 << 18)
    assert np.all(np.abs(mean - 1.0) <= np.maximum(N_SIGMA * se, WALK_FURNACE_RTOL)), (mean, se)


NEUTRAL_WALK_LOBES = {p: (list(d) if isinstance(d, tuple) else d)
                      for n in LB.WALK_LOBES for p, d in LB.LOBE_DEFAULTS[n].items()}


@pytest.mark.parametrize("blend", ["f0", "gltf"])
@pytest.mark.parametrize("rough", [0.4, 1.0])
def test_walk_with_neutral_lobes_is_the_walk_alone(rough, blend):
    """Clearcoat, sheen and specular props at their neutral values with the walk: eval equals the
    non-lobe walk's (the walk's orders >= 2 from the same key and Fresnel bits; the analytic order 1
    to float32 rounding)."""
    v, l = _pairs()
    n = len(v)
    base = mi.load_dict(_mat(roughness=rough, metallic_blend=blend, **WALK))
    lob = mi.load_dict(_mat(roughness=rough, metallic_blend=blend, **WALK, **NEUTRAL_WALK_LOBES))
    assert base.lobes is None and lob.lobes is not None and lob.lobes.used == LB.WALK_LOBES
    si = _si((v[:, 0], v[:, 1], v[:, 2]), n)
    f0 = _np(base.eval(mi.BSDFContext(), si, _v3(l)))
    f1 = _np(lob.eval(mi.BSDFContext(), si, _v3(l)))
    np.testing.assert_allclose(f1, f0, rtol=NEUTRAL_RTOL, atol=NEUTRAL_ATOL)
    # the walk contributes here (else the comparison says nothing about it)
    single = _np(mi.load_dict(_mat(roughness=rough, metallic_blend=blend)).eval(mi.BSDFContext(), si, _v3(l)))
    assert (f0 - single).max() > 1e-3


def test_walk_f90_one_is_the_models_schlick_bit_for_bit():
    """The walk's F0 / F90 Fresnel at F90 = 1 gives the model's Schlick bits (so a neutral
    KHR_materials_specular renders the walk alone), and F90 = F0 = 0 gives no walk at all."""
    n = 4096
    rng = np.random.default_rng(5)
    wi = dr.normalize(mi.Vector3f(*[mi.Float(x) for x in (rng.random(n) - 0.5, rng.random(n) - 0.5, rng.random(n))]))
    wo = dr.normalize(mi.Vector3f(*[mi.Float(x) for x in (rng.random(n) - 0.5, rng.random(n) - 0.5, rng.random(n))]))
    key = ms.query_key(1, wi.x, wi.y, wi.z, wo.x, wo.y, wo.z)
    f0 = mi.Color3f(0.9, 0.5, 0.2)
    a = np.array(ms.walk_eval(wi, wo, 0.6, f0, key, min_order=2))
    b = np.array(ms.walk_eval(wi, wo, 0.6, f0, key, min_order=2, F90=mi.Color3f(1.0)))
    assert np.array_equal(a, b) and a.max() > 1e-2
    z = np.array(ms.walk_eval(wi, wo, 0.6, mi.Color3f(0.0), key, min_order=2, F90=mi.Color3f(0.0)))
    assert z.max() == 0.0


def test_specular_factor_0_removes_the_dielectric_walk():
    """A black dielectric with specularFactor 0 (f0 = f90 = 0): nothing reflects, walk or not; with
    specularFactor 1 the walk adds energy above single scattering (its F90 is the factor's)."""
    v, l = _pairs()
    n = len(v)
    si = _si((v[:, 0], v[:, 1], v[:, 2]), n)
    dark = dict(base_color=[0.0, 0.0, 0.0], metallic=0.0, roughness=1.0, metallic_blend="gltf", specular=0.5)
    f = _np(mi.load_dict(_mat(**dark, **WALK, specular_factor=0.0)).eval(mi.BSDFContext(), si, _v3(l)))
    assert np.abs(f).max() == 0.0
    on = _np(mi.load_dict(_mat(**dark, **WALK, specular_factor=1.0, specular_color=[1.0, 1.0, 1.0])).eval(
        mi.BSDFContext(), si, _v3(l)))
    single = _np(mi.load_dict(_mat(**dark, specular_factor=1.0, specular_color=[1.0, 1.0, 1.0])).eval(
        mi.BSDFContext(), si, _v3(l)))
    assert (on - single).max() > 1e-3


# ---- what stays refused -------------------------------------------------------------------------

def test_walk_lobes_are_clearcoat_sheen_specular():
    assert LB.WALK_LOBES == ("clearcoat", "sheen", "specular")
    for n in LB.WALK_LOBES:
        assert LB.model_problem("ggx", "smith_ggx_correlated", "schlick", "random_walk", [n]) is None


@pytest.mark.parametrize("lobe", ["anisotropy", "iridescence"])
def test_walk_refused_with_anisotropy_and_iridescence(lobe):
    field, expected, found = LB.model_problem("ggx", "smith_ggx_correlated", "schlick", "random_walk",
                                              ["clearcoat", lobe])
    assert field == "brdf.multiscatter" and found == "random_walk" and f"['{lobe}']" in expected
    with pytest.raises(ValueError, match="brdf.multiscatter"):
        LB.check_model("ggx", "smith_ggx_correlated", "schlick", "random_walk", [lobe])


@pytest.mark.parametrize("name,ok", [("clearcoat", True), ("sheen", True), ("anisotropy", False),
                                     ("iridescence", False)])
def test_check_scene_refuses_only_what_the_walk_cannot_take(name, ok):
    sc = load_scene(name)
    walk = dataclasses.replace(sc, brdf=dataclasses.replace(sc.brdf, multiscatter="random_walk"))
    if ok:
        LB.check_scene(walk)
        return
    with pytest.raises(SceneError) as e:
        LB.check_scene(walk)
    assert "brdf.multiscatter" in str(e.value) and name in str(e.value)


@pytest.mark.parametrize("mode", ["local", "path"])
def test_clearcoat_scene_renders_with_the_walk(mode):
    """The built-in clearcoat grid over a rough white metal (roughness 1, where single scattering
    loses ~30 %) with the walk renders (finite) and is brighter than without it: the base's multiply
    scattered energy under the coats."""
    from reference.render import render_uncached

    sc = load_scene("clearcoat")
    objs = [dataclasses.replace(o, material=dataclasses.replace(o.material, metallic=1.0, roughness=1.0,
                                                                base_color=(0.9, 0.9, 0.9))) for o in sc.objects]
    sc = dataclasses.replace(sc, objects=objs, camera=dataclasses.replace(sc.camera, width=24, height=16))
    walk = dataclasses.replace(sc, brdf=dataclasses.replace(sc.brdf, multiscatter="random_walk"))
    a = render_uncached(sc, spp=8, mode=mode, progress=False, aovs=False).channels["G"]
    b = render_uncached(walk, spp=8, mode=mode, progress=False, aovs=False).channels["G"]
    assert np.isfinite(b).all()
    assert b.mean() > a.mean() * 1.05, (a.mean(), b.mean())


# ---- the report's model-matched reference and diagnose's hypothesis ---------------------------------

def test_lobe_scenes_get_the_random_walk_reference():
    from compare import lobes as cl
    from compare.report.references import random_walk_scene
    from compare.research import diagnose as dg

    for name in ("clearcoat", "sheen"):
        walk, why = random_walk_scene(load_scene(name))
        assert why == "" and walk.brdf.multiscatter == "random_walk"
        assert cl.no_random_walk(load_scene(name)) is None
        assert dg.hypothesis("multiple_scattering").applies_to(None, load_scene(name)) is None
    walk, why = random_walk_scene(load_scene("anisotropy"))
    assert walk is None and why == ("the glTF lobes (anisotropy) have no random walk in the reference (the walk is "
                                    "isotropic with Schlick's Fresnel)")
    assert dg.hypothesis("multiple_scattering").applies_to(None, load_scene("iridescence")) == \
        cl.no_random_walk(load_scene("iridescence"))


#: A textured white-metal quad under a clear coat in the white furnace, mean of its central pixels at
#: 16 spp: 1 within this (the walk's eval noise over ~100 pixels, measured ~3e-3).
TEXTURED_FURNACE_ATOL = 1.5e-2


def test_textured_white_metal_under_a_coat_stays_at_1_with_the_walk(tmp_path):
    """A glTF quad (pbr_textured), white metal at roughness 1 under clearcoat 1 (roughness 0) in a
    constant environment of radiance 1, ``local``: ``(1 - Fc) A_walk + Fc A_coat = 1`` (the walk's albedo
    1, the coat GGX's 1 - 1e-4); single scattering loses ~1/3 of the base."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from gltf_build import quad_asset, quad_scene
    from reference.render import render_uncached

    mat = {"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1], "metallicFactor": 1.0, "roughnessFactor": 1.0},
           "extensions": {"KHR_materials_clearcoat": {"clearcoatFactor": 1.0, "clearcoatRoughnessFactor": 0.0}}}
    sc = load_scene(quad_scene(tmp_path, quad_asset(tmp_path / "coat.gltf", mat), size=(16, 16), fov=30.0))
    walk = dataclasses.replace(sc, brdf=dataclasses.replace(sc.brdf, multiscatter="random_walk"))
    LB.check_scene(walk)
    got = render_uncached(walk, spp=16, mode="local", progress=False, aovs=False)
    single = render_uncached(sc, spp=16, mode="local", progress=False, aovs=False)
    centre = np.s_[4:12, 4:12]
    for c in "RGB":
        assert abs(float(got.channels[c][centre].mean()) - 1.0) < TEXTURED_FURNACE_ATOL, got.channels[c][centre]
        assert float(single.channels[c][centre].mean()) < 0.85
