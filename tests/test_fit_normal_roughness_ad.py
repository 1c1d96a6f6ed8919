"""fit-normal-roughness's AD method (issue 23, section 3; reference/normal_filter.py): the LOD convention
against a known answer and the raster's textureQueryLod, the gradient against finite differences, the
fit against a known table, and no roughness added where nothing is filtered (the scan's failure on
the panel). Assets are built here: a UV sphere (reference.bench_asset.make_asset) and a square facing
the camera, with procedural normal maps of alternating slopes."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from compare import renderers
from compare.research.fit_normal_roughness import run_fit_normal_roughness
from pbrcheck.errors import PbrcheckError
from pbrcheck.exr import Image
from pbrcheck.gltf_build import Doc
from pbrcheck.lights import DirectionalLight
from pbrcheck.normal_roughness import level_closed_forms
from pbrcheck.scene import Camera, Environment, asset_scene
from realtime.hooks import load_hook_file
from reference.bench_asset import make_asset
from reference.diff import load_differentiable_scene
from reference.render import _mi
from reference import normal_filter as nf

#: Slope of the stripes (x alternates +-S per texel column).
S = 0.5
#: The small real-time setup of tests/test_raster.py (fast bakes), one sample a pixel.
SMALL = {"cube_size": 32, "irradiance_source_size": 8, "irradiance_size": 8, "prefilter_levels": 4,
         "prefilter_samples": 64, "lut_size": 16, "lut_samples": 256, "supersample": 1}
#: float32 projection: the analytic LOD on a facing plane to this many levels.
LOD_TOL = 1e-3
#: The raster's textureQueryLod (quad finite differences, GPU/llvmpipe arithmetic) against the analytic
#: LOD on a facing plane: exact in exact arithmetic (the projection of a parallel plane is affine).
RASTER_LOD_TOL = 0.05
#: AD against central differences of the same samples (float32 renders, h = 1e-3 in u).
GRAD_RTOL = 0.01
#: The fitted table against the known one on levels read by >= MIN_LEVEL_PIXELS pixels (Adam on
#: 32-spp gradients, 2048-spp target: measured 0.225 for 0.227 at level 1).
RECOVERY_TOL = 0.02
MIN_LEVEL_PIXELS = 40
#: Level 0 where nothing is filtered: the model is the truth there; start 0.05, 60 steps.
LEVEL0_MAX = 0.003


def stripe_map(n: int, s: float = S) -> np.ndarray:
    nrm = np.zeros((n, n, 3))
    nrm[..., 0] = np.where(np.arange(n) % 2 == 0, s, -s)[None, :]
    nrm[..., 2] = 1.0
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    return np.round((nrm * 0.5 + 0.5) * 255).astype(np.uint8)


def bump_map(n: int, s: float = S) -> np.ndarray:
    """Slopes +-s in x per column and +-s in y per row (isotropic: every 2 x 2 block averages flat)."""
    j = np.where(np.arange(n) % 2 == 0, s, -s)
    nrm = np.stack(np.broadcast_arrays(j[None, :], j[:, None], np.ones((n, n))), -1).astype(np.float64)
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    return np.round((nrm * 0.5 + 0.5) * 255).astype(np.uint8)


def plane_asset(path, normal_map: np.ndarray, roughness: float = 0.3):
    """A 2 x 2 square in z = 0 facing +z, uv (0, 0) at its top-left (-1, 1), tangent +x; metal."""
    doc = Doc()
    pos = np.array([[-1, 1, 0], [1, 1, 0], [-1, -1, 0], [1, -1, 0]], np.float32)
    uv = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], np.float32)
    nrm = np.tile(np.array([0, 0, 1], np.float32), (4, 1))
    tan = np.tile(np.array([1, 0, 0, 1], np.float32), (4, 1))
    attrs = {"POSITION": doc.accessor(pos, "VEC3", minmax=True), "NORMAL": doc.accessor(nrm, "VEC3"),
             "TANGENT": doc.accessor(tan, "VEC4"), "TEXCOORD_0": doc.accessor(uv, "VEC2")}
    t = doc.image(normal_map)
    doc.d["materials"] = [{"pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.8, 0.7, 1.0], "metallicFactor": 1.0,
                                                    "roughnessFactor": roughness}, "normalTexture": {"index": t}}]
    doc.node(doc.mesh(attrs, doc.accessor(np.array([0, 2, 1, 1, 2, 3], np.uint32), "SCALAR"), 0))
    return doc.write(path)


def lit(scene, size: int, camera: Camera | None = None):
    """A dim constant environment and a directional light from behind the camera (highlights that
    the roughness moves; punctual lights are deterministic in the local estimator)."""
    scene = replace(scene, environment=Environment(type="constant", radiance=(0.2, 0.2, 0.2)),
                    lights=(DirectionalLight(direction=(-0.4, -0.5, -1.0), intensity=(3.0, 3.0, 3.0)),))
    return replace(scene, camera=camera) if camera is not None else scene.with_camera(width=size, height=size)


def facing_camera(size: int, distance: float = 2.0, fov: float = 40.0) -> Camera:
    return Camera(origin=(0.0, 0.0, distance), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov=fov,
                  width=size, height=size)


def model(scene, supersample: int = 1, table=None):
    mi, _ = _mi()
    ms, _ = load_differentiable_scene(scene, spp=4)
    filters = nf.attach(ms, scene.camera, supersample, mi.Float(0.0))
    u = np.zeros(filters[0].levels) if table is None else np.sqrt(np.asarray(table, np.float64))
    nf.set_table(filters, mi.Float(u.astype(np.float32)))
    return ms, filters


def test_lod_is_gl_on_a_facing_plane(tmp_path):
    """Known answer: a square of N texels over 2 units at distance D, horizontal fov F, W pixels: every
    pixel spans N D tan(F / 2) / W texels (the projection of a parallel plane is affine), so
    lod = log2 of that, less log2(s) with s x s supersampling; and the raster's textureQueryLod agrees."""
    n, size, d, fov = 64, 24, 2.0, 40.0
    scene = lit(asset_scene(plane_asset(tmp_path / "p.gltf", bump_map(n)), env=None, size=(size, size)), size,
                facing_camera(size, d, fov))
    expect = math.log2(n * d * math.tan(math.radians(fov / 2)) / size)
    for s in (1, 4):
        ms, filters = model(scene, s)
        lod = nf.lod_image(ms, filters)
        assert np.isfinite(lod).all()               # the square fills the image
        assert np.allclose(lod, expect - math.log2(s), atol=LOD_TOL), (s, expect, lod.min(), lod.max())
    # The raster: a hook setting roughness 1 where textureQueryLod is within RASTER_LOD_TOL of it
    # changes every pixel; one 2 * RASTER_LOD_TOL above it, none.
    plain = renderers.render_under_test(scene, renderers.RendererSpec.parse("default", {**SMALL, "specular_aa": "none"}))
    for c, changed in ((expect, True), (expect + 2 * RASTER_LOD_TOL, False)):
        hook = tmp_path / f"h{int(changed)}.glsl"
        hook.write_text("float hook_specular_aa(float roughness, float normal_length, float normal_lod) {\n"
                        f"    return abs(normal_lod - {c:.6f}) < {RASTER_LOD_TOL} ? 1.0 : roughness;\n}}\n")
        img = renderers.render_under_test(scene, renderers.RendererSpec.parse("default", {**SMALL, "shader": str(hook)}))
        diff = np.abs(img.rgb - plain.rgb).sum(axis=-1) > 0
        assert diff.all() if changed else not diff.any(), (c, diff.mean())


