"""The outputs of a corpus study: tables, a per-renderer summary, thumbnails and plots.

Files under the corpus folder:

* ``corpus.csv`` -- one row per (environment, renderer), columns :data:`~compare.corpus.study.ROW_COLUMNS`.
* ``corpus.json`` -- ``{"settings", "summary", "rows"}`` (strict JSON: undefined values are null).
* ``thumbs/<environment key>.png`` -- a tone-mapped thumbnail of each environment.
* ``plots/distribution.png`` -- per renderer, the distribution of ``relmse`` and ``flip_mean`` over
  the corpus (box: quartiles; whiskers: 5th and 95th percentiles; dots: every environment).
* ``plots/vs_environment.png`` -- the rank metric against the environment's dynamic range, the
  fraction of energy in its brightest 1 % of texels, and its resolution, one colour per renderer.
* ``plots/worst.png`` -- per renderer, the thumbnails of the environments with the largest error.

Summary (``summary[renderer]``): ``rows``, ``ok``, ``errors``; per metric ``median``, ``p90`` and
``worst``, where "p90" and "worst" are taken in the bad direction: for a metric where higher is
better (``psnr``) they are the 10th percentile and the minimum; ``worst_environments``: the
:data:`WORST_COUNT` environments with the worst rank metric (name, value, thumbnail).

API
---
:func:`summarize`, :func:`write_outputs`, :func:`write_csv`, :func:`write_thumbnail`,
:func:`plot_distribution`, :func:`plot_vs_environment`, :func:`plot_worst`.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np

from pbrcheck.atomic import write_bytes_atomic, write_text_atomic
from pbrcheck.fmt import csv_cell
from pbrcheck.jsonio import write_json_atomic

from ..maps import pyplot, save_figure
from ..metrics import HIGHER_IS_BETTER, METRICS

#: Environments shown per renderer among the worst.
WORST_COUNT = 5
#: Metrics of the distribution plot.
DISTRIBUTION_METRICS = ("relmse", "flip_mean")
#: Environment statistics on the x axes of the error-against-environment plot: (column, label, log x).
ENV_AXES = (("env_dynamic_range", "dynamic range (decades, max / 1st percentile)", False),
            ("env_top1_energy", "energy fraction in the brightest 1 % of texels", False),
            ("env_texels", "resolution (texels)", True))


def _finite(values) -> list[float]:
    return [float(v) for v in values if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)]


def _badness_order(metric: str, values: list[float]) -> list[float]:
    """Values sorted from best to worst."""
    return sorted(values, reverse=metric in HIGHER_IS_BETTER)


def metric_summary(metric: str, values) -> dict:
    """``{"n", "median", "p90", "worst"}`` of the finite ``values`` (p90 and worst in the bad direction)."""
    v = _finite(values)
    if not v:
        return {"n": 0, "median": None, "p90": None, "worst": None}
    a = np.array(v)
    bad_q = 10.0 if metric in HIGHER_IS_BETTER else 90.0
    return {"n": len(v), "median": float(np.median(a)), "p90": float(np.percentile(a, bad_q)),
            "worst": _badness_order(metric, v)[-1]}


def summarize(rows: list[dict], settings, env_keys: dict[str, str]) -> dict:
    """Per renderer: counts, :func:`metric_summary` of every metric and the worst environments by
    ``settings.rank_metric`` (``env_keys``: environment name -> thumbnail key)."""
    out = {}
    rank = settings.rank_metric
    for r in settings.renderers:
        mine = [x for x in rows if x["renderer"] == r.name]
        ok = [x for x in mine if x["status"] == "ok"]
        ranked = [x for x in ok if _finite([x.get(rank)])]
        ranked.sort(key=lambda x: x[rank], reverse=rank not in HIGHER_IS_BETTER)
        out[r.name] = {
            "rows": len(mine), "ok": len(ok), "errors": len(mine) - len(ok),
            "metrics": {m: metric_summary(m, [x.get(m) for x in ok]) for m in METRICS},
            "worst_environments": [{"environment": x["environment"], rank: x[rank],
                                    "thumbnail": f"thumbs/{env_keys.get(x['environment'], '')}.png"}
                                   for x in ranked[:WORST_COUNT]],
        }
    return out


def write_thumbnail(folder: Path, key: str, rgb8: np.ndarray) -> Path:
    """Write the uint8 sRGB array ``rgb8`` as ``folder/key.png`` atomically."""
    plt = pyplot()
    buf = io.BytesIO()
    plt.imsave(buf, rgb8, format="png")
    return write_bytes_atomic(folder / f"{key}.png", buf.getvalue())


def write_csv(path: Path, rows: list[dict], columns) -> Path:
    """The rows as CSV (empty cells for undefined values), written atomically. A string cell goes through
    :func:`pbrcheck.fmt.csv_cell` (environment and scene names are a user's files' names: one that
    begins with ``= + - @`` would be a spreadsheet formula)."""
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(columns)
    for r in rows:
        cells = []
        for c in columns:
            v = r.get(c)
            if v is None or (isinstance(v, float) and not math.isfinite(v)):
                cells.append("")
            else:
                cells.append(csv_cell(v))
        w.writerow(cells)
    return write_text_atomic(path, buf.getvalue())


def _renderer_rows(rows, settings):
    return [(r.name, [x for x in rows if x["renderer"] == r.name and x["status"] == "ok"]) for r in settings.renderers]


def plot_distribution(path: Path, rows: list[dict], settings) -> str | None:
    """Box plots of :data:`DISTRIBUTION_METRICS` per renderer; the PNG's name (None without data)."""
    groups = _renderer_rows(rows, settings)
    if not any(g for _, g in groups):
        return None
    plt = pyplot()
    fig, axes = plt.subplots(1, len(DISTRIBUTION_METRICS), figsize=(5 * len(DISTRIBUTION_METRICS), 3.6))
    for ax, m in zip(np.atleast_1d(axes), DISTRIBUTION_METRICS):
        data = [_finite(x.get(m) for x in g) for _, g in groups]
        pos = [i + 1 for i, d in enumerate(data) if d]
        if pos:
            ax.boxplot([d for d in data if d], positions=pos, whis=(5, 95), showfliers=False)
            for p, d in zip(pos, [d for d in data if d]):
                ax.scatter([p] * len(d), d, s=8, alpha=0.5, color="tab:blue", zorder=3)
            if all(v > 0 for d in data for v in d):
                ax.set_yscale("log")
        ax.set_xticks(range(1, len(groups) + 1), [n for n, _ in groups], rotation=20, fontsize=8)
        ax.set_ylabel(m)
        ax.grid(alpha=0.3)
    return save_figure(fig, path)


