"""Reference spp for a trusted verdict: noise floor >= 10x below the smallest error, or noise-limited."""

from __future__ import annotations

import math

import numpy as np
import pytest

import compare.renderers as renderers
from compare import verdict_spp as vs
from pbrcheck.exr import Image

H, W = 24, 32
TRUTH = np.random.default_rng(0).uniform(0.2, 1.0, (H, W, 3)).astype(np.float32)
# Per-sample variance of the synthetic reference: its pixel variance is SIGMA2 / spp.
SIGMA2 = 0.05


def _aovs():
    return {"coverage": np.ones((H, W)), "object": np.zeros((H, W)), "N.X": np.zeros((H, W)),
            "N.Y": np.zeros((H, W)), "N.Z": np.ones((H, W)), "NdotV": np.ones((H, W))}


def fake_reference(scene, *, spp, seed=0, **kw):
    rng = np.random.default_rng(1000 + spp + seed)
    var = np.full((H, W, 3), SIGMA2 / spp)
    rgb = TRUTH + np.sqrt(var) * rng.standard_normal((H, W, 3))
    calls.append(spp)
    seeds.append(seed)
    return Image.from_rgb(rgb.astype(np.float32), {"spp": str(spp)},
                          **{f"variance.{c}": var[..., i] for i, c in enumerate("RGB")}, **_aovs())


def _test_image(mse):
    """A noise-free image whose squared error against the truth is ``mse``."""
    return Image.from_rgb((TRUTH + math.sqrt(mse)).astype(np.float32), {}, **_aovs())


calls: list = []
seeds: list = []


@pytest.fixture(autouse=True)
def fake(monkeypatch):
    calls.clear()
    seeds.clear()
    monkeypatch.setattr(renderers, "render_reference", fake_reference)


def test_spp_needed():
    assert vs.spp_needed(64, 1e-4, 1e-3) == pytest.approx(64)        # exactly 10x: enough
    assert vs.spp_needed(64, 1e-4, 1e-4) == pytest.approx(640)
    assert vs.spp_needed(64, 0.0, 1e-4) == 64                         # a noise-free reference
    assert vs.spp_needed(64, 1e-4, 0.0) == math.inf                   # no error: can never be 10x


def test_chooses_the_spp_that_puts_the_floor_10x_below_the_smallest_error():
    # floor at 64 spp: 0.05 / 64 = 7.8e-4; errors 2e-3 and 0.02: the smallest needs 64 x 10 x 7.8e-4 / 2e-3
    # = 250 spp -> 256 (a power of two, 10 % headroom) -> 512 if the estimate needs it.
    ref, v = vs.reference_for_verdict(None, [_test_image(0.02), _test_image(2e-3)], spp=64, cap=4096)
    assert not v.noise_limited
    assert v.spp in (256, 512) and v.spp == int(ref.meta["spp"]) and calls[0] == 64
    assert v.ratio >= vs.NOISE_FLOOR_FACTOR
    assert v.noise_floor == pytest.approx(SIGMA2 / v.spp)
    assert v.smallest_error == pytest.approx(2e-3, rel=0.2)
    assert "spp: noise floor" in v.provenance() and "NOISE-LIMITED" not in v.provenance()
    assert [s[0] for s in v.steps] == calls


def test_enough_already_renders_the_pilot_and_then_the_final_at_the_least_spp():
    """The pilot (its own seed) decides; the final, on the caller's seed, is returned unexamined."""
    ref, v = vs.reference_for_verdict(None, [_test_image(0.05)], spp=64, seed=5)
    assert calls == [64, 64] and v.spp == 64 and not v.noise_limited
    assert seeds == [vs.pilot_seed(5), 5] and vs.pilot_seed(5) != 5
    assert [s[3] for s in v.steps] == ["pilot", "final"]
    assert vs.pilot_seed(2 ** 32 - 1) == (2 ** 32 - 1 + vs.PILOT_SEED_OFFSET) % 2 ** 32  # 32-bit seeds


def test_stops_at_the_cap_and_says_noise_limited():
    ref, v = vs.reference_for_verdict(None, [_test_image(3e-4)], spp=64, cap=512)
    assert v.noise_limited and v.spp == 512 and calls[-1] == 512
    assert "NOISE-LIMITED at the cap of 512 spp" in v.provenance()
    d = v.to_dict()
    assert d["noise_limited"] is True and d["spp"] == 512 and d["factor"] == vs.NOISE_FLOOR_FACTOR