def test_gradient_matches_finite_differences(tmp_path):
    """A 12-pixel sphere under a directional light alone (the local estimator is then deterministic in
    u for fixed samples): d loss / d u by the adjoint pass against central differences at the same seed."""
    scene = asset_scene(make_asset(tmp_path / "s.gltf", segments=16, tex=16, normal_map=stripe_map(32)), env=None,
                        size=(12, 12))
    scene = replace(lit(scene, 12), environment=Environment(type="none"))
    ms, filters = model(scene, table=[0.1] * 6)
    target = nf.render_model(ms, spp=4, seed=3) * 0.8 + 0.01
    weight = np.full(target.shape, 1.0 / target.size)
    u = np.array([0.05, 0.2, 0.3, 0.35, 0.4, 0.4])
    _, g = nf.loss_and_gradient(ms, filters, target, weight, u, spp=4, seed=7, seed_grad=7)
    h, fd = 1e-3, []
    for k in range(len(u)):
        e = np.eye(len(u))[k] * h
        lp, _ = nf.loss_and_gradient(ms, filters, target, weight, u + e, spp=4, seed=7, seed_grad=7)
        lm, _ = nf.loss_and_gradient(ms, filters, target, weight, u - e, spp=4, seed=7, seed_grad=7)
        fd.append((lp - lm) / (2 * h))
    fd = np.array(fd)
    assert np.abs(g).max() > 0
    assert np.allclose(g, fd, rtol=GRAD_RTOL, atol=GRAD_RTOL * np.abs(fd).max()), (g, fd)


