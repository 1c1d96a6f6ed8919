"""glTF scene features with known answers on assets built here (tests/gltf_build.py): skins, morph
targets, sparse morph deltas, EXT_mesh_gpu_instancing, KHR_node_visibility, KHR_materials_unlit (both
renderers and the reference), KHR_materials_variants (--variant), image formats (EXT_texture_webp,
KHR_texture_basisu's KTX2, lazy decoding), EXT_meshopt_compression, the export; then
the shared Khronos assets (skipped when ../shared is absent)."""

from __future__ import annotations

import io
import json
import math
from pathlib import Path

import numpy as np
import pytest

from pbrcheck import cli
from pbrcheck.gltf import AssetError, load_asset
from pbrcheck.scene import load_scene

from gltf_build import QUAD_IDX, QUAD_NRM, QUAD_POS, QUAD_TAN, QUAD_UV, Doc, quad_asset, quad_scene

SHARED = Path(__file__).resolve().parents[2] / "shared" / "assets" / "khronos"
#: float32 rounding of positions after a few 4x4 products.
POS_ATOL = 1e-5
#: The raster pipeline's small bakes (no IBL matters for unlit or coverage checks).
SMALL = {"cube_size": 16, "irradiance_source_size": 8, "irradiance_size": 8, "prefilter_levels": 3,
         "prefilter_samples": 16, "lut_size": 16, "lut_samples": 64, "supersample": 1, "pipeline": "raster"}
UNLIT = {"KHR_materials_unlit": {}}


def _quad_doc(material: dict | None = None, **attrs_extra) -> tuple[Doc, dict]:
    doc = Doc()
    attrs = {"POSITION": doc.accessor(QUAD_POS, "VEC3", minmax=True), "NORMAL": doc.accessor(QUAD_NRM, "VEC3"),
             "TEXCOORD_0": doc.accessor(QUAD_UV, "VEC2"), **attrs_extra}
    doc.d["materials"] = [material or {"pbrMetallicRoughness": {"metallicFactor": 0.0}}]
    return doc, attrs


def _realtime(scene_path):
    from realtime.render import render_realtime
    img = render_realtime(load_scene(scene_path), "default", SMALL, progress=False)
    return np.stack([img.channels[c] for c in "RGB"], -1), img


def _reference(scene_path, spp=4, mode="local"):
    from reference.render import render_reference
    img = render_reference(load_scene(scene_path), spp=spp, mode=mode, use_cache=False, progress=False)
    return np.stack([img.channels[c] for c in "RGB"], -1), img


# ---- skins ------------------------------------------------------------------------------------

def _skinned_quad(tmp_path: Path, angle_deg: float, name="skin.gltf") -> Path:
    """The quad skinned to two joints: vertices 0, 1 (y = -1) to joint 0 at the origin, vertices 2, 3
    (y = +1) to joint 1, a child of joint 0 at (0, 1, 0) rotated ``angle_deg`` about +Z in the file's
    node (its default pose). The inverse bind matrices are the joints' bind-pose inverses (joint 1's:
    a translation by -1 in y). The mesh node sits at x = +5: the specification ignores it."""
    doc, attrs = _quad_doc()
    joints = np.array([[0, 0, 0, 0], [0, 0, 0, 0], [1, 0, 0, 0], [1, 0, 0, 0]], np.uint8)
    weights = np.array([[1, 0, 0, 0]] * 4, np.float32)
    attrs.update(JOINTS_0=doc.accessor(joints, "VEC4"), WEIGHTS_0=doc.accessor(weights, "VEC4"),
                 TANGENT=doc.accessor(QUAD_TAN, "VEC4"))
    ibm = np.stack([np.eye(4), np.eye(4)]).astype(np.float32)
    ibm[1][1, 3] = -1.0
    ibm_acc = doc.accessor(np.ascontiguousarray(ibm.transpose(0, 2, 1)).reshape(2, 16), "MAT4")  # column-major
    h = math.radians(angle_deg) / 2
    mesh = doc.mesh(attrs, doc.accessor(QUAD_IDX, "SCALAR"), 0)
    doc.node(mesh, skin=0, translation=[5.0, 0.0, 0.0])
    doc.d["nodes"] += [{"name": "j0", "children": [2]},
                       {"name": "j1", "translation": [0.0, 1.0, 0.0], "rotation": [0.0, 0.0, math.sin(h), math.cos(h)]}]
    doc.d["scenes"][0]["nodes"].append(1)
    doc.d["skins"] = [{"joints": [1, 2], "inverseBindMatrices": ibm_acc}]
    return doc.write(tmp_path / name)


