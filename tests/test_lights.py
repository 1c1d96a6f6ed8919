"""Spot and directional lights (pbrcheck.lights, KHR_lights_punctual semantics) with known answers:
the scene model and its errors, the glTF reader, the reference in both modes and the real-time
renderer. The spot's GLSL term against its numpy twin: tests/test_realtime_glsl.py."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from pbrcheck.camera import primary_rays
from pbrcheck_cli import main
from pbrcheck.errors import SceneError
from pbrcheck.gltf import AssetError
from pbrcheck.scene import load_scene, scene_from_dict
from gltf_build import quad_asset

# Directional light on a near-Lambertian plane (specular 0, roughness 1): the Schlick term at
# v.h ~ 0.87 leaves (1 - v.h)^5 ~ 4e-5 of the albedo to the specular lobe; float32 renders.
LAMBERT_RTOL = 1e-3
# A spot light inside its inner cone against the point light: the same samples, the attenuation is
# exactly 1; the emitters' float32 arithmetic differs in order only.
SAME_RTOL = 1e-5
# Spot/point ratio at a pixel against the attenuation at the pixel centre's hit: the footprint of a
# 32 x 32 pixel on the penumbra (the attenuation's slope x half a pixel's angle).
PENUMBRA_ATOL = 0.03
# Reference (local, 16 spp) against the real-time renderer on a lit sphere, mean |diff| over the
# pixels both cover, relative to the mean: their only differences are the pixel footprint's
# sampling (exact BRDF for punctual lights in both). A point light meets it too (checked here).
LIGHT_AGREEMENT = 0.02
# The real-time renderer's bakes at their smallest (no environment: they shade nothing here).
SMALL = {"cube_size": 32, "irradiance_source_size": 8, "irradiance_size": 8, "prefilter_levels": 4,
         "prefilter_samples": 64, "lut_size": 16, "lut_samples": 64, "supersample": 2}

LAMBERT = {"base_color": [0.8, 0.8, 0.8], "metallic": 0.0, "roughness": 1.0, "specular": 0.0}
SPOT = {"type": "spot", "position": [0.0, 0.0, 5.0], "direction": [0.0, 0.0, -1.0], "intensity": [10.0, 10.0, 10.0],
        "inner_cone_angle": 0.4, "outer_cone_angle": 0.6}


def _plane_scene(lights, size=16):
    """A floor seen from straight above, no environment."""
    return scene_from_dict({
        "camera": {"origin": [0.0, 4.0, 0.0], "target": [0.0, 0.0, 0.0], "up": [0.0, 0.0, -1.0], "fov": 40.0,
                   "width": size, "height": size},
        "environment": {"type": "none"}, "lights": lights,
        "objects": [{"type": "plane", "size": 20.0, "material": LAMBERT}]})


def _sphere_scene(lights, size=24, metallic=0.0):
    return scene_from_dict({
        "camera": {"origin": [0.0, 0.0, 4.0], "fov": 40.0, "width": size, "height": size},
        "environment": {"type": "none"}, "lights": lights,
        "objects": [{"type": "sphere", "radius": 1.0,
                     "material": {**LAMBERT, "metallic": metallic, "roughness": 0.4, "specular": 0.04}}]})


def _ref(scene, mode, spp=4):
    from reference.render import render_uncached
    return render_uncached(scene, spp=spp, mode=mode, max_depth=2, progress=False, adaptive=False)


# ---- the scene model ---------------------------------------------------------------------------

def test_scene_lights_read_with_glTF_conventions():
    s = _plane_scene([SPOT, {"type": "directional", "direction": [0.0, -2.0, 0.0], "intensity": [1.0, 2.0, 3.0]},
                      {"position": [1.0, 2.0, 3.0], "intensity": [1.0, 1.0, 1.0]}])
    spot, sun, point = s.lights
    assert (spot.type, spot.inner_cone_angle, spot.outer_cone_angle) == ("spot", 0.4, 0.6)
    assert sun.type == "directional" and sun.direction == (0.0, -1.0, 0.0)  # normalized, where it travels
    assert point.type == "point"
    default = scene_from_dict({"environment": {"type": "none"}, "objects": [{"type": "sphere"}],
                               "lights": [{"type": "spot", "position": [0, 1, 0], "direction": [0, -1, 0],
                                           "intensity": [1, 1, 1]}]}).lights[0]
    assert (default.inner_cone_angle, default.outer_cone_angle) == (0.0, math.pi / 4)  # glTF's defaults
    # the resolved scene reloads to the same lights
    assert scene_from_dict(s.to_dict()).lights == s.lights


@pytest.mark.parametrize("light, field, fragment", [
    ({**SPOT, "inner_cone_angle": 0.6}, "lights[0].inner_cone_angle", "< outer_cone_angle"),
    ({**SPOT, "inner_cone_angle": -0.1}, "lights[0].inner_cone_angle", ">= 0"),
    ({**SPOT, "outer_cone_angle": 2.0}, "lights[0].outer_cone_angle", "<= 1.57"),
    ({**SPOT, "outer_cone_angle": 0.0}, "lights[0].outer_cone_angle", "> 0"),
    ({**SPOT, "direction": [0.0, 0.0, 0.0]}, "lights[0].direction", "non-zero"),
    ({**SPOT, "direction": [0.0, float("nan"), 1.0]}, "lights[0].direction", "finite"),
    ({"type": "directional", "direction": [0, -1, 0], "intensity": [1, 1, 1], "position": [0, 0, 0]},
     "lights[0].position", "unknown key"),
    ({"type": "directional", "intensity": [1, 1, 1]}, "lights[0].direction", "required"),
    ({"type": "area", "position": [0, 0, 0], "intensity": [1, 1, 1]}, "lights[0].type", "point | spot | directional"),
])
def test_bad_lights_are_typed_errors(light, field, fragment):
    with pytest.raises(SceneError) as ei:
        scene_from_dict({"environment": {"type": "none"}, "objects": [{"type": "sphere"}], "lights": [light]},
                        file="x.toml")
    msg = str(ei.value)
    assert msg.startswith("x.toml: ") and field in msg and fragment in msg and "\n" not in msg, msg


def test_cli_refuses_a_bad_spot_with_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text('[environment]\ntype = "none"\n[[objects]]\ntype = "sphere"\n[[lights]]\ntype = "spot"\n'
                   'position = [0.0, 2.0, 0.0]\ndirection = [0.0, -1.0, 0.0]\nintensity = [1.0, 1.0, 1.0]\n'
                   'inner_cone_angle = 0.5\nouter_cone_angle = 0.5\n')
    before = sorted(tmp_path.iterdir())
    assert main(["check-scene", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(bad) in err and "lights[0].inner_cone_angle" in err
    assert sorted(tmp_path.iterdir()) == before


# ---- glTF --------------------------------------------------------------------------------------

def _lit_asset(tmp_path, lights, nodes):
    f = quad_asset(tmp_path / "q.gltf", {})
    doc = json.loads(f.read_text())
    doc["extensionsUsed"] = ["KHR_lights_punctual"]
    doc["extensions"] = {"KHR_lights_punctual": {"lights": lights}}
    for n in nodes:
        doc["nodes"].append(n)
        doc["scenes"][0]["nodes"].append(len(doc["nodes"]) - 1)
    f.write_text(json.dumps(doc))
    return f


# a node rotated -90 degrees about X: its -Z points down (-Y)
DOWN = [-math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)]


def test_gltf_spot_and_directional_lights_read_with_the_node_transform(tmp_path, capsys):
    f = _lit_asset(tmp_path, [{"type": "spot", "intensity": 5.0, "color": [1.0, 0.5, 0.25],
                               "spot": {"innerConeAngle": 0.1, "outerConeAngle": 0.3}},
                              {"type": "directional", "intensity": 2.0}],
                   [{"name": "lamp", "translation": [0, 3, 0], "rotation": DOWN,
                     "extensions": {"KHR_lights_punctual": {"light": 0}}},
                    {"name": "sun", "extensions": {"KHR_lights_punctual": {"light": 1}}}])
    s = tmp_path / "s.toml"
    # the placement turns the asset 90 degrees about Y and lifts it by 1
    s.write_text('[environment]\ntype = "none"\n[[objects]]\ntype = "gltf"\npath = "q.gltf"\n'
                 'rotation = [0.0, 90.0, 0.0]\ntranslation = [0.0, 1.0, 0.0]\n')
    spot, sun = load_scene(s).lights
    assert spot.type == "spot" and spot.intensity == (5.0, 2.5, 1.25)
    np.testing.assert_allclose(spot.position, (0, 4, 0), atol=1e-12)
    np.testing.assert_allclose(spot.direction, (0, -1, 0), atol=1e-12)
    assert (spot.inner_cone_angle, spot.outer_cone_angle) == (0.1, 0.3)
    # an unrotated node's -Z, turned by the placement's 90 degrees about Y: -X
    assert sun.type == "directional" and sun.intensity == (2.0, 2.0, 2.0)
    np.testing.assert_allclose(sun.direction, (-1, 0, 0), atol=1e-12)
    assert main(["check-scene", str(f)]) == 0
    out = capsys.readouterr().out
    assert "spot 5 cd" in out and "cone 0.1..0.3 rad" in out and "directional 2 lux" in out


@pytest.mark.parametrize("light, pointer", [
    ({"type": "spot", "spot": {"innerConeAngle": 0.5, "outerConeAngle": 0.5}}, "/spot/innerConeAngle"),
    ({"type": "spot", "spot": {"outerConeAngle": 2.0}}, "/spot/outerConeAngle"),
    ({"type": "directional", "intensity": -1.0}, "/intensity"),
])
def test_bad_gltf_lights_name_the_pointer(tmp_path, capsys, light, pointer):
    f = _lit_asset(tmp_path, [light], [{"extensions": {"KHR_lights_punctual": {"light": 0}}}])
    with pytest.raises(AssetError, match=f"/extensions/KHR_lights_punctual/lights/0{pointer}"):
        load_scene(f)
    assert main(["check-scene", str(f)]) == 2
    assert capsys.readouterr().err.count("\n") == 1


# ---- known answers: the reference (both modes) and the real-time renderer --------------------

def _spec_attenuation(cd, inner, outer):
    """KHR_lights_punctual's recommended attenuation, written out here (not pbrcheck's)."""
    t = np.clip((cd - math.cos(outer)) / max(1e-3, math.cos(inner) - math.cos(outer)), 0.0, 1.0)
    return t * t


@pytest.mark.parametrize("mode", ["local", "path"])
def test_directional_light_on_a_lambertian_plane(mode):
    """E albedo / pi cos, everywhere on the plane (a directional light has no falloff)."""
    th = math.radians(60.0)
    scene = _plane_scene([{"type": "directional", "direction": [math.sin(th), -math.cos(th), 0.0],
                           "intensity": [2.0, 3.0, 4.0]}])
    img = _ref(scene, mode)
    expect = np.array([2.0, 3.0, 4.0]) * 0.8 / math.pi * math.cos(th)
    np.testing.assert_allclose(img.rgb, np.broadcast_to(expect, img.rgb.shape), rtol=LAMBERT_RTOL)
    if mode == "local":
        from realtime.render import render_realtime
        rt = render_realtime(scene, "default", SMALL, progress=False)
        np.testing.assert_allclose(rt.rgb, np.broadcast_to(expect, rt.rgb.shape), rtol=LAMBERT_RTOL)


@pytest.mark.parametrize("mode", ["local", "path"])
def test_spot_inside_outside_and_between_its_cones(mode):
    """Inside the inner cone a spot is the point light of its intensity; beyond the outer cone it
    adds nothing; between, spot / point is the spec's falloff of the angle at the pixel."""
    point = {"type": "point", "position": SPOT["position"], "intensity": SPOT["intensity"]}
    p = _ref(_sphere_scene([point]), mode)
    s = _ref(_sphere_scene([SPOT]), mode)  # the sphere subtends 11.5 degrees, the inner cone 23
    assert p.rgb.max() > 0.05
    np.testing.assert_allclose(s.rgb, p.rgb, rtol=SAME_RTOL, atol=1e-7)
    away = _ref(_sphere_scene([{**SPOT, "direction": [0.0, 1.0, -0.5]}]), mode)  # 63 - 11.5 deg off, outer 34
    assert np.all(away.rgb == 0.0)
    if mode == "path":
        return
    # a spot 2 units above the floor, tilted: the floor holds the whole penumbra
    light = {"position": [0.0, 2.0, 0.0], "intensity": [10.0, 10.0, 10.0]}
    spot = {**light, "type": "spot", "direction": [0.3, -1.0, 0.0], "inner_cone_angle": 0.2, "outer_cone_angle": 0.7}
    a = _ref(_plane_scene([spot], size=32), mode).rgb[..., 0]
    b = _ref(_plane_scene([{**light, "type": "point"}], size=32), mode).rgb[..., 0]
    o, d = primary_rays(_plane_scene([spot], size=32).camera)
    hit = o + (-o[..., 1:2] / d[..., 1:2]) * d                  # the floor y = 0 at the pixel centres
    to_hit = hit - np.array(light["position"])
    axis = np.array(spot["direction"]) / np.linalg.norm(spot["direction"])
    cd = (to_hit @ axis) / np.linalg.norm(to_hit, axis=-1)
    expect = _spec_attenuation(cd, 0.2, 0.7)
    between = (expect > 0.02) & (expect < 0.98)
    assert between.sum() > 100
    np.testing.assert_allclose(a / b, expect, atol=PENUMBRA_ATOL)


