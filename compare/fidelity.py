"""The Render Fidelity comparison with a ground truth (``pbrcheck fidelity CONFIG.json``; docs/fidelity.md).

Every scenario of a Khronos glTF Render Fidelity (RF) ``config.json`` (read as RF reads it,
:func:`pbrcheck.scenario_import.config_scenes`) is rendered by the truth (the reference in ``path``
mode: visibility and interreflection) and by every chosen renderer, on the corpus machinery
(:mod:`compare.corpus.scheduler`: serial or Dask, one row file per scenario x renderer so a run
resumes, a progress bar, a failed render an error row). Each row holds the renderer's error against
the truth with its noise flags (relmse, FLIP, Delta E ITP; per material where the scene has several)
and, beside it, RF's own metric against the three.js image (:func:`rf_metric_db`), RF's verdict
(:data:`RF_THRESHOLD_DB`) and the truth's verdict (:func:`truth_pass`); a scene with features
pbrcheck does not model (:func:`pbrcheck.unmodelled.scene_unmodelled`) is marked ``not modelled`` and
gets no verdict. :mod:`compare.fidelity_page` writes ``fidelity.csv``, ``fidelity.json`` and the page
(:func:`compare.fidelity_page.write_outputs`).

RF's metric (reimplemented from its formula). RF's comparison is model-viewer's render-fidelity
tools: ``ImageComparator.analyze`` and ``toDecibel`` in google/model-viewer
``packages/render-fidelity-tools/src/common.ts`` (commit 02e0e1fb) with pixelmatch's ``colorDelta``
(``src/third_party/pixelmatch/color-delta.ts``): over the candidate's covered pixels (alpha != 0),
``delta`` = 0.5053 dY^2 + 0.299 dI^2 + 0.1957 dQ^2 of the 8-bit RGB values in YIQ (Kotsarenko and
Ramos), ``ratio = sqrt(mean(delta^2)) / 35215`` (35215: the largest delta), reported as
``10 log10(ratio)`` dB; a scenario fails above -22 dB (``FIDELITY_TEST_THRESHOLD``) against the
three.js golden. The goldens are 8-bit sRGB PNGs of model-viewer's default tone mapping, Khronos
PBR Neutral (:func:`rf_display`). Here the covered pixels are the pixels fully covered by an object
in both images (:func:`compare.metrics.pixel_classes`): RF's goldens have a transparent background.

API
---
- :func:`rf_display`, :func:`rf_color_delta`, :func:`rf_metric_db`, :func:`rf_pass` -- RF's metric.
- :func:`truth_pass` -- the truth's verdict of one row.
- :class:`FidelitySettings`, :func:`load_scenarios`, :func:`run_fidelity`, :class:`FidelityResult`.
- :data:`ROW_COLUMNS`, :data:`RF_BASELINE`, :data:`PATH_TRACERS`.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from pbrcheck import __version__
from pbrcheck.cache import cache_key
from pbrcheck.errors import PbrcheckError
from pbrcheck.progress import Progress
from pbrcheck.scene import Scene, scene_from_dict
from pbrcheck.unmodelled import scene_unmodelled

from . import renderers
from .corpus import tasks as T
from .corpus.scheduler import (Dep, Failed, SchedulerSpec, Task, failure_of, open_executor, parse_scheduler,
                               unique_tasks)
from .corpus.study import REFERENCE, code_identity
from .corpus.study import RowWriter, prune_superseded, resumed_rows  # the corpus's resume: the rows a previous run finished
from .maps import srgb_oetf
from .metrics import compare_images, pixel_classes
from .verdict_spp import MIN_REFERENCE_SPP

#: The truth: the reference's mode with visibility and interreflection (docs/reference.md).
TRUTH_MODE = "path"
#: RF's pass threshold (model-viewer ``FIDELITY_TEST_THRESHOLD``): fail above -22 dB.
RF_THRESHOLD_DB = -22.0
#: pixelmatch's largest YIQ delta (model-viewer ``MAX_COLOR_DISTANCE``).
RF_MAX_COLOR_DISTANCE = 35215.0
#: The YIQ delta's weights and the RGB -> Y, I, Q rows (pixelmatch ``colorDelta``).
RF_YIQ_WEIGHTS = (0.5053, 0.299, 0.1957)
RF_YIQ = np.array([[0.29889531, 0.58662247, 0.11448223],
                   [0.59597799, -0.27417610, -0.32180189],
                   [0.21147017, -0.52261711, 0.31114694]])
#: Khronos PBR Neutral tone mapping's constants (model-viewer's default tone mapping; the
#: specification at KhronosGroup/ToneMapping, PBR_Neutral): the Fresnel floor, where the highlight
#: compression starts and the desaturation speed.
NEUTRAL_F90 = 0.04
NEUTRAL_START = 0.8 - NEUTRAL_F90
NEUTRAL_DESATURATION = 0.15
#: The floor of RF's ratio before the logarithm (identical images: -inf dB is shown as this).
RF_MIN_RATIO = 1e-12
#: The renderer whose image RF compares every other with (its golden).
RF_BASELINE = "ext:threejs"
#: RF's path tracers that pbrcheck has as clients (the "which path tracer is right" table).
PATH_TRACERS = ("ext:three-gpu-pathtracer", "ext:cycles")
#: The truth's verdict: a renderer agrees with the truth when its mean HDR-FLIP against it is at most
#: this (the perceptual error the committed client budgets allow an engine on the plain spheres,
#: compare/budgets/clients.toml, rounded up) or its error is within the reference's noise.
TRUTH_FLIP_PASS = 0.15
#: Seconds between two samples of the memory of a render (this process and its children).
MEMORY_POLL_S = 0.1
#: The metrics of a row, against the truth.
METRIC_NAMES = ("relmse", "flip_mean", "delta_e_itp_mean")

ROW_COLUMNS = (
    "scenario", "renderer", "status", "stage", "error", "not_modelled", "extensions",
    "relmse", "relmse_noise", "flip_mean", "flip_mean_noise", "delta_e_itp_mean", "delta_e_itp_mean_noise",
    "rf_db", "rf_pass", "truth_pass", "disagree", "wall_s", "cpu_s", "peak_mib",
    "truth_wall_s", "truth_cpu_s", "truth_peak_mib", "pixels_valid", "key",
)


class FidelityError(PbrcheckError):
    """Bad fidelity settings (exit code 2)."""


# ----------------------------------------------------------------------------------------------
# RF's metric


def _neutral(rgb: np.ndarray) -> np.ndarray:
    """Khronos PBR Neutral tone mapping of linear RGB (..., 3)."""
    c = rgb.astype(np.float64)
    x = c.min(axis=-1, keepdims=True)
    offset = np.where(x < 0.08, x - 6.25 * x * x, NEUTRAL_F90)
    c = c - offset
    peak = c.max(axis=-1, keepdims=True)
    d = 1.0 - NEUTRAL_START
    safe = np.maximum(peak, 1e-30)
    new_peak = 1.0 - d * d / (peak + d - NEUTRAL_START)
    g = 1.0 - 1.0 / (NEUTRAL_DESATURATION * (peak - new_peak) + 1.0)
    compressed = c * (new_peak / safe) * (1.0 - g) + new_peak * g
    return np.where(peak < NEUTRAL_START, c, compressed)


def rf_display(rgb: np.ndarray) -> np.ndarray:
    """Linear radiance as RF's 8-bit goldens: Khronos PBR Neutral, clamped to [0, 1], the sRGB
    transfer, rounded to 0..255 (uint8)."""
    return np.rint(srgb_oetf(np.clip(_neutral(rgb), 0.0, 1.0)) * 255.0).astype(np.uint8)


def rf_color_delta(a8: np.ndarray, b8: np.ndarray) -> np.ndarray:
    """pixelmatch's squared YIQ distance of two opaque 8-bit RGB images (..., 3) -> (...)."""
    d = (a8.astype(np.float64) - b8.astype(np.float64)) @ RF_YIQ.T
    w = RF_YIQ_WEIGHTS
    return w[0] * d[..., 0] ** 2 + w[1] * d[..., 1] ** 2 + w[2] * d[..., 2] ** 2


