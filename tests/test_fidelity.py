"""``pbrcheck fidelity`` (compare/fidelity.py, compare/fidelity_page.py) on small configs built here.

- RF's metric against a value computed by hand from pixelmatch's YIQ weights, and RF's 8-bit
  display transform (Khronos PBR Neutral, sRGB) on a value below the highlight compression;
- a run with stand-in engines (their renders replaced; the truth and the ``default`` preset real):
  RF and the truth disagreeing both ways is called out on the page and in the rows, a failing
  renderer gives an error row (never a gap), a second run with ``--resume`` computes nothing and a
  removed row is computed again; names are escaped in the page and the CSV;
- a scene using a feature pbrcheck does not model is marked and gets no verdict;
- the CLI's one line and files.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import compare.fidelity as F
from compare import renderers
from compare.fidelity_page import disagreements, write_outputs
from pbrcheck.errors import PbrcheckError
from pbrcheck.exr import Image
from tests.gltf_build import quad_asset

SIZE = 16
SPP = 4
GREY = {"name": "grey", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.0,
                                                 "roughnessFactor": 0.6}}


def test_rf_metric_matches_a_hand_computed_value():
    # Pixel 0: red against black; pixel 1: equal; pixel 2 differs but is not covered (left out).
    test = np.array([[[255, 0, 0], [10, 20, 30], [255, 255, 255]]], np.uint8)
    gold = np.array([[[0, 0, 0], [10, 20, 30], [0, 0, 0]]], np.uint8)
    covered = np.array([[True, True, False]])
    y, i, q = 255 * 0.29889531, 255 * 0.59597799, 255 * 0.21147017
    delta = 0.5053 * y * y + 0.299 * i * i + 0.1957 * q * q   # 10410.3..., pixelmatch's colorDelta
    assert F.rf_color_delta(test, gold)[0, 0] == pytest.approx(delta, rel=1e-12)
    expected = 10 * math.log10(math.sqrt((delta ** 2 + 0.0) / 2) / 35215)
    assert expected == pytest.approx(-6.798, abs=1e-3)
    assert F.rf_metric_db(test, gold, covered) == pytest.approx(expected, rel=1e-12)
    assert F.rf_pass(expected) is False and F.rf_pass(-22.0) is True and F.rf_pass(-21.99) is False
    assert F.rf_metric_db(test, gold, np.zeros_like(covered)) is None


def test_rf_display_is_pbr_neutral_then_srgb_8_bit():
    # grey 0.5: min >= 0.08, so the offset is F90 = 0.04: 0.46 < 0.76 (no compression); sRGB(0.46) = 1.055 * 0.46^(1/2.4) - 0.055 = 0.7084, x 255 = 180.6
    out = F.rf_display(np.array([[[0.5, 0.5, 0.5], [0.0, 0.0, 0.0]]]))
    assert out.dtype == np.uint8 and out[0, 0].tolist() == [181, 181, 181] and out[0, 1].tolist() == [0, 0, 0]
    hi = F.rf_display(np.array([[[100.0, 100.0, 100.0]]]))  # compressed towards (not past) white
    assert 250 <= hi[0, 0, 0] <= 255


def _config(tmp_path: Path, scenarios: list[dict], material: dict = GREY) -> Path:
    quad_asset(tmp_path / "assets" / "q.gltf", material)
    cfg = tmp_path / "config.json"
    cfg.write_text(json.dumps({"renderers": [], "scenarios": scenarios}))
    return cfg


def _scaled(img: Image, k: float) -> Image:
    rgb = img.rgb * np.float32(k)
    extra = {n: v for n, v in img.channels.items() if n not in ("R", "G", "B") and not n.endswith("variance")}
    return Image.from_rgb(rgb, dict(img.meta), **extra)


@pytest.fixture
def stand_ins(monkeypatch):
    """ext:threejs (the golden) renders 3x too bright; ext:filament renders what the golden renders
    (RF passes it, the truth fails it); ext:sample-viewer fails; presets render for real (``default``
    agrees with the truth, RF fails it against the wrong golden). Counts the renders."""
    calls = []
    real = F._render

    def fake(scene, spec):
        calls.append(spec.text)
        if spec.text == "ext:sample-viewer":
            raise PbrcheckError("ext:sample-viewer: exited with status 1; stderr: boom")
        if spec.text in ("ext:threejs", "ext:filament"):
            return _scaled(real(scene, renderers.RendererSpec.parse("default")), 3.0)
        return real(scene, spec)

    monkeypatch.setattr(F, "_render", fake)
    return calls


def _settings(*names):
    return F.FidelitySettings(tuple(renderers.RendererSpec.parse(n) for n in names), spp=SPP, size=SIZE)


def test_disagreements_error_row_resume_and_escaping(tmp_path, tmp_cache, stand_ins):
    cfg = _config(tmp_path, [{"name": "=quad<b>", "model": "assets/q.gltf", "lighting": "neutral",
                              "orbit": {"radius": 3}}])
    st = _settings("ext:threejs", "ext:filament", "ext:sample-viewer", "default")
    out = tmp_path / "out"
    res = F.run_fidelity(cfg, st, out, progress=False)
    write_outputs(res, cfg)
    rows = {r["renderer"]: r for r in res.rows}
    assert [r["renderer"] for r in res.rows] == ["ext:threejs", "ext:filament", "ext:sample-viewer", "default"]
    # the failing renderer: an error row naming the stage and the message
    sv = rows["ext:sample-viewer"]
    assert sv["status"] == "error" and sv["stage"] == "render" and "boom" in sv["error"]
    # the golden has no RF score against itself; the truth fails it (3x too bright)
    assert rows["ext:threejs"]["rf_db"] is None and rows["ext:threejs"]["truth_pass"] is False
    # filament = the golden: RF passes it (identical images), the truth fails it
    fi = rows["ext:filament"]
    assert fi["rf_db"] == pytest.approx(10 * math.log10(F.RF_MIN_RATIO)) and fi["rf_pass"] is True
    assert fi["truth_pass"] is False and fi["disagree"] is True and fi["flip_mean"] > F.TRUTH_FLIP_PASS
    # default agrees with the truth, RF fails it against the wrong golden
    de = rows["default"]
    assert de["truth_pass"] is True and de["rf_db"] > F.RF_THRESHOLD_DB and de["rf_pass"] is False
    assert de["disagree"] is True
    assert {(r["renderer"]) for r in disagreements(res.rows)} == {"ext:filament", "default"}
    html = (out / "index.html").read_text()
    assert "RF and the truth disagree (2)" in html and "=quad&lt;b&gt;" in html
    assert "=quad<b>" not in html
    csv = (out / "fidelity.csv").read_text()
    assert "'=quad<b>" in csv  # csv_cell: a leading '=' is not a formula
    doc = json.loads((out / "fidelity.json").read_text())
    assert len(doc["rows"]) == 4 and doc["summaries"]["engines"][-1]["renderer"].startswith("reference")
    # every engine's line has its time and memory; the truth's too
    eng = {e["renderer"]: e for e in doc["summaries"]["engines"]}
    assert eng["default"]["wall_s"] > 0 and eng["default"]["peak_mib"] > 0 and eng["ext:sample-viewer"]["errors"] == 1
    assert next(e for e in doc["summaries"]["engines"] if e["renderer"].startswith("reference"))["cpu_s"] >= 0
    # resume: nothing computed again, the same rows
    n = len(stand_ins)
    again = F.run_fidelity(cfg, st, out, progress=False, resume=True)
    assert again.computed == 0 and len(stand_ins) == n
    assert [r["key"] for r in again.rows] == [r["key"] for r in res.rows]
    # a removed row is computed again (and only it)
    (out / "rows" / f"{fi['key']}.json").unlink()
    third = F.run_fidelity(cfg, st, out, progress=False, resume=True)
    assert third.computed == 1 and {r["renderer"]: r for r in third.rows}["ext:filament"]["disagree"] is True


@pytest.mark.usefixtures("lobes_unmodelled")  # sheen as an unmodelled extension (tests/conftest.py)
def test_unmodelled_feature_is_marked_and_not_judged(tmp_path, tmp_cache):
    sheen = {**GREY, "extensions": {"KHR_materials_sheen": {"sheenColorFactor": [1.0, 1.0, 1.0],
                                                            "sheenRoughnessFactor": 0.5}}}
    cfg = _config(tmp_path, [{"name": "sheen", "model": "assets/q.gltf", "lighting": "neutral",
                              "orbit": {"radius": 3}}], sheen)
    doc = json.loads(cfg.parent.joinpath("assets", "q.gltf").read_text())
    doc["extensionsUsed"] = ["KHR_materials_sheen"]
    cfg.parent.joinpath("assets", "q.gltf").write_text(json.dumps(doc))
    res = F.run_fidelity(cfg, _settings("default"), tmp_path / "out", progress=False)
    write_outputs(res, cfg)
    (row,) = res.rows
    assert row["status"] == "ok" and "KHR_materials_sheen" in row["not_modelled"]
    assert row["truth_pass"] is None and row["rf_pass"] is None and row["disagree"] is None
    assert row["flip_mean"] is not None  # measured, shown, kept out of the verdicts
    html = (tmp_path / "out" / "index.html").read_text()
    assert "not modelled: KHR_materials_sheen" in html


def test_bad_scenario_is_an_error_row_and_the_cli_prints_one_summary(tmp_path, tmp_cache, capsys):
    from pbrcheck_cli import main

    cfg = _config(tmp_path, [{"name": "ok", "model": "assets/q.gltf", "lighting": "neutral", "orbit": {"radius": 3}},
                             {"name": "gone", "model": "assets/missing.gltf", "lighting": "neutral"}])
    rc = main(["fidelity", str(cfg), "--renderers", "", "--presets", "default", "--size", str(SIZE),
               "--spp", str(SPP), "--out", str(tmp_path / "o"), "--quiet"])
    out = capsys.readouterr().out
    assert rc == 0 and out.startswith("fidelity: 2 scenario(s), 2 row(s), 1 error row(s)")
    rows = json.loads((tmp_path / "o" / "fidelity.json").read_text())["rows"]
    assert [(r["scenario"], r["status"]) for r in rows] == [("ok", "ok"), ("gone", "error")]
    assert rows[1]["stage"] == "scene" and "missing.gltf" in rows[1]["error"]


def test_settings_refuse_bad_values():
    with pytest.raises(F.FidelityError, match="no renderer"):
        F.FidelitySettings(()).validate()
    with pytest.raises(F.FidelityError, match="named twice"):
        _settings("default", "default").validate()


def test_path_tracer_table_and_extension_summary_from_rows():
    from compare.fidelity_page import NOT_MODELLED, extension_summary, path_tracer_table

    def row(scen, ren, flip, nm="", ext=""):
        return {"scenario": scen, "renderer": ren, "status": "ok", "flip_mean": flip, "relmse": flip / 2,
                "flip_mean_noise": False, "not_modelled": nm, "extensions": ext,
                "rf_pass": True, "truth_pass": flip <= F.TRUTH_FLIP_PASS}
    rows = [row("a", "ext:three-gpu-pathtracer", 0.20), row("a", "ext:cycles", 0.05),
            row("b", "ext:three-gpu-pathtracer", 0.03, ext="KHR_texture_transform"),
            {"scenario": "b", "renderer": "ext:cycles", "status": "error"},
            row("c", "ext:three-gpu-pathtracer", 0.01, nm="KHR_materials_sheen", ext="KHR_materials_sheen"),
            row("c", "ext:cycles", 0.30, nm="KHR_materials_sheen", ext="KHR_materials_sheen")]
    names = ["ext:three-gpu-pathtracer", "ext:cycles"]
    table = {e["scenario"]: e for e in path_tracer_table(rows, names)}
    assert table["a"]["closest"] == "ext:cycles" and table["b"]["closest"] == "ext:three-gpu-pathtracer"
    assert table["b"]["tracers"]["ext:cycles"] is None and table["c"]["closest"] == NOT_MODELLED
    assert path_tracer_table(rows, ["default"]) == []
    ext = {(e["extension"], e["renderer"]): e for e in extension_summary(rows, names)}
    assert ext[("core", "ext:cycles")]["judged"] == 1 and ext[("core", "ext:cycles")]["flip_mean"] == 0.05
    assert ext[("KHR_materials_sheen", "ext:cycles")] == {
        "extension": "KHR_materials_sheen", "renderer": "ext:cycles", "judged": 0, "not_modelled": 1,
        "flip_mean": None, "rf_pass": 0, "rf_judged": 0, "truth_pass": 0}
    assert ext[("KHR_texture_transform", "ext:three-gpu-pathtracer")]["truth_pass"] == 1


@pytest.mark.slow
def test_dask_local_cluster_gives_the_serial_rows(tmp_path, tmp_cache):
    cfg = _config(tmp_path, [{"name": "q", "model": "assets/q.gltf", "lighting": "neutral", "orbit": {"radius": 3}}])
    st = _settings("default")
    serial = F.run_fidelity(cfg, st, tmp_path / "s", progress=False)
    dask = F.run_fidelity(cfg, st, tmp_path / "d", scheduler="local:1", progress=False)
    keep = ("key", "status", "relmse", "flip_mean", "delta_e_itp_mean", "truth_pass")
    assert [{k: r[k] for k in keep} for r in dask.rows] == [{k: r[k] for k in keep} for r in serial.rows]
    assert dask.rows[0]["status"] == "ok" and dask.scheduler == "local:1"


def test_a_row_key_changes_with_what_pbrcheck_leaves_out(tmp_path):
    """A scenario's rows are keyed by its features pbrcheck does not model: the same scene file and
    version with an extension flipped to modelled (no longer stripped from the engines' export, now
    in the truth) must not resume the rows made before (--resume would keep stale rows)."""
    import dataclasses

    cfg = _config(tmp_path, [{"name": "q", "model": "assets/q.gltf", "lighting": "neutral", "orbit": {"radius": 3}}])
    st = _settings("ext:threejs", "default")
    sc = F.load_scenarios(cfg, SIZE)[0]
    assert sc.not_modelled == ()
    left_out = dataclasses.replace(sc, not_modelled=("KHR_materials_transmission",))
    keys = [s.row_key for s in F.plan([sc], st)[1]]
    assert keys == [s.row_key for s in F.plan([sc], st)[1]]                     # deterministic
    assert not set(keys) & {s.row_key for s in F.plan([left_out], st)[1]}      # every row's key moves


def test_a_rerun_under_new_keys_leaves_one_row_file_a_slot(tmp_path, tmp_cache, stand_ins):
    """--resume after a change of every row's key (here the truth's spp): the new rows replace the old
    files of the same scenario x renderer (before, both stayed in rows/); a row file of a scenario
    outside the run stays."""
    cfg = _config(tmp_path, [{"name": "q", "model": "assets/q.gltf", "lighting": "neutral", "orbit": {"radius": 3}}])
    out = tmp_path / "out"
    first = F.run_fidelity(cfg, _settings("ext:threejs", "default"), out, progress=False)
    other = out / "rows" / "0123456789abcdef0123456789abcdef01234567.json"
    other.write_text(json.dumps({"key": other.stem, "scenario": "another", "renderer": "default"}))
    st = F.FidelitySettings(tuple(renderers.RendererSpec.parse(n) for n in ("ext:threejs", "default")),
                            spp=SPP * 2, size=SIZE)
    second = F.run_fidelity(cfg, st, out, resume=True, progress=False)
    old, new = {r["key"] for r in first.rows}, {r["key"] for r in second.rows}
    assert old.isdisjoint(new)
    assert {f.stem for f in (out / "rows").glob("*.json")} == new | {other.stem}
