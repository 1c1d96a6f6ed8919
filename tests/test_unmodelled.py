"""The honesty contract for what pbrcheck does not model (pbrcheck/unmodelled.py, compare/unmodelled.py):
the record on the asset and the scene, the stderr notice once per asset, the report's banner and
marks, the gate's ``not judged`` and its allow-by-name, export's stripping and ``--keep-unmodelled``.
Small assets built here: two quads, one of them coated (``KHR_materials_clearcoat``)."""

from __future__ import annotations

import json

import numpy as np
import pytest

# The contract's mechanism, tested on the glTF lobes as unmodelled extensions (tests/conftest.py).
pytestmark = pytest.mark.usefixtures("lobes_unmodelled")

from pbrcheck_cli import main
from pbrcheck.exr import Image, write_exr
from pbrcheck.gltf import load_asset
from pbrcheck.scene import load_scene
from pbrcheck.unmodelled import Unmodelled, strip_unmodelled
from tests.gltf_build import QUAD_IDX, QUAD_NRM, QUAD_POS, QUAD_UV, Doc, quad_scene

COAT = "KHR_materials_clearcoat"
SHEEN = "KHR_materials_sheen"


def coated_asset(path, *, used=(COAT,), coat=True, root_ext=None):
    """Two quads side by side: node0 ``plain`` (material 0), node1 ``coated`` (material 1, with
    ``KHR_materials_clearcoat`` when ``coat``); ``extensionsUsed`` = ``used``."""
    doc = Doc()
    mats = [{"name": "plain"}, {"name": "coated", "extensions": {
        COAT: {"clearcoatFactor": 1.0, "clearcoatRoughnessFactor": 0.1}} if coat else {}}]
    doc.d["materials"] = mats
    for k in range(2):
        attrs = {"POSITION": doc.accessor(QUAD_POS * 0.5 + np.float32([k - 0.5, 0, 0]), "VEC3", minmax=True),
                 "NORMAL": doc.accessor(QUAD_NRM, "VEC3"), "TEXCOORD_0": doc.accessor(QUAD_UV, "VEC2")}
        doc.node(doc.mesh(attrs, doc.accessor(QUAD_IDX, "SCALAR"), k))
    if used:
        doc.d["extensionsUsed"] = list(used)
    if root_ext:
        doc.d["extensions"] = root_ext
    return doc.write(path)


def test_asset_and_scene_record_the_feature_its_materials_and_objects(tmp_path):
    a = load_asset(coated_asset(tmp_path / "c.gltf"))
    assert a.unmodelled == (Unmodelled(COAT, ("coated",), (1,)),)
    # the scene: a sphere first, so the asset's objects are ids 1 and 2 (primitive 1 -> object 2)
    sc = quad_scene(tmp_path, tmp_path / "c.gltf")
    sc.write_text('[[objects]]\ntype = "sphere"\ncenter = [0.0, 0.0, -3.0]\nradius = 0.5\n' + sc.read_text())
    s = load_scene(sc)
    assert [o.type for o in s.objects] == ["sphere", "mesh", "mesh"]
    assert s.unmodelled == (Unmodelled(COAT, ("coated",), (2,), str((tmp_path / "c.gltf").resolve())),)


def test_undeclared_root_level_and_modelled_extensions(tmp_path):
    # declared but modelled: nothing; undeclared on a material: named; a root-level one: the whole asset
    assert load_asset(coated_asset(tmp_path / "m.gltf", used=("KHR_materials_ior",), coat=False)).unmodelled == ()
    a = load_asset(coated_asset(tmp_path / "u.gltf", used=()))
    assert a.unmodelled == (Unmodelled(COAT, ("coated",), (1,)),)
    a = load_asset(coated_asset(tmp_path / "r.gltf", used=("EXT_unknown_thing",), coat=False,
                                root_ext={"EXT_unknown_thing": {}}))
    assert a.unmodelled == (Unmodelled("EXT_unknown_thing", ("plain", "coated"), (0, 1)),)


