"""``pbrcheck_reference`` through ``mi.render``: same pixels as the version-1 renderer within noise,
passes only where memory requires them, and derivatives through ``mi.render``."""

from __future__ import annotations

import numpy as np
import pytest

import pbrcheck  # noqa: F401
from pbrcheck.scene import scene_from_dict
from reference.variant import ensure_variant

ensure_variant()
from reference import integrator as ri  # noqa: E402  (needs the variant set)
from reference import render as rr  # noqa: E402
from reference.render import _mi, render_uncached  # noqa: E402

from legacy_reference import legacy_render  # noqa: E402
from same_samples import assert_same_samples, on_cuda  # noqa: E402

# Two independent estimates agree per pixel within Z standard deviations (5 sigma: < 1e-3 false
# alarms over the ~1000 pixel-channels of these scenes).
Z = 5.0
SKY = {"type": "sky", "sun_direction": [0.3, 0.8, 0.5], "sun_angular_diameter": 20.0,
       "sun_radiance": [4, 4, 3.5], "resolution": [128, 64]}
LIGHT = {"type": "point", "position": [2.0, 2.0, 3.0], "intensity": [3.0, 3.0, 3.0]}


def _scene(roughness=0.4, metallic=0.5, size=24):
    return scene_from_dict({
        "camera": {"origin": [0, 0.5, 4], "fov": 40, "width": size, "height": size - 4},
        "environment": SKY, "lights": [LIGHT],
        "objects": [{"type": "sphere", "radius": 1.0,
                     "material": {"base_color": [0.8, 0.5, 0.3], "metallic": metallic, "roughness": roughness}},
                    {"type": "plane", "center": [0, -1, 0], "normal": [0, 1, 0], "size": [6, 6],
                     "material": {"base_color": [0.5, 0.5, 0.5], "roughness": 0.7}}]})


def _z_agree(a_mean, a_var, b_mean, b_var, atol=1e-5):
    d = np.abs(a_mean - b_mean)
    sd = np.sqrt(a_var + b_var)
    assert np.all(d <= Z * sd + atol), float((d - Z * sd).max())


@pytest.mark.parametrize("mode,rough", [("local", 0.4), ("local", 0.0), ("path", 0.4)])
def test_same_pixels_as_the_version_1_renderer(mode, rough):
    scene = _scene(roughness=rough)
    # Mitsuba's environment sampling, as the version 1 renderer (so the per-sample variances agree)
    new = render_uncached(scene, spp=64, mode=mode, max_depth=3, seed=1, progress=False, sampler="independent",
                          env_sampling="envmap")
    m, v, c = legacy_render(scene, spp=64, mode=mode, max_depth=3, seed=2)
    _z_agree(new.rgb, new.variance, m, v)
    # the variance estimates agree too (pooled over the image: a few percent at 64 spp)
    ratio = new.variance.mean() / v.mean()
    assert 0.85 < ratio < 1.15, ratio
    assert abs(new.channels["coverage"].mean() - c.mean()) < 0.02
    # the qmc sampler (replicates) and MIS compensation (the defaults): the same pixels within its
    # own noise, and less of it
    q = render_uncached(scene, spp=64, mode=mode, max_depth=3, seed=3, progress=False, sampler="qmc")
    _z_agree(q.rgb, q.variance, m, v)
    assert q.variance.mean() < new.variance.mean()
    assert abs(q.channels["coverage"].mean() - c.mean()) < 0.02
    assert q.meta["sampler"] == "qmc" and q.meta["replicates"] == "16"
    assert new.meta["reference_code_version"] == rr.REFERENCE_CODE_VERSION != "1"
    assert new.meta["integrator"].startswith("mi.render")