def rf_metric_db(test8: np.ndarray, golden8: np.ndarray, covered: np.ndarray) -> float | None:
    """RF's score of ``test8`` against ``golden8`` (8-bit RGB) over the ``covered`` pixels, in dB
    (``10 log10(sqrt(mean(delta^2)) / 35215)``); None over no pixel."""
    if not covered.any():
        return None
    delta = rf_color_delta(test8[covered], golden8[covered])
    ratio = math.sqrt(float(np.mean(delta ** 2))) / RF_MAX_COLOR_DISTANCE
    return 10.0 * math.log10(max(ratio, RF_MIN_RATIO))


def rf_pass(db: float | None) -> bool | None:
    """RF's verdict: pass at or below :data:`RF_THRESHOLD_DB`; None without a score."""
    return None if db is None else db <= RF_THRESHOLD_DB


def truth_pass(metrics: dict, noise: dict | None) -> bool | None:
    """The truth's verdict: FLIP at most :data:`TRUTH_FLIP_PASS`, or every metric within the
    reference's noise; None without a FLIP value."""
    flip = metrics.get("flip_mean")
    if flip is None:
        return None
    if noise and all(noise.get(m) for m in METRIC_NAMES):
        return True
    return flip <= TRUTH_FLIP_PASS


# ----------------------------------------------------------------------------------------------
# Settings and scenarios


