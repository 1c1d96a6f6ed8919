"""``[brdf] geometric_roughness = "threejs"``: the reference adds three.js r187's screen-space
geometric roughness (max over the view-space normal's components of max(|dFdx n|, |dFdy n|), over
one sample of the engine's raster) to the floored roughness. Tested against a numpy closed form on
spheres: the analytic sphere hit's normal, differentiated in view space by central differences
through pbrcheck.camera's rays."""
from __future__ import annotations

import numpy as np
import pytest

import pbrcheck  # noqa: F401
from pbrcheck.camera import camera_frame, primary_rays
from pbrcheck.errors import SceneError
from pbrcheck.scene import scene_from_dict

#: The reference against the closed form's derivative: Mitsuba's ray differential is the next
#: pixel's direction (a one-pixel difference, not the derivative: measured 0.2-0.6 % above it here;
#: three.js's dFdx is a one-sample difference too).
GEO_RTOL = 1e-2
#: Sub-pixel step of the closed form's central differences (its error ~ EPS^2).
EPS = 1e-3


def _scene(ss=2, geometric="threejs", roughness=0.0, origin=(0.5, 0.8, 6.0), lights=False):
    d = {"camera": {"origin": list(origin), "target": [0, 0, 0], "fov": 40, "width": 40, "height": 24},
         "environment": {"type": "none"} if lights else {"type": "sky", "resolution": [64, 32],
                                                          "sun_direction": [0.3, 0.5, 0.8], "sun_radiance": [40, 40, 40]},
         "lights": [{"type": "point", "position": [-2, 2, 4], "intensity": [10, 10, 10]}] if lights else [],
         "brdf": {"multiscatter": "random_walk", "roughness_floor": 0.045, "geometric_roughness": geometric,
                  "geometric_roughness_supersample": ss},
         "objects": [{"type": "sphere", "center": [-1.2, 0.1, 0], "radius": 0.9,
                      "material": {"metallic": 1.0, "roughness": roughness, "base_color": [0.9, 0.8, 0.7]}},
                     {"type": "sphere", "center": [1.3, -0.2, -1.0], "radius": 1.1,
                      "material": {"metallic": 0.0, "roughness": 0.3, "base_color": [0.5, 0.5, 0.5]}}]}
    return scene_from_dict(d, file="t.toml")


def closed_form(scene) -> np.ndarray:
    """numpy: g = max_c max(|dn_c/dx|, |dn_c/dy|) / supersample, n the view-space normal of the
    first sphere hit (NaN where a ray or its neighbours miss, or hit another sphere)."""
    cam = scene.camera
    r, u, f = camera_frame(cam)
    view = np.stack([r, u, -f])  # three.js's view axes: x right, y up, z toward the viewer

    def normals(ox, oy):
        o, d = primary_rays(cam, (ox, oy))
        best_t = np.full(d.shape[:2], np.inf)
        n = np.full(d.shape, np.nan)
        for s in scene.objects:
            c, R = np.asarray(s.center), s.radius
            oc = o - c
            b = d @ oc
            disc = b * b - (oc @ oc - R * R)
            t = -b - np.sqrt(np.where(disc > 0, disc, np.nan))
            hit = (t > 0) & (t < best_t)
            best_t = np.where(hit, t, best_t)
            n = np.where(hit[..., None], (o + t[..., None] * d - c) / R, n)
        return n @ view.T

    dx = (normals(0.5 + EPS, 0.5) - normals(0.5 - EPS, 0.5)) / (2 * EPS)
    dy = (normals(0.5, 0.5 + EPS) - normals(0.5, 0.5 - EPS)) / (2 * EPS)
    g = np.maximum(np.abs(dx), np.abs(dy)).max(axis=-1) / scene.brdf.geometric_roughness_supersample
    return g


@pytest.mark.parametrize("ss", [1, 2])
def test_reference_geometric_roughness_matches_the_closed_form(ss):
    from reference.render import geometric_roughness_image

    scene = _scene(ss=ss)
    got = geometric_roughness_image(scene)
    want = closed_form(scene)
    inside = np.isfinite(want) & (want < 1.0)  # the silhouette's last pixels: g -> infinity
    assert inside.sum() > 250
    np.testing.assert_allclose(got[inside], want[inside], rtol=GEO_RTOL)
    assert np.all(got[~np.isfinite(want)] == 0) or np.all(np.isfinite(got))
    # three.js's figure on the CI spheres at its 2 x 2 samples: a few hundredths in the centre
    assert 0.01 < np.median(want[inside]) < 0.2


def test_default_keeps_the_hash_and_bad_values_name_the_field():
    plain = _scene(geometric="none", ss=1)
    assert "geometric_roughness" not in plain.content_dict()["brdf"]
    assert "geometric_roughness_supersample" not in plain.content_dict()["brdf"]
    s = _scene()
    assert s.content_dict()["brdf"]["geometric_roughness"] == "threejs"
    assert scene_from_dict(s.to_dict(), file="t.toml").brdf == s.brdf  # round trip
    for key, bad in (("geometric_roughness", "babylon"), ("geometric_roughness_supersample", 0),
                     ("geometric_roughness_supersample", 1.5)):
        d = s.to_dict()
        d["brdf"][key] = bad
        with pytest.raises(SceneError) as e:
            scene_from_dict(d, file="t.toml")
        assert f"brdf.{key}" in str(e.value)


