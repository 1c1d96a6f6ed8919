"""The reference renderer: camera, furnace, peer, integrators, hard cases, variance, cache, CLI."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

import pbrcheck  # noqa: F401
from pbrcheck import brdf as nb
from pbrcheck.camera import primary_rays
from pbrcheck.environment import load_environment
from pbrcheck.exr import AOVS, RGB, VARIANCE, read_exr
from pbrcheck.scene import GEOMETRY_NAMES, load_scene, scene_from_dict
from reference import render as rr
from reference.render import _mi, load_mitsuba_scene, render_reference, render_uncached

# Per-pixel agreement of two independent Monte Carlo estimates: |a - b| <= Z sqrt(var_a + var_b).
# At 5 sigma a Gaussian pixel fails with probability 6e-7, i.e. < 1e-3 over the ~1000 pixels tested.
Z = 5.0
# Furnace: the expected value averages the quadrature albedo over 4x4 sub-pixel rays; the residual
# sub-pixel integration error plus the float32 render is below this (albedo slopes are < 1 per unit
# of n.v away from the silhouette, pixels span < 0.05 in n.v there).
FURNACE_ATOL = 2e-3


def _sphere_scene(material, *, env=None, brdf=None, size=32, extra=(), lights=()):
    d = {"camera": {"origin": [0, 0, 4], "fov": 40, "width": size, "height": size},
         "environment": env or {"type": "constant", "radiance": [1, 1, 1]},
         "objects": [{"type": "sphere", "radius": 1.0, "material": material}, *extra],
         "lights": list(lights)}
    if brdf:
        d["brdf"] = brdf
    return scene_from_dict(d)


SKY = {"type": "sky", "sun_direction": [0.3, 0.8, 0.5], "sun_angular_diameter": 20.0,
       "sun_radiance": [4, 4, 3.5], "resolution": [128, 64]}


def test_camera_rays_match_pbrcheck_camera():
    """The Mitsuba sensor the reference renders with reproduces pbrcheck.camera's rays."""
    mi, dr = _mi()
    from reference.integrator import NEAR_CLIP, pixel_centre_rays, sensor_dict

    scene = load_scene("spheres").with_camera(width=37, height=23, origin=(1.0, 2.0, 9.0), up=(0.1, 1.0, 0.0))
    sensor = mi.load_dict(sensor_dict(scene.camera))
    for off in ((0.5, 0.5), (0.0, 0.0), (0.9, 0.25)):
        o, d = primary_rays(scene.camera, off)
        ray, _ = pixel_centre_rays(sensor, off)
        got = np.array(ray.d).T.reshape(23, 37, 3)
        np.testing.assert_allclose(got, d, atol=2e-6)
        # rays start on the near plane, on the line through the camera origin
        start = np.array(ray.o).T.reshape(23, 37, 3)
        np.testing.assert_allclose(np.cross(start - o, d), 0.0, atol=1e-6)
        assert np.all(np.linalg.norm(start - o, axis=-1) <= 2 * NEAR_CLIP)


def _subpixel_ndotv(scene, k=4):
    """(H, W, k*k) n.v of a unit sphere at the origin on a k x k sub-pixel grid (NaN for misses)."""
    out = []
    for a in range(k):
        for b in range(k):
            o, d = primary_rays(scene.camera, ((a + 0.5) / k, (b + 0.5) / k))
            bq = np.sum(d * o, axis=-1)
            disc = bq * bq - (o @ o - 1.0)
            t = -bq - np.sqrt(np.where(disc > 0, disc, np.nan))
            p = o + t[..., None] * d
            out.append(np.sum(p * -d, axis=-1))
    return np.stack(out, axis=-1)


@pytest.mark.parametrize("roughness", [0.0, 0.5])
@pytest.mark.parametrize("geometry", GEOMETRY_NAMES)
def test_white_furnace_equals_quadrature_albedo(geometry, roughness):
    # (schlick_ggx_direct at roughness 0: k = (0 + 1)^2 / 8 does not vanish, so the mirror limit is
    # G1(n.v, 1/8)^2; pbrcheck.brdf.specular_dfg uses G(v, v) in its mirror limit for every term.)
    scene = _sphere_scene({"base_color": [1, 1, 1], "metallic": 1.0, "roughness": roughness},
                          brdf={"geometry": geometry}, size=32)
    # independent samples: a 5-sigma bound on ~10^3 pixel-channels needs near-Gaussian z; a qmc
    # render's z is Student-t with 15 degrees of freedom (16 replicates), whose tail is 10x heavier there
    img = render_uncached(scene, spp=32, progress=False, sampler="independent")
    nv = _subpixel_ndotv(scene)
    full = np.all(np.isfinite(nv), axis=-1) & (img.channels["coverage"] == 1.0)
    nodes = np.linspace(0.02, 1.0, 50)
    alb = np.array([nb.specular_albedo(c, roughness, geometry=geometry, fresnel="none") for c in nodes])
    exp = np.interp(np.clip(np.nan_to_num(nv), 0.02, 1.0), nodes, alb).mean(axis=-1)
    inner = full & (np.min(np.nan_to_num(nv, nan=-1.0), axis=-1) > 0.05)
    assert inner.sum() > 300
    for c in RGB:
        got = img.channels[c][inner]
        sd = np.sqrt(img.channels["variance." + c][inner])
        err = np.abs(got - exp[inner])
        assert np.all(err <= Z * sd + FURNACE_ATOL), (err.max(), (err - Z * sd).max())


