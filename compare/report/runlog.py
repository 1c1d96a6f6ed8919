"""Where a report's time went: wall and CPU seconds per stage, and what its caches served.

A report is long work on a CPU (minutes on 2 cores, most of it GL compute on llvmpipe, the
reference's kernels, HDR-FLIP and the browsers of external renderers), so it says where its own time
went: :func:`build_report <compare.report.build.build_report>` records each stage (a scene's renders,
its reference, its comparisons, sweep and convergence; the summary and reference sections; each
research section; the hard cases: its list of stages, :mod:`compare.report.stages`) with
:meth:`RunLog.stage`, counts the hits and misses of the three
caches (real-time renders, references, FLIP maps), writes ``run.json`` beside ``index.html`` and
shows the table at the end of the page. ``pbrcheck bench report`` (:func:`bench_report`) runs the
report twice in fresh processes, first with empty caches (a first run on a fresh machine), then
again, and prints both runs' figures with the goal. ``pbrcheck bench report-asset``
(:func:`bench_report_asset`) times the report of one glTF asset scene beside the spheres scene's,
same size, environment and settings (the goal: at most :data:`ASSET_REPORT_GOAL` times).

Stages are sequential and flat; a stage's CPU seconds are this process's (every thread: llvmpipe's
and Dr.Jit's workers included), so ``cpu / wall`` near the core count means the stage kept the
machine busy. External renderers render in a background thread and in their own processes (a
browser), which ``cpu_s`` does not include; ``children_cpu_s`` adds the processes this one waited for.
The cache counts are this process's: renders that a ``--scheduler``'s workers run are not in them.
Across the stages, ``work`` gives the seconds by kind of work (reference renders, real-time renders,
HDR-FLIP, plots, waiting on external renderers: :mod:`compare.worktime`), whichever stage asked.
Under ``pbrcheck bench report`` (environment ``PBRCHECK_KERNEL_HISTORY=1``) each stage also counts
its Dr.Jit kernels, launched and compiled (:mod:`reference.kernel_stats`), which the machine's load
does not change; the benchmark prints them and the first run's compiled count against
:data:`COMPILED_KERNELS_GOAL`.

API: :class:`RunLog` (:meth:`RunLog.stage` records one stage), :func:`run_section`, :func:`summary_line`,
:func:`cache_line`, :func:`stage_table`, :func:`bench_report`, :func:`bench_report_asset`,
:data:`RUN_FILE`, :data:`REPORT_GOAL_S`, :data:`FIRST_RUN_GOAL_S`, :data:`COMPILED_KERNELS_GOAL`, :data:`QUIET_LOAD_MAX`, :data:`ASSET_REPORT_GOAL`,
:data:`ASSET_REPORT_SCENES`.
"""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from pbrcheck.errors import PbrcheckError

from reference import kernel_stats

from .. import renderers, worktime
from ..metrics import FLIP_STORE_COUNTS
from .section import Section, Table

#: The run log's file in the report folder.
RUN_FILE = "run.json"
#: Goals of the report's wall time (issue 12): on 2 CPU cores, and on a machine with a GPU.
REPORT_GOAL_S = {"cpu": 120.0, "gpu": 30.0}
#: Issue 39's goals of a *first* run (empty caches, a fresh HOME: Dr.Jit's and Mesa's caches empty):
#: on this 2-core machine and on a GPU, the same content (``first_meets_first_run_goal``).
FIRST_RUN_GOAL_S = {"cpu": 150.0, "gpu": 30.0}
#: The report that ``make report`` builds (``pbrcheck bench report``'s default arguments).
MAKE_REPORT_ARGS = ("spheres", "furnace", "grazing", "--spp", "256", "--with", "ext:threejs,ext:sample-viewer",
                    "--hardcases", "--research")