def test_render_adds_the_geometric_roughness():
    """Lit by a point light only (added exactly: the same samples give the same pixels), the option
    changes the smooth metal's highlight (roughness 0.045 -> ~0.1 there) and nothing where the
    camera rays miss."""
    from reference.render import render_uncached

    on = render_uncached(_scene(lights=True), spp=8, progress=False, adaptive=False)
    off = render_uncached(_scene(geometric="none", lights=True), spp=8, progress=False, adaptive=False)
    rgb = lambda im: np.stack([im.channels[c] for c in "RGB"], -1)  # noqa: E731
    obj = on.channels["object"]
    d = np.abs(rgb(on) - rgb(off))
    assert np.isfinite(rgb(on)).all()
    assert d[obj == 0].sum() > 0.2 * rgb(off)[obj == 0].sum()  # the smooth metal's highlight
    miss = on.channels["coverage"] == 0
    assert miss.sum() > 100
    np.testing.assert_array_equal(rgb(on)[miss], rgb(off)[miss])


# --- glTF assets (issue 40): the textured material takes the geometric roughness too ------------------

#: The quad's vertex normals tilt along x: (+-TILT, 0, 1) at x = +-1, so the interpolated normal is
#: normalize(TILT x, 0, 1) (barycentric interpolation of a function linear in x is exact).
TILT = 3.0
#: Sub-pixel positions per axis of the closed form's box filter (the render's pixel integral).
SUB = 16
#: The render (256 spp of box-filter positions, a point light added exactly) against the closed form
#: averaged over SUB x SUB positions: both integrate the same function over the pixel (measured 0.9 %
#: per pixel; 6 x 6 positions and 64 spp: 8 %, the highlight of roughness 0.12 is that narrow).
ASSET_RTOL = 0.03


#: UV layouts of the tilted quad (TEXCOORD_0 per corner, tests/gltf_build.QUAD_UV's order): the unit
#: square, tiled 4 x (Mitsuba's mesh normal partials are per barycentric, its position partials per
#: texture uv: without reference.textured.uv_normal_partials g came out 4x too small), and u and v
#: swapped and mirrored (the off-diagonal terms of the chain rule).
UV_LAYOUTS = {"unit": [[0, 1], [1, 1], [1, 0], [0, 0]], "tiled": [[0, 4], [4, 4], [4, 0], [0, 0]],
              "swapped": [[1, 0], [1, 1], [0, 1], [0, 0]]}


def _tilted_quad(tmp_path, roughness, uv="tiled"):
    from gltf_build import QUAD_IDX, QUAD_POS, QUAD_TAN, Doc
    nrm = np.array([[x * TILT, 0.0, 1.0] for x, _, _ in QUAD_POS], np.float32)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    doc = Doc()
    attrs = {"POSITION": doc.accessor(QUAD_POS, "VEC3", minmax=True), "NORMAL": doc.accessor(nrm, "VEC3"),
             "TEXCOORD_0": doc.accessor(np.asarray(UV_LAYOUTS[uv], np.float32), "VEC2"),
             "TANGENT": doc.accessor(QUAD_TAN, "VEC4")}
    doc.d["materials"] = [{"pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.8, 0.7, 1.0], "metallicFactor": 1.0,
                                                    "roughnessFactor": roughness}}]
    doc.node(doc.mesh(attrs, doc.accessor(QUAD_IDX, "SCALAR"), 0))
    return doc.write(tmp_path / f"tilted{roughness}{uv}.gltf")


def _asset_scene(asset, geometric="threejs", ss=2, floor=0.0, more=()):
    return scene_from_dict({
        "camera": {"origin": [0.0, 0.0, 4.0], "target": [0.0, 0.0, 0.0], "fov": 36.0, "width": 24, "height": 12},
        "environment": {"type": "none"},
        "lights": [{"type": "point", "position": [0.4, 0.3, 3.0], "intensity": [8.0, 8.0, 8.0]}],
        "brdf": {"geometric_roughness": geometric, "geometric_roughness_supersample": ss, "roughness_floor": floor},
        "objects": [{"type": "gltf", "path": str(asset)}, *more]}, file="t.toml")


def _quad_hit(cam, ox, oy):
    """numpy: (hit point on the plane z = 0, the interpolated normal there, the direction to the viewer)
    of the rays through the pixels at sub-pixel offset (ox, oy)."""
    o, d = primary_rays(cam, (ox, oy))
    p = o + (-o[2] / d[..., 2])[..., None] * d
    n = np.stack([TILT * p[..., 0], 0 * p[..., 0], np.ones_like(p[..., 0])], -1)
    return p, n / np.linalg.norm(n, axis=-1, keepdims=True), -d


