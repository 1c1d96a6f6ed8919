"""Issue 39: the reference computes only what its caller uses (no error bars, no AOVs)."""

from __future__ import annotations

import numpy as np

import pbrcheck  # noqa: F401
from pbrcheck.scene import load_scene
from reference.variant import ensure_variant

ensure_variant()
from reference import render as rr  # noqa: E402  (needs the variant set)
from reference.render import render_uncached  # noqa: E402

#: A frozen replay against the traced kernels (issue 39): bit for bit on the CPU (LLVM); on CUDA within
#: float32 rounding (the recording may fuse and order a kernel's operations otherwise): a few ulps.
FROZEN_CUDA_RTOL = 1e-5


def assert_frozen_equal(got, want):
    """Equal bit for bit on LLVM, within FROZEN_CUDA_RTOL on CUDA (NaNs equal)."""
    mi, _ = rr._mi()
    if mi.variant().startswith("cuda"):
        np.testing.assert_allclose(got, want, rtol=FROZEN_CUDA_RTOL, atol=1e-7, equal_nan=True)
    else:
        np.testing.assert_array_equal(got, want)


#: Share of pixel-channels within 1.96 standard deviations that two unbiased, calibrated estimates
#: reach at least (0.95 expected; 0.85 leaves room for the variance channels' own noise, K = 16).
WITHIN_MIN = 0.85


def test_lean_render_has_no_error_bars_or_aovs_and_agrees():
    """error_bars=False, aovs=False: radiance and coverage only, one QMC sequence per pixel (K = 1 where
    multijitter takes the count), the same image as the default within the default's error bars."""
    scene = load_scene("spheres").with_camera(width=32, height=24)
    full = render_uncached(scene, spp=256, seed=1, progress=False, adaptive=False)
    lean = render_uncached(scene, spp=256, seed=2, progress=False, adaptive=False, **rr.LEAN_OUTPUTS)
    assert sorted(lean.channels) == ["B", "G", "R", "coverage"]
    assert lean.meta["outputs"] == "radiance+coverage" and full.meta["outputs"] == "radiance+coverage+variance+aovs"
    assert lean.meta["replicates"] == "1" and lean.meta["samples_per_replicate"] == "256"
    assert rr.lean_plan(256) == (1, 256) and rr.lean_plan(128) == (2, 64)
    d = np.stack([lean.channels[c] - full.channels[c] for c in "RGB"])
    v = np.stack([full.channels[f"variance.{c}"] for c in "RGB"])
    # the lean image's variance is at most the default's (same spp, QMC over all of them): 2 v bounds the sum
    within = np.mean(np.abs(d) <= 1.96 * np.sqrt(2 * v) + 1e-7)
    assert within >= WITHIN_MIN, within
    np.testing.assert_allclose(lean.channels["coverage"], full.channels["coverage"], atol=0.15)
    # adaptive: the pilot keeps its variance (the allocation needs it), the levels none
    ada = render_uncached(scene, spp=256, seed=3, progress=False, error_bars=False)
    assert "variance.R" not in ada.channels and "N.X" in ada.channels
    assert ada.meta["replicates"].startswith("1 or 2")


def test_frozen_pass_equals_the_traced_one_and_a_changed_scene_is_not_stale():
    """ReferenceIntegrator.freeze: render_groups' passes replayed by dr.freeze give the traced pixels bit
    for bit (one recording for repeated passes of one layout); another scene (other materials) gives its
    own traced pixels, not a replay of the first one's."""
    from dataclasses import replace

    from reference.integrator import sensor_dict

    mi, _ = rr._mi()
    scene = load_scene("spheres").with_camera(width=24, height=20)
    objs = [replace(o, material=replace(o.material, roughness=min(1.0, o.material.roughness + 0.3),
                                        base_color=tuple(0.5 * c for c in o.material.base_color)))
            for o in scene.objects]
    other = replace(scene, objects=objs)
    sensor = mi.load_dict(sensor_dict(scene.camera, 16, "qmc"))
    groups = [(None, 16, 4, 0)]
    traced = rr.load_integrator("local", sampler="qmc")
    frozen = rr.load_integrator("local", sampler="qmc")
    frozen.freeze = True
    outs = {}
    for name, sc in (("first", scene), ("other", other)):
        ms = rr.load_mitsuba_scene(sc)
        want = np.array(traced.render_groups(ms, sensor, groups, 5, 24, 20))
        got = [np.array(frozen.render_groups(ms, sensor, groups, 5, 24, 20)) for _ in range(3)]
        for g in got:  # the first traced (it fills the caches), the next two replayed
            assert_frozen_equal(g, want)
        outs[name] = want
    assert frozen._frozen is not None and frozen._frozen.n_recordings >= 1
    assert np.abs(outs["first"][..., :3] - outs["other"][..., :3]).max() > 0.05  # the replay is not stale


