"""The corpus section of the HTML report, and the corpus's own page (``OUT/index.html``).

API
---
- :func:`corpus_section` -- a :class:`~compare.report.section.Section` from a finished corpus
  (:class:`compare.corpus.study.CorpusResult` or a corpus folder with ``corpus.json``): per renderer
  the distribution (median, p90, worst) of each metric, the worst environments with thumbnails, and
  the error against the environment statistics as plots.
- :func:`write_corpus_page` -- the corpus folder's ``index.html`` with that section alone.

Image paths in the section are relative to ``prefix`` (the corpus folder as seen from the page).
"""

from __future__ import annotations

import json
from pathlib import Path

from pbrcheck.atomic import write_text_atomic
from pbrcheck.errors import PbrcheckError
from pbrcheck.fmt import TABLE_DIGITS, format_value

from ..corpus.outputs import WORST_COUNT
from ..metrics import METRICS
from .build import render_page
from .section import Section, Table


def _fmt(v) -> str:
    return format_value(v, TABLE_DIGITS)


def _load(result_or_dir) -> tuple[Path, dict]:
    if isinstance(result_or_dir, (str, Path)):
        d = Path(result_or_dir)
        try:
            data = json.loads((d / "corpus.json").read_text(encoding="utf-8"))
        except (OSError, ValueError) as e:
            raise PbrcheckError(f"{d / 'corpus.json'}: not a finished corpus ({e})") from None
        return d, data
    r = result_or_dir
    return r.out_dir, {"settings": r.settings.to_json(), "summary": r.summary, "rows": r.rows}


def corpus_section(result_or_dir, prefix: str = "") -> Section:
    """The report section of a finished corpus (see the module docstring).

    Raises
    ------
    PbrcheckError
        A folder without a readable ``corpus.json``."""
    out_dir, data = _load(result_or_dir)
    st, summary, rows = data["settings"], data["summary"], data["rows"]
    envs = sorted({r["environment"] for r in rows})
    rank = st.get("rank_metric", "relmse")
    tables = []
    for name, s in summary.items():
        tables.append(Table(
            f"{name}: {s['ok']} of {s['rows']} environment(s) measured, {s['errors']} error(s)",
            ["metric", "median", "p90 (bad side)", "worst"],
            [[m, _fmt(s["metrics"][m]["median"]), _fmt(s["metrics"][m]["p90"]), _fmt(s["metrics"][m]["worst"])]
             for m in METRICS]))
    tables.append(Table(f"Worst {WORST_COUNT} environments per renderer by {rank}",
                        ["renderer", "environment", rank],
                        [[name, w["environment"], _fmt(w[rank])] for name, s in summary.items()
                         for w in s["worst_environments"]]))
    errors = [r for r in rows if r["status"] != "ok"]
    if errors:
        tables.append(Table("Error rows", ["environment", "renderer", "stage", "message"],
                            [[r["environment"], r["renderer"], r["stage"] or "", r["error"] or ""] for r in errors]))
    images = []
    for stem, title in (("distribution", "Distribution over the corpus (box: quartiles, whiskers: 5th-95th percentile)"),
                        ("vs_environment", f"{rank} against the environment's statistics"),
                        ("worst", f"Worst environments by {rank}")):
        if (out_dir / "plots" / f"{stem}.png").is_file():
            images.append({"title": title, "src": f"{prefix}plots/{stem}.png"})
    renderers = ", ".join(r["name"] for r in st["renderers"])
    note = (f"Scene {st['scene']} lit by each of {len(envs)} environment(s), reference {st['spp']} spp "
            f"(seed {st['seed']}, {st['mode']} integrator), renderers {renderers}. One row per (environment, "
            f"renderer) in corpus.csv / corpus.json. Dynamic range: log10 of the maximum luminance over its 1st "
            f"percentile; energy fraction: share of the solid-angle weighted energy in the brightest 1 % of texels.")
    return Section("corpus", "Corpus study", note, tables, images)


def write_corpus_page(result_or_dir) -> Path:
    """Write ``index.html`` into the corpus folder (the corpus section alone); returns its path."""
    out_dir, _ = _load(result_or_dir)
    section = corpus_section(result_or_dir)
    return write_text_atomic(out_dir / "index.html", render_page([], [], [section]))
