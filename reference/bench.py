"""``pbrcheck bench reference``: the reference's throughput, efficiency and time to a trusted verdict,
measured side by side in one run on the chosen variant, as one JSON object with each figure's goal.

On the ``spheres`` scene at its own 360 x 300 (``--quick``: reduced), ``BENCH_SPP`` spp, every render
warm (one untimed render first, which compiles), median of ``RENDER_REPEATS`` alternating runs:

* ``local_msamples_per_s``: the reference (``local``, through ``mi.render`` with the
  ``pbrcheck_reference`` integrator, per-pixel moments included), camera samples per second / 1e6.
* ``mitsuba_path_msamples_per_s``: ``mi.render`` with Mitsuba's own ``path`` integrator (max depth 2,
  film only) and the project's ``pbr_material``. ``local_vs_mitsuba_path`` = the ratio of the two;
  goal >= 1.0 (the reference is no slower than Mitsuba's integrator with the same BSDF).
* ``integrator_efficiency``: ``(mean pixel variance x seconds)`` of the ``path`` mode (max depth 2)
  over that of ``local``, same spp (the CPU-seconds ratio too: the machine may be shared); goal >= 2.
* ``bsdf_speed_ratio``: seconds per ``sample + eval_pdf`` lane of Mitsuba's C++ ``roughconductor``
  (ggx, material none, alpha = roughness^2) over ``pbr_material`` (smith_ggx, fresnel none, white
  metal, same roughness) on ``BSDF_LANES`` random incident directions, median of repeats after a
  compile run; goal >= 0.9. Split into ``bsdf_trace_seconds`` (building the Dr.Jit graph: Python for
  ``pbr_material``, C++ for ``roughconductor``, once per call) and ``bsdf_kernel_seconds`` (compile
  cache lookup, launch, run): ``bsdf_kernel_ratio`` is the ratio without tracing, which is what a
  render pays (the integrator traces the BSDF once per pass, not once per sample);
  ``bsdf_speed_ratio_pass_width``: the same ratio at a render pass's width
  (:func:`reference.integrator.max_lanes`: 2^26 lanes on CUDA, 2^23 on LLVM), tracing included;
  ``bsdf_speed_ratio_frozen``: ``pbr_material`` through ``dr.freeze``
  (:class:`reference.frozen.FrozenSampleEval`: recorded once, replayed without tracing).
* ``material_gather``: the local estimator with every ``pbr_material`` gathered per lane
  (:class:`reference.bsdf.MaterialView`, the default) against Mitsuba's per-material dispatch, which
  traces the lobes once per material (30 on ``spheres``): warm seconds of a small render
  (``SMALL_SIZE`` px high, ``SMALL_SPP`` spp, moments) and of one differentiable step (render and
  backward of every object's roughness, fit-roughness's size), median of repeats; there tracing, not
  sampling, is the cost.
* ``seconds_to_10x_noise_floor``: seconds for the ``local`` reference of ``spheres`` to bring its
  noise floor (mean pixel variance) to a tenth of the default preset's error there
  (:data:`SPHERES_DEFAULT_MSE`), extrapolated from the measured per-sample variance and throughput:
  ``spp = 10 sigma^2 / MSE``, ``seconds = spp x (seconds per spp)`` (``spp_to_10x_noise_floor``).
* ``asset``: a ~50k-triangle textured glTF asset (made here, :mod:`reference.bench_asset`) at the same
  size, spp, sampler, environment and lights (spheres' own), rendered alternately with spheres in its own loop
  (``ASSET_REPEATS``; both rows under the same load): load and Mitsuba-scene (BVH) seconds apart,
  its local samples/s and ``asset_vs_spheres`` = its throughput over spheres'; goal >= 0.7.
* ``samplers``: the same figure for each sampler, side by side in one run (:data:`SAMPLER_CONFIGS`:
  ``independent``, ``qmc`` uniform, ``qmc`` adaptive, the default), each rendered at
  ``FLOOR_SPP`` spp (a warm-up render of a 16 x 12 crop first, which compiles the same kernels,
  then ``FLOOR_SEEDS`` timed renders, seeds 1 ...; median seconds): its noise floor (mean pixel
  variance over covered pixels, from its own variance channels, averaged over the seeds), the spp to the 10x floor
  extrapolated as ``FLOOR_SPP x floor / target`` (exact for independent samples; for QMC, whose
  error falls faster than 1 / spp, an upper bound), seconds and CPU seconds to it (seconds per spp
  x that spp, at 360 x 300; the adaptive pilot included); ``variance_ratio`` (independent's floor
  over this one's, at equal spp: load-independent), ``seconds_speedup`` and
  ``cpu_seconds_speedup`` (independent's seconds to the floor over this one's; goal >= 5 for the
  default on spheres); ``mean_z`` (the image mean against independent's, in standard errors:
  ``sum(a - b) / sqrt(sum(var_a + var_b))``, of the seed-averaged images) and ``pixels_within_1.96`` (share of pixel-channels
  with ``|a - b| < 1.96 sqrt(var_a + var_b)``, about 0.95 when both are unbiased and calibrated).
  Scenes: ``spheres`` (target: :data:`SPHERES_DEFAULT_MSE` / 10), ``spheres`` under a real HDR
  environment (``--envmap``, default the first of :data:`ENVMAPS`; skipped when absent) and
  ``asset``, the asset row's textured ~50k-triangle glTF (:func:`reference.bench_asset.asset_scene`:
  spheres' environment and lights; ``--quick``: its 64-segment, 128-px-texture version): for these
  two no preset error is known here (this layer cannot render the real-time image), so their target
  is independent's floor at ``FLOOR_SPP`` / ``HDR_TARGET_FACTOR``, and the speedups, ratios of
  seconds at a common target, do not depend on it.
* ``variance_reduction``: candidate variance reductions of the ``local`` estimator against its
  default, same scenes, each a **variance ratio** at equal spp (the default's floor over the
  candidate's; ``efficiency_ratio`` = that x the default's CPU seconds over the candidate's) from
  the ``independent`` sampler (per-sample moments: the variance channels are exact in expectation,
  no replicate noise), uniform spp, ``VR_SPP`` spp (quick: ``VR_SPP_QUICK``) at the bench resolution,
  ``VR_SEEDS`` seeds: ``mis_balance`` (the balance heuristic for the env and BSDF samples instead of
  the power heuristic, :data:`reference.integrator.MIS_HEURISTICS`) and ``env_envmap`` (Mitsuba's
  own environment sampling, the default until version 4, against ``compensated``,
  :mod:`reference.env_sampling`) and ``ris4`` (the environment sample resampled from 4 candidates
  of the proposal by the MIS-weighted product of the environment and the BSDF:
  :func:`reference.integrator.resampled_estimate`); scenes :data:`VR_SCENES` and the real-HDR one. Adopted only when
  the ratio is clearly above 1 (docs/reference.md records the measurements).

* ``throughput`` (issue 39): the work users run, at several sizes: the reference's default render
  (``render_uncached``: local, qmc adaptive, error bars and AOVs; ``pbrcheck_lean``: qmc uniform
  without error bars or AOVs, a film like ``path``'s) against ``mi.render`` + Mitsuba's
  ``path`` (max depth 2, film only) with the same BSDF (``pbr_material``) and with Mitsuba's C++
  ``roughconductor``, at 64, 1024 and 4096 spp (:data:`THROUGHPUT_SPP`) and two image sizes by backend
  (:data:`THROUGHPUT_SIZES`; CPU: 90 x 75 and 180 x 150, so 4096 spp stays minutes), alternating,
  median of :data:`THROUGHPUT_REPEATS` runs after a compile run each: seconds, CPU seconds, M samples/s
  and the ratios ``vs_path_same_bsdf`` / ``vs_path_roughconductor`` (the peer's seconds over pbrcheck's;
  ``_cpu``: of CPU seconds), with the machine named (:func:`machine`); the goal applies at 1024 spp
  (:data:`THROUGHPUT_GOAL`: >= 1.0 on a GPU, >= 1.5 on the CPU; the smallest ratio of the two sizes).

``--section samplers`` / ``--section variance_reduction`` / ``--section throughput``
(:func:`run_sections`): those figures alone.

API: :func:`run_bench`, :func:`run_sections`, :func:`run_asset_bench`, :func:`machine`, :data:`SAMPLER_CONFIGS`,
:data:`VR_CANDIDATES`, :data:`SECTIONS`.
"""