def test_frozen_bsdf_path_equals_the_traced_one_and_records_again_for_another_structure():
    """reference.frozen.FrozenSampleEval (issue 39): a pbr_material's sample + eval_pdf replayed by
    dr.freeze equals the traced values (assert_frozen_equal: bit for bit on the CPU); new parameter values replay (their own values, not
    the recording's); a mirror-limit roughness (another lobe's code) records anew."""
    import numpy as np

    from reference.frozen import FrozenSampleEval

    mi, dr = rr._mi()
    bsdf = mi.load_dict({"type": "pbr_material", "base_color": [0.8, 0.6, 0.4], "metallic": 0.3, "roughness": 0.5})
    params = mi.traverse(bsdf)
    from reference.bench import bsdf_lanes

    si, u1, u2 = bsdf_lanes(4096)
    frozen, traced = FrozenSampleEval(bsdf), FrozenSampleEval(bsdf, freeze=False)

    def both():
        a, b = traced(si, u1, u2), frozen(si, u1, u2)
        out = []
        for x, y in zip((a[0].wo, a[1], a[2], a[3]), (b[0].wo, b[1], b[2], b[3])):
            x, y = np.array(x), np.array(y)
            assert_frozen_equal(y, x)
            out.append(y)
        return out

    key = next(k for k in params.keys() if k.endswith("roughness"))

    def roughness(r):
        params[key] = mi.Float(r)
        params.update()
        return both()

    both()
    # dr.freeze(auto_opaque): a literal that changes between calls is made opaque, once
    roughness(0.4)
    first = roughness(0.3)
    n = frozen.n_recordings
    assert 1 <= n <= 2
    other = roughness(0.2)
    assert frozen.n_recordings == n
    assert not np.array_equal(other[2], first[2])   # the new roughness's values, not a stale replay
    roughness(0.001)   # below the mirror limit: PBRMaterial.delta
    assert frozen.n_recordings == n + 1


def _jit_hashes(fn):
    """The hashes of the JIT kernels ``fn()`` launches (Dr.Jit's kernel history)."""
    mi, dr = rr._mi()
    dr.kernel_history()   # drop what came before
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        fn()
        hist = dr.kernel_history()
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)
    return {h["hash"] for h in hist if h.get("type") == dr.KernelType.JIT}


def test_a_level_of_another_size_launches_the_same_kernels():
    """Issue 39 (compiled kernels per report): render_groups' passes of two sizes and counts (an adaptive
    render's levels) launch the same JIT kernels, none with the pass's size as a literal (a Color3f's
    block sum packed its channels in such a kernel: one compile per level)."""
    from reference.integrator import sensor_dict

    mi, _ = rr._mi()
    scene = load_scene("spheres").with_camera(width=24, height=20)
    ms = rr.load_mitsuba_scene(scene)
    sensor = mi.load_dict(sensor_dict(scene.camera, 16, "qmc"))
    integ = rr.load_integrator("local", sampler="qmc")
    integ.render_groups(ms, sensor, [(np.arange(40), 16, 2, 3 << 20)], 1, 24, 20)   # the scene's one-off tables
    a = _jit_hashes(lambda: integ.render_groups(ms, sensor, [(np.arange(100), 16, 4, 1 << 20)], 1, 24, 20))
    b = _jit_hashes(lambda: integ.render_groups(ms, sensor, [(np.arange(240), 16, 16, 2 << 20)], 1, 24, 20))
    assert a == b, (len(a), len(b))


def test_material_table_values_and_one_adjoint_kernel_for_every_material():
    """reference.material_tables.material_table: entry j is value j exactly; the gradient of a weighted sum of the
    table reaches each value (its weight), through the same backward kernel for every material (a chain
    of selects gave each material a kernel of its own length: 30 compiles for spheres' fit)."""
    from reference.material_tables import material_table, table_indices

    mi, dr = rr._mi()
    n = 7
    vals = [mi.Float(0.1 * (j + 1)) for j in range(n)]
    for v in vals:
        dr.enable_grad(v)
    w = mi.Float(np.arange(1, n + 1, dtype=np.float32))

    def run():
        t = material_table(mi.Float, vals, table_indices(n))
        dr.backward(dr.sum(t * w))
        return t

    hashes = _jit_hashes(run)
    t = run()
    np.testing.assert_array_equal(np.array(dr.detach(t)), np.float32([0.1 * (j + 1) for j in range(n)]))
    g = [float(dr.grad(v)[0]) for v in vals]
    assert g == [2.0 * (j + 1) for j in range(n)]   # two backward passes accumulated
    assert len(hashes) <= 4, len(hashes)   # the primal table, one adjoint shape (not one per material)
