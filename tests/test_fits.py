"""fit-lod on a real (small) scene, the fitted mapping in the real-time renderer, and fit-roughness."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pbrcheck.lodmap import BASIS_NAMES, LodFitError, LodMapping
from pbrcheck.scene import load_scene

# Renders, fits or quadratures of seconds each: `make test-fast` skips them, `make test` runs them.
pytestmark = pytest.mark.slow

# Small but real: the spheres scene (5 x 6 grid, sky with a sun) at 40 px high, 16 spp, 32^2 cubes
# with 6 mips. The reference is shared by every mapping, so the comparison between mappings is
# deterministic; the fitted mapping is the smooth monotone fit to the per-roughness optima of this
# very scene, so it may not be worse than the best built-in mapping by more than float rounding.
FIT_OPTS = {"cube_size": 32, "prefilter_levels": 6, "prefilter_samples": 256, "supersample": 2}
FIT_SIZE, FIT_SPP = 40, 16
#: Relative slack on "no worse than": float32 summation order only.
NO_WORSE_RTOL = 1e-6


@pytest.fixture(scope="module")
def fit(tmp_path_factory):
    from compare.research.fit_lod import run_fit_lod

    out = tmp_path_factory.mktemp("fitlod") / "fit.json"
    res = run_fit_lod(load_scene("spheres"), options=FIT_OPTS, spp=FIT_SPP, size=FIT_SIZE, out=out)
    return out, res


def test_fit_lod_json_shape(fit):
    out, res = fit
    d = json.loads(out.read_text())
    assert len(d["samples"]) == 6  # the grid's six roughness columns
    for s in d["samples"]:
        assert {"roughness", "lod", "relmse"} <= set(s)
        assert 0.0 <= s["lod"] <= FIT_OPTS["prefilter_levels"] - 1 and np.isfinite(s["relmse"])
    assert set(d["mappings"]) == {"linear", "quadratic", "log2", "fitted"}
    f = d["mappings"]["fitted"]
    assert f["cube_size"] == 32 and f["mip_count"] == 6 and f["chain"] == d["chain"] in ("linear", "quadratic", "log2")
    assert len(f["coefficients"]) == len(BASIS_NAMES)
    assert out.with_suffix(".glsl").read_text().startswith("// Fitted roughness -> LOD mapping")
    # the reference spp: from --spp up by the verdict rule, recorded with the fit
    rule = d["reference_spp"]
    assert rule["spp"] == d["spp"] >= FIT_SPP and rule["steps"][0][0] == FIT_SPP
    assert rule["noise_limited"] or rule["smallest_error"] is None or rule["ratio"] >= rule["factor"], rule
    # the per-roughness optima rise with roughness overall (rough lobes want blurrier levels)
    lods = [s["lod"] for s in d["samples"]]
    assert lods[-1] > lods[0] + 2.0, lods


def test_fitted_mapping_no_worse_than_best_builtin(fit):
    _, res = fit
    m = res.mappings
    best = min(m[k].relmse for k in ("linear", "quadratic", "log2"))
    assert m["fitted"].relmse <= best * (1 + NO_WORSE_RTOL), m


def test_realtime_uses_fitted_mapping(fit, tmp_path):
    from realtime.presets import OptionError
    from realtime.render import render_realtime

    out, _ = fit
    scene = load_scene("spheres").with_camera(width=24, height=20)
    lin = render_realtime(scene, "default", {**FIT_OPTS, "lod_mapping": "linear"}, progress=False)
    fitted = render_realtime(scene, "default", {**FIT_OPTS, "lod_mapping": f"fitted:{out}"}, progress=False)
    assert np.all(np.isfinite(fitted.rgb))
    assert np.abs(fitted.rgb - lin.rgb).max() > 1e-3
    assert json.loads(fitted.meta["options"])["lod_mapping"] == f"fitted:{out.resolve()}"
    # a cube or mip count other than the fit's is a typed error naming both
    with pytest.raises(OptionError, match="fitted for a 32\\^2 cube with 6 mips"):
        render_realtime(scene, "default", {**FIT_OPTS, "cube_size": 64, "lod_mapping": f"fitted:{out}"},
                        progress=False)
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    with pytest.raises(LodFitError):
        render_realtime(scene, "default", {**FIT_OPTS, "lod_mapping": f"fitted:{bad}"}, progress=False)


def test_fitted_override_equals_glsl_expression():
    """The #define the renderer injects is the mapping (Python evaluation of the emitted expression)."""
    m = LodMapping((1.5, 2.0, 0.25, 0.1, 0.7, 0.4), 256, 9, "log2")
    expr = m.glsl_expr("r").replace("clamp", "_clamp")
    for r in np.linspace(-0.2, 1.2, 15):
        got = eval(expr, {"r": r, "sqrt": np.sqrt, "_clamp": lambda x, a, b: min(max(x, a), b)})
        assert got == pytest.approx(float(m(r)), abs=1e-6)
    assert LodMapping.from_json(m.to_json()) == m
    with pytest.raises(LodFitError, match="chain"):
        LodMapping.from_json({**m.to_json(), "chain": "cubic"})