from __future__ import annotations

import math
import statistics
import tempfile
import time

import numpy as np

from dataclasses import replace
from pathlib import Path

from pbrcheck.environment import load_environment
from pbrcheck.scene import Environment, load_scene

from .render import LEAN_OUTPUTS, _mi, load_mitsuba_scene, render_uncached, scene_dict

#: Coverage from which a pixel counts in the noise floor (compare.metrics.FULL_COVERAGE; this layer
#: cannot import the comparator).
FULL_COVERAGE = 0.999
BENCH_RESOLUTION = (360, 300)   # the spheres scene's own resolution
BENCH_SPP = 64
RENDER_REPEATS = 3
#: The asset row's alternating renders of the asset and spheres (reference.bench_asset).
ASSET_REPEATS = 5
BSDF_LANES = 1 << 21
BSDF_REPEATS = 7
PEER_ROUGHNESS = 0.5
PATH_DEPTH = 2
#: The reference's noise floor must sit this far below the smallest error reported.
NOISE_FLOOR_FACTOR = 10.0
#: MSE of the ``default`` real-time preset against a converged ``local`` reference on ``spheres``
#: (360 x 300), the variance of the reference subtracted: measured with ``pbrcheck compare`` of
#: ``pbrcheck realtime spheres`` against ``pbrcheck reference spheres --spp 4096`` (2026-11-23: MSE
#: 2.22e-4, noise floor 4.1e-5, corrected 1.805e-4; the reference's per-sample variance is 0.17).
SPHERES_DEFAULT_MSE = 1.8e-4

#: The small renders of ``material_gather`` (fit-roughness's and the research sections' sizes).
SMALL_SIZE, SMALL_SPP = 48, 16

GOALS = {"local_vs_mitsuba_path": 1.0, "integrator_efficiency": 2.0, "bsdf_speed_ratio": 0.9,
         "default_sampler_seconds_speedup": 5.0, "asset_vs_spheres": 0.7}
