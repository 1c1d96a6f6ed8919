"""Environments: one radiance function, identical to Mitsuba's envmap lookup."""

from __future__ import annotations

import math

import numpy as np
import pytest

import pbrcheck  # noqa: F401  (sets DRJIT_LIBLLVM_PATH before Mitsuba loads)
from pbrcheck.environment import (EnvMap, load_environment, lookup_equirect, rasterize_sky,
                                  read_image_file, texel_directions, validate_pixels)
from pbrcheck.errors import EnvironmentMapError
from pbrcheck.exr import Image, write_exr
from pbrcheck.scene import Environment, load_scene, scene_from_dict

# Agreement with Mitsuba's own envmap eval, relative, where the image is smooth (the brief's goal).
MITSUBA_REL_TOL = 1e-5
# Mitsuba computes (u, v) in float32: a position error of ~1e-7 in u is ~1e-4 texel on a 1k map,
# which at a sharp edge (a sun disk next to sky) moves the bilinear value by that fraction of the
# jump between neighbouring texels. So every direction must also agree within 1e-5 relative plus
# POSITION_TOL texels' worth of the local texel range.
POSITION_TOL = 3e-4


def _mitsuba_eval(data, scale, rotation, d):
    """Mitsuba's own envmap ``eval`` on ``llvm_ad_rgb`` (exact there; CUDA's hardware texture
    interpolation is not, see reference/env_radiance.py), the process's variant restored after it
    (the reference's, which registers the project's plugins for the tests that follow)."""
    import drjit as dr
    import mitsuba as mi

    before = mi.variant()
    mi.set_variant("llvm_ad_rgb")
    try:
        em = mi.load_dict({"type": "envmap", "bitmap": mi.Bitmap(data), "scale": scale,
                           "to_world": mi.ScalarTransform4f().rotate([0, 1, 0], rotation)})
        si = dr.zeros(mi.SurfaceInteraction3f)
        si.wi = mi.Vector3f(-d[:, 0], -d[:, 1], -d[:, 2])
        return np.array(em.eval(si)).T
    finally:
        if before is not None and before != mi.variant():
            mi.set_variant(before)


# float32 directions carry ~1e-7 rad of angle error, which near a pole becomes 1e-7 / sin(theta) rad
# of azimuth: the texel-position tolerance grows accordingly there.
F32_ANGLE = 1e-7


def _local_range(data, env, d):
    """(max - min of the 2x2 texels around each lookup, scaled) x the texel-position tolerance:
    how far the bilinear value can move when float32 moves the lookup position."""
    d_local = d @ env.to_world()
    H, W = data.shape[:2]
    u = np.arctan2(d_local[:, 0], -d_local[:, 2]) / (2 * np.pi) - 0.5 / W
    u -= np.floor(u)
    v = np.arccos(np.clip(d_local[:, 1], -1, 1)) / np.pi
    ix = np.minimum((u * W).astype(int), W - 1)
    iy = np.minimum((v * (H - 1)).astype(int), H - 2)
    q = np.stack([data[iy, ix], data[iy, (ix + 1) % W], data[iy + 1, ix], data[iy + 1, (ix + 1) % W]])
    sin_t = np.sqrt(np.maximum(1.0 - d_local[:, 1] ** 2, 1e-12))
    pos_tol = POSITION_TOL + W * F32_ANGLE / (2 * np.pi * sin_t)
    return (q.max(0) - q.min(0)) * env.scale * (pos_tol / POSITION_TOL)[:, None]


def _random_dirs(n, seed=0):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return d.astype(np.float32).astype(np.float64)  # Mitsuba sees float32 directions


#: The test maps by name, with the (rotation, scale) pairs they are checked under (tests/test_env_radiance.py too).
SOURCES = [("smooth", 0.0, 1.0), ("smooth", 71.0, 3.0), ("sky", 0.0, 1.0), ("sky", 33.0, 2.5),
           ("random", -120.0, 1.0), ("tiny", 10.0, 1.0)]


def source_data(source: str) -> np.ndarray:
    """A validated test map: ``smooth`` (low frequency), ``sky`` (a 5-degree sun on 256 x 128),
    ``random`` (64 x 37 uniform texels, every edge sharp) or ``tiny`` (1 x 2, expanded)."""
    rng = np.random.default_rng(3)
    if source == "smooth":  # low-frequency: every direction within MITSUBA_REL_TOL
        dirs = texel_directions(128, 64)
        data = (2.0 + np.sin(3 * dirs[..., :1]) * np.cos(2 * dirs[..., 1:2]) + 0.3 * dirs[..., 2:3] * np.array([1, 2, 3]))
    elif source == "sky":
        data = rasterize_sky(Environment(type="sky", resolution=(256, 128), sun_angular_diameter=5.0))
    elif source == "random":
        data = rng.random((37, 64, 3)).astype(np.float32) * 5
    else:
        data = validate_pixels(rng.random((1, 2, 3)).astype(np.float32), "tiny")
    return validate_pixels(data, source)


