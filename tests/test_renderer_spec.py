"""``compare.renderers.RendererSpec``: a renderer name (preset, ``PRESET+FILE.glsl``, ``ext:NAME``) and
its option overrides parsed once, with their errors; ``render_under_test`` takes the spec and renders
its resolved options without resolving them again (one resolve per render, cached or not)."""

from __future__ import annotations

import pytest

import compare.renderers as renderers
import realtime.presets as presets
import realtime.render as rt_render
from clients.config import RendererConfigError
from compare.renderers import RendererSpec
from pbrcheck.errors import PbrcheckError
from pbrcheck.scene import load_scene
from realtime.presets import OptionError

SMALL = {"cube_size": 16, "irradiance_source_size": 8, "irradiance_size": 4, "prefilter_levels": 3,
         "prefilter_samples": 8, "lut_size": 8, "lut_samples": 8, "supersample": 1}


@pytest.fixture
def hook(tmp_path):
    f = tmp_path / "hook.glsl"
    f.write_text("vec3 hook_diffuse_ibl(vec3 n) { return vec3(0.0); }\n")
    return f


def test_a_preset_with_overrides():
    s = RendererSpec.parse("filament", {"cube_size": "64", "prefilter_levels": 5})
    assert (s.text, s.name, s.external) == ("filament", "filament", False)
    assert s.overrides == (("cube_size", "64"), ("prefilter_levels", 5))
    assert (s.options.cube_size, s.options.prefilter_levels, s.options.irradiance) == (64, 5, "sh9")
    assert str(s) == "filament" and dict(s.override_dict) == {"cube_size": "64", "prefilter_levels": 5}


def test_a_hook_file_in_the_name_is_split_once(hook):
    s = RendererSpec.parse(f"default+{hook}", {"lod_mapping": "log2"})
    assert (s.text, s.name) == (f"default+{hook}", "default")
    assert s.options.shader == str(hook) and s.options.lod_mapping == "log2"
    assert dict(s.overrides) == {"shader": str(hook), "lod_mapping": "log2"}
    v = s.with_options(lod_mapping="linear")   # a variant keeps the hook and the name
    assert (v.text, v.options.shader, v.options.lod_mapping, s.options.lod_mapping) == (
        s.text, str(hook), "linear", "log2")


@pytest.mark.parametrize("text, overrides, error, match", [
    ("nope", None, OptionError, "unknown preset 'nope'; presets are: default"),
    ("default+", None, OptionError, "expected PRESET\\+FILE.glsl, found no file"),
    ("default+missing.glsl", None, OptionError, "option shader: no such file 'missing.glsl'"),
    ("default", {"cube_size": "big"}, OptionError, "option cube_size: expected an integer, found 'big'"),
    ("default", {"no_such": 1}, OptionError, "unknown option 'no_such'"),
    ("default", {"msaa": 4, "pipeline": "raycast"}, OptionError, "option msaa: 4 needs pipeline=raster"),
    ("", None, OptionError, "expected a preset name"),
    ("ext:nope", None, RendererConfigError, "unknown external renderer 'ext:nope'"),
    ("ext:threejs", {"supersample": 2}, PbrcheckError, "takes no options"),
])
def test_bad_renderers_fail_where_they_are_parsed(text, overrides, error, match):
    with pytest.raises(error, match=match):
        RendererSpec.parse(text, overrides)


def test_an_external_renderer_has_no_options():
    s = RendererSpec.parse("ext:threejs")
    assert s.external and s.options is None and s.name == s.text == "ext:threejs"
    assert s.with_options() is s
    with pytest.raises(PbrcheckError, match="takes no options"):
        s.with_options(cube_size=64)
    with pytest.raises(OptionError, match="option cube_size"):
        RendererSpec.parse("default").with_options(cube_size=3)


def test_render_under_test_takes_a_spec_only():
    with pytest.raises(TypeError, match="takes a RendererSpec"):
        renderers.render_under_test(load_scene("furnace"), "default")


@pytest.mark.parametrize("cache", [False, True])
def test_options_are_resolved_once_per_render(cache, monkeypatch, tmp_cache):
    calls = []
    real = presets.resolve_options

    def counting(preset, overrides=None):
        calls.append(preset)
        return real(preset, overrides)

    monkeypatch.setattr(presets, "resolve_options", counting)
    monkeypatch.setattr(rt_render, "resolve_options", counting)
    spec = RendererSpec.parse("default", SMALL)
    assert calls == ["default"]
    scene = load_scene("furnace").with_camera(width=8, height=8)
    img = renderers.render_under_test(scene, spec, context=renderers.RenderContext(cache=cache))
    assert calls == ["default"]  # the render took the spec's resolved options
    assert img.meta_json("options", None)["cube_size"] == 16 and img.meta["preset"] == "default"
