"""compare.transmission_split (issue 37 item 3): the refracted lookup's classification on built scenes
with a known answer (a sphere at the screen's edge whose refracted lookups leave the screen; a
transmissive sphere behind it, which the opaque pass leaves out), checked against an independent
computation (GL matrices, the test's own Snell refraction and ray casting); the chord's closed form
against a ray march; the chord swap's algebra; the option ``transmission_lod_bias`` (GLSL against its
numpy twin, defined only where not 0); the split's parts from real renders of the real-time renderer."""

from __future__ import annotations

import numpy as np
import pytest

from compare import transmission_split as ts
from pbrcheck.camera import primary_rays, projection_matrix, view_matrix
from pbrcheck.scene import Plane, Sphere, load_scene, scene_from_dict
from realtime import transmission as rt
from realtime.glsl_harness import run_glsl

#: The edge scene's glass: IOR 1.5 (F0 0.04), a thickness of 3 (long enough for the left limb's
#: lookups, bent right by the refraction, to pass the screen's right edge).
GLASS = {"base_color": [1, 1, 1], "roughness": 0.0, "specular": 0.04, "transmission": 1.0, "thickness": 3.0}
#: The ray march's step (world units) in the chord check; the march overshoots by at most one step.
MARCH_STEP = 1e-4
#: Options of small bakes for the real-time renders (as tests/test_realtime_transmission.py's SMALL).
SMALL = {"cube_size": 32, "irradiance_source_size": 8, "irradiance_size": 8, "prefilter_levels": 4,
         "prefilter_samples": 64, "lut_size": 16, "lut_samples": 256, "supersample": 1, "pipeline": "raster"}


def _edge_scene(behind_transmission: float):
    """Sphere A (id 0) near the right edge of a 48 x 32 screen; sphere B (id 1) 4 units behind it,
    transmissive or not."""
    return scene_from_dict({
        "name": "edge", "camera": {"origin": [0, 0, 6], "target": [0, 0, 0], "fov": 40, "width": 48, "height": 32},
        "environment": {"type": "constant", "radiance": [1, 1, 1]},
        "objects": [{"type": "sphere", "center": [1.6, 0, 0], "radius": 0.4, "material": GLASS},
                    {"type": "sphere", "center": [1.2, 0, -4], "radius": 1.2,
                     "material": {**GLASS, "transmission": behind_transmission}}]})


def _snell(d, n, eta):
    """The test's own refraction (Snell's law by angles): the tangential part scaled by ``eta``, the
    normal part from ``cos(theta_t) = sqrt(1 - eta^2 sin^2(theta_i))``."""
    cos_i = -(d * n).sum(-1, keepdims=True)
    tangential = d + cos_i * n
    sin_t = eta * np.linalg.norm(tangential, axis=-1, keepdims=True)
    return eta * tangential - np.sqrt(1.0 - sin_t ** 2) * n


def _sphere_hit(o, d, c, r):
    oc = o - np.asarray(c, float)
    b = d @ oc
    disc = b * b - (oc @ oc - r * r)
    return np.where(disc >= 0, -b - np.sqrt(np.maximum(disc, 0.0)), np.inf)


def test_lookups_leave_the_screen_at_its_edge_and_meet_a_transmissive_sphere_behind():
    scene = _edge_scene(1.0)
    look = ts.lookups(scene)
    cam = scene.camera
    o, d = primary_rays(cam)
    a = look.ids == 0
    # independent: the front hit, Snell's refraction, the lookup point and its GL clip coordinates
    s = _sphere_hit(o, d[a], (1.6, 0, 0), 0.4)
    p = o + d[a] * s[:, None]
    t = _snell(d[a], (p - (1.6, 0, 0)) / 0.4, 1 / 1.5)
    q = np.concatenate([p + 3.0 * t, np.ones((len(p), 1))], -1)
    clip = q @ (projection_matrix(cam, 0.1, 100.0) @ view_matrix(cam)).T
    ndc = clip[:, :2] / clip[:, 3:]
    off = (clip[:, 3] <= 0) | (np.abs(ndc) > 1).any(-1)
    np.testing.assert_allclose(look.uv[a], 0.5 * ndc + 0.5, atol=1e-9)
    assert off.sum() >= 3 and (off == (look.cls[a] == 2)).all()
    # the left limb's lookups (bent right) leave the screen; the centre column's stay
    cols = np.nonzero(a)[1]
    assert cols[off].max() < cols.mean()
    # B behind A: the camera ray through the lookup pixel meets B (the test's own ray cast) -> transparent
    behind = look.cls[a] == 1
    assert behind.sum() >= 10
    uv = look.uv[a][behind]
    col, row = np.floor(uv[:, 0] * cam.width).astype(int), np.floor((1 - uv[:, 1]) * cam.height).astype(int)
    assert np.isfinite(_sphere_hit(o, d[row, col], (1.2, 0, -4), 1.2)).all()
    # B opaque: the same lookups land on it, now in the opaque pass: no transparent class, the same off-screen
    plain = ts.lookups(_edge_scene(0.0))
    assert (plain.cls[a] != 1).all() and ((plain.cls[a] == 2) == off).all()
    assert (plain.cls[look.ids == 1] == -1).all()   # B is not transmissive there


