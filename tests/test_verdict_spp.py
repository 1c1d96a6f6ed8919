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
    return Image.from_rgb(rgb.astype(np.float32), {"spp": str(spp)},
                          **{f"variance.{c}": var[..., i] for i, c in enumerate("RGB")}, **_aovs())


def _test_image(mse):
    """A noise-free image whose squared error against the truth is ``mse``."""
    return Image.from_rgb((TRUTH + math.sqrt(mse)).astype(np.float32), {}, **_aovs())


calls: list = []


@pytest.fixture(autouse=True)
def fake(monkeypatch):
    calls.clear()
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


def test_enough_already_renders_once():
    ref, v = vs.reference_for_verdict(None, [_test_image(0.05)], spp=64)
    assert calls == [64] and v.spp == 64 and not v.noise_limited


def test_stops_at_the_cap_and_says_noise_limited():
    ref, v = vs.reference_for_verdict(None, [_test_image(1e-5)], spp=64, cap=512)
    assert v.noise_limited and v.spp == 512 and calls[-1] == 512
    assert "NOISE-LIMITED at the cap of 512 spp" in v.provenance()
    d = v.to_dict()
    assert d["noise_limited"] is True and d["spp"] == 512 and d["factor"] == vs.NOISE_FLOOR_FACTOR
