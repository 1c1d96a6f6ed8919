"""``pbrcheck bench corpus``: a corpus serially and on a LocalCluster, and Dask's overhead per task.

A corpus of ``envs`` generated sun-and-sky environments (suns of different sizes and brightness,
written as EXR to a temporary folder) lights the CI-size spheres scene (120 x 100,
``compare/budgets/spheres_ci.toml``). Each run gets an empty render cache, so both compute the same
renders. Figures (JSON on stdout):

* ``serial_s`` -- wall time of the serial run; ``task_mean_s`` = ``serial_s / tasks``.
* ``cluster_start_s`` -- starting the LocalCluster of ``workers`` processes (not in ``dask_s``).
* ``dask_s`` -- wall time of the same corpus on it; ``speedup`` = ``serial_s / dask_s``.
* ``compute_s`` -- the sum of the tasks' compute times on the workers (Dask's task stream).
* ``idle_per_task_s`` = ``(dask_s * workers - compute_s) / tasks``: time a worker was not computing,
  per task (scheduling, transfers, and waiting at the end of the graph when fewer tasks than
  workers are left).
* ``overhead_per_task_s`` -- Dask's own cost per task: the wall time of ``tasks`` no-op tasks on the
  same cluster times ``workers``, over ``tasks``; ``overhead_fraction`` = that over
  ``task_mean_s`` (goal: :data:`OVERHEAD_GOAL`).
"""

from __future__ import annotations

import math
import os
import tempfile
import time
from pathlib import Path

from pbrcheck.cache import CACHE_ENV
from pbrcheck.environment import rasterize_sky
from pbrcheck.exr import Image, write_exr
from pbrcheck.scene import Environment, load_scene

from .scheduler import Task, open_executor, parse_scheduler
from ..renderers import RendererSpec
from .study import CorpusSettings, run_corpus

#: Scheduling overhead goal, as a fraction of the mean task time.
OVERHEAD_GOAL = 0.05
#: The CI-size scene of the benchmark.
BENCH_SCENE = Path(__file__).resolve().parents[1] / "budgets" / "spheres_ci.toml"


def make_environments(folder: Path, n: int, size: tuple[int, int] = (256, 128)) -> list[Path]:
    """Write ``n`` sun-and-sky EXRs into ``folder``: sun diameters from 30 down to 0.5 degrees
    (log-spaced) with the sun's power held fixed, so the energy concentrates as the sun shrinks."""
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for i in range(n):
        diam = 30.0 * (0.5 / 30.0) ** (i / max(n - 1, 1))
        radiance = 60.0 * (8.0 / diam) ** 2  # same solid-angle integral as an 8-degree, 60-radiance sun
        env = Environment(type="sky", sun_angular_diameter=diam, sun_radiance=(radiance, radiance * 0.95, radiance * 0.85),
                          sun_direction=(math.cos(i), 0.7, math.sin(i)), resolution=size)
        a = rasterize_sky(env)
        p = folder / f"sky_{i:02d}.exr"
        write_exr(p, Image({"R": a[..., 0], "G": a[..., 1], "B": a[..., 2]}))
        paths.append(p)
    return paths


def _noop(x):
    return x


def run_bench(*, envs: int = 6, presets: tuple[str, ...] = ("default", "runtime_is20"), spp: int = 16,
              workers: int = 2, scene: str | Path = BENCH_SCENE) -> dict:
    """Run the benchmark (see the module docstring); returns the figures."""
    from distributed import get_task_stream  # local: Dask only for this benchmark

    st = CorpusSettings(load_scene(scene), tuple(RendererSpec.parse(p) for p in presets), spp=spp)
    old_cache = os.environ.get(CACHE_ENV)
    with tempfile.TemporaryDirectory(prefix="pbrcheck-bench-corpus-") as tmp:
        tmp = Path(tmp)
        make_environments(tmp / "envs", envs)
        try:
            os.environ[CACHE_ENV] = str(tmp / "cache-serial")
            t0 = time.perf_counter()
            res = run_corpus(tmp / "envs", st, tmp / "serial", scheduler="serial", progress=False, outputs=False)
            serial_s = time.perf_counter() - t0
            n = res.tasks
            os.environ[CACHE_ENV] = str(tmp / "cache-dask")  # workers inherit it: an empty cache
            t0 = time.perf_counter()
            with open_executor(parse_scheduler(f"local:{workers}")) as ex:
                ex.client.wait_for_workers(workers)
                start_s = time.perf_counter() - t0
                with get_task_stream(ex.client) as ts:
                    t0 = time.perf_counter()
                    res2 = run_corpus(tmp / "envs", st, tmp / "dask", executor=ex, progress=False, outputs=False)
                    dask_s = time.perf_counter() - t0
                compute_s = sum(ss["stop"] - ss["start"] for rec in ts.data for ss in rec.get("startstops", ())
                                if ss.get("action") == "compute")
                noop = [Task(f"noop-{i}", _noop, (i,), "noop") for i in range(n)]
                t0 = time.perf_counter()
                ex.run(noop, lambda t, v: None)
                noop_s = time.perf_counter() - t0
        finally:
            if old_cache is None:
                os.environ.pop(CACHE_ENV, None)
            else:
                os.environ[CACHE_ENV] = old_cache
    same = [{k: v for k, v in r.items() if not k.endswith("_s")} for r in res.rows] == \
           [{k: v for k, v in r.items() if not k.endswith("_s")} for r in res2.rows]
    task_mean = serial_s / n
    overhead = noop_s * workers / n
    return {"scene": st.scene.name, "size": [st.scene.camera.width, st.scene.camera.height], "spp": spp,
            "presets": list(presets), "environments": envs, "tasks": n, "workers": workers,
            "serial_s": round(serial_s, 3), "task_mean_s": round(task_mean, 4),
            "cluster_start_s": round(start_s, 3), "dask_s": round(dask_s, 3),
            "speedup": round(serial_s / dask_s, 3), "compute_s": round(compute_s, 3),
            "idle_per_task_s": round((dask_s * workers - compute_s) / n, 4),
            "overhead_per_task_s": round(overhead, 5), "overhead_fraction": round(overhead / task_mean, 5),
            "overhead_goal": OVERHEAD_GOAL, "overhead_within_goal": bool(overhead / task_mean < OVERHEAD_GOAL),
            "rows_identical": bool(same), "cpu_count": os.cpu_count()}


__all__ = ["run_bench", "make_environments", "OVERHEAD_GOAL"]
