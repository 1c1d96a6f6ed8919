"""glTF assets: the reader (accessors, hierarchy, materials, errors), asset scenes, and the reference's
textured material on small assets with known answers built here (tests/gltf_build.py)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import pbrcheck_cli as cli
from pbrcheck.gltf import AssetError, load_asset, texture_transform_matrix
from pbrcheck.scene import load_scene

from same_samples import assert_same_samples, on_cuda
from gltf_build import MIRRORED_TAN, MIRRORED_UV, QUAD_IDX, QUAD_NRM, QUAD_POS, QUAD_UV, Doc, quad_asset, quad_scene

SHARED = Path(__file__).resolve().parents[2] / "shared" / "assets"
# Relative difference allowed between two renders that must agree up to float32 rounding of the
# texture lookups (same samples, same seed).
SAME_RENDER_RTOL = 2e-3


def _shared(name: str) -> Path:
    p = SHARED / name
    if not p.is_file():
        pytest.skip(f"{p} is absent (real assets live in ../shared/assets)")
    return p


# ---- reader -----------------------------------------------------------------------------------

def test_sparse_and_normalized_accessors(tmp_path):
    doc = Doc()
    pos = doc.accessor(QUAD_POS, "VEC3", minmax=True)
    # sparse: vertex 2 of a zero-based accessor replaced (no bufferView: zeros + sparse values)
    idx = doc.view(np.array([2], np.uint16).tobytes())
    val = doc.view(np.array([[0.25, 0.5]], np.float32).tobytes())
    doc.d["accessors"].append({"componentType": 5126, "count": 4, "type": "VEC2",
                               "sparse": {"count": 1, "indices": {"bufferView": idx, "componentType": 5123},
                                          "values": {"bufferView": val}}})
    uv = len(doc.d["accessors"]) - 1
    # normalized signed bytes (normals) and unsigned shorts (colours)
    nrm = doc.accessor(np.array([[0, 0, 127]] * 4, np.int8), "VEC3", normalized=True)
    col = doc.accessor(np.array([[65535, 0, 32768, 65535]] * 4, np.uint16), "VEC4", normalized=True)
    doc.node(doc.mesh({"POSITION": pos, "TEXCOORD_0": uv, "NORMAL": nrm, "COLOR_0": col},
                      doc.accessor(QUAD_IDX, "SCALAR"), None))
    a = load_asset(doc.write(tmp_path / "a.gltf"))
    p = a.primitives[0]
    assert p.texcoords[0][2].tolist() == [0.25, 0.5] and p.texcoords[0][0].tolist() == [0.0, 0.0]
    assert np.allclose(p.normals, [0, 0, 1])
    assert np.allclose(p.color[0], [1.0, 0.0, 32768 / 65535, 1.0])
    assert p.triangles == 2 and p.name == "node0/mesh0/0"
    # non-indexed: every 3 vertices a triangle
    doc2 = Doc()
    doc2.node(doc2.mesh({"POSITION": doc2.accessor(QUAD_POS[[0, 1, 2, 0, 2, 3]], "VEC3", minmax=True)}, None, None))
    assert load_asset(doc2.write(tmp_path / "b.gltf")).primitives[0].triangles == 2


def test_hierarchy_trs_matrix_and_flat_normals(tmp_path):
    doc = Doc()
    pos = doc.accessor(QUAD_POS, "VEC3", minmax=True)
    m = doc.mesh({"POSITION": pos}, doc.accessor(QUAD_IDX, "SCALAR"), None)
    # parent: translate +2 in x (matrix); child: rotate 90 deg about Y (TRS) and scale 2
    q = [0.0, math.sin(math.pi / 4), 0.0, math.cos(math.pi / 4)]
    doc.d["nodes"] = [{"name": "parent", "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 2, 0, 0, 1], "children": [1]},
                      {"name": "child", "mesh": m, "rotation": q, "scale": [2, 2, 2]}]
    doc.d["scenes"][0]["nodes"] = [0]
    a = load_asset(doc.write(tmp_path / "h.gltf"))
    p = a.primitives[0]
    assert p.name == "child/mesh0/0" and p.flat_normals
    # quad in the XY plane, rotated 90 deg about Y: x -> -z; then scaled 2 and moved to x = 2
    assert np.allclose(p.positions[:, 0], 2.0, atol=1e-6)
    assert np.allclose(sorted(set(np.round(p.positions[:, 2], 5))), [-2, 2])
    assert np.allclose(p.normals, [1, 0, 0], atol=1e-6)   # +Z rotated 90 deg about Y


def test_generated_tangents_follow_u(tmp_path):
    img = np.full((2, 2, 3), (128, 128, 255), np.uint8)
    a = load_asset(quad_asset(tmp_path / "t.gltf", {"normalTexture": {"index": 0}}, [(img, None)], tangents=False))
    p = a.primitives[0]
    assert p.generated_tangents
    # u grows along +x, v grows along -y (glTF's v down): T = +x, B = +y = w (N x T) -> w = +1
    assert np.allclose(p.tangents, [[1, 0, 0, 1]] * 4, atol=1e-6)


def test_texture_transform_matrix_rotation():
    m = texture_transform_matrix((0.0, 1.0), math.pi / 2, (1.0, 1.0))
    assert np.allclose(m @ [0.25, 0.1, 1.0], [0.1, 0.75, 1.0])    # (u, v) -> (v, 1 - u)


def test_shared_assets_load():
    a = load_asset(_shared("DamagedHelmet/DamagedHelmet.gltf"))
    assert a.triangles == 15452 and len(a.images) == 5 and a.primitives[0].generated_tangents
    b = load_asset(_shared("BoxTextured.glb"))     # Draco-compressed (DracoPy)
    assert b.triangles == 12 and "KHR_draco_mesh_compression" in b.extensions_used
    assert np.allclose(np.abs(b.primitives[0].positions).max(), 0.5)


# ---- bad inputs: one line, exit 2, nothing written ------------------------------------------------

def _bad(tmp_path, kind: str) -> Path:
    doc = Doc()
    pos = QUAD_POS.copy()
    if kind == "nan":
        pos[1, 0] = np.nan
    a_pos = doc.accessor(pos, "VEC3")
    a_nrm = doc.accessor(QUAD_NRM, "VEC3")
    prim = {}
    if kind == "range":
        doc.d["accessors"][a_nrm]["count"] = 400
    if kind == "mode":
        prim["mode"] = 1
    mat = None
    if kind == "texture":
        doc.d["images"] = [{"uri": "missing.png"}]
        doc.d["textures"] = [{"source": 0}]
        doc.d["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
        mat = 0
    attrs = {"POSITION": a_pos, "NORMAL": a_nrm, "TEXCOORD_0": doc.accessor(QUAD_UV, "VEC2")}
    doc.node(doc.mesh(attrs, doc.accessor(QUAD_IDX, "SCALAR"), mat, **prim))
    if kind == "required":
        doc.d["extensionsUsed"] = doc.d["extensionsRequired"] = ["KHR_materials_pbrSpecularGlossiness"]
    p = doc.write(tmp_path / f"{kind}.gltf")
    if kind == "corrupt":
        p.write_text(p.read_text()[:200])
    return p


@pytest.mark.parametrize("kind,pointer", [
    ("corrupt", "not a valid glTF"),
    ("texture", "/images/0/uri"),
    ("range", "/accessors/1"),
    ("nan", "/meshes/0/primitives/0/attributes/POSITION"),
    ("mode", "/meshes/0/primitives/0/mode"),
    ("required", "/extensionsRequired/0"),
])
def test_bad_asset_is_one_line_exit_2_nothing_written(tmp_path, capsys, kind, pointer):
    p = _bad(tmp_path, kind)
    with pytest.raises(AssetError):
        load_asset(p)
    out = tmp_path / "out"
    rc = cli.main(["export", str(p), "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and str(p) in err and pointer in err, err
    assert not out.exists()


def test_optional_unknown_extension_listed_as_ignored(tmp_path, capsys):
    p = quad_asset(tmp_path / "o.gltf", {})
    d = json.loads(p.read_text())
    d["extensionsUsed"] = ["EXT_unknown_thing"]
    p.write_text(json.dumps(d))
    assert load_asset(p).extensions_ignored == ("EXT_unknown_thing",)
    assert cli.main(["check-scene", str(p)]) == 0
    assert "ignored: EXT_unknown_thing" in capsys.readouterr().out


# ---- scenes ---------------------------------------------------------------------------------------

def test_scene_file_mixes_assets_and_spheres_with_placement(tmp_path):
    quad_asset(tmp_path / "q.gltf", {})
    s = tmp_path / "s.toml"
    s.write_text("""