#: The goal is about a quiet machine: a run that starts while other processes keep more than this
#: many cores busy (the 1-minute load average just before it, ``os.getloadavg``) has its wall time
#: inflated by them, and ``bench report`` says so (``first_quiet``) beside the goal's verdict.
QUIET_LOAD_MAX = 0.5
#: Dr.Jit kernels compiled by a first ``make report`` run before issue 39 (its measurement: 511 on
#: the CPU, ~540 by the adaptive levels' counts alone), and the goal: at most a fifth of that.
BASELINE_COMPILED_KERNELS = 511
COMPILED_KERNELS_GOAL = BASELINE_COMPILED_KERNELS // 5
#: The asset report's wall time over the spheres scene's (issue 23's goal).
ASSET_REPORT_GOAL = 2.0
#: ``bench report-asset``'s scenes (repository paths): the gate's asset check and the CI spheres,
#: both 120 x 100 under the same sky; and the report arguments both get.
ASSET_REPORT_SCENES = {"spheres": "compare/budgets/spheres_ci.toml", "asset": "compare/budgets/panel_ci.toml"}
ASSET_REPORT_ARGS = ("--presets", "default", "--spp", "256", "--no-furnace")


@dataclass
class Stage:
    """One stage: its name, wall and CPU seconds, and its Dr.Jit kernels (None: not counted)."""
    name: str
    wall_s: float
    cpu_s: float
    kernels: dict | None = None


@dataclass
class RunLog:
    """Stages of one report run and the caches' counts over it (:meth:`to_dict` for ``run.json``)."""
    stages: list = field(default_factory=list)
    _t0: float = field(default_factory=time.perf_counter)
    _c0: float = field(default_factory=time.process_time)
    _counts0: dict = field(default_factory=lambda: _counts())
    _children0: float = field(default_factory=lambda: _children_cpu())
    _work0: dict = field(default_factory=worktime.snapshot)
    # Dr.Jit's kernel counts (reference.kernel_stats), where the environment asks for them
    _kernels0: dict | None = field(default_factory=lambda: (kernel_stats.start_if_asked(), kernel_stats.snapshot())[1])

    @contextlib.contextmanager
    def stage(self, name: str):
        w, c = time.perf_counter(), time.process_time()
        k = kernel_stats.snapshot()
        try:
            yield
        finally:
            self.stages.append(Stage(name, time.perf_counter() - w, time.process_time() - c,
                                     kernel_stats.since(k) if k is not None else None))

    def to_dict(self) -> dict:
        now = _counts()
        caches = {k: now[k] - self._counts0.get(k, 0) for k in now if now[k] != self._counts0.get(k, 0)}
        return {
            "wall_s": time.perf_counter() - self._t0,
            "cpu_s": time.process_time() - self._c0,
            "children_cpu_s": _children_cpu() - self._children0,
            "cores": os.cpu_count(),
            "backends": renderers.backends(),
            "caches": caches,
            "stages": self.merged(),
            "work": worktime.since(self._work0),
            **({"kernels": kernel_stats.since(self._kernels0)} if self._kernels0 is not None else {}),
        }

    def merged(self) -> list[dict]:
        """The stages with one row per name (in order of first appearance): seconds summed, ``calls``
        counted (a scene's comparisons are one stage per renderer)."""
        rows: dict[str, dict] = {}
        for st in self.stages:
            r = rows.setdefault(st.name, {"name": st.name, "wall_s": 0.0, "cpu_s": 0.0, "calls": 0})
            r["wall_s"] += st.wall_s
            r["cpu_s"] += st.cpu_s
            r["calls"] += 1
            if st.kernels is not None:
                k = r.setdefault("kernels", {})
                for n, v in st.kernels.items():
                    k[n] = k.get(n, 0) + v
        return list(rows.values())


def _children_cpu() -> float:
    """CPU seconds of the child processes this one has waited for, so far."""
    t = os.times()
    return t.children_user + t.children_system


def _counts() -> dict:
    """The caches' hit and miss counts of this process so far."""
    out = {f"{kind}_{k}": v for kind, d in renderers.CACHE_COUNTS.items() for k, v in d.items()}
    out.update({f"flip_{k}": v for k, v in FLIP_STORE_COUNTS.items()})
    return out


