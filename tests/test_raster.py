"""The raster pipeline (realtime/raster.py): glTF meshes drawn with the shading module of the
ray-cast pass, against known answers built here (textured quads, a tessellated sphere)."""

from __future__ import annotations

import numpy as np
import pytest

import pbrcheck_cli as cli
from pbrcheck.gltf import srgb_to_linear
from pbrcheck.gltf_export import mesh_object_ids
from pbrcheck.gltf_scene import UnsupportedSceneError
from pbrcheck.scene import load_scene, scene_from_dict
from realtime.gl import is_software_renderer
from realtime.render import render_realtime

from gltf_build import quad_asset, quad_scene

SMALL = {"cube_size": 32, "irradiance_source_size": 8, "irradiance_size": 8, "prefilter_levels": 4,
         "prefilter_samples": 64, "lut_size": 16, "lut_samples": 256, "supersample": 1}
#: A constant texture against the same factor: the texture is RGBA16F (relative step 2^-11), its
#: sRGB decode the loader's in float32.
TEXTURE_FACTOR_RTOL = 2e-3
#: Raster of the 256 x 128 UV sphere against the ray-cast sphere, pixels covered in both and not on
#: the silhouette: interpolated normals of the tessellation (measured max 0.09 % at 40 x 32).
SPHERE_RTOL = 0.005
#: Pixels whose object id may differ from the numpy pixel-centre rasterizer (ties on shared edges).
EDGE_TIES = 0.01


def _render(scene_path, **opts):
    return render_realtime(load_scene(str(scene_path)), "default", {**SMALL, **opts}, progress=False)


def test_constant_texture_equals_its_factor(tmp_path):
    c = np.array([200, 100, 50], np.uint8)
    px = np.zeros((8, 8, 4), np.uint8)
    px[..., :3], px[..., 3] = c, 255
    mr = np.zeros((4, 4, 3), np.uint8)
    mr[..., 1], mr[..., 2] = 128, 255          # roughness 128/255, metallic 1 (x factors below)
    tex = quad_asset(tmp_path / "t.gltf", {"pbrMetallicRoughness": {
        "baseColorTexture": {"index": 0}, "metallicRoughnessTexture": {"index": 1},
        "metallicFactor": 0.5, "roughnessFactor": 1.0}}, [(px, None), (mr, None)])
    lin = [float(x) for x in srgb_to_linear(c.astype(np.float32) / 255.0)]
    fac = quad_asset(tmp_path / "f.gltf", {"pbrMetallicRoughness": {
        "baseColorFactor": [*lin, 1.0], "metallicFactor": 0.5, "roughnessFactor": 128 / 255}})
    env = "[0.5, 0.8, 1.0]"
    a = _render(quad_scene(tmp_path, tex, env=env, name="a.toml"))
    b = _render(quad_scene(tmp_path, fac, env=env, name="b.toml"))
    assert a.meta["pipeline"] == "raster"
    m = a.channels["coverage"] == 1
    assert m.mean() > 0.3
    assert np.allclose(a.rgb[m], b.rgb[m], rtol=TEXTURE_FACTOR_RTOL, atol=0)
    assert np.array_equal(a.channels["coverage"], b.channels["coverage"])


def test_texture_rows_top_down_and_mask_cut_out(tmp_path):
    """UV (0, 0) is the texture's top-left: its top half (red, opaque) lands on the image's top rows;
    the bottom half (alpha 0) is cut out by MASK."""
    px = np.zeros((8, 8, 4), np.uint8)
    px[:4] = (255, 0, 0, 255)
    px[4:] = (0, 0, 255, 0)
    q = quad_asset(tmp_path / "m.gltf", {"alphaMode": "MASK", "alphaCutoff": 0.5, "pbrMetallicRoughness": {
        "baseColorTexture": {"index": 0}, "metallicFactor": 0.0}}, [(px, None)])
    img = _render(quad_scene(tmp_path, q, size=(32, 32), fov=60.0), supersample=2)  # quad: rows 9-23
    cov, obj = img.channels["coverage"], img.channels["object"]
    col = 16
    assert cov[12, col] == 1 and obj[12, col] == 0          # top half of the quad: kept
    assert img.channels["R"][12, col] > 2 * img.channels["B"][12, col]
    assert cov[20, col] == 0 and obj[20, col] == -1         # bottom half: cut out
    assert cov[2, col] == 0 and obj[2, col] == -1           # background above the quad