@dataclass(frozen=True)
class FidelitySettings:
    """The renderers under test (parsed), the truth's spp and seed, the image's longer side
    (None: the scenario's own size) and the scenarios to run (None: every one)."""

    renderers: tuple[renderers.RendererSpec, ...]
    spp: int = 64
    seed: int = 0
    size: int | None = None
    scenarios: tuple[str, ...] | None = None

    def validate(self) -> None:
        if self.spp < MIN_REFERENCE_SPP:
            raise FidelityError(f"fidelity: --spp must be >= {MIN_REFERENCE_SPP}, got {self.spp}")
        if self.size is not None and self.size < 1:
            raise FidelityError(f"fidelity: --size must be >= 1, got {self.size}")
        names = [r.text for r in self.renderers]
        if not names:
            raise FidelityError("fidelity: no renderer under test")
        if len(set(names)) != len(names):
            raise FidelityError(f"fidelity: a renderer is named twice in {', '.join(names)}")

    def to_json(self) -> dict:
        return {"renderers": [r.text for r in self.renderers], "spp": self.spp, "seed": self.seed,
                "size": self.size, "scenarios": list(self.scenarios) if self.scenarios else None, "truth_mode": TRUTH_MODE, "rf_threshold_db": RF_THRESHOLD_DB,
                "truth_flip_pass": TRUTH_FLIP_PASS, "pbrcheck": __version__}


@dataclass(frozen=True)
class Scenario:
    """One RF scenario: its name, its scene (or the error that made it none), ``exclude``,
    the features pbrcheck does not model and the glTF extensions its assets use."""

    name: str
    scene: Scene | None
    problem: str | None = None
    exclude: tuple[str, ...] = ()
    not_modelled: tuple[str, ...] = ()
    extensions: tuple[str, ...] = ()


def _sized(table: dict, size: int | None) -> dict:
    """``table`` with its camera's longer side ``size`` (the aspect kept, each side at least 1)."""
    if size is None:
        return table
    cam = dict(table.get("camera", {}))
    w, h = int(cam.get("width", size)), int(cam.get("height", size))
    k = size / max(w, h)
    cam["width"], cam["height"] = max(1, round(w * k)), max(1, round(h * k))
    return {**table, "camera": cam}