def cache_line(run: dict) -> str:
    """The caches' counts of a run log in words: ``real-time renders 5 hit, 225 miss; ...``."""
    c = run.get("caches") or {}

    def one(kind: str) -> str:
        return ", ".join(f"{c[f'{kind}_{k}']} {k}" for k in ("hit", "miss", "off") if c.get(f"{kind}_{k}")) or "none"

    return f"real-time renders {one('realtime')}; references {one('reference')}; FLIP maps {one('flip')}"


def summary_line(run: dict) -> str:
    """One line of a run log for the terminal: wall and CPU seconds and the caches."""
    return f"{run['wall_s']:.1f} s ({run['cpu_s']:.1f} s CPU on {run['cores']} cores); {cache_line(run)}"


def run_section(run: dict) -> Section:
    """The page's section of a run log (:meth:`RunLog.to_dict`): one row per stage, then the caches."""
    b = run.get("backends") or {}
    wall = run["wall_s"]
    rows = [[x["name"] + (f" (x{x['calls']})" if x.get("calls", 1) > 1 else ""), f"{x['wall_s']:.1f}",
             f"{100.0 * x['wall_s'] / wall:.0f} %" if wall > 0 else "",
             f"{x['cpu_s'] / x['wall_s']:.2f}" if x["wall_s"] > 0 else ""] for x in run["stages"]]
    rest = wall - sum(x["wall_s"] for x in run["stages"])
    rows.append(["(set-up, plots' files, the page)", f"{rest:.1f}", f"{100.0 * rest / wall:.0f} %" if wall > 0 else "",
                 ""])
    note = (f"This run: {wall:.1f} s wall, {run['cpu_s']:.1f} s CPU in this process on {run['cores']} core(s) "
            f"(external renderers' browsers run beside it in their own processes); GL renderer "
            f"{b.get('gl_renderer') or 'n/a'}, reference variant {b.get('reference_variant') or 'n/a'}. "
            f"Caches: {cache_line(run)}. `pbrcheck bench report` measures a first run (empty "
            f"caches) and a second one. File: {RUN_FILE}.")
    tables = [Table("", ["stage", "wall (s)", "share", "CPU / wall"], rows)]
    work = run.get("work") or {}
    if work:
        tables.append(Table("By kind of work, whichever stage asked for it (exclusive seconds; "
                            "compare.worktime)", ["kind", "calls", "wall (s)", "CPU (s)"],
                            [[k, str(v["calls"]), f"{v['wall_s']:.1f}", f"{v['cpu_s']:.1f}"] for k, v in work.items()]))
    return Section("run", "Where this report's time went", note, tables)


def stage_table(run: dict) -> str:
    """A run log's stages and kinds of work as plain-text lines (wall and CPU seconds each), for the
    terminal (``pbrcheck bench report`` prints one per run)."""
    w = max([len(x["name"]) for x in run["stages"]] + [len(k) for k in (run.get("work") or {})] + [24])
    kern = "kernels" in run  # Dr.Jit kernels launched / compiled per stage (reference.kernel_stats)

    def k(x):
        c = x.get("kernels")
        return f"  {c['launched']:9d}  {c['compiled']:8d}" if kern and c else ""

    lines = [f"{'stage':<{w}}  {'wall s':>8}  {'CPU s':>8}  calls" + (f"  {'launched':>9}  {'compiled':>8}" if kern else "")]
    for x in run["stages"]:
        lines.append(f"{x['name']:<{w}}  {x['wall_s']:8.1f}  {x['cpu_s']:8.1f}  {x.get('calls', 1):5d}{k(x)}")
    rest_w = run["wall_s"] - sum(x["wall_s"] for x in run["stages"])
    rest_c = run["cpu_s"] - sum(x["cpu_s"] for x in run["stages"])
    lines.append(f"{'(set-up, plots, the page)':<{w}}  {rest_w:8.1f}  {rest_c:8.1f}")
    lines.append(f"{'total':<{w}}  {run['wall_s']:8.1f}  {run['cpu_s']:8.1f}  (+{run.get('children_cpu_s', 0.0):.1f} s "
                 f"CPU in child processes)")
    if kern:
        t = run["kernels"]
        lines.append(f"Dr.Jit kernels: {t['launched']} launched, {t['compiled']} compiled ({t['disk']} of them from "
                     f"the disk cache, {t['compiled_ops']} IR operations)")
    work = run.get("work") or {}
    if work:
        lines.append(f"{'kind of work (exclusive)':<{w}}  {'wall s':>8}  {'CPU s':>8}  calls")
        for k, v in work.items():
            lines.append(f"{k:<{w}}  {v['wall_s']:8.1f}  {v['cpu_s']:8.1f}  {v['calls']:5d}")
        lines.append(f"{'(none of these)':<{w}}  {run['wall_s'] - sum(v['wall_s'] for v in work.values()):8.1f}  "
                     f"{run['cpu_s'] - sum(v['cpu_s'] for v in work.values()):8.1f}")
    return "\n".join(lines)


