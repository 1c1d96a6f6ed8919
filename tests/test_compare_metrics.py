"""Comparator metric definitions on synthetic images with known answers, masking, noise floor."""

from __future__ import annotations

import math

import numpy as np
import pytest

from compare.metrics import (NOISE_EXPLAINS_FACTOR, REL_EPS, ComparisonError, compare_images, flip_map,
                             pixel_classes)
from pbrcheck.exr import Image

H, W = 24, 32


def const(v, h=H, w=W, **extra):
    return Image.from_rgb(np.full((h, w, 3), v, np.float32), **extra)


def pq(y_nits):
    """SMPTE ST 2084 inverse EOTF, written out independently of colour-science."""
    m1, m2, c1, c2, c3 = 2610 / 16384, 2523 / 4096 * 128, 3424 / 4096, 2413 / 4096 * 32, 2392 / 4096 * 32
    y = (y_nits / 10000.0) ** m1
    return ((c1 + c2 * y) / (1 + c3 * y)) ** m2


def test_known_answers_constant_images():
    r, t = 1.0, 1.1
    c = compare_images(const(r), const(t))
    m = c.metrics
    d = t - r
    assert c.summary["pixels"] == {"valid": H * W, "edge": 0, "background": 0}
    assert m["mean_abs"] == pytest.approx(d, rel=1e-5)
    assert m["rmse"] == pytest.approx(d, rel=1e-5)
    assert m["relmse"] == pytest.approx(d * d / (r * r + REL_EPS), rel=1e-4)
    assert m["smape"] == pytest.approx(d / (t + r + REL_EPS), rel=1e-5)
    for k in ("rel_p50", "rel_p95", "rel_p99", "rel_max"):
        assert m[k] == pytest.approx(d / (r + REL_EPS), rel=1e-5)
    # peak = 99.9th percentile of reference luminance = 1.0 for a grey of 1.0
    assert m["psnr"] == pytest.approx(10 * math.log10(1.0 / (d * d)), rel=1e-4)
    # grey: Rec.2020 grey, L = M = S, so I = PQ(Y), Ct = Cp = 0 and dE = 720 |dI|
    expected_de = 720 * abs(pq(110.0) - pq(100.0))
    assert m["delta_e_itp_mean"] == pytest.approx(expected_de, rel=1e-3)
    assert m["delta_e_itp_p95"] == pytest.approx(expected_de, rel=1e-3)
    assert 0 < m["flip_mean"] < 1


def test_identical_images_have_zero_error():
    rng = np.random.default_rng(1)
    img = Image.from_rgb(rng.random((H, W, 3)).astype(np.float32) * 3)
    m = compare_images(img, img).metrics
    for k in ("mean_abs", "rmse", "relmse", "smape", "rel_max", "flip_mean", "delta_e_itp_mean"):
        assert m[k] == pytest.approx(0.0, abs=1e-7), k
    assert math.isinf(m["psnr"])


def test_relative_percentiles_follow_definition():
    rng = np.random.default_rng(2)
    r = rng.random((H, W, 3)).astype(np.float32) + 0.1
    t = r * (1 + rng.random((H, W, 3)).astype(np.float32) * 0.3)
    m = compare_images(Image.from_rgb(r), Image.from_rgb(t)).metrics
    rel = np.abs(t.astype(np.float64) - r) / (r + REL_EPS)
    assert m["rel_p50"] == pytest.approx(np.percentile(rel, 50), rel=1e-6)
    assert m["rel_p95"] == pytest.approx(np.percentile(rel, 95), rel=1e-6)
    assert m["rel_max"] == pytest.approx(rel.max(), rel=1e-6)
    assert m["relmse"] == pytest.approx(np.mean((t - r.astype(np.float64)) ** 2 / (r.astype(np.float64) ** 2 + REL_EPS)), rel=1e-5)


def test_black_and_constant_reference_do_not_kill_flip():
    # flip-evaluator exits the process when its exposure range is empty; we must not.
    z = np.zeros((8, 8, 3), np.float32)
    assert float(flip_map(z, z).max()) == 0.0
    assert flip_map(z, z + 0.5).shape == (8, 8)
    assert flip_map(z + 1, z + 1).max() == 0.0


def aov_images():
    """Left 8 columns background, column 8 half covered (edge), object 0 in 9..19, object 1 after."""
    obj = np.zeros((H, W), np.float32)
    obj[:, :8] = -1
    obj[:, 20:] = 1
    cov = np.ones((H, W), np.float32)
    cov[:, :8] = 0
    cov[:, 8] = 0.5
    return obj, cov


def test_masking_excludes_background_and_silhouettes():
    obj, cov = aov_images()
    r = np.full((H, W, 3), 0.5, np.float32)
    t = r.copy()
    t[:, :9] = 5.0  # wildly wrong, but only on background and edge pixels
    c = compare_images(Image.from_rgb(r, object=obj, coverage=cov), Image.from_rgb(t, object=obj, coverage=cov))
    assert c.summary["pixels"] == {"valid": H * 23, "edge": H, "background": H * 8}
    assert c.metrics["mean_abs"] == 0.0
    assert c.metrics["rel_max"] == 0.0