@pytest.mark.parametrize("roughness", [0.2, 0.6])
def test_peer_roughconductor(roughness):
    """geometry smith_ggx, fresnel none, white metal == Mitsuba's roughconductor (ggx, material none)."""
    scene = _sphere_scene({"base_color": [1, 1, 1], "metallic": 1.0, "roughness": roughness},
                          env=SKY, brdf={"geometry": "smith_ggx", "fresnel": "none"}, size=32)
    env = load_environment(scene)
    peer = load_mitsuba_scene(scene, env, bsdf_override={
        "type": "roughconductor", "distribution": "ggx", "material": "none", "alpha": roughness ** 2})
    a = render_uncached(scene, spp=64, progress=False, seed=1)
    b = render_uncached(scene, spp=64, progress=False, seed=2, mscene=peer)
    for c in RGB:
        d = np.abs(a.channels[c] - b.channels[c])
        sd = np.sqrt(a.channels["variance." + c] + b.channels["variance." + c])
        assert np.all(d <= Z * sd + 1e-5), (d - Z * sd).max()
    hit = a.channels["coverage"] == 1
    # and not trivially: the sphere reflects a structured sky (not a flat colour)
    assert a.channels["R"][hit].std() > 0.05 and hit.sum() > 300


MAT = {"base_color": [0.8, 0.5, 0.3], "metallic": 0.5, "roughness": 0.4}
LIGHT = {"type": "point", "position": [2.0, 2.0, 3.0], "intensity": [3.0, 3.0, 3.0]}


def test_local_equals_path_depth2_on_convex_object():
    scene = _sphere_scene(MAT, env=SKY, size=32, lights=[LIGHT])
    a = render_uncached(scene, spp=64, mode="local", progress=False, seed=1)
    b = render_uncached(scene, spp=64, mode="path", max_depth=2, progress=False, seed=2)
    for c in RGB:
        d = np.abs(a.channels[c] - b.channels[c])
        sd = np.sqrt(a.channels["variance." + c] + b.channels["variance." + c])
        assert np.all(d <= Z * sd + 1e-5), (d - Z * sd).max()
    for c in AOVS:
        if c != "coverage":  # pixel-centre AOVs are deterministic; coverage is a sampled fraction
            np.testing.assert_array_equal(a.channels[c], b.channels[c])
    assert abs(a.channels["coverage"].mean() - b.channels["coverage"].mean()) < 0.01


def test_occluder_changes_path_not_local():
    occ = {"type": "sphere", "center": [0.0, 3.0, 0.0], "radius": 1.2,
           "material": {"base_color": [0.1, 0.1, 0.1], "roughness": 1.0}}
    open_ = _sphere_scene(MAT, env=SKY, size=32)
    shut = _sphere_scene(MAT, env=SKY, size=32, extra=[occ])
    la = render_uncached(open_, spp=32, mode="local", progress=False)
    lb = render_uncached(shut, spp=32, mode="local", progress=False)
    np.testing.assert_allclose(lb.rgb, la.rgb, rtol=1e-6, atol=1e-7)  # same samples, no visibility
    pa = render_uncached(open_, spp=64, mode="path", max_depth=2, progress=False)
    pb = render_uncached(shut, spp=64, mode="path", max_depth=2, progress=False, seed=1)
    top = (la.channels["object"] == 0) & (la.channels["N.Y"] > 0.5)
    diff = pa.channels["G"][top].mean() - pb.channels["G"][top].mean()
    se = np.sqrt((pa.channels["variance.G"][top] + pb.channels["variance.G"][top]).sum()) / top.sum()
    assert diff > 6 * se, (diff, se)  # the shadowed top is darker, far beyond chance


