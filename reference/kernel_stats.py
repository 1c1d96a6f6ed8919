"""Dr.Jit kernel counts of a run: kernels launched, compiled, loaded from the disk cache.

Load-independent figures of the reference's cost (issue 39): a compile is ~0.1-1 s of LLVM (CPU) or
NVRTC/PTX time whatever else runs, and a launch costs Python tracing and a kernel-cache lookup. The
counts come from ``dr.kernel_history()`` (``JitFlag.KernelHistory``): every JIT kernel launched,
``cache_hit`` 0 where it was not in the process's in-memory cache (then compiled, or loaded from
Dr.Jit's disk cache: ``cache_disk``). The history keeps each launch's IR until it is read, so it is
on only where asked (:func:`start`, or the environment variable :data:`ENV` set to 1, which
``pbrcheck bench report`` sets for its report runs), and :func:`drain` folds it into running totals
(:data:`TOTALS`) at each stage's end and after each kind of work (``compare.worktime.work``).

API: :data:`ENV`, :data:`TOTALS`, :func:`start`, :func:`active`, :func:`drain`, :func:`snapshot`,
:func:`since`, :func:`count`, :func:`start_if_asked`.
"""

from __future__ import annotations

import os
import sys
import threading

#: Set to 1 in a process's environment to count its kernels from its first stage on.
ENV = "PBRCHECK_KERNEL_HISTORY"
#: Running totals: JIT kernels ``launched``, ``compiled`` (not in memory: compiled or read from the
#: disk cache), ``disk`` (of those, read from Dr.Jit's disk cache), ``compiled_ops`` (their IR
#: operations, summed).
TOTALS = {"launched": 0, "compiled": 0, "disk": 0, "compiled_ops": 0}
_LOCK = threading.Lock()


def start() -> None:
    """Turn Dr.Jit's kernel history on (imports Dr.Jit)."""
    import drjit as dr  # local: a process that never renders with Dr.Jit needs none of it

    dr.set_flag(dr.JitFlag.KernelHistory, True)


def active() -> bool:
    """Whether the history is on (False where Dr.Jit is not imported)."""
    dr = sys.modules.get("drjit")
    return dr is not None and bool(dr.flag(dr.JitFlag.KernelHistory))


def count(history) -> dict:
    """The counts of a ``dr.kernel_history()`` list (JIT kernels only: memsets, copies and block
    reductions are Dr.Jit's precompiled routines)."""
    import drjit as dr

    out = {k: 0 for k in TOTALS}
    for h in history:
        if h.get("type") != dr.KernelType.JIT:
            continue
        out["launched"] += 1
        if not h.get("cache_hit"):
            out["compiled"] += 1
            out["disk"] += int(bool(h.get("cache_disk")))
            out["compiled_ops"] += int(h.get("operation_count") or 0)
    return out


def drain() -> None:
    """Fold the history so far into :data:`TOTALS` (and free its IR); nothing where it is off."""
    if not active():
        return
    import drjit as dr

    with _LOCK:
        c = count(dr.kernel_history())
        for k, v in c.items():
            TOTALS[k] += v


def snapshot() -> dict:
    """:data:`TOTALS` now (after a :func:`drain`), or None where the history is off."""
    if not active():
        return None
    drain()
    with _LOCK:
        return dict(TOTALS)


def since(before: dict | None) -> dict | None:
    """The counts since ``before`` (a :func:`snapshot`; None: since the history was turned on)."""
    now = snapshot()
    if now is None:
        return None
    return {k: v - (before or {}).get(k, 0) for k, v in now.items()}


def start_if_asked() -> None:
    """:func:`start` where the environment asks for it (:data:`ENV` = 1)."""
    if os.environ.get(ENV) == "1":
        start()


__all__ = ["ENV", "TOTALS", "active", "count", "drain", "since", "snapshot", "start", "start_if_asked"]