class BenchReportError(PbrcheckError):
    """A report run of ``pbrcheck bench report`` failed (its exit status and the end of its output)."""


def _run(args: list[str], out: Path, env: dict, progress: bool = False) -> dict:
    """One report run in a new process; with ``progress`` its progress bars go to this stderr (and a
    failure points there), else its output is captured and a failure quotes its end."""
    cmd = [sys.executable, "-m", "pbrcheck_cli", "report", *args, "--out", str(out)] + ([] if progress else ["--quiet"])
    load_before = _load()
    t = time.perf_counter()
    p = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=None if progress else subprocess.PIPE, text=True)
    wall = time.perf_counter() - t
    load_after = _load()
    if p.returncode != 0:
        why = "its output is above" if progress else p.stderr[-2000:]
        raise BenchReportError(f"bench report: `{' '.join(cmd)}` exited {p.returncode}:\n{why}")
    run = json.loads((out / RUN_FILE).read_text())
    run["process_wall_s"] = wall  # with the interpreter's start and imports
    # The machine's load average (1, 5, 15 min) just before and after: before, it is the other
    # processes' (this run's own is in the one after).
    run["load_before"], run["load_after"] = load_before, load_after
    return run


def _load() -> list[float] | None:
    """The 1-, 5- and 15-minute load averages (None where the platform has none)."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return None


def _matplotlib_cachedir() -> str:
    """This user's matplotlib cache folder (its font list), made if absent."""
    import matplotlib  # local: only the benchmark needs it here
    return matplotlib.get_cachedir()


