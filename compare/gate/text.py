"""The gate's lines of text: one per check, its broken bounds, its change against the baseline.

These are plain text holding names from scenes and budgets as they are; each output escapes them
for its format: :func:`emit` for a terminal (:func:`pbrcheck.fmt.terminal_safe`: control characters
shown as escapes, one line stays one line), :mod:`compare.gate.writers` for JUnit XML, Markdown and
HTML.

API
---
- :func:`check_line` -- the line of one check (verdict, metrics against budgets, baseline, sensitivity).
- :func:`error_line` -- the line of a check that was not evaluated.
- :func:`failure_lines`, :func:`change_lines`, :func:`provenance_changes` -- what a check's line is about.
- :func:`sensitivity_text`, :func:`region_text`, :func:`noise_note`, :func:`pct` -- pieces of them.
- :func:`totals_line` -- ``gate: 3 pass, 1 regressed``.
- :func:`emit` -- print lines on a terminal, escaped.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from pbrcheck.fmt import format_value, terminal_safe

from ..metrics import RELMSE
from .evaluate import BUDGET_NOISE_FACTOR
from .verdict import TOTALS_ORDER, CheckResult, Verdict

#: Regions named per verdict line.
NAMED_REGIONS = 3


def emit(lines, stream) -> None:
    """Print ``lines`` on ``stream`` (a terminal or a log), each made :func:`terminal_safe`: a name
    holding ESC, CR or a newline can neither colour, rewind nor forge a line."""
    for line in lines:
        print(terminal_safe(line), file=stream)


def pct(x: float) -> str:
    """A relative figure as a signed percentage (``+0.125%``); ``inf`` / ``nan`` as they are."""
    return f"{x:+.3%}" if math.isfinite(x) else str(x)


def noise_note(r: CheckResult) -> str:
    """`` (noise-limited: ...)`` when a budget of ``r`` is not 10x above the reference's noise in its
    metric (or an ``auto`` reference stopped at its cap)."""
    bad = [b for b in r.budget_noise if not b["trusted"]]
    parts = [f"{b['metric']} budget {format_value(b['budget'])} is {b['ratio']:.3g}x the reference's noise "
             f"{format_value(b['noise'])} (>= {BUDGET_NOISE_FACTOR:g}x "
             + (f"at {math.ceil(b['spp_needed'])} spp)" if math.isfinite(b["spp_needed"])
                else "at no spp: a budget of 0 is below any noise)")
             for b in bad]
    if r.check.reference == "auto" and r.reference_spp is not None and r.reference_spp.noise_limited:
        parts.append(r.reference_spp.provenance())
    return f" (noise-limited: {'; '.join(parts)})" if parts else ""


def failure_lines(r: CheckResult) -> list[str]:
    """One line per broken bound of ``r`` (metric, value, budget, worst objects, noise note)."""
    out = []
    for f in r.failures:
        op = ">" if f["kind"] == "max" else "<"
        worst = ", ".join(f"{o['name'] or '#' + str(o['id'])}={format_value(o['value'])}" for o in f["worst_objects"])
        note = " (within the reference's noise)" if f.get("within_noise") else ""
        out.append(f"FAIL {r.check.name}: {f['metric']} = {format_value(f['value'])} {op} budget {format_value(f['budget'])}"
                   f"{note}" + (f"; worst objects: {worst}" if worst else "") + noise_note(r))
    return out


def sensitivity_text(r: CheckResult) -> str:
    """``brightness +-k %, LOD m mip`` of a check with a baseline (what its change test can see)."""
    s = r.sensitivity
    if not s:
        return ""
    if s.get("lod") is not None:
        lod = f"LOD shift {s['lod']:.2g} mip ({s['lod_region']})"
    elif s.get("lod_probed"):
        lod = "LOD shift: none visible (no region responds to the LOD probe)"
    else:
        lod = "LOD shift: not measured (the renderer takes no shader hooks)"
    return f"sensitivity: brightness +-{s['brightness']:.2%} ({s['brightness_region']}), {lod}"


def region_text(x) -> str:
    """One region's figures: bias, relmse before -> after, the change in noise units."""
    z = x.d_relmse / x.sigma_d if x.sigma_d > 0 else (math.inf if x.d_relmse else 0.0)
    return (f"{x.name}: {RELMSE.name} {format_value(x.relmse_before)} -> {format_value(x.relmse_after)} "
            f"({pct(x.relative_d)}, {z:+.3g} sigma of the reference's noise), bias {pct(x.bias)} "
            f"(threshold {x.bias_threshold:.2g})")


