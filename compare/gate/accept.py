"""``pbrcheck gate BUDGET.toml --accept --reason "..."``: the current renders become the baselines.

Per check: the run-to-run spread (:data:`compare.baseline.SPREAD_RUNS` renders, each with its
environment baked afresh), the LOD probe where the renderer takes shader hooks, the record (what
made it), all staged with the budget's new text (a ``[[history]]`` entry: date, reason, figures)
and switched in one rename (:func:`compare.baseline.commit_accept`): a stop at any point leaves the
old set or the new one, never a mix.

API
---
- :func:`accept` -- stage, commit and report an accept.
"""

from __future__ import annotations

import datetime
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from pbrcheck.fmt import format_value, terminal_safe

from .. import renderers
from ..baseline import (BASELINE_DIR, LOD_PROBE_HOOK, SPREAD_RUNS, abandon_accept, begin_accept, commit_accept,
                        probe_response, shader_sources_hash, spread_of, stage_baseline)
from ..maps import safe_name
from .budget import Budget, scene_arg
from .evaluate import render_test, takes_hooks
from .text import emit
from .verdict import CheckResult


def _accept_one(r: CheckResult, base: Path, staging: Path, reason: str, date: str, progress: bool) -> str:
    """Measure the run-to-run spread and the LOD probe of one check, stage its baseline; returns the
    history line (the figures)."""
    c = r.check
    scene = scene_arg(base, c.scene) if c.scene else None
    images = [r.test_image.rgb]
    probe = None
    if c.test is None:
        for _ in range(SPREAD_RUNS - 1):
            renderers.trim_caches(0)  # every run bakes its environment afresh
            images.append(render_test(c, scene, progress=progress, use_cache=False).rgb)
        if takes_hooks(c):
            with tempfile.TemporaryDirectory(prefix="pbrcheck-lod-probe-") as d:
                hook = Path(d) / "lod_probe.glsl"
                hook.write_text(LOD_PROBE_HOOK, encoding="utf-8")
                img = render_test(c, scene, options={**c.options, "shader": str(hook)}, progress=progress)
            probe = probe_response(r.ref_image, r.test_image.rgb, img.rgb, r.test_image, r.names)
    spread = spread_of(images)
    meta = r.test_image.meta
    record = {
        "check": c.name, "accepted": date, "reason": reason, "preset": c.preset if c.test is None else None,
        "test": c.test, "scene": c.scene, "options": json.loads(meta["options"]) if meta.get("options") else c.options,
        "shader_sources_sha256": shader_sources_hash() if c.test is None and not renderers.is_external(c.preset) else None,
        "hook": json.loads(meta["shader"]) if meta.get("shader") else None,
        "renderer": meta.get("renderer"), "version": meta.get("version"), "gl_renderer": meta.get("gl_renderer"),
        "runs": len(images), "bit_exact": bool(np.all(spread == 0)), "spread_max": float(spread.max()),
        "metrics": r.metrics, "lod_probe": probe,
        "conventions": "regions: 'object NAME' and 'tile xA-B,yC-D' (compare/baseline.py); lod_probe: per region "
                       "bias and change of a render LOD_PROBE mip deeper",
    }
    stage_baseline(staging, safe_name(c.name), r.test_image, spread, record)
    before = r.change.verdict if r.change is not None else "new"
    fig = ", ".join(f"{k} {format_value(r.metrics.get(k))}" for k in r.check.max)
    return (f"{c.name}: {before}; {fig}; {'bit-exact' if record['bit_exact'] else 'spread max ' + format_value(record['spread_max'])}"
            f" over {len(images)} runs")


def _toml_str(s: str) -> str:
    return json.dumps(s, ensure_ascii=False)


def history_entry(date: str, reason: str, lines: list[str]) -> str:
    """A ``[[history]]`` table (TOML strings: JSON's escaping is TOML's basic-string escaping)."""
    return (f"\n[[history]]\ndate = {_toml_str(date)}\nreason = {_toml_str(reason)}\nfigures = [\n"
            + "".join(f"  {_toml_str(l)},\n" for l in lines) + "]\n")


def accept(budget: Budget, results: list[CheckResult], reason: str, *, progress: bool = True, stream=None) -> None:
    """Rewrite every check's baseline from ``results`` and append ``reason``, the date and the figures
    to the budget's ``[[history]]``: staged, then switched in one rename
    (:func:`compare.baseline.commit_accept`); nothing changes if a render fails or a stop comes
    before the switch."""
    stream = stream or sys.stdout
    base = budget.base
    date = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    staging = begin_accept(base)
    try:
        lines = [_accept_one(r, base, staging, reason, date, progress) for r in results]
        text = budget.path.read_text(encoding="utf-8")
        commit_accept(staging, budget.path, text.rstrip("\n") + "\n" + history_entry(date, reason, lines))
    finally:
        abandon_accept(staging)
    emit([f"accepted {l}" for l in lines], stream)
    print(f"gate: {len(lines)} baseline(s) written to {terminal_safe(str(base / BASELINE_DIR))}; "
          f"history appended to {terminal_safe(str(budget.path))}", file=stream)