def test_pass_sizes():
    assert ri.pass_sizes(64, 100, lanes=6400) == [64]
    assert ri.pass_sizes(64, 100, lanes=3200) == [32, 32]
    assert ri.pass_sizes(10, 100, lanes=400) == [4, 3, 3]
    assert ri.pass_sizes(5, 10_000, lanes=10) == [1] * 5  # at least one sample per pass
    for spp, npix, lanes in ((1000, 7, 300), (3, 1, 1 << 40), (1024, 108_000, 1 << 26)):
        p = ri.pass_sizes(spp, npix, lanes=lanes)
        assert sum(p) == spp and max(p) - min(p) <= 1 and max(p) * npix <= max(lanes, npix)
    assert ri.pass_sizes(1 << 20, 1 << 16, lanes=1 << 40)[0] * (1 << 16) < 1 << 32  # Mitsuba's limit
    assert ri.max_lanes() in ri.MAX_LANES.values()


def test_passes_only_where_memory_requires_them(monkeypatch):
    scene = _scene(size=16)
    one = render_uncached(scene, spp=24, seed=3, progress=False, sampler="independent")
    assert one.meta["passes"] == "1"
    monkeypatch.setitem(ri.MAX_LANES, "llvm", 16 * 12 * 7)
    monkeypatch.setitem(ri.MAX_LANES, "cuda", 16 * 12 * 7)
    done = []
    real = ri.ReferenceIntegrator.render

    def spy(self, *a, **k):
        self.progress = (lambda n, p=self.progress: (done.append(n), p and p(n)))
        return real(self, *a, **k)

    monkeypatch.setattr(ri.ReferenceIntegrator, "render", spy)
    many = render_uncached(scene, spp=24, seed=4, progress=False, sampler="independent")
    assert many.meta["passes"] == "4" and done == [6, 6, 6, 6]
    _z_agree(one.rgb, one.variance, many.rgb, many.variance)
    ratio = many.variance.mean() / one.variance.mean()
    assert 0.8 < ratio < 1.25, ratio
    np.testing.assert_array_equal(one.channels["NdotV"], many.channels["NdotV"])


@pytest.mark.parametrize("lanes", [16 * 12 * 4, 16 * 12 * 2])
def test_qmc_replicates_share_wavefronts_or_split(monkeypatch, lanes):
    """qmc: all 16 replicates in one pass where memory allows; else a pass per replicate (lanes =
    pixels x 4), or a replicate split over passes with ``advance`` (pixels x 2): the same pixels
    within noise, progress summing to the spp."""
    scene = _scene(size=16)
    assert ri.replicate_plan(64) == (16, 4)
    one = render_uncached(scene, spp=64, seed=3, progress=False, sampler="qmc", adaptive=False)
    monkeypatch.setitem(ri.MAX_LANES, "llvm", lanes)
    monkeypatch.setitem(ri.MAX_LANES, "cuda", lanes)
    done = []
    real = ri.ReferenceIntegrator.render_groups

    def spy(self, *a, **k):
        self.progress = (lambda n, p=self.progress: (done.append(n), p and p(n)))
        return real(self, *a, **k)

    monkeypatch.setattr(ri.ReferenceIntegrator, "render_groups", spy)
    many = render_uncached(scene, spp=64, seed=4, progress=False, sampler="qmc", adaptive=False)
    assert len(done) == (16 if lanes == 16 * 12 * 4 else 32) and abs(sum(done) - 64) < 1e-9
    _z_agree(one.rgb, one.variance, many.rgb, many.variance)
    ratio = many.variance.mean() / one.variance.mean()
    assert 0.7 < ratio < 1.4, ratio
    assert abs(one.channels["coverage"].mean() - many.channels["coverage"].mean()) < 0.02