def test_cap_from_a_time_budget():
    def timed(seconds, spp=64):
        return Image.from_rgb(TRUTH, {"spp": str(spp), "seconds": str(seconds)}, **_aovs())

    assert vs.cap_for_time(timed(1.0), 64, 30.0) == 1024           # 30 s at 1/64 s per spp: 1920 -> 1024
    assert vs.cap_for_time(timed(0.001), 64, 30.0) == vs.HARD_SPP_CAP  # a fast GPU: the hard cap
    assert vs.cap_for_time(timed(100.0), 64, 30.0) == 64            # never below the least spp
    assert vs.cap_for_time(Image.from_rgb(TRUTH, {}, **_aovs()), 64, 30.0) == vs.DEFAULT_SPP_CAP


def test_cpu_render_rate_is_its_cpu_time_over_its_threads():
    """On the LLVM backend the budget reads the render's CPU time over its threads, which other
    processes sharing the cores do not inflate; its wall time (here doubled by such a load) is not
    used. On a GPU, and for an entry without those fields, the wall time is."""
    loaded = {"spp": "256", "seconds": "6.0", "render_seconds": "4.4", "render_cpu_seconds": "3.6",
              "threads": "2", "variant": "llvm_ad_rgb"}
    img = Image.from_rgb(TRUTH, loaded, **_aovs())
    assert vs.seconds_per_spp(img, 256) == pytest.approx(1.8 / 256)
    assert vs.cap_for_time(img, 256, 15.0) == 2048                 # 15 s / 7 ms -> 2133 -> 2048
    gpu = Image.from_rgb(TRUTH, {**loaded, "variant": "cuda_ad_rgb"}, **_aovs())
    assert vs.seconds_per_spp(gpu, 256) == pytest.approx(4.4 / 256)  # a GPU: the render's wall time
    old = Image.from_rgb(TRUTH, {"spp": "256", "seconds": "6.0", "variant": "llvm_ad_rgb"}, **_aovs())
    assert vs.seconds_per_spp(old, 256) == pytest.approx(6.0 / 256)  # an older cache entry: its wall time
    assert math.isnan(vs.seconds_per_spp(Image.from_rgb(TRUTH, {"seconds": "x"}, **_aovs()), 256))


def test_report_default_cap_follows_the_time_budget(monkeypatch):
    def slow_reference(scene, *, spp, **kw):
        img = fake_reference(scene, spp=spp, **kw)
        img.meta["seconds"] = str(spp / 64.0)  # 1 s per 64 spp
        return img

    monkeypatch.setattr(renderers, "render_reference", slow_reference)
    ref, v = vs.reference_for_verdict(None, [_test_image(3e-4)], spp=64, cap=None, time_budget_s=10.0)
    assert v.cap == 512 and v.spp == 512 and v.noise_limited


def test_gate_budget_noise():
    from compare.gate import BUDGET_NOISE_FACTOR, Check, CheckResult, Verdict, budget_noise, noise_note

    chk = Check(name="c", max={"relmse": 0.01, "flip_mean": 0.05, "psnr_like": 1.0}, min={}, reference="r.exr")
    noise = {"simulated": {"relmse": 0.004, "flip_mean": 0.02 * math.sqrt(2)}}
    rows = {b["metric"]: b for b in budget_noise(chk, noise, 1024)}
    assert set(rows) == {"relmse", "flip_mean"}  # a metric without a simulated noise is skipped
    # relmse: one noisy image has half the simulated pair's value (variance-like)
    assert rows["relmse"]["noise"] == pytest.approx(0.002) and rows["relmse"]["ratio"] == pytest.approx(5)
    assert rows["relmse"]["spp_needed"] == pytest.approx(2048) and not rows["relmse"]["trusted"]
    # flip: 1/sqrt(2) of the pair's value, and it falls as 1/sqrt(spp)
    assert rows["flip_mean"]["noise"] == pytest.approx(0.02) and rows["flip_mean"]["ratio"] == pytest.approx(2.5)
    assert rows["flip_mean"]["spp_needed"] == pytest.approx(1024 * (BUDGET_NOISE_FACTOR / 2.5) ** 2)
    r = CheckResult(chk, Verdict.PASS, budget_noise=tuple(rows.values()))
    note = noise_note(r)
    assert note.startswith(" (noise-limited: relmse budget 0.01 is 5x") and "at 16384 spp" in note
    assert noise_note(CheckResult(chk, Verdict.PASS, budget_noise=({**rows["relmse"], "trusted": True},))) == ""