def _placed_scene(tmp_path, asset, double_sided_rot=30.0):
    p = tmp_path / "placed.toml"
    p.write_text(f"""
[camera]
origin = [0.4, 0.9, 4.0]
target = [0.0, 0.0, 0.0]
fov = 35.0
width = 48
height = 36

[environment]
type = "constant"
radiance = [1.0, 1.0, 1.0]

[[objects]]
type = "gltf"
path = "{asset.name}"
translation = [0.3, -0.2, 0.0]
rotation = [10.0, {double_sided_rot}, 5.0]
""")
    return p


def test_object_ids_on_the_pixels_of_the_reference_camera(tmp_path):
    """The object AOV equals the numpy pixel-centre rasterizer of the reference's camera."""
    q = quad_asset(tmp_path / "q.gltf", {"doubleSided": True})
    sc = load_scene(str(_placed_scene(tmp_path, q)))
    img = render_realtime(sc, "default", SMALL, progress=False)
    H, W = img.channels["object"].shape
    ids = np.full((H, W), -1.0)
    mesh_object_ids(sc, ids, np.full((H, W), np.inf))
    assert (ids >= 0).mean() > 0.2
    assert (img.channels["object"] != ids).mean() <= EDGE_TIES


def test_back_faces_culled_unless_double_sided(tmp_path):
    one = quad_asset(tmp_path / "one.gltf", {})
    two = quad_asset(tmp_path / "two.gltf", {"doubleSided": True})
    a = render_realtime(load_scene(str(_placed_scene(tmp_path, one, 180.0))), "default", SMALL, progress=False)
    assert a.channels["coverage"].max() == 0 and a.channels["object"].max() == -1
    b = render_realtime(load_scene(str(_placed_scene(tmp_path, two, 180.0))), "default", SMALL, progress=False)
    m = b.channels["coverage"] == 1
    assert m.mean() > 0.2 and np.all(b.channels["NdotV"][b.channels["object"] == 0] > 0)


def test_tessellated_sphere_matches_the_ray_cast_sphere():
    sc = scene_from_dict({
        "camera": {"origin": [0.0, 0.5, 4.0], "target": [0.0, 0.0, 0.0], "fov": 35.0, "width": 40, "height": 32},
        "environment": {"type": "constant", "radiance": [0.6, 0.7, 0.8]},
        "lights": [{"position": [2.0, 3.0, 2.0], "intensity": [8.0, 8.0, 8.0]},   # the one light loop's types
                   {"type": "spot", "position": [-2.0, 1.0, 3.0], "direction": [2.0, -1.0, -3.0],
                    "intensity": [6.0, 6.0, 6.0], "inner_cone_angle": 0.05, "outer_cone_angle": 0.3},
                   {"type": "directional", "direction": [0.0, -0.3, -1.0], "intensity": [1.0, 0.5, 0.25]}],
        "objects": [{"type": "sphere", "center": [0.0, 0.0, 0.0], "radius": 1.0,
                     "material": {"base_color": [0.8, 0.3, 0.2], "metallic": 0.0, "roughness": 0.4}}]})
    ray = render_realtime(sc, "default", SMALL, progress=False)
    ras = render_realtime(sc, "default", {**SMALL, "pipeline": "raster"}, progress=False)
    assert ray.meta["pipeline"] == "raycast" and ras.meta["pipeline"] == "raster"
    c1, c2 = ray.channels["coverage"], ras.channels["coverage"]
    inner = (c1 == 1) & (c2 == 1)
    # away from the silhouette: the 4-neighbours covered too
    inner[1:-1, 1:-1] &= inner[:-2, 1:-1] & inner[2:, 1:-1] & inner[1:-1, :-2] & inner[1:-1, 2:]
    assert inner.mean() > 0.2
    assert np.allclose(ras.rgb[inner], ray.rgb[inner], rtol=SPHERE_RTOL, atol=0)
    assert np.array_equal(ray.channels["object"][inner], ras.channels["object"][inner])
    assert (np.abs(c1 - c2) > 0).mean() < 0.1     # only silhouette pixels differ in coverage


def test_raycast_pipeline_refuses_meshes(tmp_path):
    q = quad_asset(tmp_path / "q.gltf", {})
    with pytest.raises(UnsupportedSceneError, match="pipeline=raycast"):
        _render(quad_scene(tmp_path, q), pipeline="raycast")