def test_skin_poses_vertices_by_the_joints_default_transforms(tmp_path):
    p = load_asset(_skinned_quad(tmp_path, 90.0)).primitives[0]
    # joint 1 = T(0, 1, 0) Rz(90): (x, 1) -> bind-local (x, 0) -> rotated (0, x) -> (0, 1 + x)
    expected = np.array([[-1, -1, 0], [1, -1, 0], [0, 2, 0], [0, 0, 0]], np.float64)
    assert np.allclose(p.positions, expected, atol=POS_ATOL), p.positions
    # the mesh node's translation (+5 x) is ignored; normals (+z) stay +z under a rotation about z;
    # the skinned vertices' tangents (+x) turn to +y
    assert np.allclose(p.normals, [[0, 0, 1]] * 4, atol=POS_ATOL)
    assert np.allclose(p.tangents[2:, :3], [[0, 1, 0]] * 2, atol=POS_ATOL)
    assert np.allclose(p.tangents[:2, :3], [[1, 0, 0]] * 2, atol=POS_ATOL)
    # at the bind pose (angle 0) the skin is the identity
    q = load_asset(_skinned_quad(tmp_path, 0.0, "bind.gltf")).primitives[0]
    assert np.allclose(q.positions, QUAD_POS, atol=POS_ATOL)


def test_skin_blends_two_weight_sets(tmp_path):
    """JOINTS_1 / WEIGHTS_1 count: vertex 2 half on each joint (the second set's) lands halfway."""
    path = _skinned_quad(tmp_path, 90.0)
    d = json.loads(path.read_text())
    doc = Doc()
    doc.bin = bytearray(__import__("base64").b64decode(d["buffers"][0]["uri"].split(",", 1)[1]))
    doc.d = d
    w0 = np.array([[1, 0, 0, 0], [1, 0, 0, 0], [0.5, 0, 0, 0], [1, 0, 0, 0]], np.float32)
    w1 = np.array([[0, 0, 0, 0], [0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0, 0, 0]], np.float32)
    j1 = np.array([[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0]], np.uint8)   # set 1: joint 0
    a = d["meshes"][0]["primitives"][0]["attributes"]
    a["WEIGHTS_0"] = doc.accessor(w0, "VEC4")
    a["JOINTS_1"], a["WEIGHTS_1"] = doc.accessor(j1, "VEC4"), doc.accessor(w1, "VEC4")
    p = load_asset(doc.write(tmp_path / "two.gltf")).primitives[0]
    # vertex 2 (1, 1): joint 1 takes it to (0, 2), joint 0 leaves it at (1, 1): the mean (0.5, 1.5)
    assert np.allclose(p.positions[2], [0.5, 1.5, 0.0], atol=POS_ATOL)


def test_a_skin_poses_only_primitives_with_joints(tmp_path):
    """A skinned node's primitive without JOINTS_0 is an ordinary mesh at its node's transform (as
    engines draw it): here the node's +5 x translation applies."""
    path = _skinned_quad(tmp_path, 90.0)
    d = json.loads(path.read_text())
    for k in ("JOINTS_0", "WEIGHTS_0"):
        d["meshes"][0]["primitives"][0]["attributes"].pop(k)
    path.write_text(json.dumps(d))
    p = load_asset(path).primitives[0]
    assert np.allclose(p.positions, QUAD_POS + [5, 0, 0], atol=POS_ATOL) and not p.skinned


def test_skin_joint_out_of_range_is_named(tmp_path):
    path = _skinned_quad(tmp_path, 90.0)
    d = json.loads(path.read_text())
    d["skins"][0]["joints"] = [1]
    d["skins"][0].pop("inverseBindMatrices")
    path.write_text(json.dumps(d))
    with pytest.raises(AssetError, match=r"JOINTS_0.*joint 1 out of range \(1 joints\)"):
        load_asset(path)


# ---- morph targets (and sparse accessors) -------------------------------------------------------

def _morph_quad(tmp_path: Path, name: str, *, mesh_weights=None, node_weights=None, sparse=False) -> Path:
    """The quad with one target moving vertex 2 by (0, 2, 0), its normal by (1, 0, 0) and its tangent
    by (0, 2, 0) (``sparse``: the POSITION delta as a sparse accessor without a bufferView)."""
    doc, attrs = _quad_doc()
    attrs["TANGENT"] = doc.accessor(QUAD_TAN, "VEC4")
    dpos = np.zeros((4, 3), np.float32)
    dpos[2] = (0, 2, 0)
    dn = np.zeros((4, 3), np.float32)
    dn[2] = (1, 0, 0)
    if sparse:
        iv = doc.view(np.array([2], np.uint16).tobytes())
        vv = doc.view(np.array([[0, 2, 0]], np.float32).tobytes())
        doc.d["accessors"].append({"componentType": 5126, "count": 4, "type": "VEC3", "sparse": {
            "count": 1, "indices": {"bufferView": iv, "componentType": 5123}, "values": {"bufferView": vv}}})
        tpos = len(doc.d["accessors"]) - 1
    else:
        tpos = doc.accessor(dpos, "VEC3")
    target = {"POSITION": tpos, "NORMAL": doc.accessor(dn, "VEC3"), "TANGENT": doc.accessor(dpos, "VEC3")}
    mesh = doc.mesh(attrs, doc.accessor(QUAD_IDX, "SCALAR"), 0, targets=[target])
    if mesh_weights is not None:
        doc.d["meshes"][mesh]["weights"] = mesh_weights
    doc.node(mesh, **({"weights": node_weights} if node_weights is not None else {}))
    return doc.write(tmp_path / name)


