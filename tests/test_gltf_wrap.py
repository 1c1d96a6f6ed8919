"""glTF samplers whose wrapS and wrapT differ, in the reference (reference.textured.GltfTexture):
each axis wrapped by its own mode, exactly, bilinear and nearest; the raster pass's MIRRORED_REPEAT
fold (realtime/shaders/texcoord.glsl) against its numpy twin and the reference's."""
from __future__ import annotations

import numpy as np
import pytest

from pbrcheck.gltf import WRAP_CLAMP, WRAP_MIRROR, WRAP_REPEAT, load_asset, wrap_mirror

from gltf_build import quad_asset

# A 3 x 4 (H x W) single-channel ramp: texel (row i, column j) = 10 i + j.
PX = (10.0 * np.arange(3)[:, None] + np.arange(4)[None, :]).astype(np.float32)


def _wrap_index(i: np.ndarray, n: int, mode: int) -> np.ndarray:
    """Texel index i (any integer) of an n-texel axis under glTF's wrap mode."""
    if mode == WRAP_CLAMP:
        return np.clip(i, 0, n - 1)
    if mode == WRAP_MIRROR:
        j = np.mod(i, 2 * n)
        return np.where(j < n, j, 2 * n - 1 - j)
    return np.mod(i, n)


def _expected(u: float, v: float, ws: int, wt: int, nearest: bool) -> float:
    """glTF / OpenGL texture lookup of PX at (u, v): wrap per axis, then filter."""
    h, w = PX.shape
    if nearest:
        def wrap1(x, n, mode):       # coordinate wrap, then the texel
            if mode == WRAP_CLAMP:
                x = min(max(x, 0.0), 1.0)
            elif mode == WRAP_MIRROR:
                y = x - 2.0 * np.floor(0.5 * x)
                x = 2.0 - y if y > 1.0 else y
            else:
                x = x - np.floor(x)
            return min(int(np.floor(x * n)), n - 1)
        return float(PX[wrap1(v, h, wt), wrap1(u, w, ws)])
    x, y = u * w - 0.5, v * h - 0.5
    x0, y0 = int(np.floor(x)), int(np.floor(y))
    fx, fy = x - x0, y - y0
    cols = _wrap_index(np.array([x0, x0 + 1]), w, ws)
    rows = _wrap_index(np.array([y0, y0 + 1]), h, wt)
    q = PX[np.ix_(rows, cols)]
    return float((1 - fy) * ((1 - fx) * q[0, 0] + fx * q[0, 1]) + fy * ((1 - fx) * q[1, 0] + fx * q[1, 1]))


@pytest.mark.parametrize("ws,wt", [(WRAP_REPEAT, WRAP_CLAMP), (WRAP_CLAMP, WRAP_MIRROR), (WRAP_MIRROR, WRAP_REPEAT)])
@pytest.mark.parametrize("nearest", [False, True])
def test_wrap_s_and_t_apply_to_their_own_axis(tmp_path, ws, wt, nearest):
    from reference.variant import ensure_variant
    ensure_variant()
    import drjit as dr
    import mitsuba as mi
    from reference import textured
    textured.register()

    sampler = {"wrapS": ws, "wrapT": wt}
    if nearest:
        sampler["magFilter"] = 9728
    img = np.zeros((3, 4, 3), np.uint8)          # the asset's image: only its sampler is used here
    asset = load_asset(quad_asset(tmp_path / "w.gltf", {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}},
                                  [(img, sampler)]))
    ref = asset.material(0).base_color_texture
    assert ref.wrap == (ws, wt)
    tex = mi.load_dict(textured.texture_dict(np.repeat(PX[..., None], 3, axis=2), ref))
    # UVs across every edge, beyond [0, 1] on both sides, and within half a texel of the edges
    us = np.array([-1.3, -0.6, -0.05, 0.02, 0.3, 0.51, 0.97, 1.0, 1.04, 1.6, 2.2], np.float32)
    uu, vv = np.meshgrid(us, us + 0.013)
    si = dr.zeros(mi.SurfaceInteraction3f, uu.size)
    si.uv = mi.Point2f(uu.reshape(-1), vv.reshape(-1))
    got = np.array(tex.eval(si))[0]                 # Color3f: (3, N), the channels equal
    want = np.array([_expected(float(u), float(v), ws, wt, nearest) for u, v in zip(uu.reshape(-1), vv.reshape(-1))])
    assert np.allclose(got, want, atol=1e-4), np.c_[uu.reshape(-1), vv.reshape(-1), got, want][~np.isclose(got, want, atol=1e-4)]
    # the two modes really differ on this grid (the test would catch one mode used for both axes)
    same = np.array([_expected(float(u), float(v), ws, ws, nearest) for u, v in zip(uu.reshape(-1), vv.reshape(-1))])
    assert not np.allclose(want, same, atol=1e-3)