def test_replicate_plan_and_adaptive_allocation():
    assert [ri.replicate_plan(s) for s in (2, 4, 16, 64, 128, 256, 1024, 2048, 4096)] == [
        (2, 1), (2, 2), (8, 2), (16, 4), (16, 8), (16, 16), (16, 64), (32, 64), (16, 256)]
    assert ri.replicate_plan(1000) == (1000, 1)  # no multijitter count fits: independent samples
    for spp in (64, 256, 4096):
        K, n = ri.replicate_plan(spp)
        assert K * n == spp and K >= 2 and ri.multijitter_count_ok(n)
    # Neyman (defensive, dilated): pixels with 4x the standard deviation get more spp, every pixel at least
    # half the mean (rr.ADAPTIVE_DEFENSIVE), the mean within the budget, each spp a level
    mean = np.full((4, 8, 3), 0.5)
    var = np.full((4, 8, 3), 1e-4)
    var[0, :4] *= 16.0
    alloc = rr.adaptive_allocation(mean, var, 32, 256)
    assert 128 < alloc.mean() <= 256
    assert set(alloc.tolist()) <= set(rr.adaptive_levels(256))
    a = alloc.reshape(4, 8)  # the high pixels and their neighbours (dilated by one pixel) get more
    assert np.all(a[2:] == a[2:].min()) and a.min() == a[2:].min() >= rr.ADAPTIVE_DEFENSIVE * 256
    assert np.all(a[:2, :5] >= 2 * a.min()) and np.all(a[:, 6:] == a.min())
    assert rr.adaptive_levels(256) == [32, 64, 128, 256, 512, 1024, 2048, 4096, 8192, 16384]
    for lv in rr.adaptive_levels(4096):
        K, n = ri.replicate_plan(lv)
        assert K in (16, 32) and K * n == lv
    # a pilot without variance (a constant image): uniform
    assert np.all(rr.adaptive_allocation(mean, 0 * var, 32, 256) == 256)


def test_film_render_equals_moments_mean():
    """moments = False (what AD uses) is Mitsuba's film: the same estimator and samples."""
    mi, dr = _mi()
    scene = _scene(size=16)
    ms = rr.load_mitsuba_scene(scene)
    sensor = mi.load_dict(ri.sensor_dict(scene.camera, 16))
    a = np.array(mi.render(ms, sensor=sensor, integrator=rr.load_integrator("local", moments=False),
                           spp=16, seed=5))
    b = np.array(mi.render(ms, sensor=sensor, integrator=rr.load_integrator("local"), spp=16, seed=5))
    assert a.shape == (12, 16, 3) and b.shape == (12, 16, len(ri.MOMENT_CHANNELS))
    np.testing.assert_allclose(a, b[..., :3], rtol=1e-4, atol=1e-5)


@pytest.mark.parametrize("candidates", [1, 4])
def test_gradient_through_mi_render_matches_finite_differences(candidates):
    """d mean(image) / d roughness and d / d base_color of the local integrator under mi.render
    (and with the env sample resampled from 4 candidates: detached selection, ``ri.resampled_estimate``)."""
    mi, dr = _mi()
    scene = _scene(size=16, roughness=0.4)
    d = rr.scene_dict(scene)
    d["sensor"] = ri.sensor_dict(scene.camera, 64)
    d["integrator"] = {"type": ri.INTEGRATOR_NAME, "mode": "local", "env_candidates": candidates}
    ms = mi.load_dict(d)
    params = mi.traverse(ms)
    spp = 256

    def mean_img(seed):
        return float(np.mean(np.array(mi.render(ms, params, spp=spp, seed=seed))))

    for key, h in (("object0.bsdf.roughness", 0.02), ("object0.bsdf.metallic", 0.05)):
        x0 = float(params[key][0])
        dr.enable_grad(params[key])
        params.update()
        img = mi.render(ms, params, spp=spp, seed=7)
        dr.backward(dr.mean(img, axis=None))
        g = float(np.array(dr.grad(params[key]))[0])
        dr.disable_grad(params[key])
        vals = []
        for s in (+1, -1):
            params[key] = mi.Float(x0 + s * h)
            params.update()
            vals.append(mean_img(11))  # common random numbers: the same samples both sides
        params[key] = mi.Float(x0)
        params.update()
        fd = (vals[0] - vals[1]) / (2 * h)
        assert abs(g - fd) <= 0.1 * abs(fd) + 2e-3, (key, g, fd)
        assert abs(fd) > 1e-3, (key, fd)  # not vacuous


