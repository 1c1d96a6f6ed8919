"""The render lists of ``pbrcheck sweep`` and ``pbrcheck report`` on a scheduler (``--scheduler``).

Both commands render one scene with several renderers or option sets against one reference. With
an executor from :func:`compare.corpus.scheduler.open_executor` those renders (and, for the sweep,
the comparisons) run as tasks of :mod:`compare.corpus.tasks` on the cluster; the reference is
rendered by the caller and shipped once (one task returns it, every comparison depends on it).
Results come back in list order. A failed render raises its :class:`~pbrcheck.errors.PbrcheckError`
here, as the same render would without a scheduler.

API
---
- :func:`render_images` -- images of (renderer, options) pairs.
- :func:`sweep_metrics` -- per option set: the metrics against the reference and the timings.
"""

from __future__ import annotations

from pbrcheck.cache import cache_key
from pbrcheck.environment import scene_hash
from pbrcheck.errors import PbrcheckError
from pbrcheck.scene import Scene

from .. import renderers
from ..metrics import compare_images
from ..timings import image_timings, timed_on
from . import tasks as T
from .scheduler import Dep, Failed, Task
from .study import code_identity

#: ``environment_task`` is not needed for a scene's own environment: the render tasks get this
#: stand-in for its result.
_ENV_OK: dict = {"stats": {}}


def _identity(x):
    return x


def _raise(value):
    if isinstance(value, Failed):
        raise PbrcheckError(f"{value.stage}: {value.message}")
    return value


def _render_tasks(scene: Scene, jobs: list[tuple[str, dict | None]],
                  context: renderers.RenderContext) -> list[Task]:
    # Keyed by content: the scene with its environment's pixels (not the file's path) and each
    # renderer's code (:func:`compare.corpus.study.code_identity`). A long-lived Dask scheduler
    # (tcp://) hands back a task it still holds under the same key: a key of the path and the
    # options alone gave the render of an environment file or a shader as it was before an edit.
    base = scene_hash(scene)
    code_identity.cache_clear()  # this call's code
    local = context.local()  # a worker process cannot reach this process's background renders
    return [Task(f"render-{cache_key(base=base, renderer=n, options=o or {}, code=code_identity(n))}", T.render_task,
                 (_ENV_OK, scene, n, o or None, local), "render", deliver=True) for n, o in jobs]


def render_images(executor, scene: Scene, jobs: list[tuple[str, dict | None]], progress=None, *,
                  context: renderers.RenderContext = renderers.DIRECT) -> list:
    """The images of ``scene`` for each (renderer name, options) of ``jobs``, rendered by ``executor``
    (with ``context``'s cache setting: :class:`compare.renderers.RenderContext`).

    Raises
    ------
    PbrcheckError
        A render failed (the first failure, with its message)."""
    tasks = _render_tasks(scene, jobs, context)
    out: dict[str, object] = {}
    executor.run(tasks, lambda t, v: out.__setitem__(t.key, v), _StageProgress(progress, "render"))
    return [_raise(out[t.key]) for t in tasks]


class _StageProgress:
    """Forwards ``update`` to ``progress`` for the tasks of one stage only (one step per job)."""

    def __init__(self, progress, stage: str):
        self.progress, self.stage = progress, stage

    def update(self, n: float = 1.0, note: str = ""):
        if self.progress is not None and note == self.stage:
            self.progress.update(n, note)


def _sweep_row(ref, img, scene, flip_cache: bool = False):
    if isinstance(img, Failed):
        return img
    try:
        cmp = compare_images(ref, img, scene=scene, noise=False, flip_cache=flip_cache)
    except PbrcheckError as e:
        return Failed("compare", str(e))
    pre, frame = image_timings(img)
    return {"metrics": dict(cmp.metrics), "precompute_s": pre, "frame_s": frame, "timed_on": timed_on(img)}


def sweep_metrics(executor, scene: Scene, ref, jobs: list[tuple[str, dict | None]], progress=None, *,
                  context: renderers.RenderContext = renderers.DIRECT) -> list[dict]:
    """Per (renderer, options) of ``jobs``: ``{"metrics", "precompute_s", "frame_s", "timed_on"}`` of its render
    against ``ref`` (no noise simulation, as the sweep), computed by ``executor``.

    Raises
    ------
    PbrcheckError
        A render or comparison failed."""
    renders = [replace_deliver(t) for t in _render_tasks(scene, jobs, context)]
    ref_key = f"sweep-reference-{cache_key(renders=[t.key for t in renders])}"
    tasks = [Task(ref_key, _identity, (ref,), "reference"), *renders]
    rows = [Task(f"sweep-compare-{t.key}", _sweep_row, (Dep(ref_key), Dep(t.key), scene, context.flip_cache), "compare", deliver=True)
            for t in renders]
    out: dict[str, object] = {}
    executor.run(tasks + rows, lambda t, v: out.__setitem__(t.key, v), _StageProgress(progress, "compare"))
    return [_raise(out[t.key]) for t in rows]


def replace_deliver(task: Task) -> Task:
    """``task`` with ``deliver`` off (its result stays on the cluster)."""
    return Task(task.key, task.fn, task.args, task.stage, deliver=False)
