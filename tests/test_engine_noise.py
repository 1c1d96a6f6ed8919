"""A Monte Carlo engine's own noise is not its error: the renderer contract's variance image and N
independent renders (clients/config.py, clients/run.py) reach every metric and verdict, which
subtract it as they subtract the reference's (compare/metrics.py, "noisy image under test").

A synthetic noisy renderer (a Python script in renderers.toml style) renders a known mean with a
known noise; against a noise-free reference its relmse, less the noise, must equal the mean's own
error within :data:`TOL`, and a gate budget between the two flips from fail to pass."""

from __future__ import annotations

import json
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from clients import config as C
from clients import run as R
from compare.gate import run_gate
from compare.metrics import TEST_VARIANCE_META, compare_images, worse
from compare.research.diagnose import diagnose
from compare.verdict_spp import noise_and_error
from pbrcheck.exr import ENGINE_VARIANCE_META, Image, write_exr
from pbrcheck.scene import dump_toml, scene_from_dict

#: The reference's radiance and the engine's mean: a 20 % bias, relmse 0.1^2 / (0.25 + 0.01) = 0.0385.
REF, MEAN = 0.5, 0.6
TRUE_RELMSE = (MEAN - REF) ** 2 / (REF ** 2 + 0.01)
#: The engine's per-pixel noise: one run with its variance image (sigma 0.1: it alone adds 0.0385,
#: doubling the raw relmse), or 8 runs of sigma 0.2 each (their mean: variance 0.005).
SIGMA, SIGMA_RUN, RUNS = 0.1, 0.2, 8
#: Tolerance on the corrected relmse: over ~1500 valid pixels x 3 channels the estimate's standard
#: deviation is ~1.4e-3 (noise term sqrt(2 / n) 0.0385 and the cross term 2 (0.1)(0.1) / 0.26 / sqrt(n));
#: 0.006 is over 4 of them, far below the 0.0385 the noise adds.
TOL = 0.006
#: A budget between the true error (0.0385) and the raw one (~0.077).
BUDGET = 0.05

ENGINE = textwrap.dedent('''
    import json, sys, os
    import numpy as np
    sys.path.insert(0, os.environ["PBRCHECK_ROOT"])
    from pbrcheck.hdrimage import write_pfm
    mode, scenario, out = sys.argv[1], sys.argv[2], sys.argv[3]
    sc = json.load(open(scenario))
    W, H = sc["size"]["width"], sc["size"]["height"]
    if mode == "runs":   # one of N independent runs: {seed} is the run's index
        rng = np.random.default_rng(100 + int(sys.argv[4])); sigma = %(run)r
    else:
        rng = np.random.default_rng(7); sigma = %(one)r
    img = (%(mean)r + sigma * rng.standard_normal((H, W, 3))).astype(np.float32)
    write_pfm(out, img)
    if mode == "variance":
        write_pfm(sys.argv[4], np.full((H, W, 3), sigma * sigma, np.float32))
''') % {"run": SIGMA_RUN, "one": SIGMA, "mean": MEAN}

SCENE = {
    "name": "mc", "camera": {"origin": [0, 0, 3], "fov": 60.0, "width": 96, "height": 48},
    "environment": {"type": "constant", "radiance": [1, 1, 1]},
    "objects": [{"type": "sphere", "radius": 1.0, "material": {"metallic": 1.0, "roughness": 0.5}}],
}


@pytest.fixture
def engine(tmp_path, monkeypatch, tmp_cache):
    """renderers.toml: ``mc`` (a variance image), ``mc-runs`` (8 runs), ``mc-plain`` (the same noisy
    engine that hands pbrcheck no variance)."""
    d = tmp_path / "engine"
    d.mkdir()
    (d / "mc.py").write_text(ENGINE)
    monkeypatch.setenv("PBRCHECK_ROOT", str(Path(__file__).resolve().parents[1]))
    py = json.dumps(sys.executable)
    (d / "renderers.toml").write_text(textwrap.dedent(f'''
        [renderer.mc]
        command = [{py}, "mc.py", "variance", "{{scenario}}", "{{out}}", "{{variance}}"]
        output = "pfm"
        variance = true
        [renderer.mc-runs]
        command = [{py}, "mc.py", "runs", "{{scenario}}", "{{out}}", "{{seed}}"]
        output = "pfm"
        renders = {RUNS}
        [renderer.mc-plain]
        command = [{py}, "mc.py", "plain", "{{scenario}}", "{{out}}"]
        output = "pfm"
    '''))
    C.set_renderers_file(d / "renderers.toml")
    yield d
    C.set_renderers_file(None)