[environment]
type = "constant"
[[objects]]
type = "sphere"
center = [0.0, 0.0, -3.0]
[[objects]]
type = "gltf"
path = "q.gltf"
translation = [0.0, 1.0, 0.0]
rotation = [0.0, 90.0, 0.0]
scale = 2.0
""")
    sc = load_scene(s)
    assert [o.type for o in sc.objects] == ["sphere", "mesh"] and sc.objects[1].id == 1
    assert sc.objects[1].name == "node0/mesh0/0"
    lo, hi = sc.assets[0].bounds()
    assert np.allclose(lo, [0, -1, -2], atol=1e-6) and np.allclose(hi, [0, 3, 2], atol=1e-6)


def test_asset_path_as_scene_frames_like_model_viewer(tmp_path):
    p = quad_asset(tmp_path / "q.gltf", {})
    rc = cli.main(["check-scene", str(p), "--size", "64x32"])
    assert rc == 0
    from pbrcheck.gltf_scene import asset_scene, framing_camera
    sc = asset_scene(p, size=(64, 32))
    assert (sc.camera.width, sc.camera.height) == (64, 32) and sc.environment.type == "constant"
    c = framing_camera([-1, -1, 0], [1, 1, 0], 64, 32)
    d = np.asarray(c.origin) - np.asarray(c.target)
    # 45 deg vertical fov is the smaller one: distance = 1.05 r / sin(22.5 deg), r = sqrt(2)
    assert np.isclose(np.linalg.norm(d), 1.05 * math.sqrt(2) / math.sin(math.radians(22.5)))
    assert np.isclose(math.degrees(math.acos(d[1] / np.linalg.norm(d))), 75.0)


# ---- the reference on assets with known answers ------------------------------------------------------

#: Radiance of the up-tilted mirrored quad against diffuse n.l alone: the Fresnel weight (1 - F) and
#: a rough specular lobe move it by a few per cent; a tilt the wrong way gives 0.
MIRRORED_TILT_RTOL = 0.2


def _render(scene_path, spp=16, mode="local"):
    from reference.render import render_reference
    img = render_reference(load_scene(scene_path), spp=spp, mode=mode, use_cache=False, progress=False)
    return np.stack([img.channels[c] for c in "RGB"], -1), img


def _close(a, b, rtol=SAME_RENDER_RTOL):
    assert np.all(np.abs(a - b) <= rtol * np.maximum(np.abs(b), 1e-3)), float(np.max(np.abs(a - b)))


# Standard deviations two renders of one expectation may differ by (per pixel and channel). The
# variance channels of the qmc sampler are estimated from K = 16 replicates, so a pixel's z follows
# Student's t with ~15 degrees of freedom, not a normal: P(|t_15| > 5) = 1.6e-4, about one value in a
# thousand-pixel RGB test, and a fixed seed that draws one fails forever. So the bulk must lie within
# NOISE_SIGMAS, at most NOISE_TAIL_SHARE of the values beyond it (30x the t tail), none beyond
# NOISE_SIGMAS_MAX (P(|t_15| > 12) = 4e-9); a bias of the mean is caught by the tests' own mean checks.
NOISE_SIGMAS = 5.0
NOISE_TAIL_SHARE = 5e-3
NOISE_SIGMAS_MAX = 12.0


def _assert_within_noise(diff, sd, floor=1e-6):
    z = np.abs(diff) / (sd + floor / NOISE_SIGMAS)
    assert float(np.mean(z > NOISE_SIGMAS)) <= NOISE_TAIL_SHARE and float(z.max()) <= NOISE_SIGMAS_MAX, \
        (float(np.mean(z > NOISE_SIGMAS)), float(z.max()))


def _close_noise(a, b, ia, ib):
    sd = np.sqrt(np.stack([ia.channels[f"variance.{c}"] + ib.channels[f"variance.{c}"] for c in "RGB"], -1))
    _assert_within_noise(a - b, sd)


@pytest.mark.slow
def test_constant_texture_equals_factor_and_flat_normal_map_equals_none(tmp_path, tmp_cache):
    col = (200, 120, 40)
    lin = [((c / 255 + 0.055) / 1.055) ** 2.4 for c in col]
    mr = np.zeros((4, 4, 3), np.uint8)
    mr[..., 1], mr[..., 2] = 128, 255
    tex = quad_asset(tmp_path / "tex.gltf", {"pbrMetallicRoughness": {
        "baseColorTexture": {"index": 0}, "metallicRoughnessTexture": {"index": 1}, "metallicFactor": 0.5}},
        [(np.full((4, 4, 3), col, np.uint8), None), (mr, None)])
    fac = quad_asset(tmp_path / "fac.gltf", {"pbrMetallicRoughness": {
        "baseColorFactor": lin + [1.0], "metallicFactor": 0.5, "roughnessFactor": 128 / 255}})
    a, _ = _render(quad_scene(tmp_path, tex, name="a.toml", env="[1.0, 0.5, 0.25]"))
    b, img = _render(quad_scene(tmp_path, fac, name="b.toml", env="[1.0, 0.5, 0.25]"))
    assert img.channels["coverage"][12, 12] == 1.0
    _close(a, b)
    # a flat normal map (16-bit grey channels cannot hold RGB: 8-bit 128/255 is 0.4% off flat, so
    # the comparison allows that tilt's effect) equals no normal map
    flat = quad_asset(tmp_path / "flat.gltf", {"normalTexture": {"index": 0}, "pbrMetallicRoughness": {
        "baseColorFactor": lin + [1.0], "metallicFactor": 0.5, "roughnessFactor": 128 / 255}},
        [(np.full((4, 4, 3), (128, 128, 255), np.uint8), None)])
    c, _ = _render(quad_scene(tmp_path, flat, name="c.toml", env="[1.0, 0.5, 0.25]"))
    _close(c, b, rtol=2e-2)


@pytest.mark.slow
def test_rotated_texture_transform_equals_rotated_image(tmp_path, tmp_cache):
    rng = np.random.default_rng(1)
    A = rng.integers(0, 256, (8, 8, 3), dtype=np.uint8)
    B = np.ascontiguousarray(np.rot90(A, -1))    # B(u, v) = A(v, 1 - u)
    xf = {"KHR_texture_transform": {"rotation": math.pi / 2, "offset": [0.0, 1.0]}}
    t1 = quad_asset(tmp_path / "t1.gltf", {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "extensions": xf},
                                                                      "metallicFactor": 0.0}}, [(A, None)])
    d = json.loads(t1.read_text())
    d["extensionsUsed"] = ["KHR_texture_transform"]
    t1.write_text(json.dumps(d))
    t2 = quad_asset(tmp_path / "t2.gltf", {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                                                                      "metallicFactor": 0.0}}, [(B, None)])
    a, _ = _render(quad_scene(tmp_path, t1, name="a.toml"))
    b, _ = _render(quad_scene(tmp_path, t2, name="b.toml"))
    _close(a, b, rtol=1e-2)
    assert np.std(a) > 0.05   # the texture is seen


@pytest.mark.slow
def test_white_textured_metal_in_the_white_furnace(tmp_path, tmp_cache):
    mr = np.zeros((4, 4, 3), np.uint8)
    mr[..., 2] = 255     # metallic 1, roughness 0 (mirror limit): radiance exactly 1
    white = np.full((4, 4, 3), 255, np.uint8)
    p = quad_asset(tmp_path / "w.gltf", {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                                                                    "metallicRoughnessTexture": {"index": 1}}},
                   [(white, None), (mr, None)])
    a, img = _render(quad_scene(tmp_path, p))
    assert np.allclose(a, 1.0, atol=1e-5)
    mr[..., 1] = 128     # roughness ~0.5: single scattering loses a little, never gains
    p2 = quad_asset(tmp_path / "w2.gltf", {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                                                                      "metallicRoughnessTexture": {"index": 1}}},
                    [(white, None), (mr, None)])
    b, img = _render(quad_scene(tmp_path, p2, name="b.toml"), spp=64)
    c = img.channels["coverage"] == 1.0
    sd = np.sqrt(img.channels["variance.R"])[c]
    assert np.all(b[c][:, 0] <= 1.0 + 4 * sd + 1e-4) and 0.9 < b[c].mean() <= 1.0


@pytest.mark.slow
def test_emissive_texture_seen_at_the_hit(tmp_path, tmp_cache):
    p = quad_asset(tmp_path / "e.gltf", {"emissiveTexture": {"index": 0}, "emissiveFactor": [1.0, 1.0, 1.0],
                                          "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}},
                                          "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0.0}},
                   [(np.full((2, 2, 3), 255, np.uint8), None)])
    a, img = _render(quad_scene(tmp_path, p, env="[0.0, 0.0, 0.0]"))
    c = img.channels["coverage"] == 1.0
    assert np.allclose(a[c], 4.0, rtol=1e-5)


def _two_set_assets(tmp_path):
    """Three quads with a left/right-asymmetric emissive texture and a top/bottom-asymmetric base
    colour: ``a`` reads emission from TEXCOORD_1 (u mirrored) and base colour from TEXCOORD_0; ``b``
    the same with the two sets swapped in the mesh and in the material (the same pixels); ``c``
    reads both from TEXCOORD_0 (the emission mirrored: what ignoring texCoord would render)."""
    em = np.zeros((4, 4, 3), np.uint8)
    em[:, :2] = (255, 0, 0)
    bc = np.full((4, 4, 3), 40, np.uint8)
    bc[:2] = (40, 220, 40)
    mirrored = QUAD_UV.copy()
    mirrored[:, 0] = 1.0 - mirrored[:, 0]
    nearest = {"magFilter": 9728, "wrapS": 33071, "wrapT": 33071}

    def asset(name, em_set, bc_set, uv0, uv1):
        return quad_asset(tmp_path / f"{name}.gltf", {
            "emissiveTexture": {"index": 0, "texCoord": em_set}, "emissiveFactor": [1.0, 1.0, 1.0],
            "pbrMetallicRoughness": {"baseColorTexture": {"index": 1, "texCoord": bc_set}, "metallicFactor": 0.0}},
            [(em, nearest), (bc, nearest)], uv0=uv0, uv1=uv1)

    return (asset("a", 1, 0, QUAD_UV, mirrored), asset("b", 0, 1, mirrored, QUAD_UV),
            asset("c", 0, 0, QUAD_UV, mirrored))


@pytest.mark.parametrize("mode", ["local", "path"])
def test_every_slot_reads_its_own_texcoord_set(tmp_path, tmp_cache, mode):
    """Emission on TEXCOORD_1 (the issue: it read TEXCOORD_0) and base colour on TEXCOORD_0 render as
    the same material with the sets swapped, in the reference (both modes) and the raster pipeline;
    the emission on the wrong set is mirrored."""
    a, b, c = _two_set_assets(tmp_path)
    env = "[0.3, 0.3, 0.3]"
    ra, ia = _render(quad_scene(tmp_path, a, env=env, size=(16, 16), fov=20.0, name="a.toml"), spp=8, mode=mode)
    rb, _ = _render(quad_scene(tmp_path, b, env=env, size=(16, 16), fov=20.0, name="b.toml"), spp=8, mode=mode)
    rc, _ = _render(quad_scene(tmp_path, c, env=env, size=(16, 16), fov=20.0, name="c.toml"), spp=8, mode=mode)
    _close(ra, rb)
    assert ra[8, 12, 0] > 0.9 and ra[8, 3, 0] < 0.5, (ra[8, 12], ra[8, 3])   # red emission on the right
    assert rc[8, 3, 0] > 0.9 and rc[8, 12, 0] < 0.5                          # mirrored when ignored
    assert ra[3, 8, 1] > 2 * ra[12, 8, 1]                                     # green base colour at the top
    if mode == "local":
        from realtime.render import render_realtime
        opts = {"cube_size": 16, "irradiance_source_size": 8, "irradiance_size": 8, "prefilter_levels": 3,
                "prefilter_samples": 16, "lut_size": 16, "lut_samples": 64, "supersample": 1}
        rt = [render_realtime(load_scene(str(tmp_path / f"{n}.toml")), "default", opts, progress=False).rgb
              for n in "abc"]
        assert np.allclose(rt[0], rt[1], atol=1e-3)
        assert rt[0][8, 12, 0] > 0.9 and rt[2][8, 3, 0] > 0.9 and rt[0][8, 3, 0] < 0.5


@pytest.mark.parametrize("mode", ["local", "path"])
def test_single_sided_back_face_is_culled(tmp_path, tmp_cache, mode):
    """glTF doubleSided false culls back faces: a single-sided quad seen from behind shows the
    environment, exactly, in the reference (both modes; coverage and object AOV empty) and in the
    raster pipeline; the double-sided quad stays there."""
    one = quad_asset(tmp_path / "one.gltf", {"pbrMetallicRoughness": {"metallicFactor": 0.0}})
    two = quad_asset(tmp_path / "two.gltf", {"pbrMetallicRoughness": {"metallicFactor": 0.0}, "doubleSided": True})
    scenes = []
    for q in (one, two):
        p = quad_scene(tmp_path, q, env="[0.5, 0.5, 0.5]", size=(12, 12), fov=20.0, name=f"{q.stem}.toml")
        p.write_text(p.read_text() + "rotation = [0.0, 180.0, 0.0]\n")
        scenes.append(p)
    a, ia = _render(scenes[0], spp=4, mode=mode)
    assert np.array_equal(a, np.full_like(a, 0.5))
    assert ia.channels["coverage"].max() == 0 and ia.channels["object"].max() == -1
    b, ib = _render(scenes[1], spp=4, mode=mode)
    assert ib.channels["coverage"].min() == 1 and np.abs(b - 0.5).max() > 0.05
    if mode == "local":
        from realtime.render import render_realtime
        opts = {"cube_size": 16, "irradiance_source_size": 8, "irradiance_size": 8, "prefilter_levels": 3,
                "prefilter_samples": 16, "lut_size": 16, "lut_samples": 64, "supersample": 1}
        rt = render_realtime(load_scene(str(scenes[0])), "default", opts, progress=False)
        assert rt.channels["coverage"].max() == 0 and np.allclose(rt.rgb, 0.5, atol=2e-3)


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["local", "path"])
def test_mask_cutout_shows_the_environment(tmp_path, tmp_cache, mode):
    # left half of the texture alpha 0 (cut out), right half alpha 1; a black diffuse quad in a
    # constant environment of radiance 0.5: cut-out pixels see 0.5, the rest see the black surface
    # (local) or the black surface (path: nothing reaches it except through itself: dark)
    img = np.zeros((4, 4, 4), np.uint8)
    img[..., 3] = 255
    img[:, :2, 3] = 0
    p = quad_asset(tmp_path / "m.gltf", {"alphaMode": "MASK", "pbrMetallicRoughness": {
        "baseColorTexture": {"index": 0}, "metallicFactor": 0.0},
        "doubleSided": True}, [(img, {"magFilter": 9728, "wrapS": 33071, "wrapT": 33071})])
    a, im = _render(quad_scene(tmp_path, p, env="[0.5, 0.5, 0.5]", fov=20.0), mode=mode)
    H, W = a.shape[:2]
    left, right = a[H // 2, W // 4], a[H // 2, 3 * W // 4]
    assert np.allclose(left, 0.5, atol=1e-6), left
    assert right.max() < 0.5 * 0.1, right   # specular of a black dielectric only: F0 = 0.04 x 0.5


@pytest.mark.slow
@pytest.mark.parametrize("tangents", [True, False])
def test_normal_map_green_tilts_toward_image_up(tmp_path, tmp_cache, tangents):
    # glTF: green > 0.5 tilts the normal toward the bitangent w (N x T), which points up the image
    # (decreasing v): +y on the quad. A point light above lights the up-tilted quad more than the
    # flat one, the down-tilted one less (given tangents or generated ones alike).
    vals = []
    for g in (38, 128, 218):
        img = np.full((2, 2, 3), (128, g, 218 if g != 128 else 255), np.uint8)
        p = quad_asset(tmp_path / f"n{g}.gltf", {"normalTexture": {"index": 0}, "pbrMetallicRoughness": {
            "metallicFactor": 0.0, "roughnessFactor": 1.0}}, [(img, None)], tangents=tangents)
        s = quad_scene(tmp_path, p, env="[0.0, 0.0, 0.0]", name=f"n{g}.toml")
        s.write_text(s.read_text() + "\n[[lights]]\nposition = [0.0, 6.0, 1.0]\nintensity = [40.0, 40.0, 40.0]\n")
        a, _ = _render(s, spp=4)
        vals.append(float(a[12, 12].mean()))
    assert vals[0] < vals[1] < vals[2], vals


@pytest.mark.parametrize("tangents", [True, False])
def test_normal_map_tilt_on_mirrored_uvs_agrees_between_renderers(tmp_path, tmp_cache, tangents):
    # u mirrored (tangent -x, w = -1; given or generated by MikkTSpace): green > 0.5 still tilts the
    # normal up the image (+y), towards a point light above, in the reference and in the raster
    # pipeline alike. The reference once dropped the tangent attribute (Mitsuba's eval_attribute_x
    # reads zeros for 4 channels) and fell back to Mitsuba's frame, whose bitangent is N x T with
    # w = +1: this tilt went down the image, and DamagedHelmet's mirrored half lost or gained glints.
    from realtime.render import render_realtime
    img = np.full((2, 2, 3), (128, 218, 218), np.uint8)
    p = quad_asset(tmp_path / "m.gltf", {"normalTexture": {"index": 0}, "pbrMetallicRoughness": {
        "metallicFactor": 0.0, "roughnessFactor": 1.0}}, [(img, None)], tangents=tangents, uv0=MIRRORED_UV,
                   tangent=MIRRORED_TAN)
    s = quad_scene(tmp_path, p, env="[0.0, 0.0, 0.0]", size=(8, 8))
    s.write_text(s.read_text() + "\n[[lights]]\nposition = [0.0, 6.0, 1.0]\nintensity = [40.0, 40.0, 40.0]\n")
    ref, _ = _render(s, spp=4)
    small = {"cube_size": 16, "irradiance_source_size": 8, "irradiance_size": 8, "prefilter_levels": 3,
             "prefilter_samples": 16, "lut_size": 16, "lut_samples": 64, "supersample": 1}  # no IBL here
    rt = render_realtime(load_scene(s), "default", {"pipeline": "raster", **small}, progress=False)
    # diffuse under one point light, I (n.l) / (pi d^2), the normal tilted up by atan(0.7 / 0.75)
    # ((2 x 218 / 255 - 1) in y and z); tilted down, n.l < 0: black
    n = np.array([0.0, 0.7, 0.75]) / np.hypot(0.7, 0.75)
    l = np.array([0.0, 6.0, 1.0])
    expected = 40.0 * float(n @ l) / np.linalg.norm(l) / (np.pi * float(l @ l))
    for a in (ref[4, 4].mean(), np.mean([rt.channels[c][4, 4] for c in "RGB"])):
        assert abs(a / expected - 1.0) < MIRRORED_TILT_RTOL, (a, expected)


@pytest.mark.slow
def test_color0_multiplies_the_base_colour(tmp_path, tmp_cache):
    doc = Doc()
    attrs = {"POSITION": doc.accessor(QUAD_POS, "VEC3", minmax=True), "NORMAL": doc.accessor(QUAD_NRM, "VEC3"),
             "COLOR_0": doc.accessor(np.array([[255, 128, 0, 255]] * 4, np.uint8), "VEC4", normalized=True)}
    doc.d["materials"] = [{"pbrMetallicRoughness": {"baseColorFactor": [0.5, 1.0, 1.0, 1.0], "metallicFactor": 0.0}}]
    doc.node(doc.mesh(attrs, doc.accessor(QUAD_IDX, "SCALAR"), 0))
    a, ia = _render(quad_scene(tmp_path, doc.write(tmp_path / "c.gltf"), name="c.toml"))
    f = quad_asset(tmp_path / "f.gltf", {"pbrMetallicRoughness": {"baseColorFactor": [0.5, 128 / 255, 0.0, 1.0],
                                                                    "metallicFactor": 0.0}})
    b, ib = _render(quad_scene(tmp_path, f, name="f.toml"))
    # the quads differ in UVs (hence Mitsuba's tangent frame, hence the samples): equal within noise
    _close_noise(a, b, ia, ib)
    assert a[12, 12, 2] < 0.1 * a[12, 12, 0]     # blue from the specular only: COLOR_0's blue is 0


def test_resolved_asset_scene_reloads_to_the_same_hash(tmp_path):
    from pbrcheck.environment import scene_hash
    from pbrcheck.scene import dump_toml

    doc = json.loads(quad_asset(tmp_path / "q.gltf", {}).read_text())
    doc["extensionsUsed"] = ["KHR_lights_punctual"]
    doc["extensions"] = {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 3.0}]}}
    doc["nodes"].append({"name": "lamp", "translation": [0, 2, 0], "extensions": {"KHR_lights_punctual": {"light": 0}}})
    doc["scenes"][0]["nodes"].append(1)
    (tmp_path / "q.gltf").write_text(json.dumps(doc))
    s = tmp_path / "s.toml"
    s.write_text('[environment]\ntype = "constant"\n[[lights]]\nposition = [0.0, 0.0, 3.0]\nintensity = [1.0, 1.0, 1.0]\n'
                 '[[objects]]\ntype = "sphere"\n[[objects]]\ntype = "gltf"\npath = "q.gltf"\nscale = 2.0\n')
    a = load_scene(s)
    assert len(a.lights) == 2 and a.lights[1].position == (0.0, 4.0, 0.0) and a.lights[1].intensity == (3.0, 3.0, 3.0)
    r = tmp_path / "resolved.toml"
    r.write_text(dump_toml(a.to_dict()))
    b = load_scene(r)
    assert len(b.lights) == 2 and [o.type for o in b.objects] == ["sphere", "mesh"]
    assert scene_hash(a, "e") == scene_hash(b, "e")


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["local", "path"])
def test_blend_is_exact_opacity(tmp_path, tmp_cache, mode):
    # BLEND with alpha 0.25 (opacity): three quarters of the environment (0.5) come through, a quarter
    # of the opaque surface's radiance is seen: L = 0.75 * 0.5 + 0.25 * L_opaque, within the noise
    mat = {"pbrMetallicRoughness": {"baseColorFactor": [0.6, 0.3, 0.1, 0.25], "metallicFactor": 0.0,
                                    "roughnessFactor": 0.5}}
    b = quad_asset(tmp_path / "b.gltf", {**mat, "alphaMode": "BLEND"})
    o = quad_asset(tmp_path / "o.gltf", mat)
    lb, ib = _render(quad_scene(tmp_path, b, env="[0.5, 0.5, 0.5]", name="b.toml"), spp=256, mode=mode)
    lo, io = _render(quad_scene(tmp_path, o, env="[0.5, 0.5, 0.5]", name="o.toml"), spp=256, mode=mode)
    c = io.channels["coverage"] == 1.0      # (the blended quad's coverage counts the rays it stopped)
    assert c.sum() > 100
    want = 0.75 * 0.5 + 0.25 * lo
    sd = np.sqrt(np.stack([ib.channels[f"variance.{k}"] + 0.25 ** 2 * io.channels[f"variance.{k}"] for k in "RGB"], -1))
    _assert_within_noise((lb - want)[c], sd[c], floor=1e-5)
    assert abs(float(lb[c].mean() - want[c].mean())) < 0.01 * float(want[c].mean())


def test_mesh_quantization_int16_positions(tmp_path):
    doc = Doc()
    q = (QUAD_POS * 32767).astype(np.int16)
    pos = doc.accessor(q, "VEC3", normalized=True)
    doc.node(doc.mesh({"POSITION": pos}, doc.accessor(QUAD_IDX, "SCALAR"), None), scale=[2.0, 2.0, 2.0])
    doc.d["extensionsUsed"] = doc.d["extensionsRequired"] = ["KHR_mesh_quantization"]
    a = load_asset(doc.write(tmp_path / "q.gltf"))
    assert np.allclose(a.primitives[0].positions, QUAD_POS[QUAD_IDX] * 2, atol=1e-6)   # unwelded: flat normals


def test_multiscatter_with_assets_is_the_walk_per_shading_point(tmp_path):
    # since issue 40 the textured material walks (tests/test_asset_walk.py); the walk's own
    # requirement (the height-correlated Smith term) still holds
    from pbrcheck.errors import SceneError

    quad_asset(tmp_path / "q.gltf", {})
    s = tmp_path / "s.toml"
    s.write_text('[environment]\ntype = "constant"\n[brdf]\nmultiscatter = "random_walk"\n'
                 '[[objects]]\ntype = "gltf"\npath = "q.gltf"\n')
    assert load_scene(s).brdf.multiscatter == "random_walk"
    s.write_text('[environment]\ntype = "constant"\n[brdf]\nmultiscatter = "random_walk"\ngeometry = "smith_ggx"\n'
                 '[[objects]]\ntype = "gltf"\npath = "q.gltf"\n')
    with pytest.raises(SceneError, match="brdf.geometry"):
        load_scene(s)


def _unrolled_first_opaque_hit(self, scene, sampler, ray, si, hit):
    """The alpha layers as they were written before the symbolic loop (every lane, every layer,
    every BSDF called): the image the loop must reproduce bit for bit. One copy, in the benchmark
    that measures the loop against it (tools/alpha_layers.py)."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("alpha_layers", Path(__file__).resolve().parents[1] / "tools" / "alpha_layers.py")
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    return tool.unrolled(self, scene, sampler, ray, si, hit)