#: (label, sampler, adaptive) of the ``samplers`` figures; the last is the default.
SAMPLER_CONFIGS = (("independent", "independent", False), ("qmc", "qmc", False), ("qmc_adaptive", "qmc", True))
#: The spp each sampler is rendered at, and the seeds (renders) its floor is the mean of: one
#: render's floor is itself noisy where a few highlight pixels hold most of it (``--quick``: 48 x 40).
FLOOR_SPP, FLOOR_SPP_QUICK = 512, 256
FLOOR_SEEDS, FLOOR_SEEDS_QUICK = 3, 6
#: Real HDR environments (never in the repository), tried in this order.
ENVMAPS = Path(__file__).resolve().parents[1].parent / "shared" / "envmaps"
ENVMAP_NAMES = ("royal_esplanade_1k.hdr", "venice_sunset_1k.hdr", "chinese_garden_1k.hdr")
#: The real-HDR scene's target: independent's floor at FLOOR_SPP over this (about 10^4 spp).
HDR_TARGET_FACTOR = 8.0
#: The sections :func:`run_sections` runs alone (``--section``).
SECTIONS = ("samplers", "variance_reduction", "throughput")
#: ``throughput``: the spp (the goal applies at the middle one), the two image sizes by backend (CPU:
#: a quarter and a half of spheres' 360 x 300, so that 4096 spp stays minutes), timed runs per
#: render, and the goal of pbrcheck over ``mi.render`` + ``path`` + the same BSDF by backend (issue 39).
THROUGHPUT_SPP, THROUGHPUT_SPP_QUICK = (64, 1024, 4096), (8, 16, 32)
THROUGHPUT_SIZES = {"cuda": ((360, 300), (720, 600)), "llvm": ((90, 75), (180, 150)), "quick": ((16, 12), (24, 20))}
THROUGHPUT_REPEATS = 3
THROUGHPUT_GOAL = {"cuda": 1.0, "llvm": 1.5}
#: ``variance_reduction``: spp and seeds per candidate (independent sampler, uniform spp), and the
#: candidates, (label, ``render_uncached`` keyword arguments); the first is the default.
VR_SPP, VR_SPP_QUICK = 128, 32
VR_SEEDS = 3
VR_CANDIDATES = (("default", {}), ("env_envmap", {"env_sampling": "envmap"}), ("mis_balance", {"mis": "balance"}),
                 ("ris4", {"env_candidates": 4}))
#: ``variance_reduction``'s scenes besides the real-HDR one (each at the bench resolution).
VR_SCENES = ("spheres", "furnace", "grazing")


def _timed_render(fn):
    t, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - t, time.process_time() - c


def _time_renders(scene, spp, mscene, env, repeats):
    """Median wall and CPU seconds (and mean pixel variance) of ``local``, ``path`` (depth 2) and
    Mitsuba's own ``path`` through ``mi.render``, timed alternately (so that load from other
    processes hits all alike) after one compile run each."""
    mi, dr = _mi()
    from .integrator import sensor_dict  # local: importing it loads Mitsuba (variant set first)

    d = scene_dict(scene, env)
    d["sensor"] = sensor_dict(scene.camera, spp)
    d["integrator"] = {"type": "path", "max_depth": PATH_DEPTH}
    native = mi.load_dict(d)

    def mitsuba_path(seed):
        img = mi.render(native, spp=spp, seed=seed)
        dr.eval(img)
        dr.sync_thread()
        return None

    runs = {"local": [], "path": [], "mitsuba_path": []}
    for k in range(repeats + 1):
        for mode in runs:
            if mode == "mitsuba_path":
                _, t, c = _timed_render(lambda: mitsuba_path(k))
                var = var_cov = float("nan")
            else:
                img, t, c = _timed_render(lambda: render_uncached(
                    scene, spp=spp, mode=mode, max_depth=PATH_DEPTH, mscene=mscene, env=env,
                    progress=False, seed=k, sampler="independent"))
                var = float(np.mean(img.variance))
                # the comparator's noise floor: covered pixels only (compare.metrics.FULL_COVERAGE)
                cov = img.channels["coverage"] >= FULL_COVERAGE
                var_cov = float(np.mean(img.variance[cov])) if cov.any() else var
            if k:  # the first run compiles
                runs[mode].append((t, c, var, var_cov))
    return {mode: (statistics.median(x[0] for x in r), statistics.median(x[1] for x in r),
                   float(np.mean([x[2] for x in r])), float(np.mean([x[3] for x in r])))
            for mode, r in runs.items()}


def bsdf_lanes(lanes: int, seed: int = 0):
    """``(si, u1, u2)``, evaluated: ``lanes`` surface interactions with random incident directions in
    the upper hemisphere (local frame) and uniform samples, for timing or testing a BSDF's ``sample``
    and ``eval_pdf`` (:func:`_time_bsdf`, ``tools/frozen_timings.py``, the frozen BSDF path's test)."""
    mi, dr = _mi()
    rng = np.random.default_rng(seed)
    wi = rng.normal(size=(lanes, 3)).astype(np.float32)
    wi[:, 2] = np.abs(wi[:, 2])
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    si = dr.zeros(mi.SurfaceInteraction3f, lanes)
    si.wi = mi.Vector3f(wi[:, 0], wi[:, 1], wi[:, 2])
    u1 = mi.Float(rng.random(lanes, dtype=np.float32))
    u2 = mi.Point2f(rng.random(lanes, dtype=np.float32), rng.random(lanes, dtype=np.float32))
    dr.eval(si, u1, u2)
    dr.sync_thread()
    return si, u1, u2


