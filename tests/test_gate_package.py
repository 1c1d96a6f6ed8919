"""The gate as a package (issue 33 item 5): the Verdict enum and the exit code as a function of the
verdicts, the frozen CheckResult, a check the gate refuses to judge, the budget parsed once, the
Metric registry the gate reads, the hook file parsed (not grepped) for the LOD probe, the HTML page
from its template file, the import order of the package's modules."""

from __future__ import annotations

import dataclasses
import io
import tomllib
from pathlib import Path

import numpy as np
import pytest

from compare import metrics
from compare.gate import (Check, CheckResult, NotJudged, Verdict, budget_noise, exit_code, load_budget, run_gate,
                          takes_hooks, write_html)
from pbrcheck.exr import Image, write_exr

ROOT = Path(__file__).resolve().parents[1]


def test_exit_code_is_a_function_of_the_verdicts():
    V = Verdict
    assert exit_code([]) == 0
    assert exit_code([V.PASS, V.IMPROVED, V.CHANGE_ALLOWED]) == 0
    assert exit_code([V.PASS, V.CHANGED]) == 1 and exit_code([V.OVER_BUDGET]) == 1 and exit_code([V.REGRESSED]) == 1
    assert exit_code([V.REGRESSED, V.NOT_JUDGED]) == 2 and exit_code([V.ERROR, V.OVER_BUDGET]) == 2
    assert exit_code([V.NOT_JUDGED, V.BACKEND_ERROR]) == 3
    # the printed words of the totals line
    assert [v.label for v in V] == ["pass", "fail", "regressed", "improved", "changed", "changed", "error", "error",
                                    "not judged"]
    assert [v for v in V if not v.judged] == [V.ERROR, V.BACKEND_ERROR, V.NOT_JUDGED]


def test_check_result_is_frozen():
    r = CheckResult(Check(name="c", max={"relmse": 1.0}, min={}, reference="r.exr"), Verdict.PASS)
    with pytest.raises(dataclasses.FrozenInstanceError):
        r.verdict = Verdict.ERROR
    assert not any(f.name in ("status", "outcome", "exit_code") for f in dataclasses.fields(CheckResult))


def _image(v):
    return Image.from_rgb(np.full((8, 8, 3), v, np.float32))


@pytest.fixture
def budget(tmp_path):
    write_exr(tmp_path / "ref.exr", _image(0.5))
    write_exr(tmp_path / "test.exr", _image(0.5))
    p = tmp_path / "b.toml"
    p.write_text('[[check]]\nname = "c"\ntest = "test.exr"\nreference = "ref.exr"\n[check.max]\nrelmse = 1\n')
    return p


def test_a_check_not_judged_exits_2_and_accepts_nothing(budget, monkeypatch):
    from compare.gate import evaluate

    def refuse(*a, **k):
        raise NotJudged("the scene holds a feature neither renderer models")

    monkeypatch.setattr(evaluate, "compare_images", refuse)
    out = io.StringIO()
    assert run_gate(budget, progress=False, stream=out, accept_reason="x") == 2
    text = out.getvalue()
    assert text.startswith("NOT JUDGED c: the scene holds a feature") and "gate: 0 pass, 1 not judged" in text
    assert "nothing accepted" in text and not (budget.parent / "baselines").exists()


def test_budget_toml_is_parsed_once(budget, monkeypatch):
    calls = []
    real = tomllib.loads
    monkeypatch.setattr(tomllib, "loads", lambda s: calls.append(1) or real(s))
    budget.write_text("require_baselines = false\n" + budget.read_text())
    assert run_gate(budget, progress=False, stream=io.StringIO()) == 0
    assert len(calls) == 1
    assert load_budget(budget).require_baselines is False


def test_metric_registry_is_what_the_comparator_computes_and_the_gate_reads(monkeypatch):
    from compare.metrics import METRICS

    img = Image.from_rgb(np.full((4, 4, 3), 0.5, np.float32))
    got = metrics.compare_images(img, img).metrics
    assert list(got) == list(METRICS)
    assert metrics.HIGHER_IS_BETTER == {"psnr"} and METRICS["relmse"].noise_power == 1.0
    # the gate's noise scaling reads the registry: a metric declared variance-like scales as 1/spp
    c = Check(name="c", max={"flip_mean": 0.05}, min={}, reference="r.exr")
    noise = {"simulated": {"flip_mean": 0.02}}
    assert budget_noise(c, noise, 64)[0]["noise"] == pytest.approx(0.02 / 2 ** 0.5)
    monkeypatch.setitem(METRICS, "flip_mean", dataclasses.replace(METRICS["flip_mean"], noise_power=1.0))
    row = budget_noise(c, noise, 64)[0]
    assert row["noise"] == pytest.approx(0.01) and row["spp_needed"] == pytest.approx(64 * 10 / 5)


def test_no_metric_name_literal_in_the_gate():
    """Metric names come from the registry: the gate's modules spell none of them."""
    for p in sorted((ROOT / "compare" / "gate").glob("*.py")):
        text = p.read_text(encoding="utf-8")
        for name in metrics.METRICS:
            assert f'"{name}"' not in text and f"'{name}'" not in text, (p.name, name)


def _hook_check(tmp_path, text):
    f = tmp_path / "hook.glsl"
    f.write_text(text)
    return Check(name="h", max={"relmse": 1.0}, min={}, reference="r.exr", scene="spheres", preset="default",
                 options={"shader": str(f)})


def test_takes_hooks_parses_the_hook_file(tmp_path):
    """A hook file that defines hook_D but names hook_lod in a comment still gets the LOD probe (a
    grep of its text said no); one that defines hook_lod does not (the probe would replace it)."""
    assert takes_hooks(_hook_check(tmp_path, "// unlike hook_lod, this one changes the NDF\n"
                                             "float hook_D(float NoH, float roughness) { return D_GGX(NoH, roughness); }\n"))
    assert not takes_hooks(_hook_check(tmp_path, "float hook_lod(float roughness, float max_lod, float cube_log2) "
                                                 "{ return 0.0; }\n"))
    assert not takes_hooks(dataclasses.replace(_hook_check(tmp_path, ""), preset="splitsum_basic", options={}))
    assert takes_hooks(dataclasses.replace(_hook_check(tmp_path, ""), options={}))


def test_html_page_is_the_template_file_and_package_data(tmp_path):
    tpl = ROOT / "compare" / "gate" / "templates" / "page.html"
    assert tpl.is_file()
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert "compare.gate" in cfg["packages"] and cfg["package-data"]["compare.gate"] == ["templates/*.html"]
    c = Check(name="<b>x</b>", max={"relmse": 1.0}, min={}, reference="r.exr")
    page = write_html(tmp_path, [CheckResult(c, Verdict.ERROR, error="missing <img src=x>")]).read_text()
    assert "<h2>&lt;b&gt;x&lt;/b&gt;: error</h2>" in page and "<img src=x>" not in page
    assert page.startswith("<!doctype html>") and "Every check passes" not in page
    assert "Every check passes" in write_html(tmp_path, []).read_text()