def plot_vs_environment(path: Path, rows: list[dict], settings) -> str | None:
    """The rank metric against each of :data:`ENV_AXES`, one colour per renderer."""
    groups = _renderer_rows(rows, settings)
    if not any(g for _, g in groups):
        return None
    m = settings.rank_metric
    plt = pyplot()
    fig, axes = plt.subplots(1, len(ENV_AXES), figsize=(5 * len(ENV_AXES), 3.8))
    positive = all(v > 0 for _, g in groups for v in _finite(x.get(m) for x in g))
    for ax, (col, label, logx) in zip(axes, ENV_AXES):
        for i, (name, g) in enumerate(groups):
            pts = [(x[col], x[m]) for x in g if _finite([x.get(col)]) and _finite([x.get(m)])]
            if pts:
                ax.scatter([p[0] for p in pts], [p[1] for p in pts], s=14, color=f"C{i % 10}", label=name)
        if logx:
            ax.set_xscale("log")
        if positive:
            ax.set_yscale("log")
        ax.set_xlabel(label, fontsize=8)
        ax.set_ylabel(m)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    return save_figure(fig, path)


def plot_worst(path: Path, summary: dict, out_dir: Path, rank_metric: str) -> str | None:
    """A grid of thumbnails: one row per renderer, its worst environments left to right."""
    names = [n for n, s in summary.items() if s["worst_environments"]]
    if not names:
        return None
    plt = pyplot()
    cols = max(len(summary[n]["worst_environments"]) for n in names)
    fig, axes = plt.subplots(len(names), cols, figsize=(2.6 * cols, 1.75 * len(names)), squeeze=False)
    for i, n in enumerate(names):
        worst = summary[n]["worst_environments"]
        for j in range(cols):
            ax = axes[i][j]
            ax.axis("off")
            if j >= len(worst):
                continue
            w = worst[j]
            thumb = out_dir / w["thumbnail"]
            if thumb.is_file():
                ax.imshow(plt.imread(str(thumb)))
            title = f"{w['environment']}\n{rank_metric} {w[rank_metric]:.3g}"
            ax.set_title((f"{n}: " if j == 0 else "") + title, fontsize=7)
    return save_figure(fig, path)


def write_outputs(out_dir: Path, rows: list[dict], settings, summary: dict, columns) -> dict[str, Path]:
    """Write ``corpus.csv`` (``columns``), ``corpus.json`` and the plots; returns name -> path."""
    files = {"csv": write_csv(out_dir / "corpus.csv", rows, columns),
             "json": write_json_atomic(out_dir / "corpus.json",
                                       {"settings": settings, "summary": summary, "rows": rows}, indent=1)}
    plots = out_dir / "plots"
    plots.mkdir(parents=True, exist_ok=True)
    for name, fn in (("distribution", lambda p: plot_distribution(p, rows, settings)),
                     ("vs_environment", lambda p: plot_vs_environment(p, rows, settings)),
                     ("worst", lambda p: plot_worst(p, summary, out_dir, settings.rank_metric))):
        if fn(plots / f"{name}.png"):
            files[name] = plots / f"{name}.png"
    return files