def test_core_features_skins_and_morph_targets(tmp_path, monkeypatch):
    import pbrcheck.gltf as gltf

    path = coated_asset(tmp_path / "s.gltf", used=(), coat=False)
    doc = json.loads(path.read_text())
    doc["meshes"][0]["primitives"][0]["targets"] = [{"POSITION": doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]}]
    doc["nodes"][1]["skin"] = 0
    doc["skins"] = [{"joints": [0]}]
    path.write_text(json.dumps(doc))
    # the loader models both (its MODELLED_CORE_FEATURES): not named
    assert gltf.MODELLED_CORE_FEATURES == ("skins", "morph targets")
    assert load_asset(path).unmodelled == ()
    # a core feature the loader did not model would be named, with its materials and objects
    monkeypatch.setattr(gltf, "MODELLED_CORE_FEATURES", ())
    gltf._CACHE.clear()
    a = load_asset(path)
    assert a.unmodelled == (Unmodelled("skins", ("coated",), (1,)), Unmodelled("morph targets", ("plain",), (0,)))
    gltf._CACHE.clear()


def test_stderr_names_each_feature_once_per_asset(tmp_path, capsys):
    asset = coated_asset(tmp_path / "c.gltf")
    sc = quad_scene(tmp_path, asset)
    sc.write_text(sc.read_text() + '\n[[objects]]\ntype = "gltf"\npath = "c.gltf"\ntranslation = [0.0, 2.0, 0.0]\n')
    assert main(["check-scene", str(sc)]) == 0
    err = capsys.readouterr().err
    assert err.count(COAT) == 1, err      # two instances of one asset: one line
    assert "c.gltf: not modelled: KHR_materials_clearcoat (materials: coated)" in err
    # a second command in the same process names it again (once per command), a library call never
    assert main(["check-scene", str(sc)]) == 0
    assert capsys.readouterr().err.count(COAT) == 1
    load_scene(sc)
    assert capsys.readouterr().err == ""