@pytest.mark.parametrize("sampler", ["independent", "qmc"])
def test_alpha_layers_stop_early_and_change_no_bit(tmp_path, tmp_cache, monkeypatch, sampler):
    """The local estimator's alpha layers (a symbolic loop a lane leaves at its first opaque surface;
    the transmission called on the BSDFs a ray can pass only) give the image of the unrolled layers,
    bit for bit, under both samplers (the random numbers of later sample dimensions included): a MASK
    checker quad in front of an OPAQUE single-sided quad seen from its culled back, two opaque quads
    and an analytic sphere behind, in a sky."""
    from reference.variant import ensure_variant
    ensure_variant()
    from reference.integrator import ReferenceIntegrator
    from reference.render import render_reference
    chk = np.zeros((8, 8, 4), np.uint8)
    chk[..., :3] = (200, 120, 60)
    chk[..., 3] = np.where(np.indices((8, 8)).sum(0) % 2 == 0, 255, 0)
    quad_asset(tmp_path / "mask.gltf", {"alphaMode": "MASK", "doubleSided": True, "pbrMetallicRoughness": {
        "baseColorTexture": {"index": 0}, "metallicFactor": 0.0}}, [(chk, {"magFilter": 9728})])
    for k in range(3):
        quad_asset(tmp_path / f"o{k}.gltf", {"pbrMetallicRoughness": {
            "baseColorFactor": [0.2 + 0.3 * k, 0.5, 0.8 - 0.3 * k, 1.0], "metallicFactor": k / 2}})

    def g(p, t, r=0.0, s=1.0):
        return f'[[objects]]\ntype = "gltf"\npath = "{p}"\ntranslation = {t}\nrotation = [0.0, {r}, 0.0]\nscale = {s}\n'
    s = tmp_path / "mixed.toml"
    s.write_text('[camera]\norigin = [0.0, 0.3, 5.0]\nfov = 50.0\nwidth = 24\nheight = 18\n'
                 '[environment]\ntype = "sky"\n' + g("mask.gltf", [0.0, 0.0, 0.8], s=0.9)
                 + g("o0.gltf", [0.3, 0.0, 0.2], 180.0, 0.6) + g("o1.gltf", [-0.8, 0.0, -1.0], 20.0, 0.8)
                 + g("o2.gltf", [0.8, 0.0, -1.2], -20.0, 0.8)
                 + '[[objects]]\ntype = "sphere"\ncenter = [1.5, -0.6, 0.3]\nradius = 0.4\n')
    scene = load_scene(s)
    new = render_reference(scene, spp=8, use_cache=False, progress=False, sampler=sampler)
    monkeypatch.setattr(ReferenceIntegrator, "_first_opaque_hit", _unrolled_first_opaque_hit)
    old = render_reference(scene, spp=8, use_cache=False, progress=False, sampler=sampler)
    if on_cuda():  # tests/same_samples.py
        assert_same_samples(new.rgb, old.rgb, new.variance, old.variance)
    else:
        for c in old.channels:
            assert np.array_equal(new.channels[c], old.channels[c], equal_nan=True), c
    cov = new.channels["coverage"]
    assert 0.2 < cov.mean() < 1.0   # the sky through the checker and around the quads