def load_scenarios(config: str | Path, size: int | None = None, only: tuple[str, ...] | None = None) -> list[Scenario]:
    """Every scenario of the RF config ``config`` as a :class:`Scenario`; one that the importer
    refuses or whose scene cannot be built (a missing or refused asset, a missing environment) keeps
    its ``problem`` (an error row later). ``only``: just these scenarios (by name, the config's order).

    Raises
    ------
    ScenarioError
        The config itself is unreadable or malformed.
    """
    from pbrcheck.scenario_import import config_scenes, scenario_table

    path = Path(config)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        data = None  # config_scenes names the problem
    entries: list = []
    if isinstance(data, dict) and isinstance(data.get("scenarios"), list) and "model" not in data:
        # one scenario at a time: a scenario the importer refuses (a missing model) is that
        # scenario's error row, not the end of the run
        for i, s in enumerate(data["scenarios"]):
            try:
                entries.append(scenario_table(s, path.parent, str(path), f"scenarios[{i}]"))
            except PbrcheckError as e:
                name = s.get("name") if isinstance(s, dict) and isinstance(s.get("name"), str) else f"scenarios[{i}]"
                entries.append((name, str(e)))
        entries = [(e[1]["name"], *e) if isinstance(e[0], dict) else e for e in entries]
    else:
        entries = config_scenes(path)
    if only is not None:
        names = {e[0] for e in entries}
        unknown = [n for n in only if n not in names]
        if unknown:
            raise FidelityError(f"fidelity: --scenarios: {', '.join(unknown)} not in {path} "
                                f"(it has {', '.join(sorted(names))})")
        entries = [e for e in entries if e[0] in only]
    out = []
    for entry in entries:
        if len(entry) == 2:
            out.append(Scenario(entry[0], None, entry[1]))
            continue
        name, table, meta = entry
        exclude = tuple(meta.get("exclude", ()))
        try:
            scene = scene_from_dict(_sized(table, size), file=str(path), base_dir=path.parent, contained=True)
        except PbrcheckError as e:
            out.append(Scenario(name, None, str(e), exclude))
            continue
        nm = tuple(sorted({u.feature for u in scene_unmodelled(scene)}))
        ext = tuple(sorted({x for inst in scene.assets if inst.asset is not None
                            for x in inst.asset.extensions_used}))
        out.append(Scenario(name, scene, None, exclude, nm, ext))
    return out


# ----------------------------------------------------------------------------------------------
# Tasks (what runs on a worker)


def idle_serve_processes() -> set[int]:
    """The idle serve processes of the current ``clients.run.serve_clients`` block and all their
    descendants (their browsers)."""
    import psutil

    from clients.run import idle_serve_pids

    out: set[int] = set()
    for pid in idle_serve_pids():
        with contextlib.suppress(Exception):
            out.add(pid)
            out.update(c.pid for c in psutil.Process(pid).children(recursive=True))
    return out