@pytest.fixture(scope="module")
def sphere(tmp_path_factory):
    """A 32-pixel sphere with 32-texel stripes (read at levels 0 to 2, a few silhouette pixels higher),
    roughness 0.06 - 0.38 (roughnessFactor 0.4 on the asset's gradient)."""
    tmp = tmp_path_factory.mktemp("nrad")
    p = make_asset(tmp / "stripes.gltf", segments=32, tex=64, normal_map=stripe_map(32))
    d = json.loads(p.read_text())
    d["materials"][0]["pbrMetallicRoughness"]["roughnessFactor"] = 0.4
    p.write_text(json.dumps(d))
    return tmp, lit(asset_scene(p, env=None, size=(32, 32)), 32)


def test_ad_recovers_a_known_table(sphere):
    """The truth is the model itself with Toksvig's per-level table of the stripes (0 at level 0, where
    the stripes are unit normals): from a flat start of 0.05 the fit must find it."""
    tmp, scene = sphere
    known = level_closed_forms(stripe_map(32) / 255.0)["toksvig"]
    ms, _ = model(scene, table=known)
    target = Image.from_rgb(nf.render_model(ms, spp=2048, seed=99), {"renderer": "the model, Toksvig's table"})
    res = run_fit_normal_roughness(scene, options=SMALL, out=tmp / "fit.json", target=target, iterations=100,
                                   fit_spp=32, start=[0.05] * len(known))
    assert res.method == "ad" and res.lod["supersample"] == 1
    checked = [r for r in res.levels if r.pixels >= MIN_LEVEL_PIXELS]
    assert [r.level for r in checked] == [0, 1]
    for r in checked:
        assert abs(r.fitted - known[r.level]) <= RECOVERY_TOL, (r.level, r.fitted, known[r.level])
    assert res.model_relmse["fitted"] < 0.5 * res.model_relmse["filtered"]
    assert load_hook_file(res.glsl).hooks == ("hook_specular_aa",)
    written = json.loads((tmp / "fit.json").read_text())
    assert np.allclose(written["fitted"]["increments"], [r.fitted for r in res.levels])


def test_ad_adds_no_roughness_where_nothing_is_filtered(tmp_path):
    """The panel's failure mode: a magnified normal map (lod ~ -1.5 everywhere: every pixel reads level
    0, which is the full-resolution map) against the real truth (the local reference): the model is
    the truth there, so the fit must take level 0 from 0.05 to ~0, whatever the raster's own errors."""
    size = 24
    scene = lit(asset_scene(plane_asset(tmp_path / "p.gltf", bump_map(16)), env=None, size=(size, size)), size,
                facing_camera(size))
    res = run_fit_normal_roughness(scene, options=SMALL, out=tmp_path / "fit.json", spp=16, spp_cap=32,
                                   iterations=60, fit_spp=16, start=[0.05] * 5)
    assert res.lod["max"] < 0.0 and res.levels[0].pixels == size * size
    assert res.levels[0].fitted <= LEVEL0_MAX, res.levels[0]
    assert all(r.pixels == 0 for r in res.levels[1:])


def test_ad_bad_input_changes_nothing(sphere, tmp_path):
    _, scene = sphere
    out = tmp_path / "fit.json"
    with pytest.raises(PbrcheckError, match="method"):
        run_fit_normal_roughness(scene, method="bisect", options=SMALL, out=out)
    with pytest.raises(PbrcheckError, match="anisotropy"):
        run_fit_normal_roughness(scene, options={**SMALL, "anisotropy": 4.0}, out=out)
    with pytest.raises(PbrcheckError, match="start"):
        run_fit_normal_roughness(scene, options=SMALL, out=out, start=[0.1, 0.2])
    with pytest.raises(PbrcheckError, match="iterations"):
        run_fit_normal_roughness(scene, options=SMALL, out=out, iterations=0)
    assert not out.exists() and not out.with_suffix(".glsl").exists()


def test_cli_method_and_iterations(tmp_path, capsys):
    import pbrcheck_cli as cli
    out = tmp_path / "fit.json"
    assert cli.main(["fit-normal-roughness", "spheres", "--size", "8", "--iterations", "0", "--out", str(out),
                     "--quiet"]) == 2
    assert "iterations" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["fit-normal-roughness", "spheres", "--method", "bisect", "--out", str(out), "--quiet"])
    assert not out.exists()