def bench_report(args: list[str] | None = None, *, fresh_home: bool = True, progress: bool = True) -> dict:
    """Run ``pbrcheck report ARGS`` twice, each in a new process: ``first`` with empty caches (a
    temporary ``PBRCHECK_CACHE`` and, with ``fresh_home``, a temporary ``HOME``, so Dr.Jit's kernel
    cache and Mesa's shader cache start empty too: a first run on a fresh machine; matplotlib's font
    list is kept, see the code), then ``again`` with the caches the first run left. Returns both runs'
    ``run.json`` (plus ``process_wall_s`` and the load averages before and after, ``load_before`` /
    ``load_after``), the goal for this machine (:data:`REPORT_GOAL_S`: ``gpu`` when the reference ran
    on CUDA), whether each run meets it, the first run's CPU seconds and whether it started on a quiet
    machine (``first_quiet``: :data:`QUIET_LOAD_MAX`)."""
    args = list(MAKE_REPORT_ARGS if args is None else args)
    with tempfile.TemporaryDirectory(prefix="pbrcheck-bench-report-") as tmp:
        tmp = Path(tmp)
        # the report runs count their Dr.Jit kernels per stage (reference.kernel_stats)
        env = {**os.environ, "PBRCHECK_CACHE": str(tmp / "cache"), kernel_stats.ENV: "1"}
        if fresh_home:
            (tmp / "home").mkdir()
            env["HOME"] = str(tmp / "home")
            # ... but matplotlib's font list stays where it is: built once per machine by the first
            # program that imports matplotlib (it scans the system's fonts: 34 s on the GPU machine's
            # image, under a second here), an installation cost that no report run repeats.
            env.setdefault("MPLCONFIGDIR", _matplotlib_cachedir())
        runs = {}
        for name in ("first", "again"):
            if progress:
                print(f"bench report: {name} run ...", file=sys.stderr, flush=True)
            runs[name] = _run(args, tmp / f"out_{name}", env, progress)
            if progress:
                print(f"bench report: {name} run, {summary_line(runs[name])}; load average before "
                      f"{runs[name]['load_before']}, after {runs[name]['load_after']}\n{stage_table(runs[name])}",
                      file=sys.stderr, flush=True)
    gpu = str(runs["first"]["backends"].get("reference_variant", "")).startswith("cuda")
    goal = REPORT_GOAL_S["gpu" if gpu else "cpu"]
    first_load = (runs["first"].get("load_before") or [None])[0]
    return {
        "args": args,
        "goal_s": goal,
        "goal_machine": "gpu" if gpu else "cpu",
        "first_wall_s": runs["first"]["wall_s"],
        "first_cpu_s": runs["first"].get("cpu_s"),
        "again_wall_s": runs["again"]["wall_s"],
        "first_meets_goal": runs["first"]["wall_s"] <= goal,
        "again_meets_goal": runs["again"]["wall_s"] <= goal,
        "first_run_goal_s": FIRST_RUN_GOAL_S["gpu" if gpu else "cpu"],
        "first_meets_first_run_goal": runs["first"]["wall_s"] <= FIRST_RUN_GOAL_S["gpu" if gpu else "cpu"],
        # Whether the first run started on a quiet machine (QUIET_LOAD_MAX): if not, its wall time is
        # inflated by other processes, and first_meets_goal says less about this machine.
        "first_load_before": first_load,
        "first_quiet": first_load is not None and first_load <= QUIET_LOAD_MAX,
        # load-independent: the first run's Dr.Jit kernels (reference.kernel_stats) against the goal
        "first_kernels": runs["first"].get("kernels"),
        "again_kernels": runs["again"].get("kernels"),
        "compiled_kernels_goal": COMPILED_KERNELS_GOAL,
        "compiled_kernels_meet_goal": (runs["first"].get("kernels") or {}).get("compiled", float("inf"))
                                      <= COMPILED_KERNELS_GOAL,
        "first": runs["first"],
        "again": runs["again"],
    }


def bench_report_asset(args: list[str] | None = None, *, progress: bool = True) -> dict:
    """The report of the asset scene and of the spheres scene (:data:`ASSET_REPORT_SCENES`), each
    ``pbrcheck report SCENE ARGS`` (default :data:`ASSET_REPORT_ARGS`) in a new process with an empty
    ``PBRCHECK_CACHE`` (Dr.Jit's and Mesa's kernel caches as this machine has them), alternately,
    spheres first. Returns each run's ``run.json`` (plus ``process_wall_s``), ``ratio`` = the asset's
    wall time over the spheres' and whether it meets :data:`ASSET_REPORT_GOAL`."""
    root = Path(__file__).resolve().parents[2]
    args = list(ASSET_REPORT_ARGS if args is None else args)
    runs = {}
    with tempfile.TemporaryDirectory(prefix="pbrcheck-bench-report-asset-") as tmp:
        for name, scene in ASSET_REPORT_SCENES.items():
            env = {**os.environ, "PBRCHECK_CACHE": str(Path(tmp) / f"cache_{name}")}
            if progress:
                print(f"bench report-asset: {name} ({scene}) ...", file=sys.stderr, flush=True)
            runs[name] = _run([str(root / scene), *args], Path(tmp) / f"out_{name}", env, progress)
    ratio = runs["asset"]["wall_s"] / runs["spheres"]["wall_s"]
    return {"args": args, "scenes": ASSET_REPORT_SCENES, "spheres_wall_s": runs["spheres"]["wall_s"],
            "asset_wall_s": runs["asset"]["wall_s"], "ratio": ratio, "goal": ASSET_REPORT_GOAL,
            "meets_goal": ratio <= ASSET_REPORT_GOAL, "spheres": runs["spheres"], "asset": runs["asset"]}
