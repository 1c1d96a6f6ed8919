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