# ---- the gathered materials (reference.bsdf.MaterialView) -----------------------------------------

def _render_both(scene, spp=16, seed=3):
    mi, _ = _mi()
    ms = rr.load_mitsuba_scene(scene)
    sensor = mi.load_dict(ri.sensor_dict(scene.camera, spp))
    out = []
    for gather in (False, True):
        integ = mi.load_dict({"type": ri.INTEGRATOR_NAME, "mode": "local", "moments": True,
                              "gather_materials": gather})
        out.append(np.array(mi.render(ms, sensor=sensor, integrator=integ, spp=spp, seed=seed)))
    return out


@pytest.mark.parametrize("name,multiscatter", [("spheres", "none"), ("furnace", "none"), ("furnace", "random_walk")])
def test_gathered_materials_give_the_per_instance_pixels(name, multiscatter):
    """The same lobes and the same random numbers as Mitsuba's per-material dispatch: equal pixels
    up to float rounding, mirror-limit and glossy materials mixed (spheres: 30 materials with a
    roughness-0 column; furnace: roughness 0 ... 1, with and without the random walk)."""
    from dataclasses import replace

    from pbrcheck.scene import load_scene

    scene = load_scene(name).with_camera(width=48, height=24)
    scene = replace(scene, brdf=replace(scene.brdf, multiscatter=multiscatter))
    per_instance, gathered = _render_both(scene)
    assert np.isfinite(gathered).all()
    # channels R, G, B, variance.R/G/B, coverage (ri.MOMENT_CHANNELS); CUDA: tests/same_samples.py
    assert_same_samples(gathered[..., :3], per_instance[..., :3], gathered[..., 3:6], per_instance[..., 3:6],
                        rtol=2e-5, atol=2e-6)
    if not on_cuda():
        np.testing.assert_allclose(gathered, per_instance, rtol=2e-5, atol=2e-6)


def test_gathered_materials_carry_each_instances_gradient():
    """d mean(image) / d parameter through the gather equals the per-instance dispatch's, for every
    object (the scatter into the tables routes each gradient to its own instance)."""
    mi, dr = _mi()
    scene = _scene(size=16, roughness=0.4)
    grads = {}
    for gather in (False, True):
        d = rr.scene_dict(scene)
        d["sensor"] = ri.sensor_dict(scene.camera, 16)
        d["integrator"] = {"type": ri.INTEGRATOR_NAME, "mode": "local", "gather_materials": gather}
        ms = mi.load_dict(d)
        params = mi.traverse(ms)
        keys = ["object0.bsdf.roughness", "object1.bsdf.roughness", "object0.bsdf.base_color"]
        for k in keys:
            dr.enable_grad(params[k])
        params.update()
        img = mi.render(ms, params, spp=32, seed=7)
        dr.backward(dr.mean(img, axis=None))
        grads[gather] = [np.array(dr.grad(params[k])).ravel() for k in keys]
    for a, b in zip(grads[False], grads[True]):
        assert np.all(np.abs(a) > 0), a  # not vacuous
        np.testing.assert_allclose(b, a, rtol=1e-4, atol=1e-7)


def test_a_scene_with_another_bsdf_falls_back_to_per_instance_dispatch():
    from reference.bsdf import MaterialView

    mi, _ = _mi()
    d = rr.scene_dict(_scene(size=12))
    d["object1"]["bsdf"] = {"type": "diffuse"}
    ms = mi.load_dict(d)
    assert MaterialView.table(ms) is None
    img = np.array(mi.render(ms, sensor=mi.load_dict(ri.sensor_dict(_scene(size=12).camera, 4)),
                             integrator=rr.load_integrator("local"), spp=4))
    assert np.isfinite(img).all() and img[..., :3].max() > 0
    assert MaterialView.table(rr.load_mitsuba_scene(_scene(size=12))) is not None