class _Usage:
    """Wall time, CPU time and peak resident memory of a block: this process and its descendants
    (a browser client's node and Chromium processes), polled every :data:`MEMORY_POLL_S` s.

    CPU time: this process's own (``os.times``, children excluded) plus, per descendant process seen
    during the block, the last user + system time polled (less what it had at the block's start):
    a descendant's time after its last poll (at most :data:`MEMORY_POLL_S`) is missed.
    ``RUSAGE_CHILDREN`` alone would miss Chromium's GPU and renderer processes, which this process
    never reaps. Memory: the largest sum of the resident sets of this process and its descendants,
    less the idle serve processes' trees (:func:`idle_serve_processes`: the other clients' browsers,
    kept open for the run by ``clients.run.serve_clients``, are no part of this render's memory;
    their CPU, ~0 while idle, is still polled so that a busy one's start is known)."""

    def __enter__(self):
        import psutil

        self._proc = psutil.Process(os.getpid())
        self._stop = threading.Event()
        self.peak = 0
        self._cpu_seen: dict[int, float] = {}
        self._cpu_start: dict[int, float] = {}
        self._poll_once(start=True)
        self._t0 = time.perf_counter()
        t = os.times()
        self._own0 = t.user + t.system
        self._thread = threading.Thread(target=self._poll, daemon=True)
        self._thread.start()
        return self

    def _poll_once(self, start: bool = False) -> None:
        total = 0
        idle = idle_serve_processes()
        with contextlib.suppress(Exception):
            total = self._proc.memory_info().rss
            for c in self._proc.children(recursive=True):
                with contextlib.suppress(Exception):
                    if c.pid not in idle:
                        total += c.memory_info().rss
                    ct = c.cpu_times()
                    v = ct.user + ct.system
                    key = (c.pid, c.create_time())
                    if start:
                        self._cpu_start[key] = v
                    self._cpu_seen[key] = v
        self.peak = max(self.peak, total)

    def _poll(self):
        while not self._stop.wait(MEMORY_POLL_S):
            self._poll_once()

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        self._poll_once()
        self.wall = time.perf_counter() - self._t0
        t = os.times()
        children = sum(v - self._cpu_start.get(k, 0.0) for k, v in self._cpu_seen.items())
        self.cpu = t.user + t.system - self._own0 + children
        return False

    def meta(self, prefix: str) -> dict:
        return {f"{prefix}wall_s": f"{self.wall:.3f}", f"{prefix}cpu_s": f"{self.cpu:.3f}",
                f"{prefix}peak_mib": f"{self.peak / 2 ** 20:.1f}"}


def truth_task(scene: Scene, spp: int, seed: int):
    """The truth's image of ``scene`` (``path`` mode), its usage in ``meta`` (``truth_wall_s``...)."""
    try:
        with _Usage() as u:
            img = T.on_render_thread(renderers.render_reference, scene, spp=spp, seed=seed, mode=TRUTH_MODE,
                                     use_cache=False, progress=False)
        img.meta.update(u.meta("truth_"))
        return img
    except PbrcheckError as e:
        return failure_of("reference", e)


def _render(scene: Scene, spec: renderers.RendererSpec):
    renderers.trim_caches(T.KEEP_ENVIRONMENTS)
    return renderers.render_under_test(scene, spec, progress=False, use_cache=False)


def render_task(scene: Scene, spec: renderers.RendererSpec):
    """The image of renderer ``spec``, its usage in ``meta`` (``wall_s``, ``cpu_s``, ``peak_mib``)."""
    try:
        with _Usage() as u:
            img = T.on_render_thread(_render, scene, spec)
        img.meta.update(u.meta(""))
        return img
    except PbrcheckError as e:
        return failure_of("render", e)


def _meta_float(img, key: str) -> float | None:
    try:
        return float(img.meta[key])
    except (AttributeError, KeyError, TypeError, ValueError):
        return None


def compare_task(truth, img, golden, scene: Scene, is_golden: bool) -> dict | Failed:
    """``img`` against the truth (metrics, noise flags, per material) and RF's score against
    ``golden`` (the three.js image; None where it failed or is absent, or ``img`` is it)."""
    if isinstance(img, Failed):
        return img
    out: dict = {"usage": {k: _meta_float(img, k) for k in ("wall_s", "cpu_s", "peak_mib")}}
    if isinstance(truth, Failed):
        return truth
    out["truth_usage"] = {k: _meta_float(truth, "truth_" + k) for k in ("wall_s", "cpu_s", "peak_mib")}
    try:
        cmp = compare_images(truth, img, scene=scene, ref_name="truth", test_name="renderer under test")
    except PbrcheckError as e:
        return failure_of("compare", e)
    noise = cmp.summary["noise"]
    out["metrics"] = {m: cmp.summary["metrics"].get(m) for m in METRIC_NAMES}
    out["noise"] = {m: bool(noise["within_noise"].get(m)) for m in METRIC_NAMES} if noise else {}
    out["materials"] = [{"material": m["material"], "pixels": m["pixels"],
                         **{k: m["metrics"].get(k) for k in METRIC_NAMES}}
                        for m in cmp.summary.get("materials", [])]
    out["pixels_valid"] = cmp.summary["pixels"]["valid"]
    out["rf_db"] = None
    if golden is not None and not isinstance(golden, Failed) and not is_golden:
        try:
            valid, _, _ = pixel_classes(golden, img)
            out["rf_db"] = rf_metric_db(rf_display(img.rgb), rf_display(golden.rgb), valid)
        except PbrcheckError as e:
            out["rf_error"] = str(e)
    return out


