"""The irradiance (texel sum) and prefilter bakes against their sums written out in numpy.

Both bakes compute once what is the same for every output texel (irradiance_texels.comp: the
source texels' directions, solid angles and radiances; prefilter_samples.comp: a level's half
vectors and source levels) and sum over it per texel: these tests check the sum each texel gets,
so a table read at the wrong index, a missing barrier or a face order mixed up fails here. The
source radiances are read through the same textureLod (``sample_cube``) as the shaders, so the
tolerance covers float32 arithmetic only.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pbrcheck import brdf, lodmap, sampling
from pbrcheck.environment import EnvMap
from realtime.presets import resolve_options
from realtime.render import env_cube, irradiance_cube, prefiltered_cube, sample_cube

#: float32 sums of a few hundred terms against float64 (relative).
BAKE_RTOL = 2e-4


def _env() -> EnvMap:
    rng = np.random.default_rng(11)
    return EnvMap(rng.random((12, 24, 3)).astype(np.float32) * 3.0 + 0.05, scale=1.0, rotation=25.0)


def _cube_dir(face: int, s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """env.glsl's cube_dir (GL 4.5 table 8.19 inverted), normalised, for arrays of s, t."""
    a, b = 2.0 * s - 1.0, 2.0 * t - 1.0
    one = np.ones_like(a)
    d = {0: (one, -b, -a), 1: (-one, -b, a), 2: (a, one, b), 3: (a, -one, -b), 4: (a, -b, one),
         5: (-a, -b, -one)}[face]
    d = np.stack(d, axis=-1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _texel_dirs(size: int) -> np.ndarray:
    """(6, size, size, 3): texel (x, y) of face f at ((x, y) + 0.5) / size, indexed [f, y, x]."""
    c = (np.arange(size) + 0.5) / size
    s, t = np.meshgrid(c, c)  # [y, x]
    return np.stack([_cube_dir(f, s, t) for f in range(6)])


def _solid_angles(size: int) -> np.ndarray:
    """(size, size) [y, x]: env.glsl's cube_texel_solid_angle."""
    area = lambda a, b: np.arctan2(a * b, np.sqrt(a * a + b * b + 1.0))  # noqa: E731
    e = 2.0 * np.arange(size + 1) / size - 1.0
    a0, a1 = e[None, :-1], e[None, 1:]
    b0, b1 = e[:-1, None], e[1:, None]
    return area(a0, b0) - area(a0, b1) - area(a1, b0) + area(a1, b1)


def _to_world(t: np.ndarray, n: np.ndarray) -> np.ndarray:
    """common.glsl's to_world: t (..., 3) in the frame of n (..., 3)."""
    up = np.where(np.abs(n[..., 2:3]) < 0.999, [0.0, 0.0, 1.0], [1.0, 0.0, 0.0])
    tx = np.cross(up, n)
    tx /= np.linalg.norm(tx, axis=-1, keepdims=True)
    ty = np.cross(n, tx)
    return tx * t[..., 0:1] + ty * t[..., 1:2] + n * t[..., 2:3]


def test_texel_sum_irradiance_is_the_solid_angle_weighted_sum_of_the_source_texels():
    env = _env()
    o = resolve_options("default", {"cube_size": 16, "prefilter_levels": 4, "irradiance_source_size": 8,
                                    "irradiance_size": 4, "irradiance_method": "texel_sum"})
    cube = env_cube(env, 16, "f32", {})
    irr = irradiance_cube(env, cube, o, "f32", {})
    src = _texel_dirs(8).reshape(-1, 3)
    radiance = sample_cube(cube, src, math.log2(16 / 8)).astype(np.float64)
    sa = np.tile(_solid_angles(8).ravel(), 6)
    out = _texel_dirs(4).reshape(-1, 3)
    c = out @ src.T                                     # (outputs, sources)
    w = np.where(c > 0.0, c, 0.0) * sa[None, :]
    expect = w @ radiance / np.pi
    got = sample_cube(irr, out, 0.0)                    # texel centres: the texels themselves
    np.testing.assert_allclose(got, expect, rtol=BAKE_RTOL)
    # the wrong face order would not match: faces 0 and 1 swapped in the sum
    swapped = np.concatenate([radiance[64:128], radiance[0:64], radiance[128:]])
    assert np.abs(w @ swapped / np.pi - got).max() > 100 * np.abs(expect - got).max()


@pytest.mark.parametrize("filtered, nl_weight", [(True, False), (False, True)])
def test_prefilter_level_is_the_ggx_sample_sum(filtered, nl_weight):
    env = _env()
    size, levels, ns = 16, 4, 32
    o = resolve_options("default", {"cube_size": size, "prefilter_levels": levels, "prefilter_samples": ns,
                                    "prefilter_filtered": filtered, "prefilter_nl_weight": nl_weight,
                                    "lod_mapping": "quadratic", "irradiance_source_size": 8})
    cube = env_cube(env, size, "f32", {})
    pre = prefiltered_cube(env, cube, o, "f32", {})
    for level in (1, 2):
        alpha = float(brdf.alpha_from_roughness(lodmap.roughness_quadratic(level, levels - 1)))
        ht = sampling.sample_GGX(sampling.hammersley(np.arange(ns), ns), alpha)      # (ns, 3)
        if filtered:  # ibl.glsl's filtered_is_lod with pdf = D / 4 (v = n)
            omega_s = 1.0 / (ns * np.maximum(brdf.D_GGX(ht[:, 2], alpha) * 0.25, 1e-30))
            omega_p = 4.0 * np.pi / (6.0 * size * size)
            lod = np.maximum(0.5 * np.log2(omega_s / omega_p) + 1.0, 0.0)
        else:
            lod = np.zeros(ns)
        n = _texel_dirs(size >> level).reshape(-1, 3)                                  # (texels, 3)
        h = _to_world(np.broadcast_to(ht, (len(n), ns, 3)), n[:, None, :])
        l = 2.0 * np.sum(n[:, None] * h, -1, keepdims=True) * h - n[:, None]
        nol = np.sum(n[:, None] * l, -1)
        vals = np.stack([sample_cube(cube, l[:, i], float(lod[i])) for i in range(ns)], axis=1)
        wgt = np.where(nol > 0.0, nol if nl_weight else 1.0, 0.0)
        expect = (vals * wgt[..., None]).sum(1) / np.maximum(wgt.sum(1), 1e-20)[:, None]
        got = sample_cube(pre, n, float(level))
        np.testing.assert_allclose(got, expect, rtol=BAKE_RTOL, err_msg=f"level {level}")
