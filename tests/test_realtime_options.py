"""Every option combination resolve_options accepts renders: presets x choice and bool option values
(and msaa's), drawn by hypothesis, render a 16 x 16 furnace, or a tiny normal-mapped, textured panel
with an occlusion texture and a MASK material (the raster pipeline's inputs), with finite pixels, or
are refused by resolve_options (or by render_realtime: raster-only options where auto resolves to the
ray-cast pipeline, pipeline=raycast on a mesh; by the backend: msaa above GL_MAX_SAMPLES) with a
one-line error (never a shader compile failure). The whole cross product:
tools/option_cross_product.py (docs/realtime.md)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pbrcheck.errors import BackendError
from pbrcheck.gltf_build import panel_asset
from pbrcheck.gltf_scene import UnsupportedSceneError
from pbrcheck.scene import asset_scene, load_scene
from realtime.presets import OPTIONS, PRESETS, OptionError, resolve_options
from realtime.render import render_realtime

# Small bakes: the drawn options decide which programs run, not how long they run.
SMALL = {"cube_size": 32, "irradiance_source_size": 8, "irradiance_size": 8, "prefilter_levels": 4,
         "prefilter_samples": 16, "lut_size": 8, "lut_samples": 16, "runtime_samples": 4, "supersample": 1}
#: The options a combination is drawn over: every choice and bool option (the switches of the programs).
SWITCHES = {name: (opt.choices if opt.kind == "choice" else (False, True))
            for name, opt in OPTIONS.items() if opt.kind in ("choice", "bool")}
#: msaa, an int option with requirements (alpha_to_coverage needs one of its multisampling values).
SWITCHES["msaa"] = (1, 2, 4, 8)


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    """The furnace and the MASK panel (pbrcheck.gltf_build.panel_asset, 8 segments, 16^2 textures), 16 x 16."""
    d = tmp_path_factory.mktemp("mask_panel")
    panel = panel_asset(d / "panel.glb", segments=8, tex=16, alpha_mode="MASK", alpha=0.6)
    return {"furnace": load_scene("furnace").with_camera(width=16, height=16),
            "panel": asset_scene(panel, size=(16, 16))}


@st.composite
def combinations(draw):
    scene = draw(st.sampled_from(("furnace", "panel")))
    preset = draw(st.sampled_from(sorted(PRESETS)))
    names = draw(st.lists(st.sampled_from(sorted(SWITCHES)), unique=True, min_size=1, max_size=6))
    return scene, preset, {name: draw(st.sampled_from(SWITCHES[name])) for name in names}


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(combinations())
def test_every_accepted_combination_renders(scenes, combination):
    scene_name, preset, overrides = combination
    try:
        resolve_options(preset, {**SMALL, **overrides})
    except OptionError as e:
        assert "\n" not in str(e) and str(e).startswith("option "), str(e)
        return
    try:
        img = render_realtime(scenes[scene_name], preset, {**SMALL, **overrides}, progress=False)
    except OptionError as e:  # raster-only options where auto resolves to the ray-cast pipeline
        assert "\n" not in str(e) and str(e).startswith("option "), str(e)
        return
    except BackendError as e:  # msaa above this GL's GL_MAX_SAMPLES (llvmpipe: 4): exit 3
        assert "GL_MAX_SAMPLES" in str(e) and "\n" not in str(e), str(e)
        return
    except UnsupportedSceneError as e:  # pipeline=raycast on the panel's mesh
        assert scene_name == "panel" and overrides.get("pipeline") == "raycast" and "\n" not in str(e), str(e)
        return
    for name in ("R", "G", "B"):
        assert np.all(np.isfinite(img.channels[name])), f"{scene_name} {preset} {overrides}: non-finite {name}"


def test_fresnel_none_renders_on_every_preset():
    """The combinations that once failed to compile (article 001's F with FRESNEL_NONE) or died on a
    dropped uniform (filament's sh with no diffuse term) render, and fresnel=none is F = 1."""
    scene = load_scene("furnace").with_camera(width=16, height=16)
    for preset in PRESETS:
        img = render_realtime(scene, preset, {**SMALL, "fresnel": "none"}, progress=False)
        assert np.all(np.isfinite(img.channels["R"])), preset