# ----------------------------------------------------------------------------------------------
# The run


@dataclass(frozen=True)
class Slot:
    scenario: Scenario
    renderer: renderers.RendererSpec
    compare_key: str
    row_key: str


def _keys(st: FidelitySettings, sc: Scenario, r: renderers.RendererSpec) -> tuple[str, str, str]:
    common = {"scene": sc.scene.content_dict() if sc.scene is not None else sc.problem, "pbrcheck": __version__}
    if sc.not_modelled:
        # what pbrcheck leaves out of the scene (and strips from the engines' export) is part of every
        # row's key: a feature modelled since a row was made (an extension flipped to modelled) makes
        # it stale under --resume, though neither the scene file nor the version changed
        common["not_modelled"] = list(sc.not_modelled)
    truth_k = "fidelity-truth-" + cache_key(kind="truth", spp=st.spp, seed=st.seed, mode=TRUTH_MODE,
                                            code=code_identity(REFERENCE), **common)
    ren_k = "fidelity-render-" + cache_key(kind="render", renderer=r.text, options=dict(r.overrides),
                                           code=code_identity(r.name), **common)
    return truth_k, ren_k, "fidelity-compare-" + cache_key(truth=truth_k, render=ren_k,
                                                           golden=RF_BASELINE in [x.text for x in st.renderers])


def plan(scenarios: list[Scenario], st: FidelitySettings, done=frozenset()) -> tuple[list[Task], list[Slot]]:
    """The tasks of every row not in ``done`` and every row slot (scenario x renderer)."""
    code_identity.cache_clear()
    tasks, slots = [], []
    golden = next((r for r in st.renderers if r.text == RF_BASELINE), None)
    for sc in scenarios:
        first = len(tasks)
        for r in st.renderers:
            truth_k, ren_k, cmp_k = _keys(st, sc, r)
            row_k = cache_key(compare=cmp_k, scenario=sc.name)[:40]
            slots.append(Slot(sc, r, cmp_k, row_k))
            if sc.scene is None or row_k in done:
                continue
            gold_dep = None
            if golden is not None:
                gold_k = _keys(st, sc, golden)[1]
                tasks.append(Task(gold_k, render_task, (sc.scene, golden), "render"))
                gold_dep = Dep(gold_k)
            tasks += [Task(truth_k, truth_task, (sc.scene, st.spp, st.seed), "reference"),
                      Task(ren_k, render_task, (sc.scene, r), "render"),
                      Task(cmp_k, compare_task, (Dep(truth_k), Dep(ren_k), gold_dep, sc.scene, r is golden),
                           "compare", deliver=True)]
        # per scenario, its renders before its comparisons (a comparison reads the golden render;
        # the serial executor runs in list order): each scenario's rows are written as it finishes
        mine = tasks[first:]
        tasks[first:] = [t for t in mine if t.stage != "compare"] + [t for t in mine if t.stage == "compare"]
    return unique_tasks(tasks), slots