def test_morph_default_weight_moves_a_vertex_halfway(tmp_path):
    p = load_asset(_morph_quad(tmp_path, "m.gltf", mesh_weights=[0.5])).primitives[0]
    assert np.allclose(p.positions[2], [1.0, 2.0, 0.0], atol=POS_ATOL)      # (1, 1) + 0.5 (0, 2)
    assert np.allclose(p.positions[[0, 1, 3]], QUAD_POS[[0, 1, 3]], atol=POS_ATOL)
    # normal (0, 0, 1) + 0.5 (1, 0, 0) and tangent (1, 0, 0) + 0.5 (0, 2, 0), normalized
    assert np.allclose(p.normals[2], np.array([0.5, 0.0, 1.0]) / math.hypot(0.5, 1.0), atol=POS_ATOL)
    assert np.allclose(p.tangents[2, :3], np.array([1.0, 1.0, 0.0]) / math.sqrt(2), atol=POS_ATOL)
    # no weights anywhere: the base mesh
    q = load_asset(_morph_quad(tmp_path, "zero.gltf")).primitives[0]
    assert np.allclose(q.positions, QUAD_POS, atol=POS_ATOL)


def test_morph_node_weights_override_the_mesh_weights_and_sparse_deltas_apply(tmp_path):
    p = load_asset(_morph_quad(tmp_path, "n.gltf", mesh_weights=[0.5], node_weights=[0.25], sparse=True)).primitives[0]
    assert np.allclose(p.positions[2], [1.0, 1.5, 0.0], atol=POS_ATOL)      # (1, 1) + 0.25 (0, 2)
    # the normal (0.25, 0, 1) and the tangent (1, 0.5, 0), normalized
    assert np.allclose(p.normals[2], np.array([0.25, 0.0, 1.0]) / math.hypot(0.25, 1.0), atol=POS_ATOL)
    assert np.allclose(p.tangents[2, :3], np.array([1.0, 0.5, 0.0]) / math.hypot(1.0, 0.5), atol=POS_ATOL)
    bad = _morph_quad(tmp_path, "bad.gltf", mesh_weights=[0.5, 0.5])
    with pytest.raises(AssetError, match=r"/meshes/0/weights: 2 weights for 1 morph targets"):
        load_asset(bad)


# ---- EXT_mesh_gpu_instancing and KHR_node_visibility ---------------------------------------------

def _instanced(tmp_path: Path, name="inst.gltf") -> Path:
    """The quad scaled by 0.25 drawn at x = -1.5, 0, +1.5 (TRANSLATION, SCALE; ROTATION the identity
    but for the third, 90 degrees about +Z)."""
    doc, attrs = _quad_doc({"pbrMetallicRoughness": {"baseColorFactor": [0, 1, 0, 1]}, "extensions": UNLIT})
    t = np.array([[-1.5, 0, 0], [0, 0, 0], [1.5, 0, 0]], np.float32)
    r = np.array([[0, 0, 0, 1]] * 3, np.float32)
    r[2] = (0, 0, math.sin(math.pi / 4), math.cos(math.pi / 4))
    s = np.full((3, 3), 0.25, np.float32)
    mesh = doc.mesh(attrs, doc.accessor(QUAD_IDX, "SCALAR"), 0)
    doc.node(mesh, extensions={"EXT_mesh_gpu_instancing": {"attributes": {
        "TRANSLATION": doc.accessor(t, "VEC3"), "ROTATION": doc.accessor(r, "VEC4"), "SCALE": doc.accessor(s, "VEC3")}}})
    doc.d["extensionsUsed"] = ["EXT_mesh_gpu_instancing", "KHR_materials_unlit"]
    return doc.write(tmp_path / name)


def test_instancing_draws_each_instance_at_its_place(tmp_path):
    a = load_asset(_instanced(tmp_path))
    p = a.primitives[0]
    assert len(a.primitives) == 1 and p.positions.shape == (12, 3) and p.triangles == 6
    for k, x in enumerate((-1.5, 0.0)):
        assert np.allclose(p.positions[4 * k:4 * k + 4], QUAD_POS * 0.25 + [x, 0, 0], atol=POS_ATOL)
    rotated = np.stack([-QUAD_POS[:, 1], QUAD_POS[:, 0], QUAD_POS[:, 2]], 1) * 0.25 + [1.5, 0, 0]   # Rz(90)
    assert np.allclose(p.positions[8:], rotated, atol=POS_ATOL)
    assert np.array_equal(p.indices[4:], QUAD_IDX.reshape(-1, 3) + 8)   # its two triangles, offset
    assert a.extensions_ignored == ()