def test_masking_with_aovs_on_one_side_only_and_object_disagreement():
    obj, cov = aov_images()
    ref = Image.from_rgb(np.ones((H, W, 3), np.float32), object=obj, coverage=cov)
    test = const(1.0)  # no AOVs: the reference's classes are used
    valid, edge, bg = pixel_classes(ref, test)
    assert (valid.sum(), edge.sum(), bg.sum()) == (H * 23, H, H * 8)
    obj2 = obj.copy()
    obj2[:, 20:22] = 0  # the test sees object 0 where the reference sees object 1
    valid, edge, bg = pixel_classes(ref, Image.from_rgb(np.ones((H, W, 3), np.float32), object=obj2, coverage=cov))
    assert (valid.sum(), edge.sum(), bg.sum()) == (H * 21, H * 3, H * 8)
    # neither image has AOVs: every pixel counts
    assert pixel_classes(const(1.0), const(2.0))[0].all()


def test_per_object_breakdown_and_ndotv_bins():
    obj, cov = aov_images()
    ndv = np.tile(np.linspace(0.0, 1.0, W, dtype=np.float32), (H, 1))
    r = np.full((H, W, 3), 1.0, np.float32)
    t = r.copy()
    t[:, 20:] = 1.2  # object 1 is 20 % too bright, object 0 exact
    c = compare_images(Image.from_rgb(r, object=obj, coverage=cov, NdotV=ndv),
                       Image.from_rgb(t, object=obj, coverage=cov, NdotV=ndv))
    objs = {o["id"]: o for o in c.summary["objects"]}
    assert set(objs) == {0, 1}
    assert objs[0]["metrics"]["mean_abs"] == 0.0
    assert objs[1]["metrics"]["mean_abs"] == pytest.approx(0.2, rel=1e-5)
    assert c.worst_objects("relmse", 1)[0]["id"] == 1
    bins = c.summary["ndotv"]
    assert len(bins) == 10 and sum(b["pixels"] for b in bins) == c.summary["pixels"]["valid"]
    # the high-NdotV bins are all object 1 (columns 20+), the mid ones object 0
    assert bins[-1]["metrics"]["mean_abs"] == pytest.approx(0.2, rel=1e-5)
    assert bins[4]["metrics"]["mean_abs"] == 0.0


def _noisy_pair(bias=1.0, sigma=0.03, seed=3):
    rng = np.random.default_rng(seed)
    h, w = 64, 64
    truth = (rng.random((h, w, 3)) * 2 + 0.2).astype(np.float32)
    var = np.full((h, w, 3), sigma * sigma, np.float32)
    ref = truth + rng.standard_normal(truth.shape).astype(np.float32) * sigma
    ind = truth + rng.standard_normal(truth.shape).astype(np.float32) * sigma  # independent render
    vch = {f"variance.{c}": var[..., i] for i, c in enumerate("RGB")}
    return Image.from_rgb(ref, **vch), Image.from_rgb(ind * bias, **vch), sigma * sigma


def test_independent_render_is_within_noise():
    ref, test, var = _noisy_pair()
    c = compare_images(ref, test)
    n = c.summary["noise"]
    assert n["mean_variance"] == pytest.approx(var, rel=1e-5)
    # two independent renders differ by noise of variance 2 var: corrected MSE ~ var
    assert n["mse_corrected"] == pytest.approx(n["mse"] - var)
    assert n["mse"] == pytest.approx(2 * var, rel=0.1)
    assert n["factor"] == NOISE_EXPLAINS_FACTOR
    assert all(n["within_noise"].values()), n["within_noise"]


def test_biased_image_is_not_within_noise():
    ref, test, _ = _noisy_pair(bias=1.1)
    flags = compare_images(ref, test).summary["noise"]["within_noise"]
    for k in ("mean_abs", "rmse", "relmse", "smape", "rel_p50", "psnr", "flip_mean", "delta_e_itp_mean"):
        assert not flags[k], k


def test_no_variance_means_no_noise_section():
    assert compare_images(const(1.0), const(1.1)).summary["noise"] is None


@pytest.mark.parametrize("case, message", [
    ("size", "size mismatch"),
    ("nan", "NaN"),
    ("missing", "missing channel"),
    ("novalid", "no valid pixel"),
])
def test_comparison_errors(case, message):
    ref, test = const(1.0), const(1.0)
    if case == "size":
        test = const(1.0, h=H + 1)
    elif case == "nan":
        a = np.ones((H, W, 3), np.float32)
        a[3, 4, 1] = np.nan
        test = Image.from_rgb(a)
    elif case == "missing":
        test = Image({"R": np.ones((H, W)), "G": np.ones((H, W))})
    else:
        ref = const(1.0, object=np.full((H, W), -1, np.float32), coverage=np.zeros((H, W), np.float32))
    with pytest.raises(ComparisonError, match=message):
        compare_images(ref, test)
