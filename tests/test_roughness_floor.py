"""``[brdf] roughness_floor``: the reference's material shades max(roughness, floor) (an engine's
roughness clamp as a scene-level option of the reference; three.js r187 floors at 0.045)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import pbrcheck  # noqa: F401
from pbrcheck.errors import SceneError
from pbrcheck.scene import scene_from_dict

#: three.js r187's floor (lights_physical_fragment.glsl.js: max(roughnessFactor, 0.045)).
THREEJS_FLOOR = 0.045
#: Roughness of the test spheres: below, near and above the floor (0 is the delta-lobe mirror).
ROUGHNESS = (0.0, 0.02, 0.045, 0.3)


def _scene(roughness=ROUGHNESS, **brdf):
    d = {"camera": {"origin": [0, 0, 6], "target": [0, 0, 0], "fov": 40, "width": 24, "height": 8},
         "environment": {"type": "sky", "resolution": [64, 32], "sun_direction": [0.3, 0.5, 0.8],
                         "sun_radiance": [40, 40, 40]},
         "lights": [{"type": "point", "position": [-2, 2, 4], "intensity": [10, 10, 10]}],
         "brdf": brdf,
         "objects": [{"type": "sphere", "center": [-1.8 + 1.2 * i, 0, 0], "radius": 0.5,
                      "material": {"metallic": 1.0, "roughness": r, "base_color": [0.9, 0.8, 0.7]}}
                     for i, r in enumerate(roughness)]}
    return scene_from_dict(d, file="t.toml")


def test_default_keeps_the_hash_and_a_floor_changes_it():
    s = _scene()
    assert s.brdf.roughness_floor == 0.0
    assert "roughness_floor" not in s.content_dict()["brdf"]  # earlier cache keys and references hold
    f = _scene(roughness_floor=THREEJS_FLOOR)
    assert f.content_dict()["brdf"]["roughness_floor"] == THREEJS_FLOOR
    assert scene_from_dict(f.to_dict(), file="t.toml").brdf.roughness_floor == THREEJS_FLOOR  # round trip


@pytest.mark.parametrize("bad", [-0.1, 1.5, "0.045", True])
def test_bad_floor_names_the_field(bad):
    with pytest.raises(SceneError) as e:
        _scene(roughness_floor=bad)
    assert "brdf.roughness_floor" in str(e.value)


def test_floor_equals_rendering_the_floored_roughness():
    """A floor of 0.045 renders exactly what the scene with roughness max(r, 0.045) renders (same
    samples: the same Mitsuba scene), and differs from the unfloored scene on the spheres below it."""
    from reference.render import render_uncached

    floored = render_uncached(_scene(roughness_floor=THREEJS_FLOOR), spp=16, progress=False)
    clamped = render_uncached(_scene(roughness=tuple(max(r, THREEJS_FLOOR) for r in ROUGHNESS)),
                              spp=16, progress=False)
    plain = render_uncached(_scene(), spp=16, progress=False)
    rgb = lambda im: np.stack([im.channels[c] for c in "RGB"], -1)  # noqa: E731
    np.testing.assert_array_equal(rgb(floored), rgb(clamped))
    obj = plain.channels["object"]
    below = np.isin(obj, [0, 1])  # roughness 0 and 0.02: the floor changes them
    assert np.abs(rgb(floored) - rgb(plain))[below].max() > 1e-3
    above = np.isin(obj, [2, 3])  # at or above the floor: unchanged
    np.testing.assert_array_equal(rgb(floored)[above], rgb(plain)[above])


#: glTF asset: its roughnessFactor times the metallic-roughness texture's G (0 on the left half, 1 on
#: the right): the mirror (below the floor) | a rough metal (above it).
ASSET_FACTOR = 0.6


def _asset_scene(tmp_path, textured=True, factor=ASSET_FACTOR, **brdf):
    from gltf_build import quad_asset
    nearest = {"magFilter": 9728, "minFilter": 9728}   # NEAREST: each half its own texel roughness
    mr = np.zeros((4, 4, 3), np.uint8)
    mr[..., 2] = 255                     # B: metallic 1
    mr[:, 2:, 1] = 255                   # G: roughness texel 0 | 1
    pbr = {"baseColorFactor": [0.9, 0.8, 0.7, 1.0], "roughnessFactor": factor}
    if textured:
        pbr["metallicRoughnessTexture"] = {"index": 0}
    asset = quad_asset(tmp_path / f"q{textured}{factor}.gltf", {"pbrMetallicRoughness": pbr},
                       [(mr, nearest)] if textured else [])
    # the point light's mirror reflection falls on the left half (x = -0.25): the mirror shows none of
    # it, a floored roughness a narrow highlight
    return scene_from_dict({
        "camera": {"origin": [0, 0, 4], "target": [0, 0, 0], "fov": 36, "width": 32, "height": 16},
        "environment": {"type": "none"}, "brdf": brdf,
        "lights": [{"type": "point", "position": [-0.5, 0.0, 4.0], "intensity": [10, 10, 10]}],
        "objects": [{"type": "gltf", "path": str(asset)}]}, file="t.toml")


def test_the_floor_applies_per_texel_on_a_textured_asset(tmp_path):
    """On a glTF asset the floor applies to each texel's roughness (factor x texture, then max(., floor),
    reference.textured): with a floor of 0.045 the left half (texel roughness 0, a mirror) renders as
    the untextured quad of roughness 0.045 and the right half (0.6) as without the floor; without
    the floor the left half is a mirror, which shows the point light nowhere."""
    from reference.render import render_uncached

    def rgb(scene):
        im = render_uncached(scene, spp=16, progress=False, adaptive=False)
        return np.stack([im.channels[c] for c in "RGB"], -1), im.channels["object"] >= 0

    floored, on = rgb(_asset_scene(tmp_path, roughness_floor=THREEJS_FLOOR))
    plain, _ = rgb(_asset_scene(tmp_path))
    uniform, _ = rgb(_asset_scene(tmp_path, textured=False, factor=THREEJS_FLOOR))
    cols = np.arange(on.shape[1])[None, :]
    left, right = on & (cols < 15), on & (cols > 16)   # the texels' seam (x = 0) between columns 15 and 16
    assert left.sum() > 100 and right.sum() > 100
    np.testing.assert_allclose(floored[left], uniform[left], rtol=1e-5, atol=1e-7)
    np.testing.assert_array_equal(floored[right], plain[right])
    assert plain[left].max() == 0.0 and floored[left].max() > 0.1   # the mirror vs the floored highlight
    assert floored[right].max() > 0.01                                # the rough half is lit


def test_textured_material_gets_the_floor():
    """The glTF material's Mitsuba dict carries the floor (applied after the metallic-roughness
    texture in reference.textured)."""
    from reference.textured import _material_dict

    class _Asset:
        def material(self, index):
            from types import SimpleNamespace
            return SimpleNamespace(base_color=(1, 1, 1, 1), metallic=1.0, roughness=0.0, specular=0.04,
                                   normal_texture=None, double_sided=False, base_color_texture=None,
                                   metallic_roughness_texture=None, alpha_mode="OPAQUE", unlit=False)

    brdf = replace(_scene().brdf, roughness_floor=THREEJS_FLOOR)
    d = _material_dict(_Asset(), 0, brdf, {})
    assert d["roughness_floor"] == THREEJS_FLOOR
