"""Traced against frozen (``dr.freeze``) timings of the reference's three frozen paths (issue 39).

Prints one JSON object, the machine named: for each path the median wall seconds of warm calls
traced and frozen, their ratio, and how often the frozen function recorded:

* ``render_pass``: ``ReferenceIntegrator.render_groups`` of spheres (16 replicates x 4 samples) with
  ``freeze`` off and on (``reference.frozen``);
* ``bsdf_path``: a ``pbr_material``'s ``sample`` + ``eval_pdf`` on 2^21 lanes
  (``reference.frozen.FrozenSampleEval``);
* ``fit_step``: one step of ``reference.diff.GradientStep`` (render, loss, backward) of spheres'
  three roughness parameters at 8 spp.

Usage (CPU here, CUDA on the GPU machine: ``tools/gpu/issue39.sh``)::

    .venv/bin/python tools/frozen_timings.py [--size 90x75] [--repeats 10]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np

import pbrcheck  # noqa: F401  (DRJIT_LIBLLVM_PATH before drjit)
from pbrcheck.scene import load_scene


def _median_wall(fn, repeats: int, warm: int = 2) -> float:
    for _ in range(warm):
        fn()
    ts = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return statistics.median(ts)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="90x75")
    ap.add_argument("--repeats", type=int, default=10)
    a = ap.parse_args()
    W, H = (int(x) for x in a.size.split("x"))
    from reference.variant import ensure_variant

    ensure_variant()   # (the reference's modules define Mitsuba classes at import)
    from reference import bench
    from reference import render as R
    from reference.diff import GradientStep, load_differentiable_scene, mse_loss, param_key, render_image
    from reference.frozen import FrozenSampleEval
    from reference.integrator import sensor_dict

    mi, dr = R._mi()

    def sync(x):
        dr.eval(x)
        dr.sync_thread()

    out = {"machine": bench.machine(), "size": [W, H], "repeats": a.repeats}
    scene = load_scene("spheres").with_camera(width=W, height=H)
    ms = R.load_mitsuba_scene(scene)
    sensor = mi.load_dict(sensor_dict(scene.camera, 64, "qmc"))
    row = {}
    for frozen in (False, True):
        integ = R.load_integrator("local", sampler="qmc")
        integ.freeze = frozen
        row["frozen" if frozen else "traced"] = _median_wall(
            lambda: integ.render_groups(ms, sensor, [(None, 16, 4, 0)], 1, W, H), a.repeats)
        if frozen:
            row["recordings"] = int(integ._frozen.n_recordings) if integ._frozen is not None else 0
    out["render_pass"] = row

    bsdf = mi.load_dict({"type": "pbr_material", "base_color": [1.0, 1.0, 1.0], "metallic": 1.0, "roughness": 0.5})
    si, u1, u2 = bench.bsdf_lanes(1 << 21)
    row = {}
    for frozen in (False, True):
        fse = FrozenSampleEval(bsdf, freeze=frozen)
        row["frozen" if frozen else "traced"] = _median_wall(lambda: sync(fse(si, u1, u2)[1:]), a.repeats)
        if frozen:
            row["recordings"] = fse.n_recordings
    out["bsdf_path"] = row

    dms, params = load_differentiable_scene(scene)
    keys = [param_key(i, "roughness") for i in range(len(scene.objects))]
    tgt = mi.TensorXf(np.asarray(render_image(dms, params, spp=16, seed=5), dtype=np.float32))
    for k in keys:
        dr.enable_grad(params[k])
    params.update()
    row = {}
    for frozen in (False, True):
        step = GradientStep(dms, params, keys, mse_loss, spp=8, freeze=frozen)
        seeds = iter(range(10_000))
        row["frozen" if frozen else "traced"] = _median_wall(lambda: sync(step(tgt, next(seeds))), a.repeats)
        if frozen:
            row["recordings"] = step.n_recordings
    out["fit_step"] = row
    for k in ("render_pass", "bsdf_path", "fit_step"):
        out[k]["speedup"] = out[k]["traced"] / out[k]["frozen"]
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
