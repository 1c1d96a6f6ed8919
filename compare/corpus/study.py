"""A corpus study: every renderer under test against the reference under many environments.

For every environment file of the corpus (a folder searched recursively for ``.exr`` / ``.hdr``, or
a list file of paths, one a line, relative to the list) the scene's environment is replaced by the
file, the reference and every renderer are rendered and compared, and one row per (environment,
renderer) is collected: every metric, its noise flag, pixel counts, the environment's statistics
(:mod:`compare.corpus.envstats`) and times.

Tasks and keys. Per environment: one statistics task, one reference render, one render per renderer
and one comparison per renderer (:mod:`compare.corpus.tasks`), each named by a SHA-256 over what
determines its result: the file's bytes, the scene's content less its environment, spp, seed and
mode (reference), renderer name and options (render), the two render keys (comparison), the
pbrcheck version, and the code that makes the pixels (:func:`code_identity`): a real-time preset's
sources (:func:`realtime.cache.code_hash` and every shader file, :func:`realtime.gl.shader_sources_hash`),
an external renderer's configuration with its lockfile and inputs' hashes
(:meth:`clients.config.RendererConfig.cache_dict`) and the export format, the reference's code
version and its Mitsuba and Dr.Jit releases. Identical files therefore share their renders, and a
rerun with other settings, or after an edit of a shader, never reuses a stale row.

Writes. Every finished row is written at once, atomically, to ``OUT/rows/<key>.json`` (key: the
comparison key and the environment's name); ``--resume`` keeps the rows already there (error rows
included) and submits only the tasks of the missing ones. At the end ``corpus.csv``,
``corpus.json`` (settings, per-renderer summary, rows), environment thumbnails (``thumbs/``) and the
plots (``plots/``, :mod:`compare.corpus.outputs`) are written from the rows of this corpus alone.

Bad entries (a missing or unreadable file, NaN, Inf or negative radiance, an unsupported suffix)
become error rows naming the file; a failed render or comparison becomes an error row with its
message. Neither stops the corpus.

API
---
- :class:`Entry`, :func:`discover` -- the corpus's environment files.
- :class:`CorpusSettings` -- what is rendered (renderers as :class:`compare.renderers.RendererSpec`).
- :func:`plan` -- the task graph and the rows it yields.
- :func:`code_identity` -- what of a renderer's (or the reference's) code its pixels depend on.
- :func:`resumed_rows`, :class:`RowWriter`, :func:`prune_superseded` -- rows on disk (shared with ``fidelity``):
  resumed, written as they finish, and a slot's row under an old key removed at the end of a run.
- :func:`run_corpus` -- run, write rows as they arrive, then the tables and plots; returns a
  :class:`CorpusResult`.
- :data:`ROW_COLUMNS`, :data:`TIMING_COLUMNS` -- the columns of ``corpus.csv``.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib.metadata
import json
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path
from typing import Callable

import numpy as np

from pbrcheck import __version__
from pbrcheck.cache import cache_key
from pbrcheck.errors import PbrcheckError
from pbrcheck.jsonio import write_json_atomic
from pbrcheck.progress import Progress
from pbrcheck.scene import Environment, Scene
from pbrcheck.unmodelled import scene_unmodelled

from .. import renderers
from ..metrics import METRICS
from ..verdict_spp import MIN_REFERENCE_SPP
from .envstats import STAT_COLUMNS
from .outputs import summarize, write_outputs, write_thumbnail
from .scheduler import Dep, Failed, SchedulerSpec, Task, open_executor, parse_scheduler, unique_tasks
from . import tasks as T

#: Environment file suffixes a corpus folder is searched for (case-insensitive).
SUFFIXES = (".exr", ".hdr")
#: Reference integrator of a corpus (the integral real-time image-based lighting approximates).
REFERENCE_MODE = "local"
#: Minimum reference spp (the variance channels need two samples).
MIN_SPP = MIN_REFERENCE_SPP

TIMING_COLUMNS = ("reference_s", "render_s", "precompute_s", "frame_s", "compare_s")
ROW_COLUMNS = ("environment", "renderer", "status", "stage", "error", *STAT_COLUMNS, *METRICS,
               *(f"{m}_noise" for m in METRICS), "pixels_valid", *TIMING_COLUMNS, "gl_renderer", "timing_clock",
               "path", "key")


class CorpusError(PbrcheckError):
    """A corpus that cannot be run: no such folder or list, no environment in it, bad settings."""


@dataclass(frozen=True)
class Entry:
    """One corpus environment: ``name`` (its path relative to the corpus), absolute ``path``, the
    SHA-256 of its bytes (``digest``), and ``problem`` when it cannot even be read."""

    name: str
    path: str
    digest: str
    problem: str | None = None


def _digest(path: Path) -> tuple[str, str | None]:
    h = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    except OSError as e:
        return hashlib.sha256(f"unreadable:{path}".encode()).hexdigest(), f"{path}: unreadable ({e.strerror or e})"
    return h.hexdigest(), None


def _entry(name: str, path: Path) -> Entry:
    if path.suffix.lower() not in SUFFIXES:
        return Entry(name, str(path), hashlib.sha256(f"unsupported:{path}".encode()).hexdigest(),
                     f"{path}: unsupported image type {path.suffix!r} (expected .exr or .hdr)")
    if not path.is_file():
        return Entry(name, str(path), hashlib.sha256(f"missing:{path}".encode()).hexdigest(), f"{path}: no such file")
    digest, problem = _digest(path)
    return Entry(name, str(path), digest, problem)


def discover(source: str | Path) -> list[Entry]:
    """The environments of a corpus folder (``.exr`` / ``.hdr`` files below it, sorted by relative
    path) or of a list file (one path a line, relative to the list's folder; ``#`` starts a comment).

    Raises
    ------
    CorpusError
        ``source`` does not exist, or names no environment.
    """
    src = Path(source).expanduser()
    if src.is_dir():
        files = sorted((p for p in src.rglob("*") if p.is_file() and p.suffix.lower() in SUFFIXES),
                       key=lambda p: p.relative_to(src).as_posix())
        entries = [_entry(p.relative_to(src).as_posix(), p.resolve()) for p in files]
    elif src.is_file():
        entries, seen = [], set()
        try:
            lines = src.read_text(encoding="utf-8").splitlines()
        except (OSError, UnicodeDecodeError) as e:
            raise CorpusError(f"{src}: cannot read the corpus list ({e})") from None
        for line in lines:
            line = line.split("#", 1)[0].strip()
            if not line or line in seen:
                continue
            seen.add(line)
            p = Path(line).expanduser()
            entries.append(_entry(line, (p if p.is_absolute() else src.parent / p).resolve()))
    else:
        raise CorpusError(f"{src}: no such corpus folder or list file")
    if not entries:
        raise CorpusError(f"{src}: no environment (.exr or .hdr) in the corpus")
    return entries


@dataclass(frozen=True)
class CorpusSettings:
    """The scene (its environment is replaced by each corpus file), the renderers, the reference's
    spp and seed; ``rank_metric`` orders the worst environments in the summary."""

    scene: Scene
    renderers: tuple[RendererSpec, ...]
    spp: int = 64
    seed: int = 0
    rank_metric: str = "relmse"

    def validate(self) -> None:
        """Raise :class:`CorpusError` or ``OptionError`` for bad settings (before any work)."""
        if self.spp < MIN_SPP:
            raise CorpusError(f"corpus: --spp must be >= {MIN_SPP}, got {self.spp}")
        if not self.renderers:
            raise CorpusError("corpus: no renderer under test")
        if self.rank_metric not in METRICS:
            raise CorpusError(f"corpus: --rank-metric {self.rank_metric!r}: expected one of {', '.join(METRICS)}")
        names = [r.text for r in self.renderers]
        if len(set(names)) != len(names):
            raise CorpusError(f"corpus: a renderer is named twice in {', '.join(names)}")
        # each spec was validated where it was parsed (RendererSpec.parse: its options, or that an
        # external renderer exists)

    def to_json(self) -> dict:
        return {"scene": self.scene.name, "scene_source": self.scene.source, "spp": self.spp, "seed": self.seed,
                "mode": REFERENCE_MODE, "rank_metric": self.rank_metric,
                "renderers": [{"name": r.text, "options": dict(r.overrides)} for r in self.renderers],
                "pbrcheck": __version__}


def scene_for(scene: Scene, entry: Entry) -> Scene:
    """``scene`` lit by the corpus file of ``entry`` (scale 1, no rotation)."""
    return replace(scene, environment=Environment(type="file", path=entry.path))


@dataclass(frozen=True)
class RowSlot:
    """One expected row: its environment, renderer, comparison task key and row file key."""

    entry: Entry
    renderer: RendererSpec
    compare_key: str
    row_key: str


#: :func:`code_identity`'s name for the reference.
REFERENCE = "reference"


@lru_cache(maxsize=None)
def code_identity(name: str) -> str:
    """What of the code of renderer ``name`` (a real-time preset, ``ext:NAME``, or :data:`REFERENCE`)
    its pixels depend on, as a JSON string (a key part; memoized, and cleared at every :func:`plan`:
    once per renderer and run, whatever the corpus's size). Without it a row rendered before an edit of a shader would be "done" after it (the
    pbrcheck version does not change with every edit). The reference: its code version and the
    Mitsuba and Dr.Jit releases (the variant is the worker's: not known here)."""
    if name == REFERENCE:
        from reference.render import REFERENCE_CODE_VERSION

        ident = {"code": REFERENCE_CODE_VERSION, "mitsuba": importlib.metadata.version("mitsuba"),
                 "drjit": importlib.metadata.version("drjit")}
    elif renderers.is_external(name):
        from clients.config import get_renderer
        from pbrcheck.export import EXPORT_FORMAT_VERSION

        try:
            cfg = get_renderer(name).cache_dict()
        except PbrcheckError as e:  # an unknown renderer: its render task makes the error row
            cfg = f"unavailable: {e}"
        ident = {"external": cfg, "export_format": EXPORT_FORMAT_VERSION}
    else:
        from realtime.cache import code_hash
        from realtime.gl import shader_sources_hash

        ident = {"realtime_code": code_hash(), "shaders": shader_sources_hash()}
    return json.dumps(ident, sort_keys=True)


def _keys(st: CorpusSettings, entry: Entry, r: RendererSpec) -> tuple[str, str, str, str]:
    content = st.scene.content_dict()
    content.pop("environment")
    common = {"scene": content, "environment_sha256": entry.digest, "pbrcheck": __version__}
    left_out = sorted({u.feature for u in scene_unmodelled(st.scene)})
    if left_out:  # as compare.fidelity's keys: a feature flipped to modelled makes the rows stale
        common["not_modelled"] = left_out
    env_k = "environment-" + cache_key(kind="environment", **common)
    ref_k = "reference-" + cache_key(kind="reference", spp=st.spp, seed=st.seed, mode=REFERENCE_MODE,
                                     code=code_identity(REFERENCE), **common)
    ren_k = "render-" + cache_key(kind="render", renderer=r.text, options=dict(r.overrides), code=code_identity(r.name),
                                  **common)
    cmp_k = "compare-" + cache_key(kind="compare", reference=ref_k, render=ren_k)
    return env_k, ref_k, ren_k, cmp_k


def plan(entries: list[Entry], st: CorpusSettings, done: set[str] = frozenset()) -> tuple[list[Task], list[RowSlot]]:
    """The tasks of every row whose key is not in ``done``, and every row slot of the corpus.

    Entries with a ``problem`` get no task (their rows are error rows made by the client)."""
    code_identity.cache_clear()  # this run's code (a shader edited since the last plan is seen)
    tasks: list[Task] = []
    slots: list[RowSlot] = []
    for e in entries:
        sc = scene_for(st.scene, e)
        for r in st.renderers:
            env_k, ref_k, ren_k, cmp_k = _keys(st, e, r)
            row_k = cache_key(compare=cmp_k, environment=e.name)[:40]
            slots.append(RowSlot(e, r, cmp_k, row_k))
            if e.problem or row_k in done:
                continue
            tasks += [Task(env_k, T.environment_task, (sc,), "environment", deliver=True),
                      Task(ref_k, T.reference_task, (Dep(env_k), sc, st.spp, st.seed, REFERENCE_MODE), "reference"),
                      Task(ren_k, T.render_task, (Dep(env_k), sc, r), "render"),
                      Task(cmp_k, T.compare_task, (Dep(env_k), Dep(ref_k), Dep(ren_k), sc), "compare", deliver=True)]
    return unique_tasks(tasks), slots


def make_row(slot: RowSlot, value) -> dict:
    """The row of ``slot`` from its comparison's value (a dict of :func:`~compare.corpus.tasks.compare_task`
    or a :class:`Failed`)."""
    row = {c: None for c in ROW_COLUMNS}
    row.update(environment=slot.entry.name, renderer=slot.renderer.text, path=slot.entry.path, key=slot.row_key)
    if isinstance(value, Failed):
        row.update(status="error", stage=value.stage, error=value.message)
        return row
    row["status"] = "ok"
    row.update(value["stats"])
    row.update(value["metrics"])
    row.update({f"{m}_noise": v for m, v in value["noise"].items()})
    row["pixels_valid"] = value["pixels"].get("valid")
    row.update(value["timings"])
    row.update(value.get("timed_on", {}))
    # Plain Python values: a numpy scalar prints with the process's numpy print options in the CSV
    # (a library in the client had set the 12-digit legacy mode), a float always in full.
    return {k: v.item() if isinstance(v, np.generic) else v for k, v in row.items()}


def _read_row(path: Path, key: str) -> dict | None:
    try:
        row = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return row if isinstance(row, dict) and row.get("key") == key else None


def resumed_rows(rows_dir: Path, slots) -> dict[str, dict]:
    """The rows a previous run finished (``--resume``): per slot (anything with a ``row_key``) its
    row file under ``rows_dir`` where one of that key reads back, keyed by the row key. Shared by
    ``corpus`` and ``fidelity``."""
    done: dict[str, dict] = {}
    for s in slots:
        row = _read_row(rows_dir / f"{s.row_key}.json", s.row_key)
        if row is not None:
            done[s.row_key] = row
    return done


def _row_identity(row: dict) -> tuple:
    """What a row is a row of: (its environment or scenario, its renderer)."""
    return (row.get("scenario", row.get("environment")), row.get("renderer"))


def prune_superseded(rows_dir: Path, rows: list[dict]) -> int:
    """Remove from ``rows_dir`` the row files a run's ``rows`` supersede: a file of the same
    environment or scenario and renderer as one of ``rows`` under another key (a row re-rendered
    under a new key, e.g. after a code change, left its old file behind: ``--resume`` never reads it
    again, but the folder would hold two rows of one slot). Files of slots outside this run (a
    ``--scenarios`` subset) and unreadable files are left alone. Returns the number removed."""
    keep = {r["key"] for r in rows}
    mine = {_row_identity(r) for r in rows}
    removed = 0
    for f in sorted(Path(rows_dir).glob("*.json")) if Path(rows_dir).is_dir() else ():
        if f.stem in keep:
            continue
        try:
            row = json.loads(f.read_text())
        except (OSError, ValueError):
            continue
        if isinstance(row, dict) and _row_identity(row) in mine:
            f.unlink(missing_ok=True)
            removed += 1
    return removed


@dataclass
class RowWriter:
    """Writes a run's rows as they finish (``corpus``, ``fidelity``): each atomically to
    ``rows_dir/<key>.json``, into ``done`` (the run's rows, resumed ones included), counted in
    ``computed`` and handed to ``on_row`` (progress) if given."""

    rows_dir: Path
    done: dict
    on_row: object = None
    computed: int = 0

    def __call__(self, row: dict) -> None:
        write_json_atomic(self.rows_dir / f"{row['key']}.json", row)
        self.done[row["key"]] = row
        self.computed += 1
        if self.on_row is not None:
            self.on_row(row)


@dataclass
class CorpusResult:
    """A finished corpus: its folder, settings, rows (corpus order), summary and written files."""

    out_dir: Path
    settings: CorpusSettings
    rows: list[dict]
    summary: dict
    files: dict[str, Path]
    computed: int = 0          # rows computed by this run (the rest were resumed)
    tasks: int = 0             # tasks submitted by this run


#: Files of a finished run removed when a run computes new rows (an interrupted re-run with other
#: settings must not leave the previous run's table beside its rows); written again at the end.
STALE_ON_RERUN = ("corpus.csv", "corpus.json")


def run_corpus(source: str | Path, settings: CorpusSettings, out_dir: str | Path, *,
               scheduler: str | SchedulerSpec | None = "serial", executor=None, resume: bool = False,
               progress: bool = True, on_row: Callable[[dict], None] | None = None,
               outputs: bool = True) -> CorpusResult:
    """Run the corpus ``source`` and write its results to ``out_dir`` (see the module docstring).

    Parameters
    ----------
    source : str or Path
        Corpus folder or list file (:func:`discover`).
    settings : CorpusSettings
        Scene, renderers, spp, seed.
    out_dir : str or Path
        Output folder (``rows/``, ``thumbs/``, ``plots/``, ``corpus.csv``, ``corpus.json``).
    scheduler : str or SchedulerSpec, optional
        ``serial``, ``local:N`` or ``tcp://HOST:PORT`` (ignored when ``executor`` is given).
    executor : optional
        An executor from :func:`~compare.corpus.scheduler.open_executor` (reused, e.g. by tests).
    resume : bool
        Keep the rows already in ``out_dir/rows`` and compute only the missing ones.
    progress : bool
        Show a progress bar over the tasks.
    on_row : callable, optional
        Called with each row as it is written (in completion order).
    outputs : bool
        Write ``corpus.csv``, ``corpus.json`` and the plots at the end.

    Returns
    -------
    CorpusResult

    Raises
    ------
    CorpusError, OptionError, SchedulerError
        Bad corpus, settings or scheduler: raised before anything is written.
    SchedulerUnavailable
        The scheduler cannot be reached or has no worker: also before anything is written.
    """
    settings.validate()
    entries = discover(source)
    if executor is None:
        spec = scheduler if isinstance(scheduler, SchedulerSpec) else parse_scheduler(scheduler)
    out = Path(out_dir)
    rows_dir, thumbs_dir = out / "rows", out / "thumbs"
    _, slots = plan(entries, settings)
    done = resumed_rows(rows_dir, slots) if resume else {}
    tasks, _ = plan(entries, settings, set(done))
    with contextlib.ExitStack() as stack:
        # The executor first: a scheduler that cannot be reached stops the corpus before any write.
        if tasks and executor is None:
            executor = stack.enter_context(open_executor(spec))
        if tasks:  # the summary files describe a finished run: a previous run's go before new rows come
            for name in STALE_ON_RERUN:
                (out / name).unlink(missing_ok=True)
        rows_dir.mkdir(parents=True, exist_ok=True)
        write = RowWriter(rows_dir, done, on_row)

        for s in slots:  # unreadable entries: error rows without any task
            if s.entry.problem and s.row_key not in done:
                write(make_row(s, Failed("environment", s.entry.problem)))
        waiting: dict[str, list[RowSlot]] = {}
        for s in slots:
            if s.row_key not in done:
                waiting.setdefault(s.compare_key, []).append(s)

        def on_result(task: Task, value):
            if task.stage == "environment":
                if not isinstance(value, Failed):
                    write_thumbnail(thumbs_dir, task.key, value["thumb"])
                return
            for s in waiting.pop(task.key, []):
                write(make_row(s, value))

        if tasks:
            with Progress(f"corpus {settings.scene.name}", total=len(tasks), unit="tasks", enabled=progress) as prog:
                executor.run(tasks, on_result, prog)
        for slots_left in waiting.values():  # a result that never came back (should not happen)
            for s in slots_left:
                write(make_row(s, Failed("task", "no result came back from the scheduler")))
    rows = [done[s.row_key] for s in slots]
    prune_superseded(rows_dir, rows)  # a slot's earlier row under an old key
    env_keys = {s.entry.name: _keys(settings, s.entry, s.renderer)[0] for s in slots}
    summary = summarize(rows, settings, env_keys)
    files = write_outputs(out, rows, settings, summary, ROW_COLUMNS) if outputs else {}
    return CorpusResult(out, settings, rows, summary, files, write.computed, len(tasks))