def test_instancing_covers_three_times_the_pixels_in_both_renderers(tmp_path):
    """3 instances cover 3x the pixels of one, at the known columns: 4 units away with a horizontal
    fov of 2 atan(1/2), the image's 64 columns span [-2, 2] at the quads' depth (1/16 unit a pixel),
    so each 0.5-unit quad covers exactly 8 x 8 pixels, its edges on pixel boundaries."""
    p3 = _instanced(tmp_path)
    d = json.loads(p3.read_text())
    ext = d["nodes"][0].pop("extensions")["EXT_mesh_gpu_instancing"]["attributes"]
    d["nodes"][0]["scale"] = [0.25, 0.25, 0.25]      # one quad, the middle instance
    (tmp_path / "one.gltf").write_text(json.dumps(d))
    assert ext
    cov = {}
    for name in ("inst", "one"):
        s = quad_scene(tmp_path, tmp_path / f"{name}.gltf", size=(64, 16), fov=math.degrees(2 * math.atan(0.5)),
                       env="[0.0, 0.0, 0.0]", name=f"{name}.toml")
        rt, _ = _realtime(s)
        ref, _ = _reference(s, spp=2)
        for who, img in (("rt", rt), ("ref", ref)):
            green = (img[..., 1] > 0.99) & (img[..., 0] < 0.01)
            cov[(name, who)] = green
    for who in ("rt", "ref"):
        n3, n1 = int(cov[("inst", who)].sum()), int(cov[("one", who)].sum())
        assert n1 == 64 and n3 == 3 * n1, (who, n3, n1)
        # x = -1.5, 0, 1.5 +- 0.25: columns [4, 12), [28, 36), [52, 60); rows [4, 12)
        cols = np.nonzero(cov[("inst", who)].any(axis=0))[0]
        assert list(cols) == [*range(4, 12), *range(28, 36), *range(52, 60)], (who, cols)
        assert list(np.nonzero(cov[("inst", who)].any(axis=1))[0]) == list(range(4, 12))


def _two_quads(tmp_path: Path, hidden: bool, name: str) -> Path:
    """Two unlit quads: node 0 (red) at x = -1.2, node 1 (blue) at x = +1.2 under a parent that is
    hidden by KHR_node_visibility when ``hidden``; a point light under the hidden parent too."""
    doc, attrs = _quad_doc({"pbrMetallicRoughness": {"baseColorFactor": [1, 0, 0, 1]}, "extensions": UNLIT})
    doc.d["materials"].append({"pbrMetallicRoughness": {"baseColorFactor": [0, 0, 1, 1]}, "extensions": UNLIT})
    idx = doc.accessor(QUAD_IDX, "SCALAR")
    m0, m1 = doc.mesh(attrs, idx, 0), doc.mesh(attrs, idx, 1)
    doc.node(m0, translation=[-1.2, 0, 0], scale=[0.5, 0.5, 0.5])
    doc.d["nodes"].append({"name": "blue", "mesh": m1, "translation": [1.2, 0, 0], "scale": [0.5, 0.5, 0.5],
                           "extensions": {"KHR_lights_punctual": {"light": 0}}})
    parent = {"name": "parent", "children": [1]}
    if hidden:
        parent["extensions"] = {"KHR_node_visibility": {"visible": False}}
    doc.d["nodes"].append(parent)
    doc.d["scenes"][0]["nodes"] = [0, 2]
    doc.d["extensions"] = {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 5.0}]}}
    doc.d["extensionsUsed"] = ["KHR_node_visibility", "KHR_materials_unlit", "KHR_lights_punctual"]
    return doc.write(tmp_path / name)


def test_a_hidden_node_hides_its_subtree(tmp_path):
    shown, hidden = load_asset(_two_quads(tmp_path, False, "a.gltf")), load_asset(_two_quads(tmp_path, True, "b.gltf"))
    assert [p.name for p in shown.primitives] == ["node0/mesh0/0", "blue/mesh1/0"] and len(shown.lights) == 1
    assert [p.name for p in hidden.primitives] == ["node0/mesh0/0"] and hidden.lights == ()
    for name, blue in (("a", True), ("b", False)):
        s = quad_scene(tmp_path, tmp_path / f"{name}.gltf", size=(32, 16), fov=70.0, env="[0.0, 0.0, 0.0]",
                       name=f"{name}.toml")
        for img in (_realtime(s)[0], _reference(s, spp=2)[0]):
            assert (((img[..., 2] > 0.99) & (img[..., 0] < 0.01)).sum() > 0) == blue   # hidden: drawn nowhere
            assert ((img[..., 0] > 0.99) & (img[..., 2] < 0.01)).sum() > 0



def test_an_asset_all_hidden_is_refused_naming_the_extension(tmp_path):
    p = _two_quads(tmp_path, True, "all.gltf")
    d = json.loads(p.read_text())
    d["nodes"][0]["extensions"] = {"KHR_node_visibility": {"visible": False}}
    p.write_text(json.dumps(d))
    with pytest.raises(AssetError, match=r"/scenes/0: no mesh primitive to render \(2 mesh node\(s\) hidden by "
                                         r"KHR_node_visibility\)"):
        load_asset(p)
    d["nodes"][0]["extensions"] = {"KHR_node_visibility": {"visible": "no"}}
    p.write_text(json.dumps(d))
    with pytest.raises(AssetError, match=r"/nodes/0/extensions/KHR_node_visibility/visible: a boolean, found 'no'"):
        load_asset(p)


# ---- KHR_materials_unlit ---------------------------------------------------------------------