def test_reference_and_realtime_agree_on_spot_and_directional_lights():
    from realtime.render import render_realtime
    cases = {"point": {"type": "point", "position": [2.0, 2.0, 3.0], "intensity": [10.0, 10.0, 10.0]},
             "spot": {**SPOT, "position": [2.0, 2.0, 3.0], "direction": [-2.0, -2.0, -3.0],
                      "inner_cone_angle": 0.05, "outer_cone_angle": 0.25},   # the penumbra crosses the sphere
             "directional": {"type": "directional", "direction": [-1.0, -1.0, -2.0], "intensity": [3.0, 3.0, 3.0]}}
    for name, light in cases.items():
        scene = _sphere_scene([light])
        ref = _ref(scene, "local", spp=16)
        rt = render_realtime(scene, "default", SMALL, progress=False)
        both = (ref.channels["coverage"] == 1) & (rt.channels["coverage"] == 1)
        err = np.abs(ref.rgb[both] - rt.rgb[both]).mean() / ref.rgb[both].mean()
        assert err < LIGHT_AGREEMENT, (name, err)


# ---- export ------------------------------------------------------------------------------------

def test_export_writes_spot_and_directional_lights_that_read_back(tmp_path):
    """pbrcheck export: KHR_lights_punctual spot (cones) and directional lights whose nodes' -Z is
    the light's direction; the glTF reader gives the scene's lights back."""
    from pbrcheck.export import export_scene
    from pbrcheck.gltf import load_asset
    sun = {"type": "directional", "direction": [0.3, -1.0, 0.2], "intensity": [2.0, 1.0, 0.5]}
    down = {**SPOT, "direction": [0.0, -1.0, 0.0]}  # parallel to the rotation's hint axis
    scene = _sphere_scene([SPOT, sun, down], size=8)
    export_scene(scene, tmp_path / "out")
    doc = json.loads((tmp_path / "out" / "scene.gltf").read_text())
    kinds = [L["type"] for L in doc["extensions"]["KHR_lights_punctual"]["lights"]]
    assert kinds == ["spot", "directional", "spot"] and "KHR_lights_punctual" in doc["extensionsUsed"]
    back = load_asset(tmp_path / "out" / "scene.gltf").lights
    for want, got in zip(scene.lights, back):
        assert got.type == want.type
        np.testing.assert_allclose(np.multiply(got.color, got.intensity), want.intensity, rtol=1e-12)
        np.testing.assert_allclose(got.direction, want.direction, atol=1e-9)
        if want.type == "spot":
            np.testing.assert_allclose(got.position, want.position, atol=1e-12)
            assert (got.inner_cone, got.outer_cone) == (want.inner_cone_angle, want.outer_cone_angle)
    sc = json.loads((tmp_path / "out" / "scenario.json").read_text())
    assert sc["lights"][1] == {"type": "directional", "gltf_node": "light_1", "direction": list(scene.lights[1].direction),
                               "irradiance_w_per_m2": [2.0, 1.0, 0.5]}