def test_error_objective_recovers_known_mapping():
    """Synthetic error curves (L - truth(r))^2 with the minimum on a known mapping: the
    error-minimizing fit lands on it (within RECOVERY_TOL levels, as tests/test_lodfit.py)."""
    from compare.research.monotone_fit import fit_lod_to_error

    r = np.linspace(0, 1, 16)
    grid = np.arange(0, 8.001, 0.25)
    truth = 3 * r + 4 * r * r
    err = (grid[None, :] - truth[:, None]) ** 2
    m = fit_lod_to_error(r, grid, err, cube_size=256, mip_count=9)
    assert np.max(np.abs(m(r) - truth)) < 0.1


# fit-roughness: a target rendered by the reference itself at a known roughness must come back.
# Scan + 40 Adam steps (lr 0.01 -> 0.002, mean of the last 10), 16 spp per step. Measured over
# roughness 0.03 ... 0.8 on a 48-px metal sphere under an 8-degree sun of radiance 60 (the hard case:
# the highlight is a few pixels): |r* - r| <= 0.013 for r >= 0.15, up to 0.045 below, where the scan's
# range says the image cannot tell (it spans [0.0105, 0.15]). The tests take roughness the image
# constrains; ROUGH_TOL leaves room for their smaller images' noise.
ROUGH_TOL = 0.04


def _metal_sphere(size: int, env_resolution, base_color, roughness: float, *, sun_deg: float = 20.0,
                  sun_radiance: float = 5.0, metallic: float = 1.0):
    """One sphere filling a size x size image under a sun (default: a soft 20-degree one)."""
    from compare.research.fit_roughness import sphere_under_sun

    return sphere_under_sun(size, roughness, sun_deg=sun_deg, sun_radiance=sun_radiance, metallic=metallic,
                            base_color=base_color, env_resolution=env_resolution)


def test_fit_roughness_recovers_known_roughness():
    from compare.research.fit_roughness import fit_roughness
    from reference.render import render_uncached

    scene = _metal_sphere(24, [128, 64], [0.9, 0.6, 0.3], 0.35)
    target = render_uncached(scene, spp=256, progress=False)
    rows, _ = fit_roughness(scene, target.rgb, target.channels["object"], start=[0.65])
    assert abs(rows[0].apparent_roughness - 0.35) < ROUGH_TOL, rows
    lo, hi = rows[0].range
    assert lo <= 0.35 <= hi and lo <= rows[0].apparent_roughness <= hi, rows
    assert rows[0].loss is not None and np.isfinite(rows[0].loss)


def test_fit_roughness_recovers_low_roughness_under_a_small_bright_sun():
    """The case that drifted: with plain L2 and no scan, r = 0.15 under an 8-degree sun of radiance 60
    came back as 0.05 (the highlight's pixel noise swamped the gradient below the truth; Adam walked
    towards the less noisy low roughness)."""
    from compare.research.fit_roughness import fit_roughness
    from reference.render import render_uncached

    scene = _metal_sphere(32, [512, 256], [0.9, 0.6, 0.3], 0.15, sun_deg=8.0, sun_radiance=60.0)
    target = render_uncached(scene, spp=1024, progress=False)
    rows, _ = fit_roughness(scene, target.rgb, target.channels["object"], start=[0.5])
    assert abs(rows[0].apparent_roughness - 0.15) < ROUGH_TOL, rows
    lo, hi = rows[0].range
    assert lo <= 0.15 <= hi, rows


