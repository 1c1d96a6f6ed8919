"""Heavy tails: a noise floor carried by a few pixels (a small bright source's glints, caught by one
replicate here and by none there) is not trusted to choose the reference's spp (compare.verdict_spp,
``floor_tail_rse`` and ``FLOOR_RSE_MAX``).

* the bound itself (Kish's effective number of pixels, the replicates' degrees of freedom);
* a simulated tiny bright source with a known truth: the old rule trusts a 16-spp reference whose
  actual error is many times its floor; the new one doubles to the cap and says "heavy tails";
* a real render of a test-built scene (a 0.6-degree sun of radiance 3e4 over the spheres grid, a
  mirror among them): the same, through Mitsuba; and the calibrated CI scene (spheres_ci) at the
  gate's spp, whose decisions are the same with and without the check.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

import compare.renderers as renderers
from compare import verdict_spp as vs
from pbrcheck.exr import Image, read_exr

ROOT = Path(__file__).resolve().parents[1]
H, W = 30, 40


def _aovs(h=H, w=W):
    return {"coverage": np.ones((h, w)), "object": np.zeros((h, w)), "N.X": np.zeros((h, w)),
            "N.Y": np.zeros((h, w)), "N.Z": np.ones((h, w)), "NdotV": np.ones((h, w))}


def _image(rgb, var, meta):
    return Image.from_rgb(rgb.astype(np.float32), meta,
                          **{f"variance.{c}": var[..., i].astype(np.float32) for i, c in enumerate("RGB")}, **_aovs())


def test_floor_tail_rse_is_kish_and_the_replicates_dof():
    rgb = np.full((H, W, 3), 0.5)
    even = _image(rgb, np.full((H, W, 3), 1e-3), {"spp": "64", "replicates": "16"})
    assert vs.variance_dof(even) == 15
    assert vs.floor_tail_rse(even, [even]) == pytest.approx(math.sqrt(2 / (15 * H * W)))
    one = np.zeros((H, W, 3))
    one[3, 4] = 1.0  # one pixel carries the floor: n_eff = 1
    single = _image(rgb, one, {"spp": "16", "replicates": "8"})
    assert vs.floor_tail_rse(single, [single]) == pytest.approx(math.sqrt(2 / 7))
    adaptive = _image(rgb, one, {"spp": "256", "replicates": "16 or 32 by level"})
    assert vs.variance_dof(adaptive) == 15
    assert vs.variance_dof(_image(rgb, one, {"spp": "32"})) == 31  # independent: spp - 1


# A simulated tiny bright source: GLINTS pixels each see it over a share P of their samples, with
# radiance A (a sub-pixel highlight of a sun); the rest is a smooth base with Gaussian noise.
GLINTS = [(y, x) for y in (5, 12, 20, 27) for x in (6, 19, 33)]
P, A = 0.01, 2000.0
BASE = 0.4
SIGMA = 0.2  # per-sample deviation of the base


def _truth():
    t = np.full((H, W, 3), BASE)
    for y, x in GLINTS:
        t[y, x] += P * A
    return t


def fake_glint_reference(scene, *, spp, seed=0, **kw):
    """K replicates of n samples (K = spp / 2 below 32 spp, else 16, as reference.integrator's plan)."""
    rng = np.random.default_rng([spp, seed])
    K = spp // 2 if spp < 32 else 16
    n = spp // K
    Y = BASE + SIGMA / math.sqrt(n) * rng.standard_normal((K, H, W, 1)) * np.ones(3)
    for y, x in GLINTS:
        Y[:, y, x] += A * rng.binomial(n, P, K)[:, None] / n
    rgb, var = Y.mean(0), Y.var(0, ddof=1) / K
    fake_glint_reference.calls.append(spp)
    return _image(rgb, var, {"spp": str(spp), "replicates": str(K)})


@pytest.fixture
def glints(monkeypatch):
    fake_glint_reference.calls = []
    monkeypatch.setattr(renderers, "render_reference", fake_glint_reference)


def test_a_tiny_bright_source_is_not_trusted(glints, monkeypatch):
    truth = _truth()
    engine = Image.from_rgb((truth * 1.05).astype(np.float32), {}, **_aovs())  # a 5 % error
    # Before: the pilot (16 spp) misses the glints, its floor is the base's, and it decides.
    monkeypatch.setattr(vs, "FLOOR_RSE_MAX", math.inf)
    old, v_old = vs.reference_for_verdict(None, [engine], spp=16, cap=1024, seed=3)
    assert v_old.spp == 16 and not v_old.noise_limited  # "trusted"
    actual = float(((old.rgb.astype(np.float64) - truth) ** 2).mean())
    assert actual > 10 * v_old.noise_floor  # ... but the reference is off by far more than its error bars
    # After: the floor's relative standard error is far above FLOOR_RSE_MAX: the pilot doubles.
    monkeypatch.undo()
    monkeypatch.setattr(renderers, "render_reference", fake_glint_reference)
    fake_glint_reference.calls = []
    ref, v = vs.reference_for_verdict(None, [engine], spp=16, cap=64, seed=3)
    assert fake_glint_reference.calls == [16, 32, 64, 64] and v.spp == 64
    assert v.heavy_tails and v.noise_limited and v.floor_rse > vs.FLOOR_RSE_MAX
    assert "NOISE-LIMITED (heavy tails)" in v.provenance()
    # tails=False (the research commands): the old rule, no bound computed.
    _, v_off = vs.reference_for_verdict(None, [engine], spp=16, cap=64, seed=3, tails=False)
    assert v_off.spp == 16 and v_off.floor_rse is None and not v_off.heavy_tails
    # With room to grow it goes on until the glints are sampled well enough to trust the floor.
    fake_glint_reference.calls = []
    ref, v = vs.reference_for_verdict(None, [engine], spp=16, cap=1 << 14, seed=3)
    assert v.spp > 64 and not v.heavy_tails and v.floor_rse <= vs.FLOOR_RSE_MAX
    actual = float(((ref.rgb.astype(np.float64) - truth) ** 2).mean())
    assert actual < 3 * v.noise_floor  # honest error bars: the floor predicts the actual error


def _sun_scene():
    from pbrcheck.scene import scene_from_dict
    return scene_from_dict({
        "name": "tiny_sun",
        "camera": {"origin": [0, 0, 10], "fov": 36, "width": 40, "height": 32},
        "environment": {"type": "sky", "sun_direction": [0.4, 0.6, 0.7], "sun_angular_diameter": 0.6,
                        "sun_radiance": [3e4, 3e4, 3e4], "sky_radiance": [0.25, 0.4, 0.8], "resolution": [512, 256]},
        "objects": [{"type": "sphere_grid", "name": "grid", "center": [0, 0, 0], "rows": 5, "columns": 6,
                     "radius": 0.45, "spacing": 1.0, "metallic": [0.0, 1.0], "roughness": [0.0, 1.0],
                     "material": {"base_color": [0.9, 0.6, 0.3]}}]})


def _engine(ref: Image, scale: float) -> Image:
    """A noise-free stand-in for a renderer under test: ``ref``'s radiance times ``scale``."""
    return Image.from_rgb((ref.rgb * scale).astype(np.float32), {},
                          **{k: ref.channels[k] for k in ("coverage", "object", "N.X", "N.Y", "N.Z", "NdotV")})


def test_real_render_tiny_sun_is_heavy_tailed_and_calibrated_scene_unchanged(tmp_cache, monkeypatch):
    pytest.importorskip("mitsuba")
    sc = _sun_scene()
    engine = _engine(renderers.render_reference(sc, spp=64, seed=11, progress=False), 1.05)
    monkeypatch.setattr(vs, "FLOOR_RSE_MAX", math.inf)
    _, v_old = vs.reference_for_verdict(sc, [engine], spp=16, cap=64)
    assert v_old.spp == 16 and not v_old.noise_limited  # the old rule trusts 16 spp
    monkeypatch.setattr(vs, "FLOOR_RSE_MAX", 0.15)
    assert vs.FLOOR_RSE_MAX == 0.15
    _, v = vs.reference_for_verdict(sc, [engine], spp=16, cap=64)
    # The 16- and 32-spp pilots' floors rest on a few pixels (measured: relative standard error >= 0.25):
    # the pilot doubles to the cap; the final is reported with its own bound.
    assert [s[0] for s in v.steps] == [16, 32, 64, 64] and v.spp == 64 and v.floor_rse is not None
    assert v.heavy_tails == (v.floor_rse > vs.FLOOR_RSE_MAX) and v.noise_limited == v.heavy_tails
    # The calibrated CI scene at 64 spp: the same decisions with and without the check.
    from pbrcheck.scene import load_scene
    ci = load_scene(ROOT / "compare" / "budgets" / "spheres_ci.toml")
    conv = read_exr(ROOT / "compare" / "budgets" / "refs" / "spheres_ci.exr")  # 32768 spp
    tests = [_engine(conv, 1.02)]
    _, v_new = vs.reference_for_verdict(ci, tests, spp=64, cap=256)
    monkeypatch.setattr(vs, "FLOOR_RSE_MAX", math.inf)
    _, v_old = vs.reference_for_verdict(ci, tests, spp=64, cap=256)
    assert [s[0] for s in v_new.steps] == [s[0] for s in v_old.steps] and v_new.spp == v_old.spp
    assert not v_new.heavy_tails and v_new.floor_rse <= 0.15