def _time_bsdf(bsdf, lanes, repeats, frozen: bool = False):
    """(seconds per lane in total, tracing seconds per call, kernel seconds per call): medians.
    ``frozen``: through :class:`reference.frozen.FrozenSampleEval` (recorded on the compile run,
    replayed after: "tracing" is then the replay's launch of the recorded kernels)."""
    mi, dr = _mi()
    si, u1, u2 = bsdf_lanes(lanes)
    from .frozen import FrozenSampleEval

    fse = FrozenSampleEval(bsdf, freeze=frozen)
    total, trace, kernel = [], [], []
    for k in range(repeats + 1):
        t0 = time.perf_counter()
        bs, w, f, pdf = fse(si, u1, u2)
        t1 = time.perf_counter()
        dr.eval(w, f, pdf)
        dr.sync_thread()
        t2 = time.perf_counter()
        if k:  # the first run compiles
            total.append(t2 - t0)
            trace.append(t1 - t0)
            kernel.append(t2 - t1)
    return statistics.median(total) / lanes, statistics.median(trace), statistics.median(kernel)


def _time_gather(scene, repeats):
    """{"per_instance" | "gathered": {"render_seconds", "grad_step_seconds"}} (module docstring)."""
    mi, dr = _mi()
    from .integrator import INTEGRATOR_NAME, sensor_dict  # local: needs the variant set

    small = scene.with_camera(width=round(SMALL_SIZE * scene.camera.width / scene.camera.height), height=SMALL_SIZE)
    out = {}
    for label, gather in (("per_instance", False), ("gathered", True)):
        d = scene_dict(small)
        d["sensor"] = sensor_dict(small.camera, SMALL_SPP)
        d["integrator"] = {"type": INTEGRATOR_NAME, "mode": "local", "gather_materials": gather}
        ms = mi.load_dict(d)
        moments = mi.load_dict({**d["integrator"], "moments": True})
        params = mi.traverse(ms)
        keys = [k for k in params.keys() if k.endswith(".roughness")]

        def render():
            dr.eval(mi.render(ms, sensor=ms.sensors()[0], integrator=moments, spp=SMALL_SPP))
            dr.sync_thread()

        def step():
            for k in keys:
                dr.enable_grad(params[k])
            params.update()
            dr.backward(dr.mean(mi.render(ms, params, spp=SMALL_SPP), axis=None))
            grads = [dr.grad(params[k]) for k in keys]
            dr.eval(grads)
            dr.sync_thread()
            for k in keys:
                dr.disable_grad(params[k])
            params.update()

        times = {"render_seconds": [], "grad_step_seconds": []}
        for k in range(repeats + 1):
            for name, fn in (("render_seconds", render), ("grad_step_seconds", step)):
                _, t, _ = _timed_render(fn)
                if k:  # the first run compiles
                    times[name].append(t)
        out[label] = {n: statistics.median(v) for n, v in times.items()}
    out["render_speedup"] = out["per_instance"]["render_seconds"] / out["gathered"]["render_seconds"]
    out["grad_step_speedup"] = out["per_instance"]["grad_step_seconds"] / out["gathered"]["grad_step_seconds"]
    out["materials"] = len(scene.objects)
    out["size"] = [small.camera.width, small.camera.height]
    out["spp"] = SMALL_SPP
    return out