def test_fit_roughness_without_scan_refines_from_its_start():
    """``scan=False``: Adam alone, from the given start, within [ROUGH_MIN, 1] and no range."""
    from compare.research.fit_roughness import fit_roughness
    from reference.render import render_uncached

    scene = _metal_sphere(24, [128, 64], [0.9, 0.6, 0.3], 0.35)
    target = render_uncached(scene, spp=256, progress=False)
    rows, _ = fit_roughness(scene, target.rgb, target.channels["object"], start=[0.45], scan=False)
    assert abs(rows[0].apparent_roughness - 0.35) < ROUGH_TOL, rows
    assert rows[0].start == pytest.approx(0.45) and rows[0].range is None


def test_fits_of_one_scene_share_the_scan_and_give_the_unshared_result(monkeypatch):
    """``scan_cache``: the scan's renders depend on the scene, not the target, so a second target on
    the same scene reuses them (rendered once) and gets exactly the fit it gets alone."""
    import compare.research.fit_roughness as fr
    from reference.render import render_uncached

    scene = _metal_sphere(16, [128, 64], [0.9, 0.6, 0.3], 0.35)
    t1 = render_uncached(scene, spp=64, progress=False)
    t2 = render_uncached(_metal_sphere(16, [128, 64], [0.9, 0.6, 0.3], 0.6), spp=64, progress=False)
    alone, _ = fr.fit_roughness(scene, t2.rgb, t2.channels["object"], iterations=3)
    calls = []
    real = fr.scan_renders
    monkeypatch.setattr(fr, "scan_renders", lambda *a, **k: calls.append(1) or real(*a, **k))
    shared: dict = {}
    fr.fit_roughness(scene, t1.rgb, t1.channels["object"], iterations=3, scan_cache=shared)
    rows, _ = fr.fit_roughness(scene, t2.rgb, t2.channels["object"], iterations=3, scan_cache=shared)
    assert len(calls) == 1 and len(shared) == 1
    assert rows[0].scan == alone[0].scan and rows[0].range == alone[0].range
    assert rows[0].apparent_roughness == pytest.approx(alone[0].apparent_roughness, abs=1e-6)


# unbiased_fit_loss: the product of two independent renders' errors estimates the expected render's
# loss without the variance term; its standard error predicts the spread. Synthetic Gaussian
# "renders" (2000 trials of 400 x 3 values): the means are compared at UNBIASED_Z standard errors of
# the mean over trials (a false failure once in ~16000 runs per check).
UNBIASED_Z = 4.0


def test_unbiased_fit_loss_removes_the_variance_term_and_predicts_its_spread():
    from compare.research.fit_roughness import _weight, unbiased_fit_loss

    rng = np.random.default_rng(7)
    target = rng.uniform(0.0, 3.0, (400, 3)).astype(np.float64)
    mu = target + rng.normal(0.0, 0.2, target.shape)
    sigma = rng.uniform(0.05, 0.5, target.shape)
    truth = float(np.mean((mu - target) ** 2 * _weight(target)))
    est, ses, naive = [], [], []
    for _ in range(2000):
        a = mu + sigma * rng.standard_normal(mu.shape)
        b = mu + sigma * rng.standard_normal(mu.shape)
        e, se = unbiased_fit_loss(a, b, target)
        est.append(e)
        ses.append(se)
        naive.append(float(np.mean((a - target) ** 2 * _weight(target))))
    est = np.array(est)
    sem = est.std(ddof=1) / np.sqrt(len(est))
    assert abs(est.mean() - truth) < UNBIASED_Z * sem
    bias = float(np.mean(sigma ** 2 * _weight(target)))
    assert np.mean(naive) - truth == pytest.approx(bias, rel=0.05)  # what the one-render loss adds
    assert 0.85 < np.mean(ses) / est.std(ddof=1) < 1.15


