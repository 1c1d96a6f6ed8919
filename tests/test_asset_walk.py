"""The random walk (Heitz et al. 2016, reference/multiscatter.py) on textured glTF materials, per
shading point (issue 40): a white-metal textured asset in a white furnace keeps its energy with the
walk at every texel's roughness, and loses the single-scattering share without it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from gltf_build import quad_asset, quad_scene
from pbrcheck.scene import load_scene

#: A white furnace's white metal with the walk: 1 up to the walk's noise at 64 spp over ~40 pixels
#: per half and its dropped orders beyond MAX_SCATTERING_ORDER (docs/reference.md: < 1e-3).
FURNACE_ATOL = 0.02


def _nearest():
    return {"magFilter": 9728, "minFilter": 9728}   # NEAREST: each half one roughness


@pytest.fixture
def furnace_asset(tmp_path):
    """A white-metal quad whose metallic-roughness texture (G: roughness) is 0.5 on its left half and
    1.0 on its right, under a white base colour texture."""
    mr = np.zeros((4, 4, 3), np.uint8)
    mr[..., 2] = 255                       # B: metallic 1
    mr[:, :2, 1], mr[:, 2:, 1] = 128, 255  # G: roughness 0.5 | 1.0
    white = np.full((4, 4, 3), 255, np.uint8)
    asset = quad_asset(tmp_path / "furnace.gltf", {"pbrMetallicRoughness": {
        "baseColorTexture": {"index": 0}, "metallicRoughnessTexture": {"index": 1}}},
        [(white, _nearest()), (mr, _nearest())])
    return load_scene(quad_scene(tmp_path, asset, size=(24, 24), fov=25.0))


def _halves(img):
    obj = img.channels["object"] >= 0
    w = img.shape[1]
    return [float(img.rgb[:, sl][obj[:, sl]].mean()) for sl in (slice(2, w // 2 - 2), slice(w // 2 + 2, w - 2))]


def test_white_metal_textured_asset_stays_at_one_in_a_white_furnace_with_the_walk(furnace_asset, tmp_cache):
    from compare import renderers
    scene = furnace_asset
    walk = replace(scene, brdf=replace(scene.brdf, multiscatter="random_walk"))
    single = renderers.render_reference(scene, spp=64, use_cache=False, progress=False)
    multi = renderers.render_reference(walk, spp=64, use_cache=False, progress=False)
    s_left, s_right = _halves(single)
    m_left, m_right = _halves(multi)
    assert m_left == pytest.approx(1.0, abs=FURNACE_ATOL) and m_right == pytest.approx(1.0, abs=FURNACE_ATOL)
    # without the walk the rougher half loses more (per texel roughness), both well below 1
    assert s_right < s_left < 0.97 and s_right < 0.8, (s_left, s_right)
    path = renderers.render_reference(walk, spp=64, mode="path", use_cache=False, progress=False)
    assert _halves(path)[1] == pytest.approx(1.0, abs=FURNACE_ATOL)


def test_asset_scenes_accept_the_walk_and_the_report_matches_it(furnace_asset):
    from compare.report.references import random_walk_scene
    rw, why = random_walk_scene(furnace_asset)
    assert rw is not None and rw.brdf.multiscatter == "random_walk" and why == ""