def machine() -> str:
    """The machine the reference ran on, in words: the variant and the CPU model (LLVM, with Dr.Jit's
    thread count) or the GPU's name (CUDA)."""
    mi, dr = _mi()
    import platform
    import subprocess

    if mi.variant().startswith("cuda"):
        try:
            name = subprocess.run(["nvidia-smi", "--query-gpu=name", "--format=csv,noheader"], capture_output=True,
                                  text=True, timeout=20).stdout.strip().splitlines()[0]
        except (OSError, IndexError, subprocess.SubprocessError):
            name = "a CUDA GPU"
        return f"{mi.variant()} on {name}"
    model = platform.processor() or platform.machine()
    try:
        model = next(ln.split(":", 1)[1].strip() for ln in Path("/proc/cpuinfo").read_text().splitlines()
                     if ln.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{mi.variant()} on {model} ({dr.thread_count()} threads)"


def _peer_scenes(scene, env, spp: int):
    """Mitsuba scenes rendering ``scene`` with ``mi.render`` and Mitsuba's ``path`` (max depth
    :data:`PATH_DEPTH`, film only, ``spp`` independent samples): ``same_bsdf`` (the project's
    ``pbr_material``) and ``roughconductor`` (Mitsuba's C++ GGX conductor, alpha =
    :data:`PEER_ROUGHNESS` squared, on every object)."""
    mi, _ = _mi()
    from .integrator import sensor_dict  # local: importing it loads Mitsuba (variant set first)

    rough = {"type": "roughconductor", "distribution": "ggx", "material": "none", "alpha": PEER_ROUGHNESS ** 2}
    out = {}
    for name, override in (("same_bsdf", None), ("roughconductor", rough)):
        d = scene_dict(scene, env, bsdf_override=override)
        d["sensor"] = sensor_dict(scene.camera, spp)
        d["integrator"] = {"type": "path", "max_depth": PATH_DEPTH}
        out[name] = mi.load_dict(d)
    return out


def _throughput(quick: bool = False) -> dict:
    """``throughput`` (module docstring): pbrcheck's default reference against ``mi.render`` + ``path``
    with the same BSDF and with ``roughconductor``, at each of :data:`THROUGHPUT_SPP` and two image
    sizes (:data:`THROUGHPUT_SIZES` by backend), alternating, median of the timed runs after a compile
    run each; ratios of wall and of CPU seconds (> 1: pbrcheck faster)."""
    mi, dr = _mi()
    backend = "cuda" if mi.variant().startswith("cuda") else "llvm"
    sizes = THROUGHPUT_SIZES["quick" if quick else backend]
    spps = THROUGHPUT_SPP_QUICK if quick else THROUGHPUT_SPP
    repeats = 1 if quick else THROUGHPUT_REPEATS
    base = load_scene("spheres")
    rows = []
    for W, H in sizes:
        scene = base.with_camera(width=W, height=H)
        env = load_environment(scene)
        mscene = load_mitsuba_scene(scene, env)
        for spp in spps:
            peers = _peer_scenes(scene, env, spp)
            runs = {"pbrcheck": [], "pbrcheck_lean": [], **{k: [] for k in peers}}

            def one(name, seed):
                if name.startswith("pbrcheck"):
                    kw = {"adaptive": False, **LEAN_OUTPUTS} if name == "pbrcheck_lean" else {}
                    return _timed_render(lambda: render_uncached(scene, spp=spp, seed=seed, mscene=mscene, env=env,
                                                                 progress=False, **kw))
                return _timed_render(lambda: (dr.eval(mi.render(peers[name], spp=spp, seed=seed)), dr.sync_thread()))

            for k in range(repeats + 1):
                for name in runs:
                    _, t, c = one(name, k)
                    if k:  # the first run compiles
                        runs[name].append((t, c))
            med = {n: (statistics.median(x[0] for x in r), statistics.median(x[1] for x in r)) for n, r in runs.items()}
            samples = W * H * spp
            row = {"resolution": [W, H], "spp": spp,
                   **{f"{n}_seconds": v[0] for n, v in med.items()},
                   **{f"{n}_cpu_seconds": v[1] for n, v in med.items()},
                   **{f"{n}_msamples_per_s": samples / v[0] / 1e6 for n, v in med.items()}}
            for peer in peers:
                row[f"vs_path_{peer}"] = med[peer][0] / med["pbrcheck"][0]
                row[f"vs_path_{peer}_cpu"] = med[peer][1] / med["pbrcheck"][1]
                row[f"lean_vs_path_{peer}_cpu"] = med[peer][1] / med["pbrcheck_lean"][1]
            rows.append(row)
    goal_spp = spps[len(spps) // 2]
    at_goal = [r for r in rows if r["spp"] == goal_spp]
    goal = THROUGHPUT_GOAL[backend]
    return {"machine": machine(), "rows": rows, "goal_spp": goal_spp, "goal": goal,
            "vs_path_same_bsdf_at_goal_spp": min(r["vs_path_same_bsdf"] for r in at_goal),
            "vs_path_same_bsdf_cpu_at_goal_spp": min(r["vs_path_same_bsdf_cpu"] for r in at_goal),
            "goal_met": min(r["vs_path_same_bsdf"] for r in at_goal) >= goal,
            "repeats": repeats,
            "note": "pbrcheck: render_uncached's default (local, qmc adaptive, error bars and AOVs: what users "
                    "run; samples = pixels x spp, the pilot not counted); pbrcheck_lean: qmc uniform without "
                    "error bars and AOVs (LEAN_OUTPUTS: a film, like path's); path: mi.render + Mitsuba's path "
                    f"(max depth {PATH_DEPTH}, film only, independent sampler); ratios = the peer's seconds over "
                    "pbrcheck's (> 1: pbrcheck faster); wall seconds are under the machine's load, CPU seconds "
                    "are this process's"}


def _floor_of(img) -> float:
    cov = img.channels["coverage"] >= FULL_COVERAGE
    return float(np.mean(img.variance[cov])) if cov.any() else float(np.mean(img.variance))


def _samplers(scene, spp: int, seeds: int, target: float | None, full_pixels: int) -> dict:
    """The ``samplers`` figures of one scene (module docstring); ``target`` None: independent's
    floor / :data:`HDR_TARGET_FACTOR`."""
    env = load_environment(scene)
    mscene = load_mitsuba_scene(scene, env)
    tiny = scene.with_camera(width=16, height=12)
    scale = full_pixels / (scene.camera.width * scene.camera.height)
    out, imgs = {}, {}
    for label, sampler, adaptive in SAMPLER_CONFIGS:
        def render(sc, seed):
            return render_uncached(sc, spp=spp, seed=seed, sampler=sampler, adaptive=adaptive,
                                   mscene=mscene, env=env, progress=False)
        render(tiny, 0)  # compiles the same kernels (the image size is not part of them)
        runs = [_timed_render(lambda: render(scene, 1 + k)) for k in range(seeds)]
        imgs[label] = [r[0] for r in runs]
        per_seed = [_floor_of(r[0]) for r in runs]
        floor = float(np.mean(per_seed))  # each unbiased: their mean too
        t = statistics.median(r[1] for r in runs)
        c = statistics.median(r[2] for r in runs)
        if target is None:
            target = floor / HDR_TARGET_FACTOR
        need = max(2, math.ceil(spp * floor / target))
        out[label] = {"sampler": sampler, "adaptive": adaptive, "spp": spp, "seconds": t, "cpu_seconds": c,
                      "noise_floor": floor, "noise_floor_per_seed": per_seed,
                      "spp_to_10x_noise_floor": need,
                      "seconds_to_10x_noise_floor": need * t / spp * scale,
                      "cpu_seconds_to_10x_noise_floor": need * c / spp * scale,
                      "adaptive_allocation": runs[0][0].meta.get("adaptive", "off")}
    base = out["independent"]
    a_m = np.mean([i.rgb for i in imgs["independent"]], axis=0, dtype=np.float64)
    a_v = np.mean([i.variance for i in imgs["independent"]], axis=0, dtype=np.float64) / seeds
    for label, r in out.items():
        r["variance_ratio"] = base["noise_floor"] / r["noise_floor"]
        r["spp_ratio"] = base["spp_to_10x_noise_floor"] / r["spp_to_10x_noise_floor"]
        r["seconds_speedup"] = base["seconds_to_10x_noise_floor"] / r["seconds_to_10x_noise_floor"]
        r["cpu_seconds_speedup"] = base["cpu_seconds_to_10x_noise_floor"] / r["cpu_seconds_to_10x_noise_floor"]
        if label != "independent":
            d = np.mean([i.rgb for i in imgs[label]], axis=0, dtype=np.float64) - a_m
            v = np.mean([i.variance for i in imgs[label]], axis=0, dtype=np.float64) / seeds + a_v
            r["mean_z"] = float(d.sum() / math.sqrt(max(v.sum(), 1e-300)))
            r["pixels_within_1.96"] = float(np.mean(np.abs(d) < 1.96 * np.sqrt(v) + 1e-7))
    return {"target_floor": target, "resolution": [scene.camera.width, scene.camera.height], "seeds": seeds,
            "environment": scene.environment.path or scene.environment.type, **out}


def _variance_reduction(scene, spp: int, seeds: int) -> dict:
    """The ``variance_reduction`` figures of one scene (module docstring)."""
    env = load_environment(scene)
    mscene = load_mitsuba_scene(scene, env)
    tiny = scene.with_camera(width=16, height=12)
    out, imgs = {}, {}
    for label, kw in VR_CANDIDATES:
        def render(sc, seed):
            return render_uncached(sc, spp=spp, seed=seed, sampler="independent", adaptive=False,
                                   mscene=mscene, env=env, progress=False, **kw)
        render(tiny, 0)  # compiles the same kernels
        runs = [_timed_render(lambda: render(scene, 1 + k)) for k in range(seeds)]
        imgs[label] = [r[0] for r in runs]
        out[label] = {**kw, "noise_floor": float(np.mean([_floor_of(r[0]) for r in runs])),
                      "cpu_seconds": statistics.median(r[2] for r in runs),
                      "seconds": statistics.median(r[1] for r in runs)}
    first = VR_CANDIDATES[0][0]
    base = out[first]
    a_m = np.mean([i.rgb for i in imgs[first]], axis=0, dtype=np.float64)
    a_v = np.mean([i.variance for i in imgs[first]], axis=0, dtype=np.float64) / seeds
    for label, r in out.items():
        r["variance_ratio"] = base["noise_floor"] / r["noise_floor"]
        r["efficiency_ratio"] = r["variance_ratio"] * base["cpu_seconds"] / r["cpu_seconds"]
        if label != first:
            d = np.mean([i.rgb for i in imgs[label]], axis=0, dtype=np.float64) - a_m
            v = np.mean([i.variance for i in imgs[label]], axis=0, dtype=np.float64) / seeds + a_v
            r["mean_z"] = float(d.sum() / math.sqrt(max(v.sum(), 1e-300)))
    return {"spp": spp, "seeds": seeds, "sampler": "independent",
            "resolution": [scene.camera.width, scene.camera.height], **out}


def _hdr_envmap(envmap: str | None) -> Path | None:
    if envmap:
        return Path(envmap)
    for name in ENVMAP_NAMES:
        if (ENVMAPS / name).is_file():
            return ENVMAPS / name
    return None


def run_asset_bench(quick: bool = False) -> dict:
    """The ``asset`` row alone (``pbrcheck bench reference --asset-only``), at the bench's size and spp."""
    from .bench_asset import bench_asset

    _mi()
    W, H = (48, 40) if quick else BENCH_RESOLUTION
    scene = load_scene("spheres").with_camera(width=W, height=H)
    return {"variant": _mi()[0].variant(), "resolution": [W, H], "spp": 8 if quick else BENCH_SPP,
            "asset": bench_asset(scene, 8 if quick else BENCH_SPP, 1 if quick else ASSET_REPEATS, quick=quick)}


def run_sections(sections: tuple[str, ...] = SECTIONS, quick: bool = False, envmap: str | None = None) -> dict:
    """The ``samplers`` and ``variance_reduction`` figures (module docstring) of ``sections``, as in
    :func:`run_bench` (``pbrcheck bench reference --section NAME``: one of them alone)."""
    _mi()
    bad = [x for x in sections if x not in SECTIONS]
    if bad:
        raise ValueError(f"bench reference: section must be one of {SECTIONS}, not {bad[0]!r}")
    W, H = (48, 40) if quick else BENCH_RESOLUTION
    scene = load_scene("spheres").with_camera(width=W, height=H)
    hdr = _hdr_envmap(envmap)
    hscene = (replace(scene, name=f"spheres_{hdr.stem}", environment=Environment(type="file", path=str(hdr)))
              if hdr is not None and hdr.is_file() else None)
    skipped = {"skipped": f"no real HDR environment ({ENVMAPS} absent)"}
    out = {}
    if "samplers" in sections:
        from .bench_asset import (ASSET_SEGMENTS, ASSET_SEGMENTS_QUICK, ASSET_TEXTURE_QUICK, ASSET_TEXTURE_SIZE,
                                  asset_scene, make_asset)

        full = BENCH_RESOLUTION[0] * BENCH_RESOLUTION[1]
        fspp = FLOOR_SPP_QUICK if quick else FLOOR_SPP
        fseeds = FLOOR_SEEDS_QUICK if quick else FLOOR_SEEDS
        samplers = {"spheres": _samplers(scene, fspp, fseeds, SPHERES_DEFAULT_MSE / NOISE_FLOOR_FACTOR, full)}
        samplers["spheres_hdr"] = _samplers(hscene, fspp, fseeds, None, full) if hscene is not None else skipped
        # the asset row's scene (reference.bench_asset): spheres' environment and lights, target as the HDR's
        with tempfile.TemporaryDirectory(prefix="pbrcheck-bench-asset-") as tmp:
            path = make_asset(Path(tmp) / "bench.gltf", segments=ASSET_SEGMENTS_QUICK if quick else ASSET_SEGMENTS,
                              tex=ASSET_TEXTURE_QUICK if quick else ASSET_TEXTURE_SIZE)
            samplers["asset"] = _samplers(asset_scene(scene, path), fspp, fseeds, None, full)
        out["samplers"] = samplers
    if "variance_reduction" in sections:
        vspp = VR_SPP_QUICK if quick else VR_SPP
        vr = {name: _variance_reduction(scene if name == "spheres" else load_scene(name).with_camera(width=W, height=H),
                                        vspp, VR_SEEDS) for name in VR_SCENES}
        vr["spheres_hdr"] = _variance_reduction(hscene, vspp, VR_SEEDS) if hscene is not None else skipped
        out["variance_reduction"] = vr
    if "throughput" in sections:
        out["throughput"] = _throughput(quick)
    return out


def run_bench(quick: bool = False, envmap: str | None = None) -> dict:
    """The figures of the module docstring as one JSON-ready dict (``quick``: small sizes, for tests)."""
    mi, dr = _mi()

    W, H = (48, 40) if quick else BENCH_RESOLUTION
    spp = 8 if quick else BENCH_SPP
    scene = load_scene("spheres").with_camera(width=W, height=H)
    env = load_environment(scene)
    mscene = load_mitsuba_scene(scene, env)
    rep = 1 if quick else RENDER_REPEATS
    r = _time_renders(scene, spp, mscene, env, rep)
    (t_local, c_local, v_local, vc_local), (t_path, c_path, v_path, _) = r["local"], r["path"]
    t_native, c_native, _, _ = r["mitsuba_path"]
    samples = W * H * spp

    lanes = (1 << 16) if quick else BSDF_LANES
    alpha = PEER_ROUGHNESS ** 2
    cpp = mi.load_dict({"type": "roughconductor", "distribution": "ggx", "material": "none", "alpha": alpha})
    py = mi.load_dict({"type": "pbr_material", "base_color": [1.0, 1.0, 1.0], "metallic": 1.0,
                       "roughness": PEER_ROUGHNESS, "ndf": "ggx", "geometry": "smith_ggx", "fresnel": "none"})
    repeats = 3 if quick else BSDF_REPEATS
    s_cpp, tr_cpp, k_cpp = _time_bsdf(cpp, lanes, repeats)
    s_py, tr_py, k_py = _time_bsdf(py, lanes, repeats)
    try:   # issue 39: the frozen BSDF path (a recording Dr.Jit refuses is a figure of its own, not a crash)
        s_fz, tr_fz, k_fz = _time_bsdf(py, lanes, repeats, frozen=True)
        frozen_error = None
    except RuntimeError as e:
        s_fz = tr_fz = k_fz = float("nan")
        frozen_error = str(e).splitlines()[0]
    # ... and at a render's pass width (reference.integrator.max_lanes: 2^26 lanes on CUDA, 2^23 on
    # LLVM), where the integrator traces the BSDF once per pass: the ratio a render pays
    from .integrator import max_lanes
    pass_lanes = (1 << 17) if quick else max_lanes()
    sp_cpp, _, _ = _time_bsdf(cpp, pass_lanes, repeats)
    sp_py, _, _ = _time_bsdf(py, pass_lanes, repeats)

    gather = _time_gather(scene, 2 if quick else 5)
    from .bench_asset import bench_asset  # the asset row: a ~50k-triangle textured glTF (reference.bench_asset)
    asset = bench_asset(scene, spp, max(rep, 1 if quick else ASSET_REPEATS), quick=quick)

    sections = run_sections(quick=quick, envmap=envmap)
    samplers, vr, tp = sections["samplers"], sections["variance_reduction"], sections["throughput"]

    # Time to a trusted verdict: per-sample variance sigma^2 = mean pixel variance (covered pixels,
    # as the comparator's noise floor) x spp.
    sigma2 = vc_local * spp
    spp_floor = max(2, math.ceil(NOISE_FLOOR_FACTOR * sigma2 / SPHERES_DEFAULT_MSE))
    scale = (BENCH_RESOLUTION[0] * BENCH_RESOLUTION[1]) / (W * H)
    seconds_floor = spp_floor * t_local / spp * scale
    figures = {
        "local_msamples_per_s": samples / t_local / 1e6,
        "mitsuba_path_msamples_per_s": samples / t_native / 1e6,
        "local_vs_mitsuba_path": t_native / t_local,
        "integrator_efficiency": (v_path * t_path) / (v_local * t_local),
        "integrator_efficiency_cpu_seconds": (v_path * c_path) / (v_local * c_local),
        "bsdf_speed_ratio": s_cpp / s_py,
        "bsdf_speed_ratio_frozen": s_cpp / s_fz if frozen_error is None else None,
        "bsdf_frozen_error": frozen_error,
        "bsdf_kernel_ratio": k_cpp / k_py,
        "bsdf_speed_ratio_pass_width": sp_cpp / sp_py,
        "seconds_to_10x_noise_floor": seconds_floor,
        "spp_to_10x_noise_floor": spp_floor,
        "cpu_seconds_to_10x_noise_floor": spp_floor * c_local / spp * scale,
        "material_gather_render_speedup": gather["render_speedup"],
        "material_gather_grad_step_speedup": gather["grad_step_speedup"],
        "asset_vs_spheres": asset["vs_spheres"],
        "default_sampler_seconds_speedup": samplers["spheres"][SAMPLER_CONFIGS[-1][0]]["seconds_speedup"],
        "default_sampler_cpu_seconds_speedup": samplers["spheres"][SAMPLER_CONFIGS[-1][0]]["cpu_seconds_speedup"],
        "default_sampler_spp_ratio": samplers["spheres"][SAMPLER_CONFIGS[-1][0]]["spp_ratio"],
    }
    goals = {f"{k}_goal": v for k, v in GOALS.items()}
    met = {k: figures[k] >= v for k, v in GOALS.items()}
    # the throughput goal at the users' spp (issue 39: 1024), by backend
    key = f"vs_path_same_bsdf_at_{tp['goal_spp']}spp"
    figures[key] = tp["vs_path_same_bsdf_at_goal_spp"]
    goals[f"{key}_goal"] = tp["goal"]
    met[key] = tp["goal_met"]
    return {
        **figures, **goals, "goals_met": met,
        "variant": mi.variant(),
        "machine": machine(),
        "throughput": tp,
        "scene": "spheres",
        "resolution": [W, H],
        "resolution_note": "the scene's own resolution" if not quick else "quick: reduced",
        "spp": spp,
        "local_seconds": t_local,
        "local_cpu_seconds": c_local,
        "local_mean_pixel_variance": v_local,
        "local_per_sample_variance_covered": sigma2,
        "path_max_depth": PATH_DEPTH,
        "path_seconds": t_path,
        "path_cpu_seconds": c_path,
        "path_mean_pixel_variance": v_path,
        "mitsuba_path_seconds": t_native,
        "mitsuba_path_cpu_seconds": c_native,
        "mitsuba_path_note": "mi.render + Mitsuba's path (max depth 2, film only) + pbr_material, same sensor",
        "render_repeats": rep,
        "render_timed": "median wall (and CPU) seconds of alternating local / path / Mitsuba path renders "
                        "after a compile run each",
        "bsdf_lanes": lanes,
        "bsdf_pass_lanes": pass_lanes,
        "bsdf_repeats": repeats,
        "bsdf_timed": "sample + eval_pdf per lane, median of repeats after a compile run",
        "roughconductor_seconds_per_sample": s_cpp,
        "pbr_material_seconds_per_sample": s_py,
        "bsdf_trace_seconds": {"roughconductor": tr_cpp, "pbr_material": tr_py, "pbr_material_frozen": tr_fz},
        "bsdf_kernel_seconds": {"roughconductor": k_cpp, "pbr_material": k_py, "pbr_material_frozen": k_fz},
        "peer_roughness": PEER_ROUGHNESS,
        "material_gather": gather,
        "asset": asset,
        "samplers": samplers,
        "variance_reduction": vr,
        "variance_reduction_note": "variance ratio = the default estimator's floor over the candidate's at equal "
                                   "spp (independent sampler, load-independent); efficiency_ratio also weighs "
                                   "their CPU seconds",
        "samplers_note": "each sampler at the same spp, its floor from its own variance channels; spp to the "
                         "floor extrapolated as 1/spp (exact for independent, an upper bound for qmc); seconds "
                         "are wall time under the machine's load: spp_ratio and variance_ratio do not depend on it",
        "noise_floor_factor": NOISE_FLOOR_FACTOR,
        "noise_floor_target_mse": SPHERES_DEFAULT_MSE / NOISE_FLOOR_FACTOR,
        "noise_floor_note": "spp = 10 x per-sample variance / the default preset's MSE on spheres; seconds "
                            "extrapolated from the measured local throughput to 360 x 300",
    }