def test_cli_realtime_renders_an_asset_with_env_and_emissive(tmp_path, capsys):
    """``pbrcheck realtime ASSET --env FILE``: the default material (white metal) in a grey
    environment reflects grey; the emissive factor adds (0.5, 0, 0) exactly on covered pixels."""
    from pbrcheck.exr import read_exr
    from pbrcheck.hdrimage import write_hdr

    q = quad_asset(tmp_path / "q.gltf", {"emissiveFactor": [0.5, 0.0, 0.0]})
    env = write_hdr(tmp_path / "grey.hdr", np.full((8, 16, 3), 0.25, np.float32))
    out = tmp_path / "r.exr"
    args = ["realtime", str(q), "--env", str(env), "--size", "16x12", "--out", str(out)]
    for k, v in SMALL.items():
        args += ["--set", f"{k}={v}"]
    assert cli.main(args) == 0 and out.is_file()
    img = read_exr(out)
    m = img.channels["coverage"] == 1
    assert m.mean() > 0.2
    assert np.allclose((img.channels["R"] - img.channels["G"])[m], 0.5, atol=1e-3)
    assert np.allclose(img.channels["R"][~m], 0.25, rtol=1e-3)      # background: the environment
    assert cli.main(args[:-2] + ["--out", str(tmp_path / "x.exr"), "--set", "pipeline=raycast"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "pipeline=raycast" in err[-1] and not (tmp_path / "x.exr").exists()


def _normal_quad(tmp_path, name, normals, metallic=1.0, roughness=0.3, alpha=None):
    """A quad with a tangent-space normal map (unit vectors, H x W x 3) and an optional alpha texture."""
    nm = np.round((np.asarray(normals) * 0.5 + 0.5) * 255).astype(np.uint8)
    mat = {"pbrMetallicRoughness": {"metallicFactor": metallic, "roughnessFactor": roughness},
           "normalTexture": {"index": 0}}
    return quad_asset(tmp_path / name, mat, [(nm, None)])


def test_normal_filtering_known_answers(tmp_path):
    """A flat normal map: toksvig, prefiltered, screen_space (a plane: zero derivatives) and marmoset
    (r above the horizon) leave the image unchanged to the bit. A checker of two tilted normals, seen
    minified: toksvig and prefiltered widen the roughness (the image changes), screen_space does not
    (the plane's geometric normal is constant)."""
    flat = np.zeros((16, 16, 3))
    flat[...] = (0.0, 0.0, 1.0)
    env = "[0.5, 0.8, 1.0]"
    sc = quad_scene(tmp_path, _normal_quad(tmp_path, "flat.gltf", flat), env=env, name="flat.toml")
    none = _render(sc).rgb
    for opts in ({"specular_aa": "toksvig"}, {"specular_aa": "prefiltered"}, {"specular_aa": "screen_space"},
                 {"horizon_occlusion": "marmoset"}):
        assert np.array_equal(_render(sc, **opts).rgb, none), opts
    n = np.array([0.5, 0.0, 1.0]) / np.hypot(0.5, 1.0)
    check = (np.indices((64, 64)).sum(0) % 2)[..., None]
    bumpy = np.where(check > 0, n, n * [-1, 1, 1])
    sc = quad_scene(tmp_path, _normal_quad(tmp_path, "bumpy.gltf", bumpy), env=env, size=(12, 12), name="b.toml")
    none = _render(sc).rgb
    assert np.array_equal(_render(sc, specular_aa="screen_space").rgb, none)
    for method in ("toksvig", "prefiltered"):
        assert not np.allclose(_render(sc, specular_aa=method).rgb, none, rtol=1e-3), method


def test_msaa_above_this_gl_is_refused_before_any_work(tmp_path, monkeypatch, capsys):
    """msaa above GL_MAX_SAMPLES (llvmpipe: 4): a BackendError naming the option, the value asked and
    the most this GL offers, raised before any bake (no artifact enters the render cache, for an
    environment never baked in this process); the CLI exits 3 (a limit of the backend) and writes no
    file. On a GL that offers 8, the limit is lowered to 4 here (max_msaa, the one query)."""
    from pbrcheck.errors import BackendError
    from realtime import raster
    from realtime import render as rt
    from realtime.gl import get_context
    most = raster.max_msaa()
    assert most == get_context().max_samples >= 4      # OpenGL 3.0 and later: GL_MAX_SAMPLES >= 4
    if most >= 8:   # the option's largest value renders here: the limit is lowered to 4
        monkeypatch.setattr(raster, "max_msaa", lambda: 4)
        most = 4
    asked = 2 * most
    q = quad_asset(tmp_path / "q.gltf", {"pbrMetallicRoughness": {"metallicFactor": 0.0}})
    sc = quad_scene(tmp_path, q, size=(8, 8), env="[0.123, 0.456, 0.789]")
    before = set(rt._cache)
    with pytest.raises(BackendError, match=rf"^option msaa: {asked} samples asked, .* offers at most {most} "
                                           r"\(GL_MAX_SAMPLES\)$"):
        _render(sc, msaa=asked)
    assert set(rt._cache) == before, "a bake ran before the refusal"
    _render(sc, msaa=most)            # the limit itself renders
    out = tmp_path / "m.exr"
    assert cli.main(["realtime", str(sc), "--set", f"msaa={asked}", "--out", str(out)]) == 3
    err = capsys.readouterr().err
    assert f"option msaa: {asked} samples asked" in err and f"at most {most}" in err and "%" not in err
    assert not out.exists()
    # a GL that refuses the multisampled buffers below its GL_MAX_SAMPLES: the same typed error, not a GL one
    import moderngl

    def refuse(*args, **kwargs):
        raise moderngl.Error("GL_INVALID_OPERATION")
    monkeypatch.setattr(get_context(), "renderbuffer", refuse)
    with pytest.raises(BackendError, match=rf"^option msaa: {most} samples asked, .* cannot multisample .*"
                                           r"GL_INVALID_OPERATION"):
        _render(sc, msaa=most)


def test_msaa_interior_equals_no_msaa_and_alpha_to_coverage(tmp_path):
    """An axis-aligned flat quad: MSAA (one shading per pixel at its centre) changes no interior pixel
    and only the silhouette's coverage. Alpha-to-coverage on MASK keeps the alpha test's image away
    from the cut and covers about as much in all (CLAMP_TO_EDGE: a repeating texture's alpha ramps up
    again at the quad's far edge)."""
    q = quad_asset(tmp_path / "q.gltf", {"pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 0.4}})
    sc = quad_scene(tmp_path, q, size=(24, 24), env="[0.5, 0.8, 1.0]", fov=45.0)
    a, b = _render(sc), _render(sc, msaa=4)
    inner = a.channels["coverage"] == 1
    inner[1:-1, 1:-1] &= inner[:-2, 1:-1] & inner[2:, 1:-1] & inner[1:-1, :-2] & inner[1:-1, 2:]
    assert 0.2 < inner.mean() < 0.9
    assert np.allclose(b.rgb[inner], a.rgb[inner], rtol=1e-6, atol=0)
    assert np.all(b.channels["coverage"][a.channels["coverage"] == 0] < 1)
    px = np.zeros((8, 8, 4), np.uint8)
    px[:4] = (255, 0, 0, 255)
    px[4:] = (0, 0, 255, 0)
    # cutoff 0.3: the alpha-tested edge falls inside a pixel row (alpha 0.25 at its centre is dropped)
    m = quad_asset(tmp_path / "m.gltf", {"alphaMode": "MASK", "alphaCutoff": 0.3, "pbrMetallicRoughness": {
        "baseColorTexture": {"index": 0}, "metallicFactor": 0.0}}, [(px, {"wrapS": 33071, "wrapT": 33071})])
    sc = quad_scene(tmp_path, m, size=(32, 32), fov=60.0, name="m.toml")   # quad rows 9-23, cut at row 16
    test, a2c = _render(sc, msaa=4), _render(sc, msaa=4, alpha_to_coverage=True)
    ct, ca = test.channels["coverage"], a2c.channels["coverage"]
    away = np.r_[0:14, 19:32]
    assert np.array_equal(ct[away], ca[away]) and np.allclose(test.rgb[away], a2c.rgb[away], rtol=1e-6)
    assert abs(ca.sum() - ct.sum()) <= 16
    if is_software_renderer():
        # a fractional edge where the test was binary. Mesa only: how alpha becomes a sample mask is
        # implementation-dependent (GL 4.6 core, 14.9.3), and NVIDIA's (H100) left this edge binary.
        assert np.any((ca > 0) & (ca < 1) & ((ct == 0) | (ct == 1)))