@pytest.mark.parametrize("source,rotation,scale", SOURCES)
def test_radiance_matches_mitsuba_envmap_eval(source, rotation, scale):
    data = source_data(source)
    env = EnvMap(data, scale=scale, rotation=rotation)
    d = _random_dirs(50_000)
    assert_same_radiance(env.radiance(d), _mitsuba_eval(data, scale, rotation, d), data, env, d, source)


def assert_same_radiance(ours, ref, data, env, d, source) -> None:
    """Two lookups of one map agree: every direction within MITSUBA_REL_TOL relative plus
    POSITION_TOL texels' worth of the local texel range; a smooth map's within the first term alone,
    a sky's for all but its sun's rim and horizon (sqrt gradient, ground edge)."""
    err = np.abs(ours - ref)
    assert np.all(err <= MITSUBA_REL_TOL * np.abs(ref) + POSITION_TOL * _local_range(data, env, d) + 1e-30)
    within = np.all(err <= MITSUBA_REL_TOL * np.abs(ref), axis=1)
    if source == "smooth":
        assert within.all()
    elif source == "sky":
        assert within.mean() > 0.99


def test_real_hdr_matches_mitsuba(envmap):
    data = validate_pixels(read_image_file(envmap("venice_sunset_1k.hdr")), "venice")
    env = EnvMap(data, rotation=90.0)
    d = _random_dirs(20_000, seed=5)
    ref = _mitsuba_eval(data, 1.0, 90.0, d)
    err = np.abs(env.radiance(d) - ref)
    assert np.all(err <= MITSUBA_REL_TOL * np.abs(ref) + POSITION_TOL * _local_range(data, env, d) + 1e-30)
    assert np.median(err / np.maximum(ref, 1e-12)) < MITSUBA_REL_TOL


def test_texel_centres_reproduce_texels():
    """At a texel's centre direction the function returns that texel (convention round trip)."""
    data = np.random.default_rng(0).random((9, 16, 3)).astype(np.float32)
    env = EnvMap(data)
    d = texel_directions(16, 9)[1:-1]  # poles are singular in phi
    got = env.radiance(d.reshape(-1, 3)).reshape(7, 16, 3)
    np.testing.assert_allclose(got, data[1:-1], rtol=1e-5)


def test_rotation_turns_the_map_about_y():
    data = np.zeros((9, 16, 3), np.float32)
    data[4, 4] = 1.0  # one bright texel on the equator at phi = 2 pi 4.5/16
    phi = 2 * np.pi * 4.5 / 16
    d0 = np.array([np.sin(phi), 0.0, -np.cos(phi)])
    rot = 45.0
    r = math.radians(rot)
    R = np.array([[math.cos(r), 0, math.sin(r)], [0, 1, 0], [-math.sin(r), 0, math.cos(r)]])
    env = EnvMap(data, rotation=rot)
    assert env.radiance((R @ d0)[None])[0, 0] == pytest.approx(1.0, abs=1e-5)
    assert env.radiance(d0[None])[0, 0] < 0.5