def _unlit_quad(tmp_path: Path, name="u.gltf", *, texture=True, color=True) -> Path:
    """An unlit quad: base colour factor (1, 0.5, 1) x a grey texture (sRGB 188 -> linear 0.5029) x
    COLOR_0 (1, 1, 0.5); single-sided; under a coloured environment, with metallic and roughness
    that would shade it otherwise, and an emissive factor the extension ignores."""
    tex = np.full((2, 2, 3), 188, np.uint8)
    doc, attrs = _quad_doc()
    if color:
        attrs["COLOR_0"] = doc.accessor(np.array([[1, 1, 0.5, 1]] * 4, np.float32), "VEC4")
    pbr = {"baseColorFactor": [1, 0.5, 1, 1], "metallicFactor": 0.0, "roughnessFactor": 0.3}
    if texture:
        pbr["baseColorTexture"] = {"index": doc.image(tex, {"magFilter": 9728, "minFilter": 9728})}
    doc.d["materials"] = [{"pbrMetallicRoughness": pbr, "emissiveFactor": [1, 1, 1], "extensions": UNLIT}]
    doc.node(doc.mesh(attrs, doc.accessor(QUAD_IDX, "SCALAR"), 0))
    doc.d["extensionsUsed"] = doc.d["extensionsRequired"] = ["KHR_materials_unlit"]
    return doc.write(tmp_path / name)


def test_unlit_red_quad_is_its_base_colour_in_both_renderers(tmp_path):
    p = quad_asset(tmp_path / "red.gltf", {"pbrMetallicRoughness": {"baseColorFactor": [1, 0, 0, 1],
                                                                    "metallicFactor": 0.0}, "extensions": UNLIT})
    assert load_asset(p).materials[0].unlit
    s = quad_scene(tmp_path, p, env="[0.3, 0.5, 0.7]", size=(8, 8))
    for img in (_realtime(s)[0], _reference(s)[0], _reference(s, mode="path")[0]):
        assert np.allclose(img[4, 4], [1.0, 0.0, 0.0], atol=1e-6), img[4, 4]
    # the same material lit: not (1, 0, 0)
    lit = quad_asset(tmp_path / "lit.gltf", {"pbrMetallicRoughness": {"baseColorFactor": [1, 0, 0, 1], "metallicFactor": 0.0}})
    s2 = quad_scene(tmp_path, lit, env="[0.3, 0.5, 0.7]", size=(8, 8), name="lit.toml")
    for img in (_realtime(s2)[0], _reference(s2)[0]):
        assert not np.allclose(img[4, 4], [1.0, 0.0, 0.0], atol=0.05), img[4, 4]


def test_unlit_multiplies_texture_and_vertex_colour_and_ignores_emission(tmp_path):
    s = quad_scene(tmp_path, _unlit_quad(tmp_path), env="[0.3, 0.5, 0.7]", size=(8, 8), fov=20.0)
    grey = ((188 / 255 + 0.055) / 1.055) ** 2.4
    expected = np.array([1.0, 0.5, 0.5]) * grey            # factor x texture x COLOR_0
    for img in (_realtime(s)[0], _reference(s)[0]):
        assert np.allclose(img[2:6, 2:6], expected, rtol=1e-3), img[4, 4]


# ---- KHR_materials_variants --------------------------------------------------------------------