@pytest.mark.parametrize("ws,wt,nearest", [(WRAP_REPEAT, WRAP_MIRROR, False), (WRAP_CLAMP, WRAP_REPEAT, True)])
def test_packed_lookup_is_bit_identical_to_each_slots_own(tmp_path, ws, wt, nearest):
    """reference.textured.fuse_textures: the slots that share a sampler read one packed texture, and
    every value equals that slot's own lookup bit for bit; a slot with another sampler stays apart."""
    from reference.variant import ensure_variant
    ensure_variant()
    import drjit as dr
    import mitsuba as mi
    from reference import textured
    textured.register()

    sampler = {"wrapS": ws, "wrapT": wt, **({"magFilter": 9728} if nearest else {})}
    img = np.zeros((3, 4, 3), np.uint8)
    asset = load_asset(quad_asset(tmp_path / "w.gltf", {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}},
                                  [(img, sampler)]))
    ref = asset.material(0).base_color_texture
    other = load_asset(quad_asset(tmp_path / "o.gltf", {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}},
                                  [(img, {"wrapS": WRAP_CLAMP, "wrapT": WRAP_CLAMP})])).material(0).base_color_texture
    rng = np.random.default_rng(7)
    px = {slot: rng.random((5, 6, 3)).astype(np.float32) for slot in textured.FUSED_CHANNELS}
    us = np.array([-1.3, -0.05, 0.0, 0.02, 0.3, 0.51, 0.97, 1.0, 1.6], np.float32)
    uu, vv = np.meshgrid(us, us + 0.013)
    si = dr.zeros(mi.SurfaceInteraction3f, uu.size)
    si.uv = mi.Point2f(uu.reshape(-1), vv.reshape(-1))
    for apart in (None, "normal"):
        mat = mi.load_dict({"type": textured.PLUGIN_NAME, **{
            f"{slot}_texture": textured.texture_dict(p, other if slot == apart else ref) for slot, p in px.items()}})
        packed = [[s for s, _ in slots] for _, _, slots in mat.fused]
        assert packed == [[s for s in textured.FUSED_CHANNELS if s != apart]]
        # never the GPU's texture units: CUDA's resolve the position between texels with 8 bits
        assert all(not t.use_accel() for t, _, _ in mat.fused)
        assert textured.texture_dict(px["normal"], ref)["inner"]["accel"] is False
        got = mat._lookups(si, True)
        for slot, channels in textured.FUSED_CHANNELS.items():
            own = np.array(mat._lookup(slot, si, True))
            assert np.array_equal(np.array(got[slot])[list(channels)], own[list(channels)]), slot


#: wrap_mirror: float32 GLSL against float64 numpy and Dr.Jit: the float32 input's own rounding at |x| ~ 1e3 (ulp 6e-5).
WRAP_ATOL = 1e-4
#: Coordinates: every integer and half from -4 to 4, a hair either side of 0, 1 and 2, and large ones.
WRAP_GRID = np.concatenate([np.arange(-8, 9) / 2.0, [-1e-6, 1e-6, 1 - 1e-6, 1 + 1e-6, 2 - 1e-6, 2 + 1e-6,
                                                     0.3, 1.7, -2.3, 123.25, -999.75]])


def test_wrap_mirror_glsl_matches_its_numpy_twin_and_the_reference():
    """texcoord.glsl's wrap_mirror (GLSL harness) against pbrcheck.gltf.wrap_mirror, and both against
    the reference's MIRRORED_REPEAT (reference.textured._wrap) on a grid with the folds and large |x|;
    the known answers: identity on [0, 1], 2 - x on [1, 2], even and 2-periodic."""
    from realtime.glsl_harness import run_glsl
    from reference.variant import ensure_variant
    ensure_variant()
    import mitsuba as mi

    from reference.textured import _wrap
    got = run_glsl("wrap_mirror(x0)", WRAP_GRID)
    twin = wrap_mirror(WRAP_GRID)
    np.testing.assert_allclose(got, twin, rtol=0, atol=WRAP_ATOL)
    np.testing.assert_allclose(np.array(_wrap(mi.Float(WRAP_GRID), WRAP_MIRROR)), twin, rtol=0, atol=WRAP_ATOL)
    x = np.linspace(0.0, 1.0, 11)
    assert np.allclose(wrap_mirror(x), x) and np.allclose(wrap_mirror(1.0 + x), 1.0 - x)
    assert np.allclose(wrap_mirror(-WRAP_GRID), twin) and np.allclose(wrap_mirror(WRAP_GRID + 2.0), twin)