@pytest.mark.parametrize("roughness", [0.0, 1e-4, 1.0])
def test_hard_roughness_finite(roughness):
    scene = _sphere_scene({"base_color": [0.9, 0.9, 0.9], "metallic": 0.5, "roughness": roughness},
                          env=SKY, size=24, lights=[LIGHT])
    for mode in ("local", "path"):
        img = render_uncached(scene, spp=4, mode=mode, max_depth=3, progress=False)
        for name, ch in img.channels.items():
            assert np.all(np.isfinite(ch)), (mode, name)
        assert img.channels["R"].max() > 0


@pytest.mark.parametrize("name", ["sun", "hotspot", "grazing"])
def test_builtin_hard_scenes_finite(name):
    scene = load_scene(name)
    cam = scene.camera
    scene = scene.with_camera(width=48, height=max(2, round(48 * cam.height / cam.width)))
    for mode in ("local", "path"):
        img = render_uncached(scene, spp=4, mode=mode, max_depth=3, progress=False)
        for n, ch in img.channels.items():
            assert np.all(np.isfinite(ch)), (name, mode, n)
    if name == "grazing":  # the floor plane: object 0, normal +Y, grazing n.v
        floor = img.channels["object"] == 0
        assert floor.sum() > 50
        np.testing.assert_allclose(img.channels["N.Y"][floor], 1.0, atol=1e-5)
        assert img.channels["NdotV"][floor].min() < 0.1


def test_variance_channels_match_spread_of_independent_renders():
    scene = _sphere_scene(MAT, env=SKY, size=24, lights=[LIGHT])
    runs = [render_uncached(scene, spp=16, progress=False, seed=s) for s in range(10)]
    means = np.stack([r.rgb for r in runs])
    emp = means.var(axis=0, ddof=1)
    rep = np.stack([r.variance for r in runs]).mean(axis=0)
    m = rep > 0
    ratio = emp[m].mean() / rep[m].mean()
    # 10 runs: the pooled empirical variance over ~1000 pixel-channels has a relative standard error
    # of a few percent (heavier tails near the sun); 0.8..1.25 is > 5 of them.
    assert 0.8 < ratio < 1.25, ratio
    assert np.all(rep[~m] == 0) and np.all(emp[~m] < 1e-10)  # only constant pixels report 0


def test_meta_and_channels():
    scene = _sphere_scene(MAT, env=SKY, size=16)
    img = render_uncached(scene, spp=4, progress=False)
    for c in RGB + VARIANCE + AOVS:
        assert img.has(c), c
    m = img.meta
    from pbrcheck.environment import scene_hash

    assert m["scene_hash"] == scene_hash(scene)
    for k in ("spp", "mode", "seed", "variant", "pbrcheck_version", "mitsuba_version", "drjit_version",
              "variance_method", "seconds", "render_seconds", "render_cpu_seconds", "threads"):
        assert m.get(k), k
    assert 0 < float(m["render_seconds"]) <= float(m["seconds"]) and int(m["threads"]) >= 1
    obj = img.channels["object"]
    assert set(np.unique(obj)) == {-1.0, 0.0}
    bg = obj == -1
    assert np.all(img.channels["N.X"][bg] == 0) and np.all(img.channels["NdotV"][bg] == 0)
    n = img.stack(("N.X", "N.Y", "N.Z"))[~bg]
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-5)


def test_cache_hit_miss_corruption(tmp_cache, monkeypatch):
    scene = _sphere_scene(MAT, env=SKY, size=16)
    calls = []
    real = rr.render_uncached
    monkeypatch.setattr(rr, "render_uncached", lambda *a, **k: calls.append(1) or real(*a, **k))
    a = render_reference(scene, spp=4, progress=False)
    assert a.meta["cache"] == "miss" and len(calls) == 1
    b = render_reference(scene, spp=4, progress=False)
    assert b.meta["cache"] == "hit" and len(calls) == 1
    np.testing.assert_array_equal(a.rgb, b.rgb)
    render_reference(scene, spp=4, seed=1, progress=False)
    assert len(calls) == 2
    brighter = replace(scene, environment=replace(scene.environment, sun_radiance=(5.0, 4.0, 3.5)))
    assert rr.reference_cache_key(brighter, spp=4, mode="local", seed=0, max_depth=None) != \
        rr.reference_cache_key(scene, spp=4, mode="local", seed=0, max_depth=None)
    files = list(tmp_cache.rglob("*.exr"))
    assert len(files) == 2
    key = rr.reference_cache_key(scene, spp=4, mode="local", seed=0, max_depth=None)
    path = next(f for f in files if f.stem == key)
    path.write_bytes(b"not an exr" * 10)
    c = render_reference(scene, spp=4, progress=False)
    assert c.meta["cache"] == "miss" and len(calls) == 3
    np.testing.assert_array_equal(a.rgb, c.rgb)  # deterministic given the seed
    assert read_exr(path).meta["cache_key"] == key
    render_reference(scene, spp=4, use_cache=False, progress=False)
    assert len(calls) == 4


