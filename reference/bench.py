"""``pbrcheck bench reference``: integrator efficiency and BSDF speed, as one JSON object.

* ``integrator_efficiency``: on the ``spheres`` scene (reduced resolution, see ``resolution``),
  ``(mean pixel variance x seconds)`` of Mitsuba's ``path`` integrator (max depth 2, same BSDF)
  divided by that of ``local``, at the scene's resolution and the same spp; median wall seconds of
  alternating runs after a compile run (the CPU-seconds ratio is reported too: the machine is shared).
  Goal >= 2.
* ``bsdf_speed_ratio``: seconds per sample of Mitsuba's C++ ``roughconductor`` (ggx, material none,
  alpha = roughness^2) divided by that of ``pbr_material`` in the peer configuration (geometry
  smith_ggx, fresnel none, white metal), timing ``sample`` + ``eval_pdf`` of a wavefront of random
  incident directions (the median of several repeats). Goal >= 0.9.
"""

from __future__ import annotations

import statistics
import time

import numpy as np

from pbrcheck.environment import load_environment
from pbrcheck.scene import load_scene

from .render import _mi, load_mitsuba_scene, render_uncached

BENCH_RESOLUTION = (360, 300)   # the spheres scene's own resolution
BENCH_SPP = 64
RENDER_REPEATS = 3
BSDF_LANES = 1 << 21
BSDF_REPEATS = 7
PEER_ROUGHNESS = 0.5


def _time_renders(scene, spp, mscene, env, repeats):
    """Median wall and CPU seconds and mean pixel variance of ``local`` and ``path`` (depth 2), timed
    alternately (so that load from other processes hits both alike) after one compile run each."""
    runs = {"local": [], "path": []}
    for k in range(repeats + 1):
        for mode in ("local", "path"):
            t, c = time.perf_counter(), time.process_time()
            img = render_uncached(scene, spp=spp, mode=mode, max_depth=2, mscene=mscene, env=env,
                                  progress=False, seed=k)
            if k:
                runs[mode].append((time.perf_counter() - t, time.process_time() - c, float(np.mean(img.variance))))
    out = {}
    for mode, r in runs.items():
        out[mode] = (statistics.median(x[0] for x in r), statistics.median(x[1] for x in r),
                     float(np.mean([x[2] for x in r])))
    return out


def _time_bsdf(bsdf, lanes, repeats):
    mi, dr = _mi()
    rng = np.random.default_rng(0)
    wi = rng.normal(size=(lanes, 3)).astype(np.float32)
    wi[:, 2] = np.abs(wi[:, 2])
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    si = dr.zeros(mi.SurfaceInteraction3f, lanes)
    si.wi = mi.Vector3f(wi[:, 0], wi[:, 1], wi[:, 2])
    u1 = mi.Float(rng.random(lanes, dtype=np.float32))
    u2 = mi.Point2f(rng.random(lanes, dtype=np.float32), rng.random(lanes, dtype=np.float32))
    dr.eval(si, u1, u2)
    ctx = mi.BSDFContext()
    times = []
    for k in range(repeats + 1):
        t = time.perf_counter()
        bs, w = bsdf.sample(ctx, si, u1, u2)
        f, pdf = bsdf.eval_pdf(ctx, si, bs.wo)
        dr.eval(w, f, pdf)
        dr.sync_thread()
        if k:  # the first run compiles
            times.append(time.perf_counter() - t)
    return statistics.median(times) / lanes


def run_bench(quick: bool = False) -> dict:
    mi, dr = _mi()

    W, H = (48, 40) if quick else BENCH_RESOLUTION
    spp = 8 if quick else BENCH_SPP
    scene = load_scene("spheres").with_camera(width=W, height=H)
    env = load_environment(scene)
    mscene = load_mitsuba_scene(scene, env)
    rep = 1 if quick else RENDER_REPEATS
    r = _time_renders(scene, spp, mscene, env, rep)
    (t_local, c_local, v_local), (t_path, c_path, v_path) = r["local"], r["path"]

    lanes = (1 << 16) if quick else BSDF_LANES
    alpha = PEER_ROUGHNESS ** 2
    cpp = mi.load_dict({"type": "roughconductor", "distribution": "ggx", "material": "none", "alpha": alpha})
    py = mi.load_dict({"type": "pbr_material", "base_color": [1.0, 1.0, 1.0], "metallic": 1.0,
                       "roughness": PEER_ROUGHNESS, "ndf": "ggx", "geometry": "smith_ggx", "fresnel": "none"})
    repeats = 3 if quick else BSDF_REPEATS
    s_cpp = _time_bsdf(cpp, lanes, repeats)
    s_py = _time_bsdf(py, lanes, repeats)
    return {
        "integrator_efficiency": (v_path * t_path) / (v_local * t_local),
        "integrator_efficiency_goal": 2.0,
        "integrator_efficiency_cpu_seconds": (v_path * c_path) / (v_local * c_local),
        "bsdf_speed_ratio": s_cpp / s_py,
        "bsdf_speed_ratio_goal": 0.9,
        "scene": "spheres",
        "resolution": [W, H],
        "resolution_note": "the scene's own resolution" if not quick else "quick: reduced",
        "spp": spp,
        "local_seconds": t_local,
        "local_cpu_seconds": c_local,
        "local_mean_pixel_variance": v_local,
        "path_max_depth": 2,
        "path_seconds": t_path,
        "path_cpu_seconds": c_path,
        "path_mean_pixel_variance": v_path,
        "render_repeats": rep,
        "render_timed": "median wall (and CPU) seconds of alternating local/path renders after a compile run",
        "bsdf_lanes": lanes,
        "bsdf_repeats": repeats,
        "bsdf_timed": "sample + eval_pdf per lane, median of repeats after a compile run",
        "roughconductor_seconds_per_sample": s_cpp,
        "pbr_material_seconds_per_sample": s_py,
        "peer_roughness": PEER_ROUGHNESS,
        "variant": mi.variant(),
    }