def _variants(tmp_path: Path) -> Path:
    """An unlit quad: default material red; variant "green" maps it to green, "blue" to blue."""
    doc, attrs = _quad_doc({"pbrMetallicRoughness": {"baseColorFactor": [1, 0, 0, 1]}, "extensions": UNLIT})
    doc.d["materials"] += [{"name": "g", "pbrMetallicRoughness": {"baseColorFactor": [0, 1, 0, 1]}, "extensions": UNLIT},
                           {"name": "b", "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 1, 1]}, "extensions": UNLIT}]
    doc.node(doc.mesh(attrs, doc.accessor(QUAD_IDX, "SCALAR"), 0, extensions={"KHR_materials_variants": {
        "mappings": [{"material": 1, "variants": [0]}, {"material": 2, "variants": [1]}]}}))
    doc.d["extensions"] = {"KHR_materials_variants": {"variants": [{"name": "green"}, {"name": "blue"}]}}
    doc.d["extensionsUsed"] = ["KHR_materials_variants", "KHR_materials_unlit"]
    return doc.write(tmp_path / "v.gltf")


def test_variants_switch_the_material_and_default_to_the_files(tmp_path):
    p = _variants(tmp_path)
    assert load_asset(p).primitives[0].material == 0 and load_asset(p).variants == ("green", "blue")
    assert load_asset(p, variant="blue").primitives[0].material == 2
    with pytest.raises(AssetError, match=r"no material variant purple \(the file's variants: green, blue\)"):
        load_asset(p, variant="purple")
    colours = {}
    for v in (None, "green"):
        toml = tmp_path / f"{v}.toml"
        quad_scene(tmp_path, p, size=(8, 8), name=toml.name)
        if v is not None:
            toml.write_text(toml.read_text() + f'variant = "{v}"\n')
        colours[v] = (_realtime(toml)[0][4, 4], _reference(toml)[0][4, 4])
    assert all(np.allclose(c, [1, 0, 0], atol=1e-6) for c in colours[None])
    assert all(np.allclose(c, [0, 1, 0], atol=1e-6) for c in colours["green"])
    # the variant is part of both renderers' cache keys
    from realtime.cache import realtime_cache_key
    from reference.render import reference_cache_key
    a, b = load_scene(tmp_path / "None.toml"), load_scene(tmp_path / "green.toml")
    assert realtime_cache_key(a, "default") != realtime_cache_key(b, "default")
    ref_key = lambda sc: reference_cache_key(sc, spp=8, mode="local", seed=0, max_depth=None)  # noqa: E731
    assert ref_key(a) != ref_key(b)


def test_variant_option_on_the_cli_and_check_scene_lists_variants(tmp_path, capsys):
    p = _variants(tmp_path)
    assert cli.main(["check-scene", str(p), "--variant", "blue"]) == 0
    out = capsys.readouterr().out
    assert "material variants (--variant NAME): green, blue; drawn: blue" in out
    assert "material 'b'" in out
    assert cli.main(["check-scene", str(p), "--variant", "purple"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no material variant purple (the file's variants: green, blue)" in err[0]


# ---- images --------------------------------------------------------------------------------------

def _webp_bytes(px: np.ndarray) -> bytes:
    from PIL import Image
    b = io.BytesIO()
    Image.fromarray(px).save(b, format="WEBP", lossless=True)
    return b.getvalue()


def _textured(tmp_path: Path, name: str, texture: dict, images: list[dict], required=()) -> Path:
    doc, attrs = _quad_doc({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}})
    doc.d["images"], doc.d["textures"] = images, [texture]
    doc.node(doc.mesh(attrs, doc.accessor(QUAD_IDX, "SCALAR"), 0))
    doc.d["extensionsUsed"] = sorted({e for e in texture.get("extensions", {})} | set(required))
    if required:
        doc.d["extensionsRequired"] = list(required)
    return doc.write(tmp_path / name)


def _uri(raw: bytes, mime: str) -> str:
    import base64
    return f"data:{mime};base64," + base64.b64encode(raw).decode()


RED = np.full((2, 2, 3), (255, 0, 0), np.uint8)
BLUE = np.full((2, 2, 3), (0, 0, 255), np.uint8)
KTX2 = b"\xabKTX 20\xbb\r\n\x1a\n" + bytes(64)          # a KTX2 signature, then nothing valid
#: :data:`QUADRANTS` as KTX2 with a UASTC payload, written by alktx2 0.1.7's basisu encoder (Basis
#: Universal 2.10; codec "uastc", quality 100, effort 4, zstd level 0); each quadrant is one flat
#: 4 x 4 block, so the transcoded RGBA8 is exact.
UASTC_QUADRANTS = __import__("base64").b64decode(
    "q0tUWCAyMLsNChoKAAAAAAEAAAAIAAAACAAAAAAAAAAAAAAAAQAAAAEAAAACAAAAaAAAACwAAACUAAAAJAAAAAAAAAAAAAAAAAAAAAAAAAC4"
    "AAAAAAAAADQAAAAAAAAAQAAAAAAAAAAsAAAAAAAAAAIAKACmAQIAAwMAABAAAAAAAAAAAAB/AAAAAAAAAAAA/////x8AAABLVFh3cml0ZXIAQm"
    "FzaXMgVW5pdmVyc2FsIDIuMTAAACi1L/0gQF0BAPj3HwDgH3oAFwDg/x8C4AEAF+Af4B8CDwD3////H3zvBABDFQMIB/kUwAg=")
QUADRANTS = np.zeros((8, 8, 3), np.uint8)
QUADRANTS[:4, :4], QUADRANTS[:4, 4:], QUADRANTS[4:, :4], QUADRANTS[4:, 4:] = (255, 0, 0), (0, 0, 255), (0, 255, 0), 255


def test_webp_is_decoded_and_preferred_over_the_core_fallback(tmp_path):
    from pbrcheck.gltf_build import png_bytes
    p = _textured(tmp_path, "w.gltf", {"source": 1, "extensions": {"EXT_texture_webp": {"source": 0}}},
                  [{"uri": _uri(_webp_bytes(RED), "image/webp")}, {"uri": _uri(png_bytes(BLUE), "image/png")}])
    a = load_asset(p)
    t = a.materials[0].base_color_texture
    assert t.image == 0 and a.images[0].mime == "image/webp"
    assert (a.images[0].pixels[..., :3] == RED).all()
    assert not a.images[1].decoded and a.extensions_ignored == ()     # the unused PNG is not decoded


def test_basisu_ktx2_is_decoded_preferred_over_the_fallback_and_named_when_corrupt(tmp_path):
    """KTX2 (UASTC) of an 8 x 8 image, quadrants red / blue (top) and green / white (bottom): read
    through KHR_texture_basisu in preference to the PNG fallback, decoded exactly (flat 4 x 4 blocks),
    top row first, whether the extension is optional or required."""
    from pbrcheck.gltf_build import png_bytes
    images = [{"uri": _uri(UASTC_QUADRANTS, "image/ktx2")}, {"uri": _uri(png_bytes(BLUE), "image/png")}]
    for name, required in (("o.gltf", ()), ("r.gltf", ("KHR_texture_basisu",))):
        p = _textured(tmp_path, name, {"source": 1, "extensions": {"KHR_texture_basisu": {"source": 0}}}, images,
                      required=required)
        a = load_asset(p)
        assert a.materials[0].base_color_texture.image == 0 and a.images[0].mime == "image/ktx2"
        assert np.array_equal(a.images[0].pixels[..., :3], QUADRANTS) and (a.images[0].pixels[..., 3] == 255).all()
        assert not a.images[1].decoded
    # a corrupt KTX2: one line naming the format, not Pillow's stream object
    bad = _textured(tmp_path, "c.gltf", {"source": 0}, [{"uri": _uri(KTX2, "image/ktx2")}])
    with pytest.raises(AssetError) as e:
        load_asset(bad)
    assert "KTX2" in str(e.value) and "BytesIO" not in str(e.value) and "\n" not in str(e.value)
    png = _textured(tmp_path, "p.gltf", {"source": 0}, [{"uri": _uri(b"\x89PNG\r\n\x1a\n" + bytes(20), "image/png")}])
    with pytest.raises(AssetError, match=r"/images/0: unreadable texture image 'data URI' \(PNG; "
                                         r"UnidentifiedImageError: cannot identify image file\)$"):
        load_asset(png)


def _meshopt_quad(tmp_path: Path, name: str, *, fallback: bool, required: bool) -> Path:
    """The quad with every buffer view compressed by meshoptimizer into buffer 1 (attributes as
    ATTRIBUTES, the indices as TRIANGLES); buffer 0 (the core fields' data) holds zeros when
    ``fallback`` (so that reading it would show), else nothing (a fallback buffer without uri, as the
    extension allows)."""
    import base64

    import meshopt
    p = quad_asset(tmp_path / name, {})
    d = json.loads(p.read_text())
    plain = base64.b64decode(d["buffers"][0]["uri"].split(",", 1)[1])
    prim = d["meshes"][0]["primitives"][0]
    comp = bytearray()
    for acc, mode in [(a, "ATTRIBUTES") for a in prim["attributes"].values()] + [(prim["indices"], "TRIANGLES")]:
        a = d["accessors"][acc]
        v = d["bufferViews"][a["bufferView"]]
        rows = np.frombuffer(plain[v["byteOffset"]:v["byteOffset"] + v["byteLength"]], np.uint8)
        if mode == "ATTRIBUTES":
            stride = v["byteLength"] // a["count"]
            raw = meshopt.encode_gltf_buffer(rows.reshape(a["count"], stride), mode)
            v["byteStride"] = stride
        else:
            stride = 2
            raw = meshopt.encode_gltf_buffer(rows.view(np.uint16).astype(np.uint32), mode)
        while len(comp) % 4:
            comp.append(0)
        v["extensions"] = {"EXT_meshopt_compression": {"buffer": 1, "byteOffset": len(comp), "byteLength": len(raw),
                                                       "byteStride": stride, "count": a["count"], "mode": mode}}
        comp += raw
    d["buffers"].append({"byteLength": len(comp), "uri": _uri(bytes(comp), "application/octet-stream")})
    d["buffers"][0] = {"byteLength": len(plain), "extensions": {"EXT_meshopt_compression": {"fallback": True}},
                       **({"uri": _uri(bytes(len(plain)), "application/octet-stream")} if fallback else {})}
    d["extensionsUsed"] = ["EXT_meshopt_compression"]
    if required:
        d["extensionsRequired"] = ["EXT_meshopt_compression"]
    p.write_text(json.dumps(d))
    return p


def test_meshopt_compressed_buffer_views_are_decoded(tmp_path):
    """Required, with a data-less fallback buffer, and optional, with a fallback buffer of zeros: the
    decoded views give the quad (the fallback is not read)."""
    for name, fallback, required in (("r.gltf", False, True), ("o.gltf", True, False)):
        p = load_asset(_meshopt_quad(tmp_path, name, fallback=fallback, required=required)).primitives[0]
        assert np.array_equal(p.positions, QUAD_POS) and np.array_equal(p.indices, QUAD_IDX.reshape(-1, 3))
    bad = _meshopt_quad(tmp_path, "bad.gltf", fallback=False, required=True)
    d = json.loads(bad.read_text())
    d["bufferViews"][d["accessors"][0]["bufferView"]]["extensions"]["EXT_meshopt_compression"]["mode"] = "PACKED"
    bad.write_text(json.dumps(d))
    with pytest.raises(AssetError, match=r"EXT_meshopt_compression/mode: one of ATTRIBUTES, TRIANGLES, INDICES"):
        load_asset(bad)


def test_an_unused_undecodable_image_is_not_decoded(tmp_path):
    p = quad_asset(tmp_path / "q.gltf", {})
    d = json.loads(p.read_text())
    d["images"] = [{"uri": _uri(b"not an image at all", "image/png")}]
    p.write_text(json.dumps(d))
    a = load_asset(p)
    assert not a.images[0].decoded


# ---- export --------------------------------------------------------------------------------------

def test_export_draws_the_selected_variant_and_drops_hidden_nodes(tmp_path):
    from pbrcheck.export import export_scene
    v = tmp_path / "v.toml"
    quad_scene(tmp_path, _variants(tmp_path), name=v.name)
    v.write_text(v.read_text() + 'variant = "blue"\n')
    export_scene(load_scene(v), tmp_path / "ev")
    d = json.loads((tmp_path / "ev" / "scene.gltf").read_text())
    assert d["meshes"][0]["primitives"][0]["material"] == 2
    h = quad_scene(tmp_path, _two_quads(tmp_path, True, "h.gltf"), name="h.toml")
    export_scene(load_scene(h), tmp_path / "eh")
    d = json.loads((tmp_path / "eh" / "scene.gltf").read_text())
    by_name = {n.get("name"): n for n in d["nodes"]}
    assert "mesh" in by_name["node0"] and "mesh" not in by_name["blue"]
    assert "KHR_lights_punctual" not in by_name["blue"].get("extensions", {})


def test_export_keeps_skins_morphs_and_instances_for_the_engines(tmp_path):
    from pbrcheck.export import export_scene
    for name, asset in (("s", _skinned_quad(tmp_path, 90.0)), ("m", _morph_quad(tmp_path, "m.gltf", mesh_weights=[0.5])),
                        ("i", _instanced(tmp_path))):
        s = quad_scene(tmp_path, asset, name=f"{name}.toml")
        export_scene(load_scene(s), tmp_path / name)
        src, out = json.loads(asset.read_text()), json.loads((tmp_path / name / "scene.gltf").read_text())
        assert out["meshes"] == src["meshes"] and out.get("skins") == src.get("skins")
        assert out["nodes"][:len(src["nodes"])] == src["nodes"]


# ---- the shared Khronos assets ---------------------------------------------------------------------

def _shared(name: str) -> Path:
    p = SHARED / name / f"{name}.gltf"
    if not p.is_file():
        pytest.skip(f"{p} is absent (the real assets live in ../shared/assets)")
    return p


def _copy_edited(src: Path, dst_dir: Path, edit) -> Path:
    """``src`` (.gltf) and its external resources (a few KiB) copied into ``dst_dir``, its JSON edited
    by ``edit``."""
    import shutil
    d = json.loads(src.read_text())
    for key in ("buffers", "images"):
        for b in d.get(key, []):
            if "uri" in b and not b["uri"].startswith("data:"):
                shutil.copyfile(src.parent / b["uri"], dst_dir / b["uri"])
    edit(d)
    dst = dst_dir / src.name
    dst.write_text(json.dumps(d))
    return dst


def _pose_edit(name):
    def skin(d):
        d["nodes"][2]["rotation"] = [0.0, 0.0, math.sin(math.radians(30)), math.cos(math.radians(30))]

    def drop_skin(d):
        d["nodes"][2]["rotation"] = [0.0, 0.0, math.sin(math.radians(30)), math.cos(math.radians(30))]
        d["nodes"][0].pop("skin")

    def morph(d):
        d["meshes"][0].pop("weights")

    def inst(d):
        d["nodes"][0].pop("extensions")
        d["extensionsUsed"].remove("EXT_mesh_gpu_instancing")

    def unlit(d):
        for m in d["materials"]:
            m.pop("extensions")
        d["extensionsUsed"], d["extensionsRequired"] = [], []
    return {"SimpleSkin": (skin, drop_skin), "SimpleMorph": (None, morph), "SimpleInstancing": (None, inst),
            "UnlitTest": (None, unlit)}[name]


@pytest.mark.slow
@pytest.mark.parametrize("name", ["SimpleSkin", "SimpleMorph", "SimpleInstancing", "UnlitTest"])
def test_shared_asset_feature_changes_both_images(tmp_path, name):
    """Each shared asset renders in both renderers; removing its feature from the file changes both
    images. SimpleSkin's default pose is its bind pose (an identity skin), so its check poses the
    joint (30 deg about z in the file) and then drops the skin: the posed and unposed images differ."""
    src = _shared(name)
    with_edit, without_edit = _pose_edit(name)
    images = []
    for k, edit in enumerate((with_edit, without_edit)):
        d = tmp_path / str(k)
        d.mkdir()
        asset = _copy_edited(src, d, edit or (lambda doc: None))
        scene = d / "scene.toml"
        a = load_asset(asset)
        lo, hi = a.bounds()
        from pbrcheck.gltf_scene import framing_camera
        if not images:
            cam = framing_camera(lo, hi, 24, 24)
        scene.write_text(f"""
[camera]
origin = {list(cam.origin)}
target = {list(cam.target)}
fov = {cam.fov}
width = 24
height = 24

[environment]
type = "constant"
radiance = [0.8, 0.8, 0.8]

[[objects]]
type = "gltf"
path = "{asset}"
""")
        images.append((_realtime(scene)[0], _reference(scene, spp=2)[0]))
    for who in (0, 1):
        a, b = images[0][who], images[1][who]
        assert np.isfinite(a).all() and a.max() > 0
        # the feature moves a visible part of the image (not one pixel's noise: over 5% of the pixels)
        assert (np.abs(a - b).max(axis=-1) > 0.05).mean() > 0.05, (name, who)