def test_tiny_images_expand_to_the_same_function():
    two_by_one = np.array([[[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]], np.float32)
    e = validate_pixels(two_by_one, "2x1")
    assert e.shape == (3, 2, 3)
    assert np.all(e[0] == e[1]) and np.all(e[1] == e[2])
    two_rows = np.stack([np.ones((2, 3)), 3 * np.ones((2, 3))]).astype(np.float32)
    e = validate_pixels(two_rows, "2 rows")
    assert e.shape == (3, 2, 3) and np.allclose(e[1], 2.0)
    # equator of the 2-row map: halfway in theta, halfway between the rows
    env = EnvMap(e)
    assert env.radiance(np.array([[1.0, 0.0, 0.0]]))[0, 0] == pytest.approx(2.0)


@pytest.mark.parametrize("bad,fragment", [
    (np.full((4, 8, 3), np.nan, np.float32), "NaN"),
    (np.full((4, 8, 3), np.inf, np.float32), "Inf"),
    (-np.ones((4, 8, 3), np.float32), "negative"),
    (np.ones((4, 8, 2), np.float32), "shape"),
    (np.ones((4,), np.float32), "shape"),
])
def test_bad_pixels_are_named_errors(bad, fragment):
    with pytest.raises(EnvironmentMapError) as ei:
        validate_pixels(bad, "env.exr")
    assert str(ei.value).startswith("env.exr: ") and fragment in str(ei.value)


def test_file_environment_exr_nan_is_an_error(tmp_path):
    data = np.ones((8, 16, 3), np.float32)
    data[2, 3, 1] = np.nan
    write_exr(tmp_path / "nan.exr", Image.from_rgb(data))
    scene = scene_from_dict({"environment": {"type": "file", "path": "nan.exr"}, "objects": [{"type": "sphere"}]},
                            file=str(tmp_path / "s.toml"), base_dir=tmp_path)
    with pytest.raises(EnvironmentMapError, match=r"nan\.exr: 1 pixel\(s\) hold NaN"):
        load_environment(scene)


def test_unreadable_file_is_named(tmp_path):
    p = tmp_path / "broken.hdr"
    p.write_bytes(b"not an image")
    with pytest.raises(EnvironmentMapError, match="broken.hdr: unreadable image"):
        read_image_file(p)


def test_exr_environment_round_trip_and_scale(tmp_path):
    data = np.random.default_rng(1).random((16, 32, 3)).astype(np.float32)
    write_exr(tmp_path / "env.exr", Image.from_rgb(data))
    scene = scene_from_dict({"environment": {"type": "file", "path": "env.exr", "scale": 2.0},
                             "objects": [{"type": "sphere"}]}, file="s.toml", base_dir=tmp_path)
    env = load_environment(scene)
    np.testing.assert_array_equal(env.data, data)
    d = texel_directions(32, 16)[5, 7]
    assert env.radiance(d[None])[0] == pytest.approx(2.0 * data[5, 7], rel=1e-5)


def test_hdr_file_loads(envmap):
    env = EnvMap(validate_pixels(read_image_file(envmap("quarry_01_1k.hdr")), "quarry"))
    assert (env.width, env.height) == (1024, 512)
    assert env.max_radiance > 65504  # the brief's figure: the sun is above the half-float maximum


def test_constant_and_none():
    s = scene_from_dict({"environment": {"type": "constant", "radiance": [0.5, 1.0, 2.0]},
                         "objects": [{"type": "sphere"}]})
    env = load_environment(s)
    d = _random_dirs(100)
    np.testing.assert_allclose(env.radiance(d), np.broadcast_to([0.5, 1.0, 2.0], (100, 3)), rtol=1e-6)
    s = scene_from_dict({"environment": {"type": "none"}, "objects": [{"type": "sphere"}]})
    assert np.all(load_environment(s).radiance(d) == 0)


def test_sky_sun_keeps_its_energy_and_exceeds_half_float():
    """The sun's rasterized power (sum of texel coverage x solid angle) equals the disk's solid
    angle x radiance within 2% even when the disk spans only ~3 texels."""
    env = load_environment(load_scene("sun"))
    e = load_scene("sun").environment
    assert env.max_radiance > 65504
    W, H = e.resolution
    sun_only = rasterize_sky(e) - rasterize_sky(Environment(**{**e.__dict__, "sun_radiance": (0.0, 0.0, 0.0)}))
    theta = np.pi * np.arange(H) / (H - 1)
    # solid angle of a texel's footprint: (2 pi / W) * (pi / (H - 1)) * sin(theta)
    omega = (2 * np.pi / W) * (np.pi / (H - 1)) * np.sin(theta)
    power = np.sum(sun_only[..., 0] * omega[:, None])
    r = math.radians(e.sun_angular_diameter) / 2
    expected = 2 * np.pi * (1 - math.cos(r)) * e.sun_radiance[0]
    assert power == pytest.approx(expected, rel=0.02)


def test_content_hash_tracks_pixels_scale_rotation():
    a = np.ones((4, 8, 3), np.float32)
    b = a.copy()
    b[1, 1, 1] = 1.0001
    h = {EnvMap(a).content_hash, EnvMap(b).content_hash, EnvMap(a, scale=2).content_hash,
         EnvMap(a, rotation=1).content_hash}
    assert len(h) == 4
    assert EnvMap(a).content_hash == EnvMap(a.copy()).content_hash


def test_lookup_poles_and_seam_finite():
    data = np.random.default_rng(2).random((5, 8, 3))
    d = np.array([[0, 1, 0], [0, -1, 0], [0, 0, -1], [1e-9, 0, -1], [-1e-9, 0, -1]], float)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    out = lookup_equirect(data, d)
    assert np.all(np.isfinite(out))
    assert np.allclose(out[2], out[3]) and np.allclose(out[3], out[4], atol=1e-6)  # no seam