def _quad_g(scene, ox, oy):
    """numpy: three.js's g at sub-pixel offset (ox, oy), by central differences of the normal (the
    camera looks down -z with +y up: view space is world space, up to signs that abs removes)."""
    cam = scene.camera
    dx = (_quad_hit(cam, ox + EPS, oy)[1] - _quad_hit(cam, ox - EPS, oy)[1]) / (2 * EPS)
    dy = (_quad_hit(cam, ox, oy + EPS)[1] - _quad_hit(cam, ox, oy - EPS)[1]) / (2 * EPS)
    return np.maximum(np.abs(dx), np.abs(dy)).max(axis=-1) / scene.brdf.geometric_roughness_supersample


def _asset_closed_form(scene, roughness):
    """numpy, per pixel: the mean over SUB x SUB sub-pixel positions of the metal's point-lit radiance
    at ``min(max(roughness, floor) + g, 1)`` (:func:`_quad_g`), and whether every position hits the quad."""
    from pbrcheck.brdf import brdf_eval
    cam, (light,) = scene.camera, scene.lights
    total, inside = 0.0, True
    for oy in (np.arange(SUB) + 0.5) / SUB:
        for ox in (np.arange(SUB) + 0.5) / SUB:
            p, n, v = _quad_hit(cam, ox, oy)
            r = np.minimum(np.maximum(roughness, scene.brdf.roughness_floor) + _quad_g(scene, ox, oy), 1.0)
            to_l = np.asarray(light.position) - p
            dist2 = (to_l ** 2).sum(-1, keepdims=True)
            l = to_l / np.sqrt(dist2)
            f = brdf_eval(n, v, l, (0.9, 0.8, 0.7), 1.0, r, 0.04)
            total = total + f * np.clip((n * l).sum(-1, keepdims=True), 0, None) * np.asarray(light.intensity) / dist2
            inside = inside & (np.abs(p[..., 0]) < 1) & (np.abs(p[..., 1]) < 1)
    return total / SUB ** 2, inside


@pytest.mark.parametrize("uv", sorted(UV_LAYOUTS))
def test_a_gltf_asset_geometric_roughness_matches_the_closed_form(tmp_path, uv):
    """g at the pixel centres of the tilted glTF quad, whatever its UV layout (the normal's
    derivative is the surface's, not the texture's)."""
    from reference.render import geometric_roughness_image

    scene = _asset_scene(_tilted_quad(tmp_path, 0.1, uv), floor=0.045)
    got_g = geometric_roughness_image(scene)
    want_g = _quad_g(scene, 0.5, 0.5)
    centre = _quad_hit(scene.camera, 0.5, 0.5)[0]
    on_quad = (np.abs(centre[..., 0]) < 1) & (np.abs(centre[..., 1]) < 1)
    assert on_quad.sum() >= 150
    np.testing.assert_allclose(got_g[on_quad], want_g[on_quad], rtol=GEO_RTOL)
    assert 0.015 < want_g[on_quad].min() and 0.15 < want_g[on_quad].max() < 0.5   # of the order of the roughness


def test_a_gltf_asset_shades_the_geometric_roughness(tmp_path):
    """The tilted glTF quad (UV tiled 4 x), a smooth metal lit by a point light: the reference shades
    min(max(r, floor) + g, 1) per lane with g the closed form's, and without the option it does not."""
    from reference.render import render_uncached

    asset = _tilted_quad(tmp_path, 0.1)
    scene = _asset_scene(asset, floor=0.045)

    rgb = lambda im: np.stack([im.channels[c] for c in "RGB"], -1)  # noqa: E731
    on = rgb(render_uncached(scene, spp=256, progress=False, adaptive=False))
    off = rgb(render_uncached(_asset_scene(asset, geometric="none", floor=0.045), spp=64, progress=False,
                              adaptive=False))
    want, inside = _asset_closed_form(scene, 0.1)
    assert inside.sum() >= 100
    np.testing.assert_allclose(on[inside].mean(0), want[inside].mean(0), rtol=ASSET_RTOL)
    per_pixel = np.abs(on[inside] - want[inside]).sum() / want[inside].sum()
    assert per_pixel < ASSET_RTOL
    assert np.abs(off[inside] - want[inside]).sum() / want[inside].sum() > 5 * ASSET_RTOL   # the option shows

    # several materials (a second asset, an analytic sphere; both behind the camera): the calls go
    # through dr.switch, each callee with its lanes of g; the image is the same
    behind = ({"type": "gltf", "path": str(asset), "translation": [0.0, 0.0, 9.0]},
              {"type": "sphere", "center": [0.0, 0.0, 12.0], "radius": 1.0, "material": {"roughness": 0.2}})
    several = rgb(render_uncached(_asset_scene(asset, floor=0.045, more=behind), spp=256, progress=False,
                                  adaptive=False))
    np.testing.assert_allclose(several, on, rtol=1e-4, atol=1e-6)
