"""Run ``pbrcheck report ARGS`` with every piece of work logged, and print where the CPU went.

    .venv/bin/python tools/report_trace.py [--external-cpu] [--json FILE] -- REPORT ARGS

Run it with an empty ``PBRCHECK_CACHE`` (and a fresh ``HOME``) to see a first run (issue 25, the
120 s goal: docs/compare.md). Each real-time bake that misses the per-process ``_baked`` cache
(prefilter, irradiance, DFG LUT, ...), each real-time render (its frame: its CPU less its bakes'),
each reference render and each HDR-FLIP map is logged with the report stage that asked for it and
its CPU and wall seconds; the summary prints totals by kind and by (stage, kind), the keys rendered
or baked more than once (none means no repeated work), and the largest single items.
``--external-cpu``: also the CPU seconds of the external renderers' processes (node and Chromium run
in sessions of their own that ``run.json`` does not count): ``/proc`` polled every 0.1 s for the
processes of those sessions (a lower bound: the last ticks of a short-lived process can be missed).
Wraps internals (``realtime.render._baked``, ``render_realtime``, ``reference.render.render_uncached``,
``compare.metrics._flip_map``, ``RunLog.stage``); measures, changes nothing on disk but the report.
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import functools
import hashlib
import json
import os
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import compare.metrics as _metrics  # noqa: E402
import compare.renderers  # noqa: E402,F401  (imported before the patch: it holds names by value)
import compare.report.build  # noqa: E402,F401
import compare.report.runlog as _runlog  # noqa: E402
import compare.verdict_spp  # noqa: E402,F401
import realtime.cache  # noqa: E402,F401
import realtime.render as _rt  # noqa: E402
import reference.render as _ref  # noqa: E402

LOG: list[dict] = []
_STAGE = {"name": "(set-up)"}


def _entry(kind: str, key: str, cpu: float, wall: float) -> None:
    LOG.append({"kind": kind, "stage": _STAGE["name"], "key": key, "cpu": cpu, "wall": wall})


def _traced(kind: str, fn, describe):
    @functools.wraps(fn)
    def wrapper(*a, **k):
        c, w = time.process_time(), time.perf_counter()
        out = fn(*a, **k)
        cpu, wall = time.process_time() - c, time.perf_counter() - w   # before describing it
        _entry(kind, describe(a, k), cpu, wall)
        return out
    return wrapper


def _install() -> None:
    stage = _runlog.RunLog.stage

    @contextlib.contextmanager
    def named_stage(self, name):
        _STAGE["name"] = name
        with stage(self, name):
            yield

    _runlog.RunLog.stage = named_stage
    baked = _rt._baked

    def traced_baked(key, timings, run):  # key: realtime.presets.bake_key, its first element the bake
        if key in _rt._cache:
            return baked(key, timings, run)
        c, w = time.process_time(), time.perf_counter()
        out = baked(key, timings, run)
        _entry("bake:" + key[0], repr(key), time.process_time() - c, time.perf_counter() - w)
        return out

    _rt._baked = traced_baked
    patched = {
        "render_realtime": _traced("realtime", _rt.render_realtime, lambda a, k: (
            f"{a[0].name} {a[0].camera.width}x{a[0].camera.height} {a[1] if len(a) > 1 else k.get('preset')} "
            f"{a[2] if len(a) > 2 else k.get('options')}")),
        "render_uncached": _traced("reference", _ref.render_uncached, lambda a, k: (
            f"{a[0].name} {a[0].camera.width}x{a[0].camera.height} spp={k.get('spp')} mode={k.get('mode')} "
            f"seed={k.get('seed')} key={_reference_key(a[0], k)[:12]}")),
        "_flip_map": _traced("flip", _metrics._flip_map, lambda a, k: (
            f"{a[0].shape} inputs={hashlib.sha256(a[0].tobytes() + a[1].tobytes()).hexdigest()[:12]}")),
    }
    owners = {"render_realtime": _rt, "render_uncached": _ref, "_flip_map": _metrics}
    for name, fn in patched.items():
        setattr(owners[name], name, fn)
        for m in list(sys.modules.values()):   # modules that imported the name by value
            if m is not None and m is not owners[name] and getattr(m, name, None) is not None and \
                    getattr(m, "__name__", "").startswith(("compare", "realtime", "reference", "pbrcheck")):
                setattr(m, name, fn)


def _reference_key(scene, k: dict) -> str:
    """The reference cache's key of a render_uncached call (scene content included: diagnose's
    hypothesis scenes share the name and size of the scene they edit)."""
    return _ref.reference_cache_key(scene, spp=k.get("spp", 64), mode=k.get("mode", "local"), seed=k.get("seed", 0),
                                    max_depth=k.get("max_depth"), **{n: k[n] for n in ("sampler", "adaptive") if n in k})


class _ExternalCpu:
    """CPU ticks of the processes in sessions led by this process's children (node, Chromium)."""

    def __init__(self):
        self.ticks: dict[int, int] = {}
        self.sessions: set[int] = set()
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._poll, daemon=True)

    @staticmethod
    def _stat(pid: int):
        s = open(f"/proc/{pid}/stat").read()
        f = s[s.rfind(")") + 2:].split()
        return int(f[1]), int(f[3]), int(f[11]) + int(f[12])  # ppid, session, utime + stime

    def _poll(self):
        me = os.getpid()
        while not self.stop.is_set():
            for p in os.listdir("/proc"):
                if not p.isdigit():
                    continue
                try:
                    ppid, sid, ticks = self._stat(int(p))
                    if sid not in self.sessions and sid == int(p) and ppid == me:
                        self.sessions.add(sid)
                except (OSError, ValueError, IndexError):
                    continue
                if sid in self.sessions:
                    self.ticks[int(p)] = max(self.ticks.get(int(p), 0), ticks)
            time.sleep(0.1)

    def seconds(self) -> float:
        return sum(self.ticks.values()) / os.sysconf("SC_CLK_TCK")