def _ref() -> Image:
    return Image.from_rgb(np.full((48, 96, 3), REF, np.float32))


def test_variance_image_is_subtracted_from_relmse(engine):
    img = R.render_external(scene_from_dict(SCENE), "mc")
    assert img.meta[ENGINE_VARIANCE_META] == "the renderer's variance image"
    np.testing.assert_allclose(img.variance, SIGMA ** 2, rtol=1e-6)
    c = compare_images(_ref(), img, flip=False, itp=False)
    raw = c.summary["test_noise"]["metrics_raw"]["relmse"]
    assert raw == pytest.approx(2 * TRUE_RELMSE, abs=2 * TOL)       # the noise doubles it
    assert c.metrics["relmse"] == pytest.approx(TRUE_RELMSE, abs=TOL)
    assert c.summary["test_noise"]["relmse"] == pytest.approx(SIGMA ** 2 / (REF ** 2 + 0.01), rel=1e-6)
    assert worse(raw, BUDGET, upper=True) and not worse(c.metrics["relmse"], BUDGET, upper=True)
    # rmse likewise: sqrt(mse - sigma^2) is the mean's 0.1
    assert c.metrics["rmse"] == pytest.approx(MEAN - REF, abs=0.01)


def test_n_independent_renders_give_mean_and_variance_of_the_mean(engine):
    img = R.render_external(scene_from_dict(SCENE), "mc-runs")
    assert img.meta[ENGINE_VARIANCE_META].startswith(f"{RUNS} independent renders")
    # the mean of 8 runs of sigma 0.2: variance 0.005 (the estimate's mean over ~14k values)
    assert float(img.variance.mean()) == pytest.approx(SIGMA_RUN ** 2 / RUNS, rel=0.05)
    assert float(img.rgb.mean()) == pytest.approx(MEAN, abs=0.005)
    c = compare_images(_ref(), img, flip=False, itp=False)
    assert c.metrics["relmse"] == pytest.approx(TRUE_RELMSE, abs=TOL)
    assert c.summary["test_noise"]["metrics_raw"]["relmse"] > TRUE_RELMSE + 0.01


def test_gate_verdict_flips_with_the_engines_variance(engine, tmp_path, capsys):
    (tmp_path / "mc.toml").write_text(dump_toml(SCENE))
    write_exr(tmp_path / "ref.exr", _ref())
    checks = "".join(textwrap.dedent(f'''
        [[check]]
        name = "{name}"
        scene = "mc.toml"
        preset = "ext:{name}"
        reference = "ref.exr"
        [check.max]
        relmse = {BUDGET}
    ''') for name in ("mc", "mc-plain"))
    (tmp_path / "b.toml").write_text(checks)
    rc = run_gate(tmp_path / "b.toml")
    out = capsys.readouterr().out
    assert rc == 1  # mc-plain fails: its noise counts as its error
    verdicts = {ln.split()[1]: ln.split()[0] for ln in out.splitlines()
                if ln.split() and ln.split()[0] in ("pass", "fail")}
    assert verdicts == {"mc": "pass", "mc-plain": "fail"}, out