def make_row(slot: Slot, value) -> dict:
    """The row of ``slot`` from its comparison (a dict of :func:`compare_task` or :class:`Failed`)."""
    sc = slot.scenario
    row = {c: None for c in ROW_COLUMNS}
    row.update(scenario=sc.name, renderer=slot.renderer.text, key=slot.row_key,
               not_modelled=", ".join(sc.not_modelled), extensions=", ".join(sc.extensions))
    if isinstance(value, Failed):
        row.update(status="error", stage=value.stage, error=value.message)
        return row
    row["status"] = "ok"
    row.update(value["metrics"])
    row.update({f"{m}_noise": v for m, v in value["noise"].items()})
    row.update(value["usage"])
    row.update({f"truth_{k}": v for k, v in value["truth_usage"].items()})
    row["pixels_valid"] = value["pixels_valid"]
    row["materials"] = value["materials"]
    row["rf_db"] = value["rf_db"]
    if not sc.not_modelled:  # verdicts only where the truth models the scene
        row["rf_pass"] = rf_pass(value["rf_db"])
        row["truth_pass"] = truth_pass(value["metrics"], value["noise"])
        if row["rf_pass"] is not None and row["truth_pass"] is not None:
            row["disagree"] = row["rf_pass"] != row["truth_pass"]
    return {k: v.item() if isinstance(v, np.generic) else v for k, v in row.items()}


@dataclass
class FidelityResult:
    """A finished run: its folder, settings, scenarios, rows (scenario x renderer order), wall time
    of this run, rows computed by it and the scheduler it ran on."""

    out_dir: Path
    settings: FidelitySettings
    scenarios: list[Scenario]
    rows: list[dict]
    wall_s: float = 0.0
    computed: int = 0
    scheduler: str = "serial"


def run_fidelity(config: str | Path, settings: FidelitySettings, out_dir: str | Path, *,
                 scheduler: str | SchedulerSpec | None = "serial", executor=None, resume: bool = False,
                 progress: bool = True, on_row: Callable[[dict], None] | None = None) -> FidelityResult:
    """Run every scenario of ``config`` through the truth and ``settings.renderers``; rows in
    ``out_dir/rows/`` (``resume``: rows already there are kept); the tables and the page are
    :func:`compare.fidelity_page.write_outputs`'s.

    Raises
    ------
    FidelityError, ScenarioError, SchedulerError
        Bad settings, config or scheduler: before anything is written.
    """
    settings.validate()
    t0 = time.perf_counter()
    scenarios = load_scenarios(config, settings.size, settings.scenarios)
    spec = None if executor is not None else (
        scheduler if isinstance(scheduler, SchedulerSpec) else parse_scheduler(scheduler))
    out = Path(out_dir)
    rows_dir = out / "rows"
    _, slots = plan(scenarios, settings)
    done = resumed_rows(rows_dir, slots) if resume else {}
    tasks, _ = plan(scenarios, settings, set(done))
    with contextlib.ExitStack() as stack:
        if tasks and executor is None:
            executor = stack.enter_context(open_executor(spec))
        rows_dir.mkdir(parents=True, exist_ok=True)

        write = RowWriter(rows_dir, done, on_row)

        for s in slots:
            if s.scenario.scene is None and s.row_key not in done:
                write(make_row(s, Failed("scene", s.scenario.problem or "no scene")))
        waiting: dict[str, list[Slot]] = {}
        for s in slots:
            if s.row_key not in done:
                waiting.setdefault(s.compare_key, []).append(s)

        def on_result(task: Task, value):
            for s in waiting.pop(task.key, []):
                write(make_row(s, value))

        if tasks:
            with Progress("fidelity", total=len(tasks), unit="tasks", enabled=progress) as prog:
                executor.run(tasks, on_result, prog)
        for left in waiting.values():  # never a silent gap
            for s in left:
                write(make_row(s, Failed("task", "no result came back from the scheduler")))
    rows = [done[s.row_key] for s in slots]
    prune_superseded(rows_dir, rows)  # a slot's earlier row under an old key
    return FidelityResult(out, settings, scenarios, rows, time.perf_counter() - t0, write.computed,
                          scheduler=str(spec or "executor"))

