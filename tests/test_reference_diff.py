"""Differentiable reference: the AD gradient wrt roughness agrees with central finite differences."""

from __future__ import annotations

import pytest

import numpy as np

import pbrcheck  # noqa: F401
from pbrcheck.scene import scene_from_dict
from reference.diff import fit_materials, load_differentiable_scene, param_key, render_image, render_with_gradient
from reference.render import _mi

# Renders, fits or quadratures of seconds each: `make test-fast` skips them, `make test` runs them.
pytestmark = pytest.mark.slow

# Central-difference step in roughness: the second-order error (h^2/6 f''') is < 0.1% here.
FD_STEP = 0.02
# AD and FD are two different Monte Carlo estimates of the same derivative: AD is averaged over
# independent seeds, whose spread gives its standard error; we accept 4 standard errors (false
# failure rate ~6e-5) plus 3% of the value for the FD estimate's own residual noise.
AD_SEEDS = 4
SIGMAS = 4.0
FD_RTOL = 0.03
# A frozen step against the traced one (issue 39): the same float32 operations, but a sum over every
# lane (the loss, a parameter's gradient) may be reduced in another order: a few units of float32
# rounding (2^-24 = 6e-8) at most, each Adam step passing them on relatively.
FROZEN_RTOL = 1e-6


def _scene(roughness=0.4):
    return scene_from_dict({
        "camera": {"origin": [0, 0, 4], "fov": 40, "width": 32, "height": 32},
        "environment": {"type": "sky", "sun_direction": [0.3, 0.8, 0.5], "sun_angular_diameter": 20.0,
                        "sun_radiance": [5, 5, 5], "resolution": [128, 64]},
        "objects": [{"type": "sphere", "radius": 1.0,
                     "material": {"base_color": [0.9, 0.6, 0.3], "metallic": 1.0, "roughness": roughness}}]})


def test_ad_gradient_matches_finite_differences():
    mi, dr = _mi()
    ms, params = load_differentiable_scene(_scene(0.4))
    k = param_key(0, "roughness")
    ad = []
    for seed in range(AD_SEEDS):
        _, _, g = render_with_gradient(ms, params, [k], lambda img: dr.mean(img, axis=None), spp=1024, seed=seed)
        ad.append(float(g[k][0]))
    ad_mean = float(np.mean(ad))
    ad_se = float(np.std(ad, ddof=1) / np.sqrt(AD_SEEDS))
    vals = []
    for sgn in (1, -1):
        params[k] = mi.Float(0.4 + sgn * FD_STEP)
        params.update()
        vals.append(float(render_image(ms, params, spp=4096, seed=11).mean()))
    fd = (vals[0] - vals[1]) / (2 * FD_STEP)
    assert fd < 0 and ad_mean < 0  # rougher metal in this light: darker on average
    assert abs(ad_mean - fd) <= SIGMAS * ad_se + FD_RTOL * abs(fd), (ad, ad_mean, ad_se, fd)


def test_adam_fit_recovers_roughness():
    mi, dr = _mi()
    ms, params = load_differentiable_scene(_scene(0.3))
    k = param_key(0, "roughness")
    target = render_image(ms, params, spp=256, seed=5)
    params[k] = mi.Float(0.7)
    params.update()
    losses = fit_materials(ms, params, [k], target, iterations=25, lr=0.05, spp=16)
    r = float(np.array(params[k])[0])
    assert losses[-1] < 0.25 * losses[0], losses
    assert abs(r - 0.3) < 0.1, r


def test_mitsuba_sensor_matches_pbrcheck_camera():
    """The differentiable path renders through Mitsuba's perspective sensor: it must put the pixels
    where pbrcheck.camera does (fov axis, aspect, orientation, pixel centres, box filter). An
    off-centre dark sphere on a constant sky in a non-square image: mi.render equals the project's
    own rays within noise. Radiance here is in [0, 1], so Mitsuba's unknown per-sample variance is at
    most 1/4: the difference's variance is at most the reference's + 1/(4 spp). A one-pixel shift or
    a mirrored image moves edges by far more than that."""
    from reference.render import render_uncached

    scene = scene_from_dict({
        "camera": {"origin": [0.3, 0.2, 5], "target": [0, 0, 0], "up": [0.2, 1, 0], "fov": 35,
                   "width": 40, "height": 24},
        "environment": {"type": "constant", "radiance": [1, 1, 1]},
        "objects": [{"type": "sphere", "center": [0.9, 0.5, 0], "radius": 0.6,
                     "material": {"base_color": [0, 0, 0], "metallic": 1.0, "roughness": 1.0}}]})
    ms, params = load_differentiable_scene(scene, max_depth=2)
    got = render_image(ms, params, spp=256, seed=1)
    ref = render_uncached(scene, spp=256, progress=False)
    assert got.shape == (24, 40, 3)
    d = np.abs(got - ref.rgb)
    sd = np.sqrt(ref.variance + 0.25 / 256)
    assert np.all(d <= 5 * sd + 2e-3), (d - 5 * sd).max()
    # and it is not trivially flat: the sphere covers part of the frame, off-centre
    cov = ref.channels["coverage"]
    assert 0.05 < cov.mean() < 0.5 and cov[:, 20:].sum() > 3 * cov[:, :20].sum()
    for wrong in (got[:, ::-1], got[::-1], np.roll(got, 1, axis=1)):  # mirrored or shifted: caught
        assert np.any(np.abs(wrong - ref.rgb) > 5 * sd + 2e-3)