def test_cli_reference_and_bench(tmp_path, tmp_cache, capsys):
    from pbrcheck_cli import main

    toml = tmp_path / "s.toml"
    toml.write_text('[camera]\nwidth = 16\nheight = 12\n[environment]\ntype = "constant"\n'
                    '[[objects]]\ntype = "sphere"\n')
    out = tmp_path / "ref.exr"
    assert main(["reference", str(toml), "--spp", "4", "--mode", "path", "--max-depth", "2",
                 "--seed", "3", "--out", str(out)]) == 0
    img = read_exr(out, require=RGB + VARIANCE + AOVS)
    assert img.shape == (12, 16) and img.meta["mode"] == "path" and img.meta["seed"] == "3"
    assert main(["reference", "nonexistent-scene"]) == 2
    capsys.readouterr()
    assert main(["bench", "reference", "--quick"]) == 0
    res = json.loads(capsys.readouterr().out)
    for k in ("integrator_efficiency", "bsdf_speed_ratio", "bsdf_speed_ratio_pass_width", "bsdf_speed_ratio_frozen", "local_seconds", "path_seconds", "spp",
              "resolution", "variant"):
        assert k in res, k
    assert res["integrator_efficiency"] > 0 and res["bsdf_speed_ratio"] > 0 and res["bsdf_speed_ratio_frozen"] > 0
    g = res["material_gather"]
    assert g["materials"] == 30 and g["gathered"]["render_seconds"] > 0 and g["per_instance"]["grad_step_seconds"] > 0
    assert res["material_gather_render_speedup"] == g["render_speedup"] > 0
    # the samplers' figures of the asset scene (the textured glTF), beside spheres'
    a = res["samplers"]["asset"]
    assert a["environment"] == res["samplers"]["spheres"]["environment"]
    for label in ("qmc", "qmc_adaptive"):
        for k in ("variance_ratio", "spp_ratio", "seconds_speedup", "mean_z", "pixels_within_1.96"):
            assert np.isfinite(a[label][k]) and (k == "mean_z" or a[label][k] > 0), (label, k)
    assert a["independent"]["variance_ratio"] == 1.0 and a["target_floor"] > 0
    assert "ris4" in res["variance_reduction"]["spheres"]  # the RIS candidate (reference.integrator.resampled_estimate)
    # throughput (issue 39): pbrcheck against mi.render + path, same BSDF and roughconductor, 3 spp x 2 sizes
    t = res["throughput"]
    assert len(t["rows"]) == 6 and {tuple(r["resolution"]) for r in t["rows"]} == {(16, 12), (24, 20)}
    assert t["machine"] == res["machine"] and res["variant"] in t["machine"]
    for r in t["rows"]:
        for k in ("vs_path_same_bsdf", "vs_path_roughconductor", "vs_path_same_bsdf_cpu", "lean_vs_path_same_bsdf_cpu"):
            assert np.isfinite(r[k]) and r[k] > 0, k
    key = f"vs_path_same_bsdf_at_{t['goal_spp']}spp"
    assert t["goal_spp"] == 16 and res[key] == t["vs_path_same_bsdf_at_goal_spp"]
    assert res[f"{key}_goal"] == t["goal"] and key in res["goals_met"]
    from reference.bench import run_sections
    with pytest.raises(ValueError, match="section must be one of"):
        run_sections(("samplers", "everything"), quick=True)


def test_black_environment_point_lights_only():
    """No envmap emitter (all-black environment): local shades the lights exactly (its only noise is
    the pixel footprint), path (which picks one light per sample) agrees within its noise."""
    scene = _sphere_scene(MAT, env={"type": "none"}, size=24,
                          lights=[LIGHT, {"type": "point", "position": [-3, 1, 2], "intensity": [1, 2, 3]}])
    a = render_uncached(scene, spp=16, mode="local", progress=False)
    b = render_uncached(scene, spp=64, mode="path", max_depth=2, progress=False)
    inside = a.channels["coverage"] == 1
    assert a.rgb[inside].max() > 0.05
    # per-sample variance: local's is the footprint's alone, far below path's light selection noise
    assert a.variance[inside].mean() * 16 < 0.25 * b.variance[inside].mean() * 64
    assert np.all(a.rgb[a.channels["coverage"] == 0] == 0)
    for i, c in enumerate(RGB):
        d = np.abs(a.rgb[..., i] - b.rgb[..., i])
        sd = np.sqrt(a.variance[..., i] + b.variance[..., i])
        assert np.all(d <= Z * sd + 1e-4), (d - Z * sd).max()