def test_flip_and_itp_maps_are_memoized_by_content(monkeypatch):
    from compare import metrics

    calls = []
    real = metrics._flip_map
    monkeypatch.setattr(metrics, "_flip_map", lambda r, t: calls.append(1) or real(r, t))
    a = TRUTH[:8, :8].copy()
    b = a * 1.1
    m1 = metrics.flip_map(a, b)
    m2 = metrics.flip_map(a.copy(), b.copy())          # same content: no second evaluation
    np.testing.assert_array_equal(m1, m2)
    m1[0, 0] = -1.0                                     # callers get copies
    assert metrics.flip_map(a, b)[0, 0] >= 0 and len(calls) == 1
    metrics.flip_map(a, b * 1.01)                       # other content: evaluated
    assert len(calls) == 2
    e1 = metrics.delta_e_itp_map(a, b)
    np.testing.assert_array_equal(e1, metrics.delta_e_itp_map(a, b))


def test_errors_within_the_noise_do_not_set_the_spp():
    """An exact renderer (corrected MSE <= 0) cannot ever be 10x above the floor: it is left out, the
    smallest *resolved* error sets the spp; with none at all the first render stands."""
    exact = Image.from_rgb(TRUTH.copy(), {}, **_aovs())
    ref, v = vs.reference_for_verdict(None, [exact, _test_image(0.05)], spp=64, cap=4096)
    assert calls == [64, 64] and not v.noise_limited and v.smallest_error == pytest.approx(0.05, rel=0.2)
    calls.clear()
    ref, v = vs.reference_for_verdict(None, [exact], spp=64, cap=4096)
    assert calls == [64, 64] and v.smallest_error is None and not v.noise_limited
    assert "no error above it" in v.provenance()


def test_noise_and_error_equal_the_comparators_noise_floor():
    from compare.metrics import compare_images

    ref = fake_reference(None, spp=64)
    t = _test_image(2e-3)
    n = compare_images(ref, t).summary["noise"]
    floor, err = vs.noise_and_error(ref, [t])
    assert floor == pytest.approx(n["mean_variance"], rel=1e-6)
    assert err == pytest.approx(n["mse_corrected"], rel=1e-5)


def test_an_error_within_its_standard_error_does_not_set_the_spp():
    """A chance positive corrected MSE of an exact renderer (noise of the MSE estimate) is not an error."""
    ref = fake_reference(None, spp=64)
    for seed in range(20):  # exact images: corrected MSE 0 +- se; never "resolved" at 3 se
        rng = np.random.default_rng(seed)
        t = Image.from_rgb((TRUTH + 1e-6 * rng.standard_normal(TRUTH.shape)).astype(np.float32), {}, **_aovs())
        assert vs.noise_and_error(ref, [t])[1] is None


def test_the_relative_metric_weights_pixels_as_relmse_does():
    """metric="relmse": floor and error are relmse's (each pixel over r^2 + REL_EPS), so an error in
    dark pixels, lost in the absolute MSE beside a bright pixel's noise, sets the spp."""
    from compare.metrics import REL_EPS, compare_images

    img = _test_image(4e-3)
    ref = fake_reference(None, spp=64)
    f, e = vs.noise_and_error(ref, [img], metric="relmse")
    c = compare_images(ref, img, noise=False)
    w = 1.0 / (ref.rgb.astype(np.float64) ** 2 + REL_EPS)
    assert f == pytest.approx(float((ref.variance * w).mean()), rel=1e-9)
    assert e == pytest.approx(c.metrics["relmse"] - f, rel=1e-6)
    # A bright, noisy pixel column and a dark region with a small error.
    truth = np.full((H, W, 3), 0.02, np.float32)
    truth[:, :2] = 50.0

    def ref_at(scene, *, spp, seed=0, **kw):
        rng = np.random.default_rng(7 + spp)
        var = np.where(truth > 1, 400.0, 1e-4) / spp
        calls.append(spp)
        rgb = truth + np.sqrt(var) * rng.standard_normal(truth.shape)
        return Image.from_rgb(rgb.astype(np.float32), {"spp": str(spp)},
                              **{f"variance.{c}": var[..., i] for i, c in enumerate("RGB")}, **_aovs())

    renderers.render_reference = ref_at  # restored by the autouse fixture's monkeypatch
    dark_err = Image.from_rgb(np.where(truth > 1, truth, truth * 1.1).astype(np.float32), {}, **_aovs())
    _, v_abs = vs.reference_for_verdict(None, [dark_err], spp=16, cap=1 << 14)
    _, v_rel = vs.reference_for_verdict(None, [dark_err], spp=16, cap=1 << 14, metric="relmse")
    assert v_abs.smallest_error is None  # absolute: the bright pixels' noise hides the dark error
    assert v_rel.metric == "relmse" and v_rel.smallest_error is not None
    assert v_rel.noise_limited or v_rel.ratio >= vs.NOISE_FLOOR_FACTOR, v_rel
    assert "relmse" in v_rel.provenance()
    with pytest.raises(ValueError, match="verdict metric"):
        vs.noise_and_error(ref, [img], metric="flip")


