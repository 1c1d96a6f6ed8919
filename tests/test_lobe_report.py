"""The glTF PBR extensions' lobes on the comparison side (issue 36 item 4 and the findings).

- :mod:`compare.lobes`: the objects of each lobe (the built-in lobe scenes, a glTF asset), the
  lobe families read from the real-time registry (an option found generically), the forms a
  renderer can switch to, the pooled metrics;
- the export: each built-in lobe scene's glTF carries its extension with the scene's values (round
  trip through pbrcheck's own glTF loader), and is stripped and named while unmodelled;
- the report's lobe sections, ``sweep --lobes`` and ``explain``'s lobe rows (fake renderers,
  ``tests/test_compare_report.py``'s);
- ``diagnose``: one ``lobe:`` hypothesis per departure of :mod:`compare.lobe_findings`, offered only
  for scenes with its lobe, skipped while the real-time renderer lacks the option, named when planted;
- docs/renderers.md's lobes table has a row per departure.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import compare.lobes as cl
import compare.report.lobes_section as ls
import compare.report.sweep as sw
import compare.research.diagnose as dg
from compare.lobe_findings import DEPARTURES, ENGINE_OF_RENDERER
from pbrcheck import lobe_params as lp
from pbrcheck.exr import Image
from pbrcheck.export import export_scene
from pbrcheck.gltf import load_asset
from pbrcheck.scene import load_scene, scene_from_dict
from tests.test_compare_report import SCENE, fake_reference, fakes, raycast  # noqa: F401  (fixture)

ROOT = Path(__file__).resolve().parents[1]
LOBE_SCENES = ["clearcoat", "sheen", "specular", "anisotropy", "iridescence"]

#: test_compare_report's tiny scene, its grid clear-coated, and one plain sphere below it.
TINY_LOBES = (SCENE.replace('name = "tiny"', 'name = "tinylobes"')
              + 'clearcoat = 1.0\nclearcoat_roughness = 0.25\n[[objects]]\ntype = "sphere"\ncenter = [0.0, -1.8, 0.0]\n'
              'radius = 0.3\n[objects.material]\nbase_color = [0.2, 0.5, 0.3]\n')


@pytest.fixture
def lobe_scene_file(tmp_path):
    p = tmp_path / "tinylobes.toml"
    p.write_text(TINY_LOBES)
    return p


def _families(monkeypatch, fams):
    """Every module that reads the lobe families sees ``fams`` (the real-time renderer taking them)."""
    for mod in (cl, ls, sw):
        monkeypatch.setattr(mod, "lobe_families", lambda: list(fams))


# ---- compare.lobes ---------------------------------------------------------------------------------

@pytest.mark.parametrize("name", LOBE_SCENES)
def test_the_builtin_lobe_scenes_carry_their_lobe_on_all_but_the_neutral_corner(name):
    s = load_scene(name)
    lobes = cl.object_lobes(s)
    ext = f"KHR_materials_{name}"
    assert list(lobes) == [ext] and cl.scene_lobes(s) == (ext,)
    # the grid's neutral corner (factor 0) carries none, except iridescence's whose every sphere has a film
    assert len(lobes[ext]) == (25 if name == "iridescence" else 24)
    assert cl.object_lobes(load_scene("spheres")) == {}


def test_a_gltf_mesh_object_carries_its_materials_active_lobes(tmp_path):
    from tests.gltf_build import quad_asset, quad_scene

    asset = quad_asset(tmp_path / "q.gltf", {"pbrMetallicRoughness": {}, "extensions": {
        lp.SHEEN: {"sheenColorFactor": [0.5, 0.5, 0.5]}, lp.CLEARCOAT: {"clearcoatFactor": 0.0}}})
    s = load_scene(str(quad_scene(tmp_path, asset)))
    meshes = tuple(o.id for o in s.objects if o.type == "mesh")
    assert meshes and cl.object_lobes(s) == {lp.SHEEN: meshes}   # the neutral clearcoat changes nothing


def test_lobe_families_are_the_registrys_with_the_option_found_generically(monkeypatch):
    from realtime import presets
    from realtime.registry import COAT_IBLS, LOBE_REGISTRIES

    fams = {f.switch: f for f in cl.lobe_families()}
    assert set(fams) == set(LOBE_REGISTRIES)   # every lobe family today names a lobe
    assert fams["COAT_IBL"].extension == lp.CLEARCOAT and fams["SHEEN_DFG"].extension == lp.SHEEN
    assert fams["ANISOTROPY_BEND"].members == ("sample_viewer", "threejs", "filament", "babylon", "fitted")
    # an option whose registry is the family's, whatever its name, is the family's option
    monkeypatch.setattr(presets, "OPTION_REGISTRIES", {"coat_ibl_form": COAT_IBLS})
    assert {f.switch: f.option for f in cl.lobe_families()}["COAT_IBL"] == "coat_ibl_form"


class _Spec:
    """A real-time spec that takes ``coat_ibl`` with the members of ``accepts``."""

    def __init__(self, accepts=(), external=False, current=None):
        self.accepts, self.external, self.text = accepts, external, "default"
        self.options = type("O", (), {"coat_ibl": current})() if current else object()

    def with_options(self, **kw):
        from pbrcheck.errors import PbrcheckError

        if any(k != "coat_ibl" or v not in self.accepts for k, v in kw.items()):
            raise PbrcheckError(f"refused {kw}")
        return self


COAT = cl.LobeFamily("COAT_IBL", lp.CLEARCOAT, ("filament", "sample_viewer", "threejs"), "sample_viewer", "coat_ibl")
SHEEN = cl.LobeFamily("SHEEN_DFG", lp.SHEEN, ("lut_charlie", "threejs"), "lut_charlie", None)


def test_lobe_variants_are_the_other_accepted_members_of_the_scenes_lobes():
    s = load_scene("clearcoat")
    spec = _Spec(accepts=("filament", "threejs"), current="threejs")
    assert cl.lobe_variants(spec, s, [COAT, SHEEN]) == [{"coat_ibl": "filament"}]   # not its own, not refused
    assert cl.lobe_variants(_Spec(accepts=COAT.members), s, [COAT]) == [{"coat_ibl": "filament"}, {"coat_ibl": "threejs"}]
    assert cl.lobe_variants(_Spec(accepts=COAT.members), load_scene("sheen"), [COAT, SHEEN]) == []   # no clearcoat there
    assert cl.lobe_variants(_Spec(accepts=COAT.members, external=True), s, [COAT]) == []


def test_pooled_metrics_weight_the_objects_by_their_pixels():
    objs = [{"id": 0, "name": "a", "pixels": 10, "metrics": {"relmse": 0.1, "flip_mean": 0.2, "mean_abs": 1.0, "rmse": 1.0}},
            {"id": 1, "name": "b", "pixels": 30, "metrics": {"relmse": 0.5, "flip_mean": 0.4, "mean_abs": 2.0, "rmse": 3.0}},
            {"id": 2, "name": "c", "pixels": 50, "metrics": {"relmse": 9.0, "flip_mean": 9.0, "mean_abs": 9.0, "rmse": 9.0}}]
    p = cl.pooled_metrics(objs, (0, 1))
    assert p["pixels"] == 40 and p["objects"] == 2
    assert p["relmse"] == pytest.approx((10 * 0.1 + 30 * 0.5) / 40) and p["flip_mean"] == pytest.approx(0.35)
    assert p["rmse"] == pytest.approx(np.sqrt((10 * 1.0 + 30 * 9.0) / 40))
    assert p["worst"] == {"id": 1, "name": "b", "relmse": 0.5}
    assert cl.pooled_metrics(objs, (7,)) == {"pixels": 0, "objects": 0, "relmse": None, "flip_mean": None,
                                             "mean_abs": None, "rmse": None, "worst": None}


def test_parameter_groups_are_the_grids_rows_and_columns():
    g = cl.parameter_groups(load_scene("clearcoat"), lp.CLEARCOAT)
    assert list(g) == [f"clearcoat={v}" for v in (0.0, 0.25, 0.5, 0.75, 1.0)] + \
        [f"clearcoat_roughness={v}" for v in (0.0, 0.25, 0.5, 0.75, 1.0)]
    # the neutral corner (both 0) carries no clearcoat: 4 in its row and column, 5 elsewhere
    assert [len(v) for v in g.values()] == [4, 5, 5, 5, 5] * 2
    assert set(g["clearcoat=1.0"]) == {20, 21, 22, 23, 24}   # the top row (objects row-major from the bottom)
    assert cl.parameter_groups(load_scene("clearcoat"), lp.SHEEN) == {}


def test_lobe_sections_add_a_by_parameter_table_where_a_scene_varies_them():
    row = {"renderer": "default", "forms": "-", "objects": 2, "pixels": 40, "relmse": 0.1, "flip_mean": 0.2,
           "mean_abs": 0.3, "rmse": 0.4, "worst": {"id": 1, "name": "b", "relmse": 0.2},
           "by_parameter": {"clearcoat=0.5": 0.05, "clearcoat=1.0": 0.2}}
    (sec,) = ls.lobe_sections([("grid", {lp.CLEARCOAT: [row]}), ("none", {})])
    assert sec.id == "lobe-clearcoat" and len(sec.tables) == 2
    assert sec.tables[0].rows == [["grid", "default", "-", "2", "40", "0.1", "0.2", "0.3", "0.4", "b (0.2)"]]
    assert sec.tables[1].headers == ["scene", "renderer", "clearcoat=0.5", "clearcoat=1.0"]
    assert sec.tables[1].rows == [["grid", "default", "0.05", "0.2"]]
    assert ls.lobe_sections([("none", {})]) == []


# ---- the export --------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", LOBE_SCENES)
def test_the_exported_gltf_of_each_lobe_scene_carries_its_values(name, tmp_path):
    s = load_scene(name)
    ext = f"KHR_materials_{name}"
    export_scene(s, tmp_path / "kept", keep_unmodelled=True)
    doc = json.loads((tmp_path / "kept" / "scene.gltf").read_text())
    assert ext in doc["extensionsUsed"]
    mats = {m.name: m for m in load_asset(tmp_path / "kept" / "scene.gltf").materials}
    changed = 0
    for o in s.objects:
        back = lp.scene_fields_of({f: getattr(mats[f"material_{o.id}"], f) for f, _ in lp.LOBE_EXTENSIONS.values()})
        assert back == {k: getattr(o.material, k) for k in lp.SCENE_DEFAULTS}, o.name
        changed += back != lp.SCENE_DEFAULTS
    assert changed == len(cl.object_lobes(s)[ext])
    # what the engines get by default (clients/run.py's export): the extension while both renderers
    # model it, else removed and named (pbrcheck.unmodelled)
    ex = export_scene(s, tmp_path / "default")
    used = json.loads((tmp_path / "default" / "scene.gltf").read_text()).get("extensionsUsed", [])
    if ext in lp.MODELLED_LOBE_EXTENSIONS:
        assert ext in used and not ex.unmodelled
    else:
        assert ext not in used and [f for f, _ in ex.unmodelled] == [ext]


# ---- the report, sweep and explain (fake renderers) ---------------------------------------------------

def test_the_report_has_a_section_per_lobe_with_the_pooled_errors(fakes, lobe_scene_file, tmp_path, tmp_cache,  # noqa: F811
                                                                  monkeypatch):
    from compare.report import build

    fam = cl.LobeFamily("COAT_IBL", lp.CLEARCOAT, (32, 16), 32, "lut_size")   # the fake takes lut_size
    _families(monkeypatch, [fam])
    cfg = build.ReportConfig(presets=["default", "cheap"], spp=4, convergence=False, sweep=False, furnace=False,
                             progress=False)
    index = build.build_report([str(lobe_scene_file)], tmp_path / "r", cfg)
    run = json.loads((tmp_path / "r" / "run.json").read_text())
    assert [s["name"] for s in run["stages"]] == ["tinylobes: renderers under test", "tinylobes: reference",
                                                  "tinylobes: comparisons and diagnose", "tinylobes: lobes",
                                                  "summary and furnace", "both references"]
    data = json.loads((tmp_path / "r" / "tinylobes" / "metrics.json").read_text())
    rows = data["lobes"][lp.CLEARCOAT]
    assert [r["renderer"] for r in rows] == ["default", "cheap", "default + lut_size=16"]
    assert [r["forms"] for r in rows] == ["lut_size=32", "lut_size=32", "lut_size=16"]
    assert {lp.CLEARCOAT: [{"lut_size": 16}]} == {lp.CLEARCOAT: [o for p, o in fakes["realtime"] if o]}
    # pooled over the six clearcoat spheres only (the plain sphere, object 6, left out)
    objs = [o for o in data["presets"]["cheap"]["objects"] if o["id"] < 6]
    want = sum(o["pixels"] * o["metrics"]["relmse"] for o in objs) / sum(o["pixels"] for o in objs)
    assert rows[1]["relmse"] == pytest.approx(want) and rows[1]["objects"] == 6
    assert rows[1]["relmse"] > rows[0]["relmse"]   # cheap's bias is the larger
    html = index.read_text()
    assert html.index('id="summary"') < html.index('id="lobe-clearcoat"') < html.index('id="tinylobes"')
    assert "Lobe: clearcoat (KHR_materials_clearcoat)" in html and 'id="lobe-sheen"' not in html
    assert "does not model KHR_materials_clearcoat yet" in html or lp.CLEARCOAT in lp.MODELLED_LOBE_EXTENSIONS


def test_a_report_without_lobes_has_no_lobe_stage_nor_key(fakes, tmp_path, tmp_cache):  # noqa: F811
    from compare.report import build

    p = tmp_path / "plain.toml"
    p.write_text(TINY_LOBES.replace('name = "tinylobes"', 'name = "plain"').replace("clearcoat = 1.0\n", "")
                 .replace("clearcoat_roughness = 0.25\n", ""))
    cfg = build.ReportConfig(presets=["default"], spp=4, convergence=False, sweep=False, furnace=False, progress=False)
    index = build.build_report([str(p)], tmp_path / "r", cfg)
    assert "lobes" not in json.loads((tmp_path / "r" / "plain" / "metrics.json").read_text())
    assert "plain: lobes" not in (tmp_path / "r" / "run.json").read_text() and 'id="lobe-' not in index.read_text()


def test_forms_of_an_engine_are_its_departures_and_of_a_preset_its_options(monkeypatch):
    _families(monkeypatch, [COAT])
    assert ls.forms_of("ext:sample-viewer", lp.CLEARCOAT, None) == "coat_ibl_no_albedo"
    assert ls.forms_of("ext:threejs", lp.CLEARCOAT, None) == "coat_fresnel_voh, coat_ibl_split_sum_fresnel"
    assert ls.forms_of("ext:threejs", lp.SPECULAR, None) == "no departure found"
    assert ls.forms_of("default", lp.CLEARCOAT, {"coat_ibl": "threejs"}) == "coat_ibl=threejs"
    assert ls.forms_of("default", lp.SHEEN, {}) == "not an option yet"


def test_sweep_lobes_renders_each_form_and_refuses_without_any(fakes, lobe_scene_file, tmp_path, monkeypatch):  # noqa: F811
    from pbrcheck_cli import main

    _families(monkeypatch, [])
    assert main(["sweep", str(lobe_scene_file), "--lobes", "--out", str(tmp_path / "no"), "--spp", "4", "--quiet"]) == 2
    _families(monkeypatch, [cl.LobeFamily("COAT_IBL", lp.CLEARCOAT, (32, 16, 8), 32, "lut_size")])
    assert main(["sweep", str(lobe_scene_file), "--lobes", "--out", str(tmp_path / "sw"), "--spp", "4", "--quiet"]) == 0
    rows = json.loads((tmp_path / "sw" / "sweep.json").read_text())
    assert [r["options"] for r in rows] == [{}, {"lut_size": 16}, {"lut_size": 8}]
    assert "lut_size" in (tmp_path / "sw" / "sweep.csv").read_text().splitlines()[0]
    with pytest.raises(sw.SweepError, match="has no object with a glTF PBR extension lobe"):
        sw.lobe_combos(sw.renderers.RendererSpec.parse("default"), load_scene("spheres"))


def test_explain_adds_a_row_per_lobe_form_outside_the_combined_rows(monkeypatch):
    from compare.research import explain as ex

    monkeypatch.setattr(ex, "lobe_variants", lambda spec, scene: [{"coat_ibl": "filament"}, {"coat_ibl": "threejs"}])
    assert ex.lobe_sources(object(), None) == {"lobe:coat_ibl=filament": {"coat_ibl": "filament"},
                                               "lobe:coat_ibl=threejs": {"coat_ibl": "threejs"}}
    from compare.research.results import ExplainCombined, ExplainResult, ExplainRow

    res = ExplainResult("s", "default", {}, 4, [8, 8], "relmse", {"relmse": 0.2, "flip_mean": 0.1}, None,
                        [ExplainRow("lut", {}, {"relmse": 0.19, "flip_mean": 0.1}, 0.01),
                         ExplainRow("lobe:coat_ibl=threejs", {"coat_ibl": "threejs"}, {"relmse": 0.1, "flip_mean": 0.1},
                                    0.1)],
                        all_exact=ExplainCombined({}, {"relmse": 0.19, "flip_mean": 0.1}, 0.01))
    md = ex.table_markdown(res)
    assert "| lobe:coat_ibl=threejs | 0.1 |" in md and "left out of the combined rows" in md


# ---- diagnose ---------------------------------------------------------------------------------------

LOBE_HYPS = [h for h in dg.HYPOTHESES if h.kind == "lobe"]


def test_each_departure_with_a_real_time_twin_is_one_lobe_hypothesis():
    want = [f"lobe:{d.name}" for d in DEPARTURES if d.switch is not None]
    assert [h.name for h in LOBE_HYPS] == want and len(want) >= 10
    assert all(dg.hypothesis(n).kind == "lobe" for n in want)
    assert {h.lobe for h in LOBE_HYPS} == {lp.CLEARCOAT, lp.SHEEN, lp.ANISOTROPY, lp.IRIDESCENCE}
    assert all(h.model for h in LOBE_HYPS)


def test_lobe_hypotheses_are_offered_only_for_scenes_with_their_lobe():
    sheen, clear, plain = load_scene("sheen"), load_scene("clearcoat"), load_scene("spheres")
    assert {h.lobe for h in LOBE_HYPS if dg.offered(h, sheen)} == {lp.SHEEN}
    assert {h.lobe for h in LOBE_HYPS if dg.offered(h, clear)} == {lp.CLEARCOAT}
    assert not any(dg.offered(h, plain) for h in LOBE_HYPS) and not any(dg.offered(h, None) for h in LOBE_HYPS)


def _tiny_sheen_scene():
    return scene_from_dict({"name": "tinysheen", "camera": {"origin": [0, 0, 8], "fov": 30, "width": 24, "height": 24},
                            "environment": {"type": "constant", "radiance": [1, 1, 1]},
                            "objects": [{"type": "sphere_grid", "rows": 2, "columns": 3, "radius": 0.6, "spacing": 1.4,
                                         "material": {"base_color": [0.8, 0.5, 0.3], "sheen_color": [1, 1, 1],
                                                      "sheen_roughness": 0.5}}]})


#: The fake twin's additive sheen per member: a rim (NdotV small) whose strength is the form's.
RIM = {"lut": 0.0, "filament": 0.1, "threejs": 0.3}


def _fake_twin(scene, spec, *, progress=True, context=None, use_cache=True):
    rgb, aovs = raycast(scene)
    member = dict(spec.overrides).get("sheen_scaling", "lut")
    rim = np.where(aovs["object"] >= 0, (1 - aovs["NdotV"]) ** 2, 0.0)
    return Image.from_rgb((rgb + RIM[member] * rim[..., None]).astype(np.float32), {}, **aovs)


def test_a_planted_sheen_form_is_named_and_skipped_without_the_option(fakes, monkeypatch):  # noqa: F811
    import compare.renderers as renderers

    s = _tiny_sheen_scene()
    ref = fake_reference(s, spp=64)
    test = Image.from_rgb(_fake_twin(s, type("S", (), {"overrides": (("sheen_scaling", "threejs"),)})()).rgb, {})
    # the real-time renderer without the option: every sheen hypothesis listed, skipped, saying why
    _families(monkeypatch, [cl.LobeFamily("SHEEN_SCALING", lp.SHEEN, ("lut", "filament", "threejs"), "lut", None)])
    d = dg.diagnose(ref, test, s, spp=16)
    rows = {r.hypothesis: r for r in d.rows if r.kind == "lobe"}
    assert set(rows) == {h.name for h in LOBE_HYPS if h.lobe == lp.SHEEN}
    assert "no option for SHEEN_SCALING yet" in rows["lobe:sheen_scaling_constant"].skipped
    assert d.likely != "lobe:sheen_scaling_constant"
    # with the option: the constant scaling's twin (reference + RT(threejs) - RT(lut)) explains it
    _families(monkeypatch, [cl.LobeFamily("SHEEN_SCALING", lp.SHEEN, ("lut", "filament", "threejs"), "lut",
                                          "sheen_scaling")])
    monkeypatch.setattr(renderers, "resolve_options", lambda preset, overrides=None: dict(overrides or {}))
    monkeypatch.setattr(renderers, "render_under_test", _fake_twin)
    d = dg.diagnose(ref, test, s, spp=16)
    assert d.likely == "lobe:sheen_scaling_constant", dg.table_markdown(d)
    assert "departure from the extension's specification" in d.line
    row = next(r for r in d.rows if r.hypothesis == "lobe:sheen_scaling_constant")
    assert row.fitted == {"option": "sheen_scaling=threejs", "against": "lut"} and row.reduction > 0.9
    scaling_neubelt = next(r for r in d.rows if r.hypothesis == "lobe:sheen_scaling_neubelt")
    assert scaling_neubelt.reduction < row.reduction   # the other form's rim is a third of the planted one
    # a form only punctual lights see is skipped on a scene lit by its environment alone
    coat = next(h for h in LOBE_HYPS if h.name == "lobe:coat_fresnel_voh")
    assert "punctual lights only" in coat.applies_to(ref, load_scene("clearcoat"))


# ---- docs ---------------------------------------------------------------------------------------------

def test_every_departure_is_a_row_of_the_docs_lobes_table():
    text = (ROOT / "docs" / "renderers.md").read_text()
    table = text[text.index("## 11. The lobes"):]
    for d in DEPARTURES:
        assert f"`{d.name}`" in table, d.name
    for engine in set(ENGINE_OF_RENDERER.values()):
        assert engine in table


# ---- the export's tangents (anisotropy) ---------------------------------------------------------------

def _accessor(doc: dict, data: bytes, i: int) -> np.ndarray:
    acc = doc["accessors"][i]
    view = doc["bufferViews"][acc["bufferView"]]
    width = {"VEC3": 3, "VEC4": 4}[acc["type"]]
    return np.frombuffer(data, np.float32, acc["count"] * width, view["byteOffset"]).reshape(-1, width)


def test_anisotropic_objects_carry_the_references_tangent_frame_and_only_they():
    from pbrcheck.export import gltf_document

    s = scene_from_dict({"environment": {"type": "constant"}, "objects": [
        {"type": "sphere", "center": [0, 0, 0], "radius": 1.0, "material": {"anisotropy_strength": 0.5}},
        {"type": "sphere", "center": [3, 0, 0], "radius": 1.0, "material": {}},
        {"type": "plane", "center": [0, -1, 0], "normal": [0, 1, 0], "size": [4, 4],
         "material": {"anisotropy_strength": 1.0}}]})
    doc, data, _, _ = gltf_document(s)
    prims = [m["primitives"][0]["attributes"] for m in doc["meshes"]]
    assert "TANGENT" in prims[0] and "TANGENT" not in prims[1] and "TANGENT" in prims[2]
    n = _accessor(doc, data, prims[0]["NORMAL"])
    t = _accessor(doc, data, prims[0]["TANGENT"])
    assert np.all(t[:, 3] == 1.0)                                   # bitangent = n x t
    side = np.hypot(n[:, 0], n[:, 1]) > 1e-3                       # off the z axis: Mitsuba's dp/du
    want = np.stack([-n[side, 1], n[side, 0], np.zeros(side.sum())], 1) / np.hypot(n[side, 0], n[side, 1])[:, None]
    assert np.allclose(t[side, :3], want, atol=1e-6)
    assert np.allclose((t[:, :3] * n).sum(1), 0.0, atol=1e-6)       # tangent to the sphere everywhere
    assert np.allclose(_accessor(doc, data, prims[2]["TANGENT"]), [[1, 0, 0, 1]] * 4)   # a floor's: +X
    # a scene without anisotropy exports no tangent at all (its files as before)
    plain, _, _, _ = gltf_document(load_scene("clearcoat"))
    assert not any("TANGENT" in m["primitives"][0]["attributes"] for m in plain["meshes"])


def test_a_scene_with_anisotropy_has_no_random_walk_reference():
    """The walk carries clearcoat, sheen and specular (tests/test_walk_lobes.py); anisotropy and
    iridescence still leave a scene without the random-walk reference and diagnose's hypothesis."""
    from compare.report.references import random_walk_scene

    walk, why = random_walk_scene(load_scene("anisotropy"))
    assert walk is None and why == ("the glTF lobes (anisotropy) have no random walk in the reference (the walk "
                                    "is isotropic with Schlick's Fresnel)")
    assert random_walk_scene(load_scene("sheen"))[0].brdf.multiscatter == "random_walk"
    assert random_walk_scene(load_scene("spheres"))[0].brdf.multiscatter == "random_walk"
    ms = dg.hypothesis("multiple_scattering")
    assert ms.applies_to(None, load_scene("iridescence")) == cl.no_random_walk(load_scene("iridescence"))
    assert ms.applies_to(None, load_scene("clearcoat")) is None
    assert ms.applies_to(None, load_scene("spheres")) is None
