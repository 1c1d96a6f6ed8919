"""The task functions of a corpus: what runs on a worker (or in this process, serially).

Each function takes plain, picklable arguments (scenes are frozen dataclasses, images
:class:`~pbrcheck.exr.Image`) and returns a picklable value or :class:`~compare.corpus.scheduler.Failed`
for a typed error; a :class:`Failed` argument is passed on unchanged, so an unreadable environment
gives one error row per renderer without rendering anything.

Renders go through :mod:`compare.renderers` (so ``ext:NAME`` renderers work wherever the seam
accepts them) on one dedicated thread per process (:func:`on_render_thread`): the GL context and
the Mitsuba variant belong to the process and are created by the renderers on first use, and the
GL context is never touched from two threads.

API
---
- :func:`environment_task` -- statistics and thumbnail of one environment file.
- :func:`reference_task`, :func:`render_task` -- the reference and one renderer under test.
- :func:`compare_task` -- the comparison: every metric, its noise flag, pixel counts and timings.
- :func:`on_render_thread` -- run a function on this process's render thread.
"""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor

from pbrcheck.environment import load_environment
from pbrcheck.errors import PbrcheckError
from pbrcheck.scene import Scene

from .. import renderers
from ..metrics import METRICS, compare_images
from ..timings import image_timings, timed_on
from .envstats import environment_stats, thumbnail
from .scheduler import Failed, failure_of

#: Environments whose bakes a process keeps between renders (:func:`compare.renderers.trim_caches`):
#: a worker sees each environment for a few consecutive tasks (one per renderer); keeping every
#: one would grow a worker by ~30 MiB per 1k environment over a long corpus.
KEEP_ENVIRONMENTS = 4

_render_pool: ThreadPoolExecutor | None = None
_render_pool_lock = threading.Lock()


def on_render_thread(fn, *args, **kwargs):
    """``fn(*args, **kwargs)`` on this process's one render thread (directly when called from the
    main thread, as the serial executor does: the renderers' context then lives there)."""
    global _render_pool
    if threading.current_thread() is threading.main_thread():
        return fn(*args, **kwargs)
    with _render_pool_lock:
        if _render_pool is None:
            _render_pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="pbrcheck-render")
    return _render_pool.submit(fn, *args, **kwargs).result()


def environment_task(scene: Scene) -> dict | Failed:
    """Load and validate ``scene``'s environment; its statistics
    (:func:`compare.corpus.envstats.environment_stats`) and ``thumb`` (uint8 sRGB array)."""
    try:
        env = load_environment(scene)
        return {"stats": environment_stats(env), "thumb": thumbnail(env)}
    except PbrcheckError as e:
        return failure_of("environment", e)


def reference_task(env: dict | Failed, scene: Scene, spp: int, seed: int, mode: str):
    """The reference image (through the render cache of the worker's ``PBRCHECK_CACHE``)."""
    if isinstance(env, Failed):
        return env
    try:
        return on_render_thread(renderers.render_reference, scene, spp=spp, seed=seed, mode=mode,
                                use_cache=True, progress=False)
    except PbrcheckError as e:
        return failure_of("reference", e)


def _render_bounded(scene: Scene, spec: renderers.RendererSpec, context: renderers.RenderContext):
    renderers.trim_caches(KEEP_ENVIRONMENTS)
    return renderers.render_under_test(scene, spec, progress=False, context=context)


def render_task(env: dict | Failed, scene: Scene, spec: renderers.RendererSpec,
                context: renderers.RenderContext = renderers.DIRECT):
    """The image of renderer ``spec`` (rendered in ``context``: the report's cache setting);
    ``meta["render_seconds"]`` is its wall time."""
    if isinstance(env, Failed):
        return env
    try:
        t0 = time.perf_counter()
        img = on_render_thread(_render_bounded, scene, spec, context)
        img.meta["render_seconds"] = f"{time.perf_counter() - t0:.6f}"
        return img
    except PbrcheckError as e:
        return failure_of("render", e)


def _seconds(meta: dict, key: str) -> float | None:
    try:
        return float(meta[key])
    except (KeyError, TypeError, ValueError):
        return None


def compare_task(env: dict | Failed, ref, img, scene: Scene) -> dict | Failed:
    """Compare ``img`` with ``ref``: ``metrics`` (name -> value), ``noise`` (name -> within the
    reference's noise), ``pixels`` (valid / edge / background counts), ``stats`` (the environment's)
    ``timings`` (``reference_s``, ``render_s``, ``precompute_s``, ``frame_s``, ``compare_s``) and
    ``timed_on`` (:func:`compare.timings.timed_on`: the GL renderer and clock of the render's times)."""
    for x in (env, ref, img):
        if isinstance(x, Failed):
            return x
    try:
        t0 = time.perf_counter()
        cmp = compare_images(ref, img, scene=scene, ref_name="reference", test_name="renderer under test")
        compare_s = time.perf_counter() - t0
    except PbrcheckError as e:
        return failure_of("compare", e)
    noise = cmp.summary["noise"]
    pre, frame = image_timings(img)
    return {"metrics": dict(cmp.metrics),
            "noise": {m: bool(noise and noise["within_noise"].get(m)) for m in METRICS},
            "pixels": dict(cmp.summary["pixels"]), "stats": env["stats"],
            "timings": {"reference_s": _seconds(ref.meta, "seconds"), "render_s": _seconds(img.meta, "render_seconds"),
                        "precompute_s": pre, "frame_s": frame, "compare_s": compare_s},
            "timed_on": timed_on(img)}