def change_lines(r: CheckResult, budget_path: str = "BUDGET.toml") -> list[str]:
    """The lines of a check's change against its baseline (nothing for ``pass``)."""
    c = r.change
    if c is None or c.verdict == "pass":
        return []
    name = r.check.name
    worse, better, changed = c.by_state("worse"), c.by_state("better"), c.by_state("changed")
    n = len(c.regions)
    if c.verdict == "regressed":
        head = f"REGRESSED {name}: {len(worse)} of {n} regions significantly worse against the reference"
        if better:
            head += f" ({len(better)} better)"
        rows = worse
    elif c.verdict == "improved":
        head = (f"IMPROVED {name}: {len(better)} of {n} regions significantly better against the reference, "
                f"none worse; accept it: pbrcheck gate {budget_path} --accept --reason \"...\"")
        rows = better
    else:
        how = "allowed by on_change = \"pass\"" if r.check.on_change == "pass" else "accept it if intended"
        head = (f"CHANGED {name}: {len(changed)} of {n} regions differ from the baseline beyond the renderer's "
                f"run-to-run noise, neither better nor worse beyond the reference's noise ({how}: "
                f"pbrcheck gate {budget_path} --accept --reason \"...\")")
        rows = changed
    out = [head]
    out += [f"     {region_text(x)}" for x in rows[:NAMED_REGIONS]]
    if len(rows) > NAMED_REGIONS:
        out.append(f"     ... and {len(rows) - NAMED_REGIONS} more region(s)")
    if r.likely:
        out.append(f"     likely term: {r.likely}")
    out += [f"     note: {n}" for n in provenance_changes(r)]
    return out


def provenance_changes(r: CheckResult) -> list[str]:
    """What made the baseline and differs now (GL renderer, client version, shader sources, hook
    file): a change may come from the machine, not the shaders."""
    if r.baseline is None or r.test_image is None:
        return []
    rec, meta, out = r.baseline.record, r.test_image.meta, []
    for key, what in (("gl_renderer", "GL renderer"), ("version", "renderer version")):
        if rec.get(key) and meta.get(key) and rec[key] != meta[key]:
            out.append(f"the baseline was made with {what} {rec[key]!r}, this run used {meta[key]!r}")
    if rec.get("shader_sources_sha256") and meta.get("renderer") == "realtime":
        from ..baseline import shader_sources_hash

        if shader_sources_hash() != rec["shader_sources_sha256"]:
            out.append("the real-time shader sources changed since the baseline was accepted")
    hook = json.loads(meta["shader"]) if meta.get("shader") else None
    old = rec.get("hook") or None
    if (hook or {}).get("sha256") != (old or {}).get("sha256"):
        out.append("the shader hook file differs from the baseline's" if hook or old else "")
    return [x for x in out if x]


def check_line(r: CheckResult) -> str:
    """The line of an evaluated check: its verdict, each metric against its budget, the baseline's
    verdict and the sensitivity, the noise note."""
    m = r.metrics or {}
    acc = ", ".join(f"{k} {format_value(m.get(k))} {'<=' if kind == 'max' else '>='} {format_value(b)}"
                    for kind, d in (("max", r.check.max), ("min", r.check.min)) for k, b in d.items())
    if r.change is None:
        base = "no accepted baseline (accuracy only)"
    else:
        base = f"baseline: {r.change.verdict} over {len(r.change.regions)} regions"
    sens = sensitivity_text(r)
    return f"{r.verdict.label} {r.check.name} ({acc}; {base}" + (f"; {sens}" if sens else "") + ")" + noise_note(r)


def error_line(r: CheckResult) -> str:
    """``ERROR name: message`` (``NOT JUDGED name: reason``) of a check that was not evaluated."""
    return f"{r.verdict.label.upper()} {r.check.name}: {r.error}"


def lines_of(r: CheckResult, budget_path: str) -> list[str]:
    """Every line the gate prints for ``r``, in order."""
    if not r.verdict.judged:
        return [error_line(r)]
    out = failure_lines(r) + change_lines(r, budget_path) + [check_line(r)]
    if r.maps:
        out.append(f"     error maps: {Path(r.maps['rel_error']).parent}")
    return out


def totals_line(results: list[CheckResult]) -> str:
    """``gate: N pass, ...`` (pass always, the other labels when they occur)."""
    n = {k: sum(r.verdict.label == k for r in results) for k in TOTALS_ORDER}
    return "gate: " + ", ".join(f"{v} {k}" for k, v in n.items() if v or k == Verdict.PASS.label)