# ---- differentiable as point lights are ----------------------------------------------------------

# AD against central differences in base colour (the diffuse term is linear in it, so the step adds
# no error): two renders on different seeds whose only noise is the pixel footprint's (no
# environment), 16 x 16 at 64 spp: ~1 % measured, this allows three times that.
FD_STEP = 0.05
FD_RTOL = 0.03


@pytest.mark.parametrize("light", ["spot", "directional"])
def test_gradient_under_spot_and_directional_lights_matches_finite_differences(light):
    import drjit as dr
    import mitsuba as mi
    from reference.diff import load_differentiable_scene, param_key, render_image, render_with_gradient
    lights = {"spot": {**SPOT, "position": [2.0, 2.0, 3.0], "direction": [-2.0, -2.0, -3.0],
                       "inner_cone_angle": 0.05, "outer_cone_angle": 0.25},
              "directional": {"type": "directional", "direction": [-1.0, -1.0, -2.0], "intensity": [3.0, 3.0, 3.0]}}
    ms, params = load_differentiable_scene(_sphere_scene([lights[light]], size=16), spp=64)
    k = param_key(0, "base_color")
    _, _, g = render_with_gradient(ms, params, [k], lambda img: dr.mean(img, axis=None), spp=64, seed=1)
    vals = []
    for sgn in (1, -1):
        params[k] = mi.Color3f(0.8 + sgn * FD_STEP, 0.8, 0.8)
        params.update()
        vals.append(float(render_image(ms, params, spp=64, seed=2).mean()))
    fd = (vals[0] - vals[1]) / (2 * FD_STEP)
    assert fd > 1e-3
    assert float(np.ravel(g[k])[0]) == pytest.approx(fd, rel=FD_RTOL)
