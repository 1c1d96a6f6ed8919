"""Every option combination resolve_options accepts renders: presets x choice and bool option values,
drawn by hypothesis, render a 16 x 16 furnace with finite pixels, or are refused by resolve_options
(or by render_realtime: raster-only options where auto resolves to the ray-cast pipeline) with a
one-line OptionError (never a shader compile failure). The whole cross product:
tools/option_cross_product.py (docs/realtime.md)."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pbrcheck.scene import load_scene
from realtime.presets import OPTIONS, PRESETS, OptionError, resolve_options
from realtime.render import render_realtime

# Small bakes: the drawn options decide which programs run, not how long they run.
SMALL = {"cube_size": 32, "irradiance_source_size": 8, "irradiance_size": 8, "prefilter_levels": 4,
         "prefilter_samples": 16, "lut_size": 8, "lut_samples": 16, "runtime_samples": 4, "supersample": 1}
#: The options a combination is drawn over: every choice and bool option (the switches of the programs).
SWITCHES = {name: (opt.choices if opt.kind == "choice" else (False, True))
            for name, opt in OPTIONS.items() if opt.kind in ("choice", "bool")}


@st.composite
def combinations(draw):
    preset = draw(st.sampled_from(sorted(PRESETS)))
    names = draw(st.lists(st.sampled_from(sorted(SWITCHES)), unique=True, min_size=1, max_size=6))
    return preset, {name: draw(st.sampled_from(SWITCHES[name])) for name in names}


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(combinations())
def test_every_accepted_combination_renders(combination):
    preset, overrides = combination
    try:
        resolve_options(preset, {**SMALL, **overrides})
    except OptionError as e:
        assert "\n" not in str(e) and str(e).startswith("option "), str(e)
        return
    scene = load_scene("furnace").with_camera(width=16, height=16)
    try:
        img = render_realtime(scene, preset, {**SMALL, **overrides}, progress=False)
    except OptionError as e:  # raster-only options where auto resolves to the ray-cast pipeline
        assert "\n" not in str(e) and str(e).startswith("option "), str(e)
        return
    for name in ("R", "G", "B"):
        assert np.all(np.isfinite(img.channels[name])), f"{preset} {overrides}: non-finite {name}"


def test_fresnel_none_renders_on_every_preset():
    """The combinations that once failed to compile (article 001's F with FRESNEL_NONE) or died on a
    dropped uniform (filament's sh with no diffuse term) render, and fresnel=none is F = 1."""
    scene = load_scene("furnace").with_camera(width=16, height=16)
    for preset in PRESETS:
        img = render_realtime(scene, preset, {**SMALL, "fresnel": "none"}, progress=False)
        assert np.all(np.isfinite(img.channels["R"])), preset