def test_chord_lengths_match_a_ray_march():
    rng = np.random.default_rng(7)
    sphere = Sphere(0, (0.3, -0.2, 0.1), 0.7, load_scene("glass").objects[0].material)
    # front-face points and inward refracted directions (into the sphere: t.n < 0)
    n = rng.normal(size=(40, 3))
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    d = -n + 0.6 * rng.normal(size=(40, 3))
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    t = _snell(d, n, 1 / 1.5)
    p = np.asarray(sphere.center) + sphere.radius * n
    got = ts.chord_lengths(sphere, p, t)
    s = np.full(len(p), 0.0)
    inside = np.ones(len(p), bool)
    while inside.any():   # march to the first point outside
        s = np.where(inside, s + MARCH_STEP, s)
        inside = np.linalg.norm(p + s[:, None] * t - sphere.center, axis=-1) <= sphere.radius
    np.testing.assert_allclose(got, s, atol=2 * MARCH_STEP)
    assert got.min() > 0.1 and got.max() <= 2 * sphere.radius
    # a slab of thickness 0.5 under a plane of normal +y: thickness / cos(theta_t)
    mat = sphere.material.__class__(thickness=0.5)
    slab = Plane(1, (0, 0, 0), (0, 1, 0), (10.0, 10.0), mat)
    tt = _snell(d, np.array([0.0, 1.0, 0.0]), 1 / 1.5)
    tt = tt[tt[:, 1] < 0]
    s = np.zeros(len(tt))
    while (-(s * tt[:, 1]) < 0.5).any():
        s = np.where(-(s * tt[:, 1]) < 0.5, s + MARCH_STEP, s)
    np.testing.assert_allclose(ts.chord_lengths(slab, np.zeros_like(tt), tt), s, atol=2 * MARCH_STEP / 0.1)


def test_chord_swap_replaces_the_thickness_attenuation_by_the_chords():
    scene = load_scene("glass").with_camera(width=32, height=24)
    look = ts.lookups(scene)
    rng = np.random.default_rng(3)
    S, X = rng.uniform(0.1, 1.0, (24, 32, 3)), rng.uniform(0.1, 1.0, (24, 32, 3))
    a_t, want = np.ones((24, 32, 3)), S + X
    for ob in scene.objects:
        m = look.ids == ob.id
        if ob.material.attenuation_distance > 0 and m.any():
            sigma = -np.log(np.asarray(ob.material.attenuation_color)) / ob.material.attenuation_distance
            a_t[m] = np.exp(-sigma * ob.material.thickness)
            want[m] = S[m] + np.exp(-sigma * look.chord[m][:, None]) * X[m]
    got = ts.chord_swap(scene, look, S + a_t * X, S + X)
    np.testing.assert_allclose(got, np.where(a_t < 1, want, S + X), rtol=1e-12)
    tinted = np.isin(look.ids, [ob.id for ob in scene.objects if ob.name.startswith("tinted")])
    assert tinted.sum() > 100 and (np.abs(got - (S + a_t * X))[tinted] > 1e-3).mean() > 0.9


def test_lod_bias_glsl_matches_numpy_and_is_defined_only_where_not_zero():
    from realtime.presets import resolve_options
    lod, b = np.meshgrid([0.0, 0.5, 2.6, 9.0], [-16.0, -1.0, 0.0, 0.5, 3.0], indexing="ij")
    got = run_glsl("transmission_lod_biased(x0, x1)", lod, b)
    np.testing.assert_allclose(got, rt.biased_lod(lod, b), atol=1e-6)
    assert rt.biased_lod(0.5, -1.0) == 0.0 and rt.biased_lod(2.0, 1.5) == 3.5
    glass, plain = load_scene("glass"), load_scene("spheres")
    o0, o1 = resolve_options("default"), resolve_options("default", {"transmission_lod_bias": -1.5})
    assert rt.lod_bias_defines(rt.transmission_defines(glass, o0, "raster"), o0) == {}
    assert rt.lod_bias_defines(rt.transmission_defines(glass, o1, "raster"), o1) == {"TRANSMISSION_LOD_BIAS": "-1.5"}
    assert rt.lod_bias_defines(rt.transmission_defines(plain, o1, "raster"), o1) == {}   # no transmission program