def test_export_strips_unmodelled_material_extensions_unless_kept(tmp_path, capsys):
    sc = quad_scene(tmp_path, coated_asset(tmp_path / "c.gltf", used=(COAT, "KHR_materials_ior")), size=(8, 8))
    assert main(["export", str(sc), "--out", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    assert err.count("c.gltf: not modelled: KHR_materials_clearcoat") == 1
    assert "export: KHR_materials_clearcoat removed (--keep-unmodelled keeps it): materials coated" in err
    doc = json.loads((tmp_path / "out" / "scene.gltf").read_text())
    assert "extensions" not in doc["materials"][1] and doc["extensionsUsed"] == ["KHR_materials_ior"]
    assert main(["export", str(sc), "--out", str(tmp_path / "kept"), "--keep-unmodelled"]) == 0
    assert "export: KHR_materials_clearcoat kept (--keep-unmodelled): materials coated" in capsys.readouterr().err
    doc = json.loads((tmp_path / "kept" / "scene.gltf").read_text())
    assert doc["materials"][1]["extensions"][COAT]["clearcoatFactor"] == 1.0 and COAT in doc["extensionsUsed"]


def test_strip_keeps_modelled_and_still_used_extensions():
    doc = {"extensionsUsed": [COAT, SHEEN, "KHR_materials_ior"], "extensionsRequired": [SHEEN],
           "materials": [{"name": "a", "extensions": {COAT: {}, "KHR_materials_ior": {"ior": 1.4}}},
                         {"extensions": {SHEEN: {}}}],
           "nodes": [{"extensions": {SHEEN: {}}}]}   # sheen stays in use on a node: declared still
    assert strip_unmodelled(doc, ("KHR_materials_ior",)) == [(COAT, ("a",)), (SHEEN, ("material1",))]
    assert doc["materials"] == [{"name": "a", "extensions": {"KHR_materials_ior": {"ior": 1.4}}}, {}]
    assert doc["extensionsUsed"] == [SHEEN, "KHR_materials_ior"] and doc["extensionsRequired"] == [SHEEN]


def test_report_banner_and_marked_material_rows(tmp_path):
    from compare.report.build import render_page
    from compare.report.results import SceneSection
    from compare.report.scene import material_rows, unmodelled_banner

    s = load_scene(quad_scene(tmp_path, coated_asset(tmp_path / "c.gltf")))
    summary = {"materials": [{"material": "c.gltf: plain", "objects": [0], "pixels": 10, "metrics": {"relmse": 0.1}},
                             {"material": "c.gltf: coated", "objects": [1], "pixels": 12, "metrics": {"relmse": 0.2}}]}
    rows = material_rows("ext:threejs", summary, s.unmodelled)
    assert "unmodelled" not in rows[0] and rows[1]["unmodelled"] == [COAT]
    banner = unmodelled_banner(s)
    assert banner == [{"asset": "c.gltf", "feature": COAT, "materials": "coated"}]
    html = render_page([SceneSection("s0", "q", "", 4, "s0/reference.png", [], [], [], None, [], None, rows,
                                     unmodelled=banner)], [], [])
    head = html.split("Scene q</h2>")[1].split("<h3>")[0]
    assert 'class="banner"' in head and "c.gltf: <code>KHR_materials_clearcoat</code> (materials: coated)" in head
    table = html.split("<h3>Metrics per glTF material</h3>")[1].split("</table>")[0]
    plain, coated = table.split("c.gltf: plain")[1], table.split("c.gltf: coated")[1]
    assert plain.split("</td>")[0] == "" and coated.split("</td>")[0].endswith("not modelled: KHR_materials_clearcoat</strong>")
    # a scene without unmodelled features: no banner
    html = render_page([SceneSection("s0", "q", "", 4, "s0/reference.png", [], [], [], None, [], None, [])], [], [])
    assert 'class="banner"' not in html


@pytest.fixture
def gate_files(tmp_path):
    """A scene of the coated asset, a stored reference and a test image (equal: a pass when judged)."""
    sc = quad_scene(tmp_path, coated_asset(tmp_path / "c.gltf"), size=(8, 8))
    img = Image.from_rgb(np.full((8, 8, 3), 0.5, np.float32))
    write_exr(tmp_path / "ref.exr", img)
    write_exr(tmp_path / "test.exr", img)

    def budget(extra=""):
        (tmp_path / "b.toml").write_text(f'[[check]]\nname = "coat"\nscene = "{sc.name}"\nreference = "ref.exr"\n'
                                         f'test = "test.exr"\n{extra}[check.max]\nrelmse = 0.01\n')
        return str(tmp_path / "b.toml")
    return budget


def test_gate_does_not_judge_an_unmodelled_feature(gate_files, capsys, tmp_path):
    assert main(["gate", gate_files(), "--quiet", "--junit", str(tmp_path / "j.xml"), "--summary",
                 str(tmp_path / "s.md"), "--html", str(tmp_path / "h")]) == 2
    out = capsys.readouterr().out
    assert "NOT JUDGED coat: the scene uses what pbrcheck does not model: KHR_materials_clearcoat (materials: coated)" in out
    assert 'allow_unmodelled = ["KHR_materials_clearcoat"]' in out and "gate: 0 pass, 1 not judged" in out
    assert 'errors="1"' in (tmp_path / "j.xml").read_text()
    summary = (tmp_path / "s.md").read_text()
    assert "| coat | NOT JUDGED |  |  | " in summary and "allow\\_unmodelled = \\[\"KHR\\_materials\\_clearcoat\"\\]" in summary
    assert "coat: not judged</h2>" in (tmp_path / "h" / "index.html").read_text()
    # --accept accepts nothing
    assert main(["gate", gate_files(), "--quiet", "--accept", "--reason", "x"]) == 2
    assert "nothing accepted" in capsys.readouterr().out and not (tmp_path / "baselines").exists()


def test_gate_judges_a_feature_allowed_by_name(gate_files, capsys):
    assert main(["gate", gate_files(f'allow_unmodelled = ["{COAT}"]\n'), "--quiet"]) == 0
    assert "gate: 1 pass" in capsys.readouterr().out
    # another feature allowed is not this one
    assert main(["gate", gate_files(f'allow_unmodelled = ["{SHEEN}"]\n'), "--quiet"]) == 2


def test_gate_refuses_a_malformed_allow_list(gate_files, capsys):
    assert main(["gate", gate_files('allow_unmodelled = "KHR_materials_clearcoat"\n'), "--quiet"]) == 2
    assert "check[0].allow_unmodelled: expected a list of feature names" in capsys.readouterr().err


def test_unjudged_reason_of_a_table_and_of_no_scene(tmp_path):
    from compare.unmodelled import unjudged_reason

    s = load_scene(quad_scene(tmp_path, coated_asset(tmp_path / "c.gltf")))
    assert "KHR_materials_clearcoat (materials: coated)" in unjudged_reason(s, {})
    assert unjudged_reason(s, {"allow_unmodelled": [COAT]}) is None
    assert unjudged_reason(None, {}) is None
    plain = load_scene(quad_scene(tmp_path, coated_asset(tmp_path / "p.gltf", used=(), coat=False), name="p.toml"))
    assert unjudged_reason(plain, {}) is None


def test_compare_with_scene_names_it(tmp_path, capsys):
    sc = quad_scene(tmp_path, coated_asset(tmp_path / "c.gltf"), size=(8, 8))
    img = Image.from_rgb(np.full((8, 8, 3), 0.5, np.float32))
    img.channels["object"] = np.zeros((8, 8), np.float32)
    write_exr(tmp_path / "a.exr", img)
    assert main(["compare", str(tmp_path / "a.exr"), str(tmp_path / "a.exr"), "--scene", str(sc)]) == 0
    assert capsys.readouterr().err.count("c.gltf: not modelled: KHR_materials_clearcoat (materials: coated)") == 1


def test_external_cache_key_changes_only_for_scenes_with_unmodelled_features(tmp_path):
    from pbrcheck.cache import cache_key
    from pbrcheck.environment import scene_hash
    from pbrcheck.export import EXPORT_FORMAT_VERSION
    from clients.config import load_renderers
    from clients.run import cache_key_for, renderer_version

    cfg = load_renderers()["threejs"]
    plain = load_scene(quad_scene(tmp_path, coated_asset(tmp_path / "p.gltf", used=(), coat=False), name="p.toml"))
    coated = load_scene(quad_scene(tmp_path, coated_asset(tmp_path / "c.gltf")))
    # a scene without unmodelled features keeps the key it had (its cached renders stay valid)
    assert cache_key_for(plain, cfg, "e") == cache_key(kind="external", scene=scene_hash(plain, "e"),
                                                       renderer=cfg.cache_dict(), export_format=EXPORT_FORMAT_VERSION,
                                                       version=renderer_version(cfg))
    assert cache_key_for(coated, cfg, "e") != cache_key(kind="external", scene=scene_hash(coated, "e"),
                                                        renderer=cfg.cache_dict(), export_format=EXPORT_FORMAT_VERSION,
                                                        version=renderer_version(cfg))


@pytest.mark.slow
def test_reference_names_it_once(tmp_path, capsys, tmp_cache):
    sc = quad_scene(tmp_path, coated_asset(tmp_path / "c.gltf"), size=(8, 8))
    assert main(["reference", str(sc), "--spp", "4", "--out", str(tmp_path / "r.exr")]) == 0
    assert capsys.readouterr().err.count("c.gltf: not modelled: KHR_materials_clearcoat") == 1