def test_noise_flags_verdict_spp_and_diagnose_carry_the_test_variance():
    rng = np.random.default_rng(3)
    ref = Image.from_rgb(np.full((48, 96, 3), REF, np.float32),
                         **{c: np.full((48, 96), 1e-4, np.float32) for c in ("variance.R", "variance.G", "variance.B")})
    # an unbiased engine: all of its difference is noise
    rgb = (REF + SIGMA * rng.standard_normal((48, 96, 3))).astype(np.float32)
    var = {c: np.full((48, 96), SIGMA ** 2, np.float32) for c in ("variance.R", "variance.G", "variance.B")}
    noisy = Image.from_rgb(rgb, {TEST_VARIANCE_META: "test"}, **var)
    plain = Image.from_rgb(rgb)
    c = compare_images(ref, noisy, flip=False, itp=False)
    c0 = compare_images(ref, plain, flip=False, itp=False)
    assert c.summary["noise"]["within_noise"]["relmse"] and c.summary["noise"]["within_noise"]["mean_abs"]
    assert not c0.summary["noise"]["within_noise"]["relmse"]
    assert c.summary["noise"]["mse_corrected"] == pytest.approx(0.0, abs=1e-3)
    assert c0.summary["noise"]["mse_corrected"] == pytest.approx(SIGMA ** 2, rel=0.05)
    # the verdict rule: no error resolved above the noise for the engine that says its noise
    assert noise_and_error(ref, [noisy])[1] is None
    assert noise_and_error(ref, [plain])[1] == pytest.approx(SIGMA ** 2, rel=0.05)
    # diagnose: within the noise, nothing to explain
    d = diagnose(ref, noisy)
    assert d.error_before < 0.1 * diagnose(ref, plain).error_before
    assert "within the reference's noise" in d.line or d.likely is None


def test_a_reference_compared_as_a_test_keeps_its_raw_figures():
    """pbrcheck's own renders carry variance without the contract's mark: nothing is subtracted
    (the convergence study compares exactly the raw MSE with its variance prediction)."""
    rng = np.random.default_rng(4)
    rgb = (REF + SIGMA * rng.standard_normal((48, 96, 3))).astype(np.float32)
    var = {c: np.full((48, 96), SIGMA ** 2, np.float32) for c in ("variance.R", "variance.G", "variance.B")}
    low = Image.from_rgb(rgb, {"renderer": "reference"}, **var)
    c = compare_images(_ref(), low, flip=False, itp=False)
    assert "test_noise" not in c.summary
    assert c.metrics["relmse"] == pytest.approx(SIGMA ** 2 / (REF ** 2 + 0.01), rel=0.05)
    forced = compare_images(_ref(), low, flip=False, itp=False, subtract_test_noise=True)
    assert forced.metrics["relmse"] == pytest.approx(0.0, abs=TOL)


@pytest.mark.parametrize("body,msg", [
    ('command = ["e", "{out}", "{variance}"]\noutput = "png-srgb"\nvariance = true', "png-srgb has no variance"),
    ('command = ["e", "{out}"]\nvariance = true', "variance = true needs {variance}"),
    ('command = ["e", "{out}", "{seed}"]', "{seed} only with renders > 1"),
    ('command = ["e", "{out}", "{seed}"]\nrenders = 0', "renders: expected an integer from 1 to 64"),
    ('command = ["e", "{out}", "{seed}", "{variance}"]\nrenders = 2\nvariance = true', "give one or the other"),
])
def test_noise_keys_are_validated(tmp_path, body, msg):
    p = tmp_path / "r.toml"
    p.write_text("[renderer.x]\n" + body + "\n")
    with pytest.raises(C.RendererConfigError, match=None) as e:
        C.load_renderers(p)
    assert msg in str(e.value) and "renderer.x" in str(e.value)


def test_cache_key_moves_only_for_noisy_renderers(tmp_path):
    p = tmp_path / "r.toml"
    p.write_text('[renderer.x]\ncommand = ["e", "{out}"]\n[renderer.y]\ncommand = ["e", "{out}", "{seed}"]\n'
                 'renders = 4\n')
    got = C.load_renderers(p)
    assert set(got["x"].cache_dict()) == {"name", "command", "output", "lockfile", "inputs"}
    assert got["y"].cache_dict()["renders"] == 4