def test_split_parts_come_from_real_renders():
    """A truth whose transmission is read 2 levels above the rule (the real-time renderer with
    ``transmission_lod_bias = 2``): the default preset's scan finds +2 best on every sphere and its LOD
    part is its whole error there; the thickness part is 0 on the clear spheres (no attenuation: the
    renders with and without it are the same) and not on the tinted ones."""
    from compare import renderers
    scene = load_scene("glass").with_camera(width=24, height=18)
    truth = renderers.render_under_test(scene, renderers.RendererSpec.parse("default", {**SMALL, "transmission_lod_bias": 2.0}))
    rows = {r["object"]: r for r in ts.split(scene, truth, "default", overrides=SMALL, biases=(0.0, 2.0))}
    assert set(rows) == {"all"} | {ob.name for ob in scene.objects[:6]}
    for name, r in rows.items():
        assert r["total"] > 1e-4, name
        assert r["lod"] == pytest.approx(r["total"], abs=1e-12), name
        assert name == "all" or r["lod_bias"] == 2.0
        assert r["offscreen"] == 0.0
        if name.startswith("clear"):
            assert r["thickness"] == 0.0
        elif name.startswith("tinted"):
            assert abs(r["thickness"]) > 1e-4


def _box(lo, hi) -> np.ndarray:
    """(12, 3, 3) triangles of the axis-aligned box [lo, hi]."""
    c = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])], float)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return np.array([c[[a, b, e]] for a, b, d, e in quads] + [c[[b, d, e]] for a, b, d, e in quads])


def test_ray_triangles_finds_a_boxs_exit_as_the_slab_closed_form():
    """A mesh's chord: the refracted ray from a point of the box's top face (y = 0.5) to its first
    hit; where it leaves through the bottom face it is the slab's ``thickness / cos(theta_t)``."""
    rng = np.random.default_rng(5)
    tris = _box((-2.0, -0.5, -2.0), (2.0, 0.5, 2.0))
    p = np.column_stack([rng.uniform(-0.5, 0.5, 30), np.full(30, 0.5), rng.uniform(-0.5, 0.5, 30)])
    d = rng.normal(size=(30, 3)) * (0.4, 0.0, 0.4) + (0.0, -1.0, 0.0)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    t = _snell(d, np.array([0.0, 1.0, 0.0]), 1 / 1.5)
    s, k = ts.ray_triangles(p, t, tris)
    np.testing.assert_allclose(s, 1.0 / -t[:, 1], rtol=1e-12)
    assert (k >= 0).all() and set(k) <= {2, 8}   # the bottom face (y = -0.5: quad 2) and its second triangle
    # from the outside along -z: the front face at distance 3 - 2 = 1; a miss is inf, -1
    s2, k2 = ts.ray_triangles(np.array([0.0, 0.0, 3.0]), np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]), tris)
    assert s2[0] == pytest.approx(1.0) and s2[1] == np.inf and k2[1] == -1


def test_without_attenuation_rewrites_a_gltf_asset(tmp_path):
    """The thickness part's render ``B`` of a glTF asset: the document without the volume's
    attenuation, in a temporary copy, with the same camera; the source file unchanged."""
    from gltf_build import quad_asset
    from pbrcheck.scene import asset_scene
    vol = {"thicknessFactor": 0.5, "attenuationDistance": 0.25, "attenuationColor": [0.9, 0.4, 0.1]}
    src = quad_asset(tmp_path / "slab.gltf", {"pbrMetallicRoughness": {"metallicFactor": 0.0}, "extensions": {
        "KHR_materials_transmission": {"transmissionFactor": 1.0}, "KHR_materials_volume": vol}})
    before = src.read_text()
    scene = asset_scene(src, size=(16, 12))
    with ts._without_attenuation(scene) as free:
        ob = free.objects[0]
        v = free.assets[ob.instance].asset.material(ob.gltf_material).volume
        assert v.thickness == 0.5 and v.attenuation_distance == np.inf and v.attenuation_color == (1.0, 1.0, 1.0)
        assert free.camera == scene.camera
    v0 = scene.assets[0].asset.material(scene.objects[0].gltf_material).volume
    assert v0.attenuation_distance == 0.25 and src.read_text() == before
