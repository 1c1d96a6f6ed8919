"""Every baked artifact's process-cache key is derived from the options that declare the bake
(``Option.bakes``, realtime/presets.py): changing an option that affects a bake changes that bake's
key, an option that does not leaves it; a bake reading an undeclared option fails instead of keying a
stale texture; defaults live on the options only; ``RealtimeOptions`` is attribute access only."""

from __future__ import annotations

from collections.abc import Mapping

import pytest

from pbrcheck.scene import load_scene
from realtime.gl import shader_sources_hash
from realtime import render as R
from realtime.presets import (BAKES, OPTIONS, PRESETS, BakeInputs, OptionError, bake_inputs, bake_key,
                              bake_options, parse_value, resolve_options)

#: Contexts an option's change is tried in (an option with requirements needs them met).
CONTEXTS = ({}, {"pipeline": "raster"}, {"pipeline": "raster", "msaa": 2})


def _other_values(name: str, tmp_path) -> list:
    """Valid values of option ``name`` other than its default (a few; the first that resolves is used)."""
    opt = OPTIONS[name]
    d = opt.default
    if opt.kind == "bool":
        return [not d]
    if opt.kind == "choice":
        return [c for c in opt.choices if c != d]
    if opt.kind == "file":
        hook = tmp_path / "hook.glsl"
        hook.write_text("vec3 hook_diffuse_ibl(vec3 n) { return vec3(0.0); }\n")
        return [str(hook)]
    if opt.kind == "int":
        return [v for v in (d * 2, d // 2, d + 1, d - 1) if opt.lo <= v <= opt.hi]
    return [v for v in (d + 0.5, d * 0.5, d + 0.25) if opt.lo <= v <= opt.hi]


def _changed_pair(name: str, tmp_path):
    """(options, options with ``name`` changed) from the default preset, both accepted."""
    for ctx in CONTEXTS:
        for v in _other_values(name, tmp_path):
            try:
                return resolve_options("default", ctx), resolve_options("default", {**ctx, name: v})
            except OptionError:
                continue
    raise AssertionError(f"option {name}: no other value is accepted in any context")


@pytest.mark.parametrize("name", sorted(OPTIONS))
def test_an_option_changes_exactly_the_keys_of_the_bakes_it_declares(name, tmp_path):
    base, changed = _changed_pair(name, tmp_path)
    assert getattr(base, name) != getattr(changed, name)
    moved = {b for b in BAKES if bake_inputs(b, base).key("env") != bake_inputs(b, changed).key("env")}
    assert moved == set(OPTIONS[name].bakes), name


def test_a_bake_reading_an_undeclared_option_fails_naming_it():
    o = resolve_options("default")
    sh9 = bake_inputs("sh9", o, cube_format="f32")
    assert (sh9.cube_size, sh9.irradiance_source_size) == (256, 32)
    with pytest.raises(AttributeError, match="bake 'sh9' reads option 'prefilter_samples'.*Option.bakes"):
        sh9.prefilter_samples
    with pytest.raises(KeyError, match="missing \\['cube_format'\\]"):
        bake_key("env_cube", "env", cube_size=64)          # a plain-argument bake keyed without an option
    with pytest.raises(KeyError, match="not its own \\['lut_size'\\]"):
        bake_key("env_cube", "env", cube_size=64, cube_format="f32", lut_size=8)
    with pytest.raises(KeyError, match="does not read option"):
        bake_inputs("kd_lut", o, cube_format="f16")          # a resolved value for an option it does not read
    with pytest.raises(AttributeError):
        sh9.cube_size = 3


def test_resolved_values_key_what_the_bake_reads():
    """A value the render resolves (cube_format f16 switched to f32, lut_geometry scene) keys the bake
    by the resolved value: two requests that bake the same texture share its key."""
    f16, f32 = resolve_options("default", {"cube_format": "f16"}), resolve_options("default")
    assert bake_inputs("prefilter", f16, cube_format="f32").key("e") == bake_inputs("prefilter", f32).key("e")
    assert bake_inputs("prefilter", f16).key("e") != bake_inputs("prefilter", f32).key("e")
    scene = bake_inputs("dfg_lut", f32, lut_geometry="smith_ggx", ndf="ggx")
    assert scene.key() == bake_inputs("dfg_lut", resolve_options("default", {"lut_geometry": "smith_ggx", "ndf": "ggx"})).key()


def test_the_render_bakes_under_the_derived_keys(tmp_path):
    """A furnace render keys each bake as bake_inputs/bake_key derive it; re-rendering with an option
    no bake reads adds no bake, with a prefilter option exactly one new prefiltered cube."""
    small = {"cube_size": 16, "irradiance_source_size": 8, "irradiance_size": 4, "prefilter_levels": 3,
             "prefilter_samples": 8, "lut_size": 8, "lut_samples": 8, "supersample": 1}
    scene = load_scene("furnace").with_camera(width=8, height=8)
    R.trim_environment_caches(0)
    R.render_realtime(scene, "default", small, progress=False)
    o = resolve_options("default", small)
    env = R.environment_of(scene).content_hash
    terms = R.resolved_terms(scene, o)
    want = [bake_key("env_cube", env, cube_size=16, cube_format="f32"),
            bake_inputs("irradiance", o).key(env), bake_inputs("prefilter", o, lod_mapping=o.chain).key(env),
            bake_key("dfg_lut", lut_size=8, lut_samples=8, lut_format="f32", lut_geometry=terms["lut_geometry"],
                     ndf=terms["ndf"], lut_sampling="vndf"),
            bake_key("kd_lut", lut_size=8)]
    for k in want:  # the process's bakes are also keyed by the shader sources (realtime.render._baked)
        assert (*k, shader_sources_hash()) in R._cache, k[0]
    bakes = lambda: {k for k in R._cache if isinstance(k, tuple) and k[0] in BAKES}  # noqa: E731
    before = bakes()
    R.render_realtime(scene, "default", {**small, "exposure": 2.0, "min_roughness": 0.1}, progress=False)
    assert bakes() == before
    R.render_realtime(scene, "default", {**small, "prefilter_samples": 16}, progress=False)
    assert [k[0] for k in bakes() - before] == ["prefilter"]


def test_defaults_live_on_the_options_and_are_valid():
    assert PRESETS["default"] == {name: opt.default for name, opt in OPTIONS.items()}
    for name, opt in OPTIONS.items():
        assert parse_value(name, opt.default) == opt.default, name
        assert set(opt.bakes) <= set(BAKES), name
    assert all(bake_options(b) for b in BAKES)              # every bake is keyed by some option
    with pytest.raises(KeyError, match="unknown bake"):
        bake_options("nope")


def test_realtime_options_are_attributes_only():
    o = resolve_options("default")
    assert o.cube_size == 256 and not isinstance(o, Mapping) and not isinstance(bake_inputs("kd_lut", o), Mapping)
    with pytest.raises(TypeError):
        o["cube_size"]
    assert o.as_dict()["cube_size"] == 256 and isinstance(bake_inputs("kd_lut", o), BakeInputs)
