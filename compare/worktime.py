"""Wall and CPU seconds by kind of work, across the stages of a run (the report's "where the time went").

The report's stages (:mod:`compare.report.runlog`) say which part of the page took the time; this
says which *kind* of work did, whichever stage asked for it: reference renders (the verdict rule's
pilots included), real-time renders, HDR-FLIP maps, plots, and the time spent waiting for external
renderers (their browsers run in processes of their own). :func:`work` wraps each such call;
nested calls are **exclusive**: a reference render inside a research section counts as
``reference``, and its seconds are taken out of any enclosing kind. CPU seconds are this process's
(``time.process_time``: every thread, Dr.Jit's and llvmpipe's workers included), so a kind measured
while a background thread works (external renderers' prefetch) also counts that thread's CPU.
Counted per thread (a stack each), summed into :data:`WORK`; :func:`snapshot` and :func:`since`
give a run's share.

API: :data:`KINDS`, :data:`WORK`, :func:`work`, :func:`snapshot`, :func:`since`.
"""

from __future__ import annotations

import contextlib
import threading
import time

from reference import kernel_stats

#: The kinds of work counted (in the order the run log shows them).
KINDS = ("reference", "realtime", "flip", "plots", "clients")
#: kind -> {"wall_s", "cpu_s", "calls"}: exclusive seconds of this process so far.
WORK: dict[str, dict] = {k: {"wall_s": 0.0, "cpu_s": 0.0, "calls": 0} for k in KINDS}
_LOCAL = threading.local()
_LOCK = threading.Lock()


@contextlib.contextmanager
def work(kind: str):
    """Count the block's wall and CPU seconds as ``kind`` (one of :data:`KINDS`), less those of
    kinds nested in it; re-raises whatever the block raises (its seconds still count)."""
    if kind not in WORK:
        raise ValueError(f"unknown kind of work {kind!r}; one of {KINDS}")
    stack = getattr(_LOCAL, "stack", None)
    if stack is None:
        stack = _LOCAL.stack = []
    frame = [0.0, 0.0]  # nested kinds' wall and CPU seconds
    stack.append(frame)
    w, c = time.perf_counter(), time.process_time()
    try:
        yield
    finally:
        dw, dc = time.perf_counter() - w, time.process_time() - c
        stack.pop()
        if stack:
            stack[-1][0] += dw
            stack[-1][1] += dc
        kernel_stats.drain()  # Dr.Jit's kernel history, where it is on: its IR freed as it goes
        with _LOCK:
            row = WORK[kind]
            row["wall_s"] += dw - frame[0]
            row["cpu_s"] += dc - frame[1]
            row["calls"] += 1


def snapshot() -> dict:
    """A copy of :data:`WORK` now."""
    with _LOCK:
        return {k: dict(v) for k, v in WORK.items()}


def since(before: dict) -> dict:
    """The work done since ``before`` (a :func:`snapshot`), kinds with calls only."""
    now = snapshot()
    out = {}
    for k, v in now.items():
        b = before.get(k, {})
        calls = v["calls"] - b.get("calls", 0)
        if calls:
            out[k] = {"wall_s": v["wall_s"] - b.get("wall_s", 0.0), "cpu_s": v["cpu_s"] - b.get("cpu_s", 0.0),
                      "calls": calls}
    return out


__all__ = ["KINDS", "WORK", "since", "snapshot", "work"]