def test_one_integrator_renders_two_scenes_each_with_its_own_materials():
    """The material table is per scene: an integrator object reused across scenes (as a cached one
    would be) gives each scene the pixels a fresh integrator gives it."""
    mi, _ = _mi()
    a, b = _scene(size=12, roughness=0.2, metallic=1.0), _scene(size=12, roughness=0.8, metallic=0.0)
    sensor = mi.load_dict(ri.sensor_dict(a.camera, 8))
    shared = rr.load_integrator("local")
    out = {}
    for name, sc in (("a", a), ("b", b), ("a2", a)):
        ms = rr.load_mitsuba_scene(sc)
        out[name] = np.array(mi.render(ms, sensor=sensor, integrator=shared, spp=8, seed=1))
        fresh = np.array(mi.render(ms, sensor=sensor, integrator=rr.load_integrator("local"), spp=8, seed=1))
        np.testing.assert_allclose(out[name], fresh, rtol=1e-5, atol=1e-6)
    assert not np.allclose(out["a"][..., :3], out["b"][..., :3])


def test_cache_key_names_the_sampler_and_adaptive():
    scene = _scene(size=12)
    k = lambda **kw: rr.reference_cache_key(scene, spp=kw.pop("spp", 256), mode="local", seed=0, max_depth=None, **kw)  # noqa: E731
    assert rr.DEFAULT_SAMPLER == "qmc" and rr.DEFAULT_ADAPTIVE
    assert k() == k(sampler="qmc", adaptive=True)
    assert len({k(sampler="independent"), k(sampler="qmc", adaptive=False), k(sampler="qmc", adaptive=True)}) == 3
    # below ADAPTIVE_MIN_SPP an adaptive render is the uniform one: one entry
    assert k(spp=64, adaptive=True) == k(spp=64, adaptive=False)
    assert k(sampler="independent", adaptive=True) == k(sampler="independent", adaptive=False)
    with pytest.raises(ValueError, match="sampler"):
        k(sampler="sobol")


@pytest.mark.parametrize("rough,option", [(0.4, {"mis": "balance"}), (0.05, {"mis": "balance"}),
                                          (0.4, {"env_sampling": "envmap"}), (0.05, {"env_sampling": "envmap"})])
def test_measured_candidates_estimate_the_same_pixels(rough, option):
    """``mis = "balance"`` (a measured candidate, not the default) and ``env_sampling = "envmap"``
    (Mitsuba's environment sampling, the default's predecessor against MIS compensation): other
    weightings or proposals of the same integral, so the same image within noise; an unknown name
    is refused."""
    scene = _scene(roughness=rough)
    a = render_uncached(scene, spp=64, seed=5, progress=False, sampler="independent", adaptive=False)
    b = render_uncached(scene, spp=64, seed=6, progress=False, sampler="independent", adaptive=False, **option)
    _z_agree(a.rgb, a.variance, b.rgb, b.variance)
    assert 0.5 < b.variance.mean() / a.variance.mean() < 2.0
    assert not np.array_equal(a.rgb, render_uncached(scene, spp=64, seed=5, progress=False, sampler="independent",
                                                     adaptive=False, **option).rgb)  # the switch is live
    with pytest.raises(ValueError, match="mis must be one of"):
        rr.load_integrator("local", mis="cutoff")
    with pytest.raises(ValueError, match="env_sampling must be one of"):
        rr.load_integrator("local", env_sampling="product")


@pytest.mark.parametrize("sampler", ["qmc", "independent"])
def test_a_scene_that_cannot_emit_renders_black(sampler):
    # A black environment and no light: the estimator folds to a width-1 literal zero, which the
    # replicate passes once failed to reshape per pixel (a traceback instead of a black image).
    scene = scene_from_dict({
        "camera": {"origin": [0, 0, 4], "fov": 40, "width": 12, "height": 8},
        "environment": {"type": "constant", "radiance": [0.0, 0.0, 0.0]},
        "objects": [{"type": "sphere", "radius": 1.0}]})
    img = render_uncached(scene, spp=4, sampler=sampler, progress=False)
    for c in ("R", "G", "B", "variance.R"):
        assert np.all(img.channels[c] == 0.0)
    assert img.channels["coverage"].max() == 1.0 and img.channels["coverage"].min() == 0.0