def test_bracket_takes_the_lowest_upper_bound_and_the_first_told_apart_neighbours():
    from compare.research.fit_roughness import bracket

    scan = [[0.0105, 0.0010, 0.0006], [0.03, -0.0002, 0.0030], [0.06, 0.0006, 0.0007], [0.1, 0.0009, 0.0003],
            [0.15, 0.0010, 0.0003], [0.2, 0.00004, 0.0003], [0.27, 0.0009, 0.0002], [0.35, 0.0021, 0.0002]]
    start, (lo, hi) = bracket(scan)
    assert start == 0.2  # not 0.03, whose estimate is lowest but whose upper bound is not
    assert (lo, hi) == (0.15, 0.27)
    flat = [[r, 0.001, 0.01] for r in (0.1, 0.2, 0.3)]
    assert bracket(flat)[1] == [0.1, 0.3]  # nothing told apart: the whole grid
    with pytest.raises(ValueError):
        bracket([])


def test_fit_roughness_on_a_mirror_stays_differentiable():
    """A roughness-0 material starts the fit at ROUGH_MIN (the reference's mirror lobe below it has no
    roughness derivative: Mitsuba's prb used to raise "not attached to the AD graph" when every fitted
    object was a mirror); r* stays within [ROUGH_MIN, 1]."""
    from compare.research.fit_roughness import ROUGH_MIN, fit_roughness
    from reference.render import render_uncached

    scene = _metal_sphere(12, [64, 32], [0.9, 0.9, 0.9], 0.0)
    target = render_uncached(scene, spp=64, progress=False)
    rows, _ = fit_roughness(scene, target.rgb, target.channels["object"], iterations=5)
    assert ROUGH_MIN <= rows[0].apparent_roughness <= 1.0 and np.isfinite(rows[0].loss), rows


SPHERE_TOML = """
name = "one_sphere"
[camera]
origin = [0.0, 0.0, 4.0]
fov = 40.0
width = 16
height = 16
[environment]
type = "sky"
sun_direction = [0.3, 0.8, 0.5]
sun_angular_diameter = 20.0
sun_radiance = [5.0, 5.0, 5.0]
resolution = [64, 32]
[[objects]]
type = "sphere"
name = "ball"
radius = 1.0
[objects.material]
base_color = [0.9, 0.6, 0.3]
metallic = 1.0
roughness = 0.4
"""


@pytest.mark.parametrize("extra", [[], ["--no-scan"]])
def test_fit_roughness_cli_writes_json_and_table(tmp_path, capsys, extra):
    from pbrcheck_cli import main

    scene = tmp_path / "one.toml"
    scene.write_text(SPHERE_TOML)
    out = tmp_path / "o" / "fit.json"
    rc = main(["fit-roughness", str(scene), "--size", "0", "--iterations", "4", "--spp", "4", "--out", str(out), *extra])
    assert rc == 0
    d = json.loads(out.read_text())
    assert d["loss"] == "tone_mse" and d["scan"] is (not extra) and d["size"] == [16, 16]
    (o,) = d["objects"]
    assert o["name"] == "ball" and o["roughness"] == 0.4 and 0.0 < o["apparent_roughness"] <= 1.0
    if extra:
        assert "range" not in o and o["start"] == 0.4
    else:
        lo, hi = o["range"]
        assert lo <= o["apparent_roughness"] <= hi and len(o["scan"]) >= 13
    printed = capsys.readouterr().out
    assert "| ball | 0.400 |" in printed and f"json: {out}" in printed


def test_bench_fit_roughness_prints_the_self_check(capsys):
    """``pbrcheck bench fit-roughness``: JSON with a row per roughness and the summary figures."""
    from pbrcheck_cli import main

    rc = main(["bench", "fit-roughness", "--size", "12", "--roughness", "0.35", "--target-spp", "64",
               "--sun", "20", "--sun-radiance", "5"])
    assert rc == 0
    d = json.loads(capsys.readouterr().out)
    (row,) = d["rows"]
    assert row["roughness"] == 0.35 and row["error"] == pytest.approx(row["apparent_roughness"] - 0.35)
    lo, hi = row["range"]
    assert row["truth_in_range"] == (lo <= 0.35 <= hi) and d["truth_in_range"] == int(row["truth_in_range"])
    assert d["max_abs_error"] == pytest.approx(abs(row["error"])) and d["size"] == 12