def summary(log: list[dict]) -> str:
    """The totals by kind and by (stage, kind), the repeated keys and the largest items, as text."""
    lines = []
    frames, pending = [], 0.0
    for e in log:  # a render's bakes are logged before it: its frame is its CPU less theirs
        if e["kind"].startswith("bake:"):
            pending += e["cpu"]
        elif e["kind"] == "realtime":
            frames.append({**e, "kind": "frame", "cpu": e["cpu"] - pending})
            pending = 0.0
        else:
            pending = 0.0
    rows = [e for e in log if e["kind"] != "realtime"] + frames
    by_kind, by_stage = collections.defaultdict(lambda: [0, 0.0]), collections.defaultdict(lambda: [0, 0.0])
    for e in rows:
        by_kind[e["kind"]][0] += 1
        by_kind[e["kind"]][1] += e["cpu"]
        by_stage[(e["stage"], e["kind"])][0] += 1
        by_stage[(e["stage"], e["kind"])][1] += e["cpu"]
    lines.append("kind (a frame: its render's CPU less its bakes')        count    CPU s")
    lines += [f"{k:54s} {n:6d} {c:8.1f}" for k, (n, c) in sorted(by_kind.items(), key=lambda x: -x[1][1])]
    lines.append("\nstage / kind                                           count    CPU s")
    lines += [f"{(s + ' / ' + k)[:54]:54s} {n:6d} {c:8.1f}" for (s, k), (n, c) in by_stage.items()]
    counts = collections.Counter((e["kind"], e["key"]) for e in log)
    twice = [f"{k}: {key} x{n}" for (k, key), n in counts.items() if n > 1]
    lines.append(f"\nkeys done more than once: {len(twice)}" + "".join(f"\n  {t}" for t in twice))
    lines.append("\nlargest items (CPU s):")
    lines += [f"{e['cpu']:7.2f}  {e['kind']:15s} {e['stage'][:28]:28s} {e['key'][:110]}"
              for e in sorted(rows, key=lambda e: -e["cpu"])[:20]]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", help="also write every logged item to this file")
    ap.add_argument("--external-cpu", action="store_true", help="measure the external renderers' processes too")
    ap.add_argument("report_args", nargs=argparse.REMAINDER)
    a = ap.parse_args(argv)
    rargs = a.report_args[1:] if a.report_args[:1] == ["--"] else a.report_args
    _install()
    ext = _ExternalCpu() if a.external_cpu else None
    if ext:
        ext.thread.start()
    from pbrcheck_cli import main as cli_main
    try:
        rc = cli_main(["report", *rargs])
    finally:
        if ext:
            ext.stop.set()
            ext.thread.join()
        if a.json:
            with open(a.json, "w") as f:
                json.dump(LOG, f, indent=0)
    print(summary(LOG))
    if ext:
        print(f"\nexternal renderers' processes (node, Chromium): {ext.seconds():.1f} CPU s over "
              f"{len(ext.ticks)} processes (not in run.json)")
    return rc


if __name__ == "__main__":
    sys.exit(main())
