"""``pbrcheck compare`` and ``pbrcheck gate`` through pbrcheck.cli.main: outputs and exit codes."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from pbrcheck.cli import main
from pbrcheck.exr import Image, write_exr

H, W = 20, 24


def img(scale=1.0, h=H, w=W, nan=False, seed=0, aovs=True):
    rng = np.random.default_rng(seed)
    rgb = (rng.random((h, w, 3)) + 0.1).astype(np.float32) * scale
    if nan:
        rgb[2, 3, 0] = np.nan
    extra = {}
    if aovs:
        obj = np.zeros((h, w), np.float32)
        obj[:, : w // 4] = -1
        obj[:, w // 2:] = 1
        cov = (obj >= 0).astype(np.float32)
        extra = {"object": obj, "coverage": cov, "NdotV": np.full((h, w), 0.5, np.float32)}
    return Image.from_rgb(rgb, **extra)


@pytest.fixture
def exrs(tmp_path):
    d = tmp_path / "img"
    write_exr(d / "ref.exr", img())
    write_exr(d / "good.exr", img(1.001))
    write_exr(d / "bad.exr", img(1.5))
    write_exr(d / "small.exr", img(h=H - 2))
    write_exr(d / "nan.exr", img(nan=True))
    write_exr(d / "nochan.exr", Image({"Y": np.ones((H, W), np.float32)}))
    return d


def test_compare_writes_json_and_maps(exrs, tmp_path, capsys):
    out = tmp_path / "out"
    rc = main(["compare", str(exrs / "ref.exr"), str(exrs / "bad.exr"), "--json", str(out / "c.json"),
               "--maps", str(out / "maps")])
    assert rc == 0
    data = json.loads((out / "c.json").read_text())
    assert set(data["metrics"]) == {"mean_abs", "rmse", "relmse", "smape", "rel_p50", "rel_p95", "rel_p99",
                                    "rel_max", "psnr", "flip_mean", "delta_e_itp_mean", "delta_e_itp_p95"}
    assert data["pixels"]["background"] == H * (W // 4)
    assert {o["id"] for o in data["objects"]} == {0, 1}
    assert data["ndotv"] and data["noise"] is None
    for name in ("rel_error.png", "flip.png", "diff.exr"):
        assert (out / "maps" / name).stat().st_size > 0
    from pbrcheck.exr import read_exr

    diff = read_exr(out / "maps" / "diff.exr")
    assert np.allclose(diff.rgb, img(1.5).rgb - img().rgb, atol=1e-6)
    assert "relmse" in capsys.readouterr().out
    # with --scene, objects carry names and materials
    assert main(["compare", str(exrs / "ref.exr"), str(exrs / "bad.exr"), "--scene", "spheres",
                 "--json", str(out / "s.json")]) == 0
    objs = json.loads((out / "s.json").read_text())["objects"]
    assert objs[1]["name"] == "grid[r0,c1]" and objs[1]["material"]["roughness"] == pytest.approx(0.2)


@pytest.mark.parametrize("other, msg", [("small.exr", "size mismatch"), ("nan.exr", "NaN"),
                                        ("nochan.exr", "missing channel"), ("absent.exr", "no such file")])
def test_compare_errors_exit_2_and_write_nothing(exrs, tmp_path, capsys, other, msg):
    out = tmp_path / "out"
    rc = main(["compare", str(exrs / "ref.exr"), str(exrs / other), "--json", str(out / "c.json"),
               "--maps", str(out / "maps")])
    err = capsys.readouterr().err
    assert rc == 2
    assert msg in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not out.exists()


def budget(tmp_path, body: str):
    p = tmp_path / "budget.toml"
    p.write_text(body)
    return p


CHECK = """
[[check]]
name = "{name}"
test = "img/{test}"
reference = "{ref}"
[check.max]
relmse = 0.01
flip_mean = 0.2
"""


def run_gate(tmp_path, body, *extra):
    p = budget(tmp_path, body)
    return main(["gate", str(p), "--quiet", "--maps", str(tmp_path / "maps"), *extra])


def test_gate_passes_within_budget(exrs, tmp_path, capsys):
    rc = run_gate(tmp_path, CHECK.format(name="ok", test="good.exr", ref="img/ref.exr"),
                  "--junit", str(tmp_path / "j.xml"), "--summary", str(tmp_path / "s.md"))
    assert rc == 0, capsys.readouterr()
    suite = ET.parse(tmp_path / "j.xml").getroot().find("testsuite")
    assert suite.get("tests") == "1" and suite.get("failures") == "0" and suite.get("errors") == "0"
    assert "| ok | pass | relmse |" in (tmp_path / "s.md").read_text()
    assert not (tmp_path / "maps").exists()


def test_gate_exceeded_exits_1_with_details_and_maps(exrs, tmp_path, capsys):
    body = CHECK.format(name="ok", test="good.exr", ref="img/ref.exr") + \
        CHECK.format(name="too bright", test="bad.exr", ref="img/ref.exr")
    rc = run_gate(tmp_path, body, "--junit", str(tmp_path / "j.xml"), "--summary", str(tmp_path / "s.md"))
    out = capsys.readouterr().out
    assert rc == 1
    line = next(l for l in out.splitlines() if l.startswith("FAIL too bright: relmse"))
    assert "budget 0.01" in line and "worst objects:" in line
    suite = ET.parse(tmp_path / "j.xml").getroot().find("testsuite")
    assert suite.get("failures") == "1"
    assert suite.find("testcase[@name='too bright']/failure") is not None
    assert "FAIL" in (tmp_path / "s.md").read_text()
    assert (tmp_path / "maps" / "too_bright" / "rel_error.png").is_file()


@pytest.mark.parametrize("ref, test, msg", [
    ("img/absent.exr", "good.exr", "no such file"),
    ("img/ref.exr", "absent.exr", "no such file"),
    ("img/ref.exr", "small.exr", "size mismatch"),
    ("img/ref.exr", "nan.exr", "NaN"),
])
def test_gate_missing_data_exits_2(exrs, tmp_path, capsys, ref, test, msg):
    body = CHECK.format(name="a", test="good.exr", ref="img/ref.exr") + CHECK.format(name="b", test=test, ref=ref)
    rc = run_gate(tmp_path, body, "--junit", str(tmp_path / "j.xml"))
    out = capsys.readouterr().out
    assert rc == 2
    assert "ERROR b:" in out and msg in out
    suite = ET.parse(tmp_path / "j.xml").getroot().find("testsuite")
    assert suite.get("errors") == "1"


@pytest.mark.parametrize("body, msg", [
    ("this is not toml", "invalid TOML"),
    ("", "at least one [[check]]"),
    ("[[check]]\nname='x'\ntest='img/good.exr'\nreference='img/ref.exr'\n[check.max]\nbogus=1\n", "bogus"),
    ("[[check]]\nname='x'\ntest='img/good.exr'\nreference='img/ref.exr'\n[check.max]\nrelmse='big'\n", "a finite number >= 0"),
    ("[[check]]\nname='x'\ntest='img/good.exr'\nreference='img/ref.exr'\n", "at least one metric budget"),
    ("[[check]]\nname='x'\nreference='img/ref.exr'\n[check.max]\nrelmse=1\n", "neither"),
    ("[[check]]\ntest='img/good.exr'\nreference='img/ref.exr'\n[check.max]\nrelmse=1\n", "name"),
    ("[[check]]\nname='x'\ntest='img/good.exr'\nreference='auto'\n[check.max]\nrelmse=1\n", "auto"),
    ("[[check]]\nname='x'\ntest='img/good.exr'\n[check.max]\nrelmse=1\n", "reference"),
    ("[[check]]\nname='x'\nscene='spheres'\nreference='auto'\nspp=1\n[check.max]\nrelmse=1\n", "spp"),
    ("[[check]]\nname='x'\ntest='img/good.exr'\nreference='img/ref.exr'\ncolour='red'\n[check.max]\nrelmse=1\n", "colour"),
])
def test_gate_malformed_budget_exits_2_writing_nothing(exrs, tmp_path, capsys, body, msg):
    rc = run_gate(tmp_path, body, "--junit", str(tmp_path / "j.xml"), "--summary", str(tmp_path / "s.md"))
    err = capsys.readouterr().err
    assert rc == 2
    assert msg in err and "budget.toml" in err
    assert not (tmp_path / "j.xml").exists() and not (tmp_path / "s.md").exists()


def test_gate_missing_budget_file(tmp_path, capsys):
    assert main(["gate", str(tmp_path / "nope.toml")]) == 2
    assert "no such budget file" in capsys.readouterr().err


def test_gate_min_bound_for_psnr(exrs, tmp_path, capsys):
    body = ("[[check]]\nname='p'\ntest='img/bad.exr'\nreference='img/ref.exr'\n[check.min]\npsnr=40\n")
    assert run_gate(tmp_path, body) == 1
    assert "psnr" in capsys.readouterr().out


def test_committed_ci_budget_is_well_formed():
    from pathlib import Path

    from compare.gate import load_budget, scene_arg

    budget = load_budget(Path(__file__).resolve().parents[1] / "compare" / "budgets" / "ci.toml")
    checks, base = budget.checks, budget.base
    assert len(checks) >= 2 and all(c.max for c in checks)
    for c in checks:
        scene = scene_arg(base, c.scene)
        assert scene.camera.width * scene.camera.height <= 200 * 200  # CI size