def test_a_probe_looks_for_an_unresolved_error_once_more():
    """probe=16: an error hidden by the first render's noise is looked for at 16x the spp, and then
    gets its trusted spp; an exact renderer costs that one render and is "within noise"."""
    hidden = _test_image(2e-5)  # under 3 standard errors (~2e-5 each) of the 64-spp MSE estimate
    _, v0 = vs.reference_for_verdict(None, [hidden], spp=64, cap=1 << 14)
    assert v0.smallest_error is None and calls == [64, 64]
    calls.clear()
    _, v = vs.reference_for_verdict(None, [hidden], spp=64, cap=1 << 14, probe=16)
    assert calls[:2] == [64, 1024] and v.smallest_error is not None
    assert v.noise_limited or v.ratio >= vs.NOISE_FLOOR_FACTOR, v
    calls.clear()
    exact = Image.from_rgb(TRUTH.copy(), {}, **_aovs())
    _, ve = vs.reference_for_verdict(None, [exact], spp=64, cap=1 << 14, probe=16)
    assert calls == [64, 1024, 1024] and ve.smallest_error is None and not ve.noise_limited
    calls.clear()
    _, vc = vs.reference_for_verdict(None, [exact], spp=64, cap=256, probe=16)
    assert calls == [64, 256, 256]  # the probe stops at the cap; the final at the probe's spp


def test_the_returned_reference_is_not_selected_on_its_own_noise():
    """Kirk & Arvo's bias, made visible: each render's variance channel is itself an estimate
    (scaled by a random u, median 1, the image's noise scaled with it), and the error sits where one
    render in two says "10x reached". Stopping on a render keeps those whose floor came out low: the
    pilots that stopped at 64 spp have floors well below the true one. The final, rendered after the
    decision on a seed of its own, has the true floor on average."""
    sigma_u = 0.3

    def noisy_floor(scene, *, spp, seed=0, **kw):
        rng = np.random.default_rng([spp, seed])
        u = math.exp(sigma_u * rng.standard_normal())
        var = np.full((H, W, 3), u * SIGMA2 / spp)
        rgb = TRUTH + np.sqrt(var) * rng.standard_normal((H, W, 3))
        return Image.from_rgb(rgb.astype(np.float32), {"spp": str(spp)},
                              **{f"variance.{c}": var[..., i] for i, c in enumerate("RGB")}, **_aovs())

    renderers.render_reference = noisy_floor  # restored by the autouse fixture's monkeypatch
    true64 = SIGMA2 / 64
    err = _test_image(vs.NOISE_FLOOR_FACTOR * true64)  # 10x the true floor at 64 spp: borderline
    stopped_pilots, finals = [], []
    for seed in range(300):
        _, v = vs.reference_for_verdict(None, [err], spp=64, cap=4096, seed=seed)
        assert v.steps[-1][3] == "final" and v.steps[-1][0] == v.spp
        if v.spp == 64:
            stopped_pilots.append(v.steps[0][1] / true64)
            finals.append(v.noise_floor / true64)
    n = len(finals)
    assert 80 < n < 220  # about one seed in two stops at 64 spp
    # selected: E[u | u <= ~1] ~ 0.79 for log-normal u with sigma 0.3
    assert np.mean(stopped_pilots) < 0.9
    # not selected: E[u] = exp(sigma^2 / 2) = 1.046, standard error ~0.32 / sqrt(n)
    assert abs(np.mean(finals) - math.exp(sigma_u ** 2 / 2)) < 4 * 0.32 / math.sqrt(n)
