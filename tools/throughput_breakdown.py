"""Where the default reference render's CPU time goes against Mitsuba's ``path`` (issue 39).

Prints, for ``spheres`` at a size and spp (default 90 x 75, 1024 spp), the median process CPU
seconds of warm renders of: the default (``qmc`` adaptive, error bars, AOVs), ``qmc`` uniform,
``qmc`` uniform lean, ``independent`` uniform with and without AOVs, and ``mi.render`` + ``path`` +
the same BSDF (``reference.bench._peer_scenes``); then one default render's pilot and levels,
each group's pixels, replicates, samples, CPU seconds and ns a sample. docs/reference.md's
"blocker" table is its output.

    .venv/bin/python tools/throughput_breakdown.py [--size 90x75] [--spp 1024] [--repeats 3]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

import pbrcheck  # noqa: F401  (DRJIT_LIBLLVM_PATH before drjit)
from pbrcheck.scene import load_scene
from reference import bench
from reference import render as R


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="90x75")
    ap.add_argument("--spp", type=int, default=1024)
    ap.add_argument("--repeats", type=int, default=3)
    a = ap.parse_args()
    W, H = (int(x) for x in a.size.split("x"))
    mi, dr = R._mi()
    scene = load_scene("spheres").with_camera(width=W, height=H)
    env = R.load_environment(scene)
    ms = R.load_mitsuba_scene(scene, env)
    peer = bench._peer_scenes(scene, env, a.spp)["same_bsdf"]
    cfgs = {"default": {}, "qmc_uniform": {"adaptive": False},
            "qmc_uniform_lean": {"adaptive": False, **R.LEAN_OUTPUTS},
            "independent": {"sampler": "independent"},
            "independent_no_aovs": {"sampler": "independent", "aovs": False}}
    runs = {k: [] for k in [*cfgs, "path_same_bsdf"]}
    for rep in range(a.repeats + 1):
        for k in runs:
            c = time.process_time()
            if k == "path_same_bsdf":
                dr.eval(mi.render(peer, spp=a.spp, seed=rep))
                dr.sync_thread()
            else:
                R.render_uncached(scene, spp=a.spp, seed=rep, mscene=ms, env=env, progress=False, **cfgs[k])
            if rep:   # the first run compiles
                runs[k].append(time.process_time() - c)
    med = {k: statistics.median(v) for k, v in runs.items()}
    print(f"machine: {bench.machine()}; spheres {W} x {H}, {a.spp} spp; median CPU s of {a.repeats} warm renders")
    for k, v in med.items():
        print(f"  {k:22s} {v:.3f} s   path / this {med['path_same_bsdf'] / v:.2f}")

    from reference.integrator import ReferenceIntegrator
    orig = ReferenceIntegrator.render_groups
    log = []

    def timed(self, scene, sensor, groups, seed, W, H, variance=True):
        acc = None
        for g in groups:
            c = time.process_time()
            out = np.array(orig(self, scene, sensor, [g], seed, W, H, variance))
            log.append((W * H if g[0] is None else len(g[0]), g[1], g[2], time.process_time() - c))
            acc = out if acc is None else acc + out
        return mi.TensorXf(acc)

    ReferenceIntegrator.render_groups = timed
    try:
        img = R.render_uncached(scene, spp=a.spp, seed=a.repeats + 1, mscene=ms, env=env, progress=False)
    finally:
        ReferenceIntegrator.render_groups = orig
    print(f"one default render by group ({img.meta.get('adaptive')}): the first is the pilot")
    for npx, K, n, t in log:
        s = npx * K * n
        print(f"  {npx:6d} px  K {K:2d} x n {n:5d} = {K * n:6d} spp  {s / 1e6:6.2f} M samples  {t:.3f} s  "
              f"{t / s * 1e9:4.0f} ns a sample")


if __name__ == "__main__":
    main()