def test_frozen_fit_equals_the_traced_fit_bit_for_bit():
    """fit_materials(freeze=True) (issue 39): every iterate equals the traced fit's within float32
    rounding (same seeds, same Adam; measured: bit for bit here). A gradient is a sum over every
    lane, whose order the recording's kernels may change: FROZEN_RTOL, not equality."""
    mi, _ = _mi()
    ms, params = load_differentiable_scene(_scene(0.3))
    k = param_key(0, "roughness")
    target = render_image(ms, params, spp=64, seed=5)
    runs = {}
    for freeze in (False, True):
        params[k] = mi.Float(0.7)
        params.update()
        hist = []
        losses = fit_materials(ms, params, [k], target, iterations=6, lr=0.05, spp=4, lr_final=0.02,
                               freeze=freeze, history=hist)
        runs[freeze] = (losses, [h[k].tolist() for h in hist])
    np.testing.assert_allclose(runs[True][1], runs[False][1], rtol=FROZEN_RTOL, atol=0)
    np.testing.assert_allclose(runs[True][0], runs[False][0], rtol=FROZEN_RTOL, atol=0)
    assert runs[True][1][-1] != runs[True][1][0]   # it moved


def test_frozen_gradient_step_records_again_when_a_bsdf_changes_structure():
    """GradientStep(freeze=True) replays for new parameter values and records anew when a BSDF's
    Python structure changes (roughness below the mirror limit: another lobe's code); each result
    equals the traced step's on the same state within FROZEN_RTOL (measured: 7e-8 on the recording
    call, the gradient's sum in another order; 0 on replays)."""
    from reference.diff import GradientStep, mse_loss

    mi, dr = _mi()
    ms, params = load_differentiable_scene(_scene(0.3))
    k = param_key(0, "roughness")
    tgt = mi.TensorXf(np.asarray(render_image(ms, params, spp=16, seed=5), dtype=np.float32))
    frozen = GradientStep(ms, params, [k], mse_loss, spp=4, freeze=True)
    traced = GradientStep(ms, params, [k], mse_loss, spp=4, freeze=False)

    def both(value, seed):
        params[k] = mi.Float(value)
        dr.enable_grad(params[k])
        params.update()
        out = []
        for step in (traced, frozen):
            dr.clear_grad(params[k])
            loss, (g,) = step(tgt, seed)
            out.append((np.array(loss).ravel()[0], np.array(g).tolist()))
        np.testing.assert_allclose(out[1][1], out[0][1], rtol=FROZEN_RTOL, atol=0)
        np.testing.assert_allclose(out[1][0], out[0][0], rtol=FROZEN_RTOL, atol=0)
        return out[1][1]

    both(0.5, 1)
    both(0.45, 2)
    both(0.4, 3)
    n = frozen.n_recordings
    assert n <= 2, n
    assert both(0.35, 4) != both(0.36, 4)   # replayed with the new values, not stale
    assert frozen.n_recordings == n
    both(0.005, 5)   # a mirror: PBRMaterial.delta flips
    assert frozen.n_recordings == n + 1


def test_a_step_dr_freeze_cannot_record_runs_traced_and_says_so():
    """GradientStep: where Dr.Jit refuses a recording (simulated), the step and the rest of the fit
    run traced with the traced numbers, one RuntimeWarning naming the reason; other errors propagate."""
    from reference.diff import GradientStep, mse_loss

    mi, dr = _mi()
    ms, params = load_differentiable_scene(_scene(0.3))
    k = param_key(0, "roughness")
    tgt = mi.TensorXf(np.asarray(render_image(ms, params, spp=16, seed=5), dtype=np.float32))
    dr.enable_grad(params[k])
    params.update()
    step = GradientStep(ms, params, [k], mse_loss, spp=4, freeze=True)
    traced = GradientStep(ms, params, [k], mse_loss, spp=4, freeze=False)

    def refuse(*a):
        raise RuntimeError("record(): error encountered while recording a frozen function (simulated)")

    step(tgt, 1)                 # the scene's first step runs traced
    step._frozen = refuse
    dr.clear_grad(params[k])
    with pytest.warns(RuntimeWarning, match="could not record"):
        loss, (g,) = step(tgt, 2)
    got = (np.array(loss).ravel()[0], np.array(g).tolist())
    dr.clear_grad(params[k])
    loss2, (g2,) = traced(tgt, 2)
    assert got == (np.array(loss2).ravel()[0], np.array(g2).tolist())
    assert step.freeze is False and "simulated" in step.fallback
    step2 = GradientStep(ms, params, [k], mse_loss, spp=4, freeze=True)
    step2(tgt, 1)

    def other(*a):
        raise RuntimeError("something else")

    step2._frozen = other
    with pytest.raises(RuntimeError, match="something else"):
        step2(tgt, 2)
