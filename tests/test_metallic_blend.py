"""``[brdf] metallic_blend = "f0" | "gltf"`` (issue 40): pbrcheck's F0 mix (the seed articles'
model, the default) and glTF 2.0 Appendix B's ``mix(dielectric_brdf, metal_brdf, metallic)``, in
every twin (numpy, Dr.Jit, GLSL), the renderers, the walk and the export.

The closed forms: Appendix B written out,
``f = (1 - m) [(1 - F(s)) c / pi + F(s) V D] + m F(c) V D`` with ``V D = D G / (4 n.l n.v)`` and
``F(x)`` Schlick at ``v.h`` with F0 ``x``; and its difference to the F0 mix, which is the diffuse
weight alone: ``f_gltf - f_f0 = (1 - m) m (c - s) (1 - (1 - v.h)^5) c / pi`` (Schlick is linear in
F0, so the specular lobes agree): zero at metallic 0 and 1, largest near 0.5."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from pbrcheck import brdf
from pbrcheck.scene import load_scene, scene_from_dict

BASE = (0.9, 0.6, 0.3)
SPEC = 0.04
#: float32 Dr.Jit / GLSL against float64 numpy (tests/test_reference_bsdf.py, tests/test_realtime_glsl.py).
RTOL_F32 = 2e-4
ATOL_F32 = 1e-5


def _dirs(n=300, seed=5):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(n, 3))
    l = rng.normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2]) + 0.05
    l[:, 2] = np.abs(l[:, 2]) + 0.05
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    l /= np.linalg.norm(l, axis=1, keepdims=True)
    return v.astype(np.float32).astype(np.float64), l.astype(np.float32).astype(np.float64), \
        np.resize([0.15, 0.3, 0.5, 0.8, 1.0], n)


def _schlick(VoH, f0):
    return f0 + (1.0 - f0) * (1.0 - VoH[:, None]) ** 5


def gltf_closed_form(v, l, m, rough):
    """glTF 2.0 Appendix B, term by term (V D from the model's own specular lobe with F = 1)."""
    n = np.array([0.0, 0.0, 1.0])
    h = (v + l) / np.linalg.norm(v + l, axis=1, keepdims=True)
    VoH = np.clip(np.sum(v * h, axis=1), 0.0, 1.0)
    VD = brdf.brdf_eval(n, v, l, (1.0, 1.0, 1.0), 1.0, rough, SPEC, fresnel="none")   # D G / (4 n.l n.v)
    c = np.array(BASE)
    Fs, Fc = _schlick(VoH, np.full(3, SPEC)), _schlick(VoH, c)
    dielectric = (1.0 - Fs) * c / math.pi + Fs * VD
    metal = Fc * VD
    return (1.0 - m) * dielectric + m * metal


def blend_difference(v, l, m):
    h = (v + l) / np.linalg.norm(v + l, axis=1, keepdims=True)
    VoH = np.clip(np.sum(v * h, axis=1), 0.0, 1.0)
    return (1.0 - m) * m * (np.array(BASE) - SPEC) * (1.0 - (1.0 - VoH[:, None]) ** 5) * np.array(BASE) / math.pi


@pytest.mark.parametrize("m", [0.0, 0.25, 0.5, 0.75, 1.0])
def test_numpy_blends_against_their_closed_forms(m):
    v, l, rough = _dirs()
    n = np.array([0.0, 0.0, 1.0])
    f0 = brdf.brdf_eval(n, v, l, BASE, m, rough, SPEC)
    gl = brdf.brdf_eval(n, v, l, BASE, m, rough, SPEC, metallic_blend="gltf")
    np.testing.assert_allclose(gl, gltf_closed_form(v, l, m, rough), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(gl - f0, blend_difference(v, l, m), rtol=1e-9, atol=1e-14)
    if 0.0 < m < 1.0:   # the blends differ where partially metallic: by 10 % or more of the red diffuse here
        assert float(np.max((gl - f0)[:, 0])) > 0.1 * (1 - m) * BASE[0] / math.pi * m
    else:
        np.testing.assert_array_equal(gl, f0)
    with pytest.raises(ValueError, match="metallic_blend"):
        brdf.brdf_eval(n, v, l, BASE, m, rough, SPEC, metallic_blend="average")


@pytest.mark.parametrize("blend", ["f0", "gltf"])
def test_drjit_twin(blend):
    from reference.variant import ensure_variant
    ensure_variant()
    import drjit as dr
    import mitsuba as mi
    v, l, rough = _dirs(200)
    n3 = np.array([0.0, 0.0, 1.0])
    for m in (0.25, 0.5, 0.75):
        for r in (0.3, 0.8):
            b = mi.load_dict({"type": "pbr_material", "base_color": list(BASE), "metallic": m, "roughness": r,
                              "specular": SPEC, "metallic_blend": blend})
            si = dr.zeros(mi.SurfaceInteraction3f, len(v))
            si.wi = mi.Vector3f(v[:, 0], v[:, 1], v[:, 2])
            got = np.array(b.eval(mi.BSDFContext(), si, mi.Vector3f(l[:, 0], l[:, 1], l[:, 2])))
            got = got.T if got.shape[0] == 3 else got
            ref = brdf.brdf_eval(n3, v, l, BASE, m, r, SPEC, metallic_blend=blend) * l[:, 2:3]
            np.testing.assert_allclose(got, ref, rtol=RTOL_F32, atol=1e-6, err_msg=f"{blend} m={m} r={r}")
            # sampling stays consistent: weight = f cos / pdf
            rng = np.random.default_rng(3)
            k = 2048
            si2 = dr.zeros(mi.SurfaceInteraction3f, k)
            si2.wi = dr.normalize(mi.Vector3f(0.5, 0.2, 0.8))
            bs, w = b.sample(mi.BSDFContext(), si2, mi.Float(rng.random(k)), mi.Point2f(rng.random(k), rng.random(k)))
            f, pdf = b.eval_pdf(mi.BSDFContext(), si2, bs.wo)
            ok = np.array(pdf) > 0
            np.testing.assert_allclose((np.array(f) / np.maximum(np.array(pdf), 1e-20))[:, ok],
                                       np.array(w)[:, ok], rtol=1e-4)


@pytest.mark.parametrize("blend", ["f0", "gltf"])
def test_glsl_twin(blend):
    from realtime.glsl_harness import run_glsl
    v, l, rough = _dirs(200)
    n3 = np.array([0.0, 0.0, 1.0])
    defines = {"METALLIC_BLEND_GLTF": 1} if blend == "gltf" else None
    for m in (0.25, 0.5, 0.75):
        g = run_glsl(f"brdf_eval(vec3(0,0,1), vec3(x0,x1,x2), vec3(x3,x4,x5), vec3{BASE}, {m}, x6, {SPEC})",
                     v[:, 0], v[:, 1], v[:, 2], l[:, 0], l[:, 1], l[:, 2], rough, components=3, defines=defines)
        ref = brdf.brdf_eval(n3, v, l, BASE, m, rough, SPEC, metallic_blend=blend)
        np.testing.assert_allclose(g, ref, rtol=RTOL_F32, atol=ATOL_F32, err_msg=f"{blend} m={m}")


# --- the renderers on partially metallic spheres ----------------------------------------------------

SPHERES = {
    "name": "partial-metals", "camera": {"origin": [0, 0, 9.0], "fov": 40.0, "width": 96, "height": 32},
    "environment": {"type": "none"},
    "lights": [{"type": "directional", "direction": [-0.3, -0.2, -1.0], "intensity": [3.0, 3.0, 3.0]}],
    "objects": [{"type": "sphere", "center": [x, 0.0, 0.0], "radius": 0.9,
                 "material": {"base_color": list(BASE), "metallic": m, "roughness": 0.5}}
                for x, m in ((-2.0, 0.0), (0.0, 0.5), (2.0, 1.0))],
}


def _sphere_means(img):
    ids = np.rint(img.channels["object"]).astype(int)
    inner = ids.copy()   # pixels whose 4 neighbours see the same sphere (no silhouette)
    inner[1:-1, 1:-1] = np.where((ids[1:-1, 1:-1] == ids[:-2, 1:-1]) & (ids[1:-1, 1:-1] == ids[2:, 1:-1])
                                 & (ids[1:-1, 1:-1] == ids[1:-1, :-2]) & (ids[1:-1, 1:-1] == ids[1:-1, 2:]),
                                 ids[1:-1, 1:-1], -1)
    return [img.rgb[inner == k].mean(axis=0) for k in range(3)], inner


def _closed_form_image(scene, inner):
    """Each sphere pixel's radiance at its centre: f(l, v) E n.l (directional light, no environment)."""
    from pbrcheck.camera import primary_rays
    o, d = primary_rays(scene.camera)
    out = np.zeros(d.shape)
    li = scene.lights[0]
    ldir = -np.asarray(li.direction) / np.linalg.norm(li.direction)
    for ob in scene.objects:
        mask = inner == ob.id
        dd = d[mask]
        oc = o - np.asarray(ob.center)
        b = dd @ oc
        t = -b - np.sqrt(np.maximum(b * b - (oc @ oc - ob.radius ** 2), 0.0))
        nrm = (o + dd * t[:, None] - np.asarray(ob.center)) / ob.radius
        v = -dd
        ll = np.broadcast_to(ldir, nrm.shape)
        f = brdf.brdf_eval(nrm, v, ll, ob.material.base_color, ob.material.metallic, ob.material.roughness,
                           ob.material.specular, metallic_blend=scene.brdf.metallic_blend)
        out[mask] = f * np.asarray(li.intensity) * np.clip(np.sum(nrm * ll, axis=1), 0.0, None)[:, None]
    return out


#: Per sphere mean against the pixel-centre closed form: both renderers box-filter or shade pixel
#: centres of the same smooth shading; 2 % covers the reference's in-pixel variation at 96 x 32.
SPHERE_RTOL = 0.02


@pytest.mark.parametrize("blend", ["f0", "gltf"])
def test_partially_metallic_spheres_in_both_renderers(blend, tmp_cache):
    from compare import renderers
    scene = scene_from_dict({**SPHERES, "brdf": {"metallic_blend": blend}})
    assert scene.brdf.metallic_blend == blend
    ref = renderers.render_reference(scene, spp=16, use_cache=False, progress=False)
    rt = renderers.render_under_test(scene, renderers.RendererSpec.parse("default"), progress=False)
    means, inner = _sphere_means(ref)
    cf = _closed_form_image(scene, inner)
    for k in range(3):
        want = cf[inner == k].mean(axis=0)
        np.testing.assert_allclose(means[k], want, rtol=SPHERE_RTOL, err_msg=f"reference {blend} sphere {k}")
        np.testing.assert_allclose(_sphere_means(rt)[0][k], want, rtol=SPHERE_RTOL, err_msg=f"default {blend} {k}")
    assert '"metallic_blend": "%s"' % blend in rt.meta["terms"]
    if blend == "gltf":   # the half-metal sphere is brighter than under the F0 mix; the others equal
        other = _closed_form_image(replace(scene, brdf=replace(scene.brdf, metallic_blend="f0")), inner)
        assert cf[inner == 1].mean() > 1.05 * other[inner == 1].mean()
        np.testing.assert_allclose(cf[inner == 0], other[inner == 0])


def test_the_walk_under_the_gltf_blend_is_the_mix_of_the_two_walks(tmp_cache):
    """glTF's blend is linear in metallic by definition, multiple scattering included: a rough white
    half metal in a white furnace with the random walk is the mean of the dielectric's and the metal's
    images (each walk at its own F0: reference.multiscatter.blend_walk). The F0 mix is not such a
    mix (one walk of the mixed F0 and a diffuse under its Fresnel): measured at 256 spp, dielectric
    0.977, metal 1.000, half metal 0.988 under glTF's blend and 0.584 under the F0 mix."""
    from compare import renderers
    base = {"name": "furnace-half", "camera": {"origin": [0, 0, 4.0], "fov": 30.0, "width": 32, "height": 32},
            "environment": {"type": "constant", "radiance": [1, 1, 1]}}

    def mean(m, blend):
        s = scene_from_dict({**base, "brdf": {"metallic_blend": blend, "multiscatter": "random_walk"},
                             "objects": [{"type": "sphere", "radius": 1.0, "material": {
                                 "base_color": [1, 1, 1], "metallic": m, "roughness": 1.0, "specular": 0.04}}]})
        img = renderers.render_reference(s, spp=256, use_cache=False, progress=False)
        return float(img.rgb[img.channels["object"] >= 0].mean())

    ends = 0.5 * (mean(0.0, "gltf") + mean(1.0, "gltf"))
    assert mean(0.5, "gltf") == pytest.approx(ends, abs=WALK_ATOL)
    assert mean(0.5, "f0") < ends - 0.1


#: Mean radiance of ~800 sphere pixels at 256 spp of a walk: standard error ~1e-3; 0.006 is 6 of them.
WALK_ATOL = 0.006


def test_scene_option_hash_and_export(tmp_path):
    s = load_scene("spheres")
    assert s.brdf.metallic_blend == "f0" and "metallic_blend" not in s.content_dict()["brdf"]
    g = replace(s, brdf=replace(s.brdf, metallic_blend="gltf"))
    assert g.content_dict()["brdf"]["metallic_blend"] == "gltf"
    from pbrcheck.errors import SceneError
    with pytest.raises(SceneError, match="brdf.metallic_blend"):
        scene_from_dict({**SPHERES, "brdf": {"metallic_blend": "average"}})
    import json
    from pbrcheck.export import export_scene
    exp = export_scene(scene_from_dict({**SPHERES, "brdf": {"metallic_blend": "gltf"}}), tmp_path / "x")
    mb = json.loads(open(exp.files["scenario.json"]).read())["metallic_blend"]
    assert mb["reference"] == "gltf" and mb["gltf_engines"] == "gltf" and mb["partially_metallic_objects"] == 1


def test_a_scene_with_a_gltf_asset_defaults_to_gltfs_blend(tmp_path):
    """Issue 40: a scene holding a glTF asset (a scene file's ``gltf`` object, an asset path given as
    the SCENE, an asset beside analytic objects) renders glTF 2.0's blend unless it says otherwise;
    scenes without one keep the seeds' F0 mix; the choice survives check-scene's resolved TOML."""
    from gltf_build import quad_asset, quad_scene
    from pbrcheck.gltf_objects import ASSET_METALLIC_BLEND
    from pbrcheck.scene import dump_toml
    assert ASSET_METALLIC_BLEND == "gltf"
    asset = quad_asset(tmp_path / "q.gltf", {"pbrMetallicRoughness": {"metallicFactor": 0.5}})
    file_scene = load_scene(quad_scene(tmp_path, asset))
    assert file_scene.brdf.metallic_blend == "gltf"
    assert load_scene(asset).brdf.metallic_blend == "gltf"              # the asset path alone
    mixed = {**SPHERES, "objects": [*SPHERES["objects"], {"type": "gltf", "path": str(asset)}]}
    assert scene_from_dict(mixed).brdf.metallic_blend == "gltf"        # the blend is the scene's
    assert scene_from_dict(SPHERES).brdf.metallic_blend == "f0"
    assert load_scene("spheres").brdf.metallic_blend == "f0"
    kept = scene_from_dict({**mixed, "brdf": {"metallic_blend": "f0"}})
    assert kept.brdf.metallic_blend == "f0"
    again = tmp_path / "resolved.toml"
    again.write_text(dump_toml(kept.to_dict()))
    assert load_scene(again).brdf.metallic_blend == "f0"                # not turned back into the default
    assert kept.content_dict() != scene_from_dict(mixed).content_dict()   # another cache entry


def test_a_textured_asset_takes_the_blend_in_both_renderers(tmp_path, tmp_cache):
    """A half-metal glTF quad in a white environment: under glTF's blend both renderers (the
    textured material, the raster pipeline) show it brighter than under the F0 mix, by the closed
    form's diffuse difference at normal view and within the split sum's error of each other."""
    from gltf_build import quad_asset, quad_scene
    from compare import renderers
    asset = quad_asset(tmp_path / "q.gltf", {"pbrMetallicRoughness": {
        "baseColorFactor": [*BASE, 1.0], "metallicFactor": 0.5, "roughnessFactor": 0.6}})
    got = {}
    for blend in ("f0", "gltf"):
        scene = load_scene(quad_scene(tmp_path, asset, size=(16, 16), name=f"{blend}.toml"))
        scene = replace(scene, brdf=replace(scene.brdf, metallic_blend=blend))
        ref = renderers.render_reference(scene, spp=32, use_cache=False, progress=False)
        rt = renderers.render_under_test(scene, renderers.RendererSpec.parse("default"), progress=False)
        c = slice(5, 11)
        got[blend] = (ref.rgb[c, c].mean(axis=(0, 1)), rt.rgb[c, c].mean(axis=(0, 1)))
    for k in range(2):   # reference, real-time: the red channel gains more than the blue (c - s)
        gain = got["gltf"][k] - got["f0"][k]
        assert gain[0] > 0.02 and gain[0] > 2 * gain[2], (k, got)
    np.testing.assert_allclose(got["gltf"][1], got["gltf"][0], rtol=0.05)