def test_resampled_env_sample_estimates_the_same_pixels():
    """``env_candidates = M`` (RIS of the environment sample, ``ri.resampled_estimate``): one
    candidate is the default estimator itself, sample for sample; four estimate the same image
    within noise, under a sun (the compensated proposal) and Mitsuba's own proposal; a count
    outside [1, MAX_ENV_CANDIDATES] is refused."""
    scene = _scene(roughness=0.3)
    kw = dict(spp=64, progress=False, sampler="independent", adaptive=False)
    a = render_uncached(scene, seed=5, **kw)
    np.testing.assert_array_equal(a.rgb, render_uncached(scene, seed=5, env_candidates=1, **kw).rgb)
    for option in ({}, {"env_sampling": "envmap"}):
        b = render_uncached(scene, seed=6, env_candidates=4, **kw, **option)
        _z_agree(a.rgb, a.variance, b.rgb, b.variance)
        assert b.variance.mean() < a.variance.mean()  # the product of env and BSDF helps here
    for bad in (0, ri.MAX_ENV_CANDIDATES + 1):
        with pytest.raises(ValueError, match="env_candidates must be in"):
            rr.load_integrator("local", env_candidates=bad)


def test_resampled_env_sample_renders_the_furnace_white():
    """A known answer: the furnace (white metal spheres, F0 = 1, roughness 0 ... 1, a constant white
    environment, whose proposal is uniform, so the resampling alone shapes the env sample to the
    lobe) with the energy-conserving random walk is 1 in every sphere pixel; the RIS estimator's
    mean over them within 4 standard errors (or 0.3 %), and its pixels within 5 sigma of 1."""
    from dataclasses import replace

    from pbrcheck.scene import load_scene

    s = load_scene("furnace")
    s = replace(s, brdf=replace(s.brdf, multiscatter="random_walk")).with_camera(width=48, height=24)
    img = render_uncached(s, spp=64, progress=False, sampler="independent", adaptive=False, env_candidates=4)
    cov = img.channels["coverage"] >= 1.0
    rgb, var = img.rgb[cov], img.variance[cov]
    assert np.all(np.isfinite(rgb)) and rgb.size > 300
    se = np.sqrt(var.sum()) / rgb.size
    assert abs(rgb.mean() - 1.0) <= max(4.0 * se, 3e-3), (rgb.mean(), se)
    assert np.all(np.abs(rgb - 1.0) <= Z * np.sqrt(var) + 1e-4)


def test_resampling_picks_each_candidate_in_proportion_to_its_weight():
    """``ri.resampled_estimate`` on fixed candidate estimates per lane (random colours, some zero):
    its expectation over the selection uniform alone is the candidates' mean, which holds only when
    candidate j is chosen with probability ``Y(c_j) / sum Y(c)`` (a uniform pick, or always the
    last, is off by the colours' spread)."""
    mi, dr = _mi()
    rng = np.random.default_rng(3)
    M, lanes = 3, 1 << 18
    cands = rng.random((M, 3, lanes)) * (rng.random((M, 1, lanes)) < 0.8)
    cands[:, :, :8] = 0.0  # lanes where no candidate counts: 0
    it = iter([mi.Color3f(*c.astype(np.float32)) for c in cands])
    out = np.array(ri.resampled_estimate(lambda: next(it), M, mi.Float(rng.random(lanes).astype(np.float32))))
    want = cands.mean(0)
    assert np.all(out[:, :8] == 0.0) and np.all(np.isfinite(out))
    d = out - want
    z = d.mean(1) / (d.std(1) / np.sqrt(lanes))
    assert np.all(np.abs(z) < Z), z
