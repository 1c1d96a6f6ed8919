"""``pbrcheck export``: the glTF re-imported with a glTF reader (pygltflib), the Khronos glTF
validator, the tessellation rule, the environment's orientation (three.js's equirectUv in numpy),
RGBE and PFM round trips, the scenario and its model-viewer scenario, atomic writes."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from pbrcheck_cli import main
from pbrcheck.environment import load_environment
from pbrcheck.errors import PbrcheckError
from pbrcheck.export import (ENV_MAX_WIDTH, SILHOUETTE_TOLERANCE_PX, equirect_image, export_scene, export_width,
                             ior_from_f0, pixels_per_unit, sphere_segments, uv_sphere)
from pbrcheck.hdrimage import read_hdr, read_pfm, write_hdr, write_pfm
from pbrcheck.scene import load_scene, scene_from_dict

ROOT = Path(__file__).resolve().parents[1]
THREEJS = ROOT / "clients" / "threejs"

SCENE = {
    "name": "mixed",
    "camera": {"origin": [0.0, 1.0, 6.0], "target": [0.0, 0.0, 0.0], "fov": 50.0, "width": 64, "height": 48},
    "environment": {"type": "sky", "resolution": [64, 32], "rotation": 30.0, "scale": 2.0},
    "lights": [{"type": "point", "position": [1.0, 3.0, 2.0], "intensity": [20.0, 10.0, 5.0]}],
    "objects": [
        {"type": "sphere", "name": "ball", "center": [-1.0, 0.0, 0.0], "radius": 0.8,
         "material": {"base_color": [0.9, 0.2, 0.1], "metallic": 0.0, "roughness": 0.3, "specular": 0.5}},
        {"type": "plane", "name": "floor", "center": [0.0, -1.0, 0.0], "normal": [0.0, 1.0, 0.0], "size": [6.0, 4.0],
         "material": {"base_color": [0.5, 0.5, 0.5], "metallic": 0.0, "roughness": 0.8}},
        {"type": "sphere_grid", "name": "g", "center": [1.5, 0.0, 0.0], "rows": 1, "columns": 2, "radius": 0.3,
         "spacing": 0.7, "metallic": 1.0, "roughness": [0.1, 0.9], "material": {"base_color": [1.0, 0.8, 0.5]}},
    ],
}


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    scene = scene_from_dict(SCENE)
    out = tmp_path_factory.mktemp("export")
    return scene, export_scene(scene, out)


def test_gltf_reimported_with_a_gltf_reader(exported):
    pygltflib = pytest.importorskip("pygltflib")
    scene, exp = exported
    g = pygltflib.GLTF2().load(str(exp.files["scene.gltf"]))
    blob = exp.files["scene.bin"].read_bytes()

    def acc(i):
        a = g.accessors[i]
        v = g.bufferViews[a.bufferView]
        dt = {5126: np.float32, 5123: np.uint16, 5125: np.uint32}[a.componentType]
        n = {"VEC3": 3, "SCALAR": 1}[a.type]
        return np.frombuffer(blob, dt, a.count * n, v.byteOffset + (a.byteOffset or 0)).reshape(a.count, n)

    objs = {n.extras["pbrcheck_object"]: n for n in g.nodes if n.extras and "pbrcheck_object" in n.extras}
    assert sorted(objs) == [o.id for o in scene.objects] == [0, 1, 2, 3]
    for o in scene.objects:
        node = objs[o.id]
        assert node.name == f"object_{o.id}_{o.name}"
        prim = g.meshes[node.mesh].primitives[0]
        mat = g.materials[prim.material]
        pbr = mat.pbrMetallicRoughness
        assert pbr.baseColorFactor == pytest.approx(list(o.material.base_color) + [1.0])
        assert pbr.metallicFactor == pytest.approx(o.material.metallic)
        assert pbr.roughnessFactor == pytest.approx(o.material.roughness)
        assert mat.doubleSided is False
        pos, nrm = acc(prim.attributes.POSITION), acc(prim.attributes.NORMAL)
        assert np.allclose(np.linalg.norm(nrm, axis=1), 1.0, atol=1e-6)
        if o.type == "sphere":
            assert node.translation == pytest.approx(list(o.center)) and node.scale == pytest.approx([o.radius] * 3)
            assert np.allclose(pos, nrm, atol=1e-6)                        # analytic normals
        else:
            assert np.allclose(nrm, [0.0, 1.0, 0.0]) and pos[:, 1] == pytest.approx(-1.0)
            assert np.ptp(pos[:, 0]) == pytest.approx(6.0) and np.ptp(pos[:, 2]) == pytest.approx(4.0)
            idx = acc(prim.indices).reshape(-1, 3)
            for t in idx:                                                    # front face = +Y
                assert np.cross(pos[t[1]] - pos[t[0]], pos[t[2]] - pos[t[0]])[1] > 0
    ball = g.materials[g.meshes[objs[0].mesh].primitives[0].material]
    assert ball.extensions["KHR_materials_ior"]["ior"] == pytest.approx(ior_from_f0(0.5))
    assert g.materials[g.meshes[objs[1].mesh].primitives[0].material].extensions in ({}, None)
    lights = g.extensions["KHR_lights_punctual"]["lights"]
    assert lights[0]["type"] == "point" and lights[0]["intensity"] == pytest.approx(20.0)
    assert lights[0]["color"] == pytest.approx([1.0, 0.5, 0.25])
    lnode = next(n for n in g.nodes if n.extensions and "KHR_lights_punctual" in n.extensions)
    assert lnode.translation == pytest.approx([1.0, 3.0, 2.0])
    cam = g.cameras[0].perspective
    assert cam.yfov == pytest.approx(2 * math.atan(math.tan(math.radians(25.0)) * 48 / 64))
    assert cam.aspectRatio == pytest.approx(64 / 48)
    cnode = next(n for n in g.nodes if n.camera is not None)
    x, y, z, w = cnode.rotation                                             # local -Z looks at the target
    q = np.array([x, y, z])
    fwd = np.array([0.0, 0.0, -1.0])
    fwd = fwd + 2 * w * np.cross(q, fwd) + 2 * np.cross(q, np.cross(q, fwd))
    want = -np.array([0.0, 1.0, 6.0]) / np.linalg.norm([0.0, 1.0, 6.0])
    assert np.allclose(fwd, want, atol=1e-6)


def test_ior_formula():
    for f0 in (0.0, 0.02, 0.04, 0.5, 0.9):
        ior = ior_from_f0(f0)
        assert ((ior - 1) / (ior + 1)) ** 2 == pytest.approx(f0, abs=1e-12)
    assert ior_from_f0(0.04) == pytest.approx(1.5)
    assert ior_from_f0(1.0) == 0.0                   # the extension's special value: F0 = 1


def test_tessellation_rule_bounds_the_silhouette_error():
    scene = load_scene("spheres")
    for s in scene.objects[:3]:
        n = sphere_segments(scene, s)
        pos, idx = uv_sphere(n)
        centroids = pos[idx].mean(axis=1)
        depth = 1.0 - np.linalg.norm(centroids, axis=1)                    # unit sphere, flat triangles
        worst_px = depth.max() * s.radius * pixels_per_unit(scene, s.center, s.radius)
        assert worst_px <= SILHOUETTE_TOLERANCE_PX
        pos2, idx2 = uv_sphere(n - 4)                                      # the rule is not wasteful
        worst2 = (1 - np.linalg.norm(pos2[idx2].mean(axis=1), axis=1)).max() * s.radius * \
            pixels_per_unit(scene, s.center, s.radius)
        assert worst2 > SILHOUETTE_TOLERANCE_PX / 3
    assert n % 4 == 0 and len(idx) == 2 * n * (n // 2 - 1)


def test_environment_orientation_is_threejs_equirectuv(exported):
    scene, exp = exported
    env = load_environment(scene)
    img = equirect_image(env, 256)
    H, W = img.shape[:2]
    rng = np.random.default_rng(1)
    d = rng.normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d = d[np.abs(d[:, 1]) < 0.95]
    # three.js (common.glsl.js): u = atan(d.z, d.x)/2pi + 0.5, v = asin(d.y)/pi + 0.5; the EXR's top
    # row is v = 1 (EXRLoader, flipY off); nearest texel
    u = np.arctan2(d[:, 2], d[:, 0]) / (2 * np.pi) + 0.5
    v = np.arcsin(d[:, 1]) / np.pi + 0.5
    col = np.clip((u * W).astype(int), 0, W - 1)
    row = np.clip(((1 - v) * H).astype(int), 0, H - 1)
    got = img[row, col]
    want = env.radiance(d)
    rel = np.abs(got - want) / (want + 0.05)
    assert np.median(rel) < 0.05, np.median(rel)


def test_environment_files_agree_and_scenario(exported):
    scene, exp = exported
    from pbrcheck.exr import read_exr
    e = read_exr(exp.files["environment.exr"]).rgb
    h = read_hdr(exp.files["environment.hdr"])
    assert e.shape == h.shape and e.shape[1] == 2 * e.shape[0] == 128
    assert np.all(np.abs(h - e) <= e.max(axis=-1, keepdims=True) / 128 + 1e-6)  # RGBE: 8-bit shared mantissa
    sc = json.loads(exp.files["scenario.json"].read_text())
    assert sc["size"] == {"width": 64, "height": 48} and sc["output"]["format"] == "exr"
    assert sc["environment"]["width"] == 128 and "atan2(d.z, d.x)" in sc["environment"]["orientation"]
    assert sc["lights"][0]["intensity_w_per_sr"] == [20.0, 10.0, 5.0]
    assert [o["gltf_node"] for o in sc["objects"]][:2] == ["object_0_ball", "object_1_floor"]
    mv = sc["model_viewer"]
    assert mv["dimensions"] == {"width": 64, "height": 48} and mv["renderSkybox"] is True
    assert mv["orbit"]["radius"] == pytest.approx(math.sqrt(37)) and mv["orbit"]["theta"] == pytest.approx(0.0)
    assert mv["orbit"]["phi"] == pytest.approx(math.degrees(math.acos(1 / math.sqrt(37))))
    assert [export_width(w) for w in (16, 64, 1024, 4096)] == [64, 128, 2048, ENV_MAX_WIDTH]


def test_rgbe_and_pfm_round_trips(tmp_path):
    rng = np.random.default_rng(0)
    a = (rng.random((9, 300, 3)) * np.logspace(-3, 4, 300)[None, :, None]).astype(np.float32)
    a[0, 0] = 0
    write_hdr(tmp_path / "a.hdr", a)                                        # RLE scanlines (width 300)
    tol = a.max(axis=-1, keepdims=True) / 128 + 1e-30
    assert np.all(np.abs(read_hdr(tmp_path / "a.hdr") - a) <= tol)
    write_hdr(tmp_path / "b.hdr", a[:, :5])                                 # flat scanlines (width 5)
    assert np.all(np.abs(read_hdr(tmp_path / "b.hdr") - a[:, :5]) <= tol[:, :5])
    write_pfm(tmp_path / "a.pfm", a)
    assert np.array_equal(read_pfm(tmp_path / "a.pfm"), a)
    assert (tmp_path / "a.pfm").read_bytes().startswith(b"PF\n300 9\n-1.0\n")
    with pytest.raises(PbrcheckError, match="RGBE stores only finite non-negative"):
        write_hdr(tmp_path / "c.hdr", -a)
    assert not (tmp_path / "c.hdr").exists()


def test_cli_export_and_bad_input_writes_nothing(tmp_path, capsys):
    assert main(["export", "furnace", "--out", str(tmp_path / "f")]) == 0
    assert sorted(p.name for p in (tmp_path / "f").iterdir()) == sorted(
        ["scene.gltf", "scene.bin", "environment.exr", "environment.hdr", "scenario.json"])
    assert "triangles" in capsys.readouterr().out
    bad = tmp_path / "bad.toml"
    bad.write_text("name = 'x'\n[environment]\ntype = 'file'\npath = 'missing.exr'\n[[objects]]\ntype = 'sphere'\n")
    assert main(["export", str(bad), "--out", str(tmp_path / "g")]) == 2
    assert not (tmp_path / "g").exists()


def _validator():
    node = shutil.which("node")
    if node is None or not (THREEJS / "node_modules" / "gltf-validator").is_dir():
        pytest.skip("node or clients/threejs/node_modules/gltf-validator absent (make setup runs npm ci)")
    return node


EXTREMES = {  # KHR_materials_ior at its ends: specular 1 (ior 0, the special value) and 0 (ior 1)
    "name": "extremes", "camera": {"width": 32, "height": 16}, "environment": {"type": "constant"},
    "objects": [{"type": "sphere", "center": [-1.5, 0, 0], "material": {"specular": 1.0}},
                {"type": "sphere", "center": [1.5, 0, 0], "material": {"specular": 0.0, "roughness": 0.0}}],
}


@pytest.mark.parametrize("name", ["mixed", "spheres", "extremes"])
def test_khronos_gltf_validator_no_errors_or_warnings(exported, tmp_path, name):
    node = _validator()
    if name == "mixed":
        folder = exported[1].out_dir
    else:
        scene = scene_from_dict(EXTREMES) if name == "extremes" else load_scene(name)
        folder = export_scene(scene, tmp_path).out_dir
    r = subprocess.run([node, str(THREEJS / "validate.mjs"), str(folder / "scene.gltf")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    issues = json.loads(r.stdout)["issues"]
    assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, issues["messages"]
