"""The gate's CI outputs: JUnit XML, a Markdown summary with thumbnails, an HTML page.

Names come from scenes, assets and budgets a CI job may not trust; each writer escapes them for its
format (docs/security.md): JUnit through :func:`pbrcheck.fmt.xml_text` (XML 1.0 forbids most control
characters: a name holding ESC would make the file unparseable), the Markdown summary through
:func:`pbrcheck.fmt.markdown_cell` (no raw HTML, no ``|`` or newline breaking the table), the HTML
page through its template's autoescaping (``templates/page.html``, Jinja).

API
---
- :func:`write_junit` -- one testcase per check and per region of a regressed check.
- :func:`write_summary` -- the Markdown summary (PNGs in ``<stem>-img/`` beside it).
- :func:`write_html` -- ``DIR/index.html``: the baseline / current slider of every check not ``pass``.
- :func:`write_thumbnails` -- before / after / difference PNGs of a check with a baseline.

References: JUnit XML as read by CI systems; W3C XML 1.0 section 2.2 (characters); GitHub Flavored
Markdown's tables.
"""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from pbrcheck.atomic import write_text_atomic
from pbrcheck.fmt import format_value, markdown_cell, xml_text

from ..maps import safe_name
from ..metrics import RELMSE
from .text import change_lines, check_line, failure_lines, noise_note, pct, region_text, sensitivity_text
from .verdict import CheckResult, Verdict

#: Width in pixels of the summary's thumbnails (larger images are shown with an integer stride).
THUMB_WIDTH = 160
#: Relative difference |t1 - t0| / (t0 + REL_EPS) shown at full colour in the difference thumbnail.
DIFF_THUMB_MAX = 0.05
#: The HTML page's template (package data of compare.gate).
TEMPLATE_PACKAGE, TEMPLATE_DIR, TEMPLATE_NAME = "compare.gate", "templates", "page.html"


def _el(tag: str, parent=None, text: str | None = None, **attrs) -> ET.Element:
    """An XML element whose attributes and text are XML 1.0-legal (:func:`xml_text`)."""
    attrs = {k: xml_text(v) for k, v in attrs.items()}
    el = ET.Element(tag, attrs) if parent is None else ET.SubElement(parent, tag, attrs)
    if text is not None:
        el.text = xml_text(text)
    return el


def write_junit(path: Path, results: list[CheckResult]) -> Path:
    """Write the results as JUnit XML: one testcase per check, and one per region of a regressed
    check that got worse (``<check>/<region>``); failures and errors as such. Atomic; well-formed
    whatever the names hold."""
    cases = []
    for r in results:
        tc = _el("testcase", classname="pbrcheck.gate", name=r.check.name, time=f"{r.seconds:.3f}")
        lines = failure_lines(r) + change_lines(r)
        if not r.verdict.judged:
            _el("error", tc, r.error, message=r.error or r.verdict.label)
        elif r.verdict.exit:
            _el("failure", tc, "\n".join(lines), message=lines[0] if lines else r.verdict.label)
        if r.metrics:
            out = [check_line(r)] + [f"{k} = {format_value(v)}" for k, v in r.metrics.items()]
            if r.reference_spp is not None:
                out.append(f"reference: {r.reference_spp.provenance()}")
            out += [f"budget {b['metric']}: {b['ratio']:.3g}x the reference's noise" for b in r.budget_noise]
            _el("system-out", tc, "\n".join(out))
        cases.append(tc)
        if r.change is not None and r.change.verdict == "regressed":
            for x in r.change.by_state("worse"):
                sub = _el("testcase", classname=f"pbrcheck.gate.{r.check.name}", name=f"{r.check.name}/{x.name}",
                          time="0")
                _el("failure", sub, region_text(x), message=f"regressed: {region_text(x)}")
                cases.append(sub)
    fails = sum(1 for c in cases if c.find("failure") is not None)
    suite = ET.Element("testsuite", name="pbrcheck-gate", tests=str(len(cases)), failures=str(fails),
                       errors=str(sum(not r.verdict.judged for r in results)),
                       time=f"{sum(r.seconds for r in results):.3f}")
    suite.extend(cases)
    root = ET.Element("testsuites")
    root.append(suite)
    ET.indent(root)
    text = ET.tostring(root, encoding="unicode", xml_declaration=False)
    return write_text_atomic(Path(path), '<?xml version="1.0" encoding="utf-8"?>\n' + text + "\n")


def write_thumbnails(folder: Path, r: CheckResult) -> dict[str, Path]:
    """Before (baseline) / after (current) / difference PNGs of a check with a baseline."""
    from ..maps import _save_rgb, display_rgb, false_colour  # matplotlib: only when thumbnails are written
    from ..metrics import REL_EPS

    if r.baseline is None or r.test_image is None:
        return {}
    t0 = r.baseline.image.rgb.astype(np.float64)
    t1 = r.test_image.rgb.astype(np.float64)
    step = max(1, int(math.ceil(t0.shape[1] / THUMB_WIDTH)))
    opts = None
    if r.test_image.meta.get("options"):
        try:
            opts = json.loads(r.test_image.meta["options"])
        except ValueError:
            opts = None
    disp = (lambda x: np.clip(x, 0, 1)) if r.test_image.meta.get("display_referred") == "1" else (lambda x: display_rgb(x, opts))
    rel = (np.abs(t1 - t0) / (np.abs(t0) + REL_EPS)).max(axis=-1)
    stem = safe_name(r.check.name)
    out = {}
    for kind, img in (("before", disp(t0)), ("after", disp(t1)), ("diff", false_colour(rel, DIFF_THUMB_MAX, "inferno"))):
        out[kind] = _save_rgb(Path(folder) / f"{stem}-{kind}.png", img[::step, ::step])
    return out


def _row(*cells: str) -> str:
    return "| " + " | ".join(cells) + " |"


def write_summary(path: Path, results: list[CheckResult], budget_path: str = "BUDGET.toml") -> Path:
    """Write the Markdown summary (for a CI job summary): every check's verdict, metrics against
    budgets and change against its baseline, a per-object table and before / after / difference
    thumbnails for every check that is not ``pass`` (PNGs in ``<summary stem>-img/`` beside it).
    Every name and message goes through :func:`markdown_cell`."""
    path = Path(path)
    img_dir = path.parent / f"{path.stem}-img"
    md = markdown_cell
    lines = ["# pbrcheck gate", "", "| check | outcome | metric | value | budget |", "|---|---|---|---|---|"]
    for r in results:
        budgets = [(m, b, ">") for m, b in r.check.max.items()] + [(m, b, "<") for m, b in r.check.min.items()]
        if not r.verdict.judged:
            lines.append(_row(md(r.check.name), r.verdict.label.upper(), "", "", md(r.error or "")))
            continue
        failed = {f["metric"] for f in r.failures}
        for m, b, op in budgets:
            st = "FAIL" if m in failed else r.verdict.label
            lines.append(_row(md(r.check.name), st, m, format_value(r.metrics.get(m)),
                              f"{'<=' if op == '>' else '>='} {format_value(b)}"))
    sens = [f"- {md(r.check.name)}: {md(sensitivity_text(r))}" for r in results if r.sensitivity]
    if sens:
        lines += ["", "## Sensitivity (smallest change the baseline comparison detects)", ""] + sens
    for r in results:
        if r.change is None or r.change.verdict == "pass":
            continue
        lines += ["", f"## {md(r.check.name)}: {r.change.verdict}", ""] + [md(l.strip()) for l in change_lines(r, budget_path)[:1]]
        if r.likely:
            lines.append(f"\nLikely term: {md(r.likely)}.")
        thumbs = write_thumbnails(img_dir, r)
        if thumbs:
            rel = {k: f"{img_dir.name}/{p.name}" for k, p in thumbs.items()}
            lines += ["", "| before (baseline) | after | difference (0..5 %) |", "|---|---|---|",
                      f"| ![before]({rel['before']}) | ![after]({rel['after']}) | ![difference]({rel['diff']}) |"]
        rows = [x for x in r.change.regions if x.name.startswith("object ") and x.state != "same"]
        lines += ["", f"| object | state | bias | {RELMSE.name} before | {RELMSE.name} after | change | sigma (ref. noise) |",
                  "|---|---|---|---|---|---|---|"]
        for x in rows:
            lines.append(_row(md(x.name[len("object "):]), x.state, pct(x.bias), format_value(x.relmse_before),
                              format_value(x.relmse_after), pct(x.relative_d), format_value(x.sigma_d)))
        if not rows:
            lines.append("| (no object changed; screen tiles did) | | | | | | |")
    refs = [f"- {md(r.check.name)}: {md(r.reference_spp.provenance())}; budgets / noise: "
            + ", ".join(f"{b['metric']} {b['ratio']:.3g}x" for b in r.budget_noise) + md(noise_note(r))
            for r in results if r.reference_spp is not None]
    if refs:
        lines += ["", "## References (noise floor against the error and the budgets; goal >= 10x)", ""] + refs
    fails = [l for r in results for l in failure_lines(r)]
    if fails:
        lines += ["", "## Failures", ""] + [f"- {md(l)}" for l in fails]
    return write_text_atomic(path, "\n".join(lines) + "\n")


def _section(r: CheckResult, folder: Path, budget_path: str) -> dict:
    """One check's section of the HTML page (the template's ``sections`` item)."""
    lines = failure_lines(r) + change_lines(r, budget_path) + ([f"error: {r.error}"] if r.error else [])
    thumbs = write_thumbnails(folder, r)
    regions = None
    if r.change is not None:
        regions = [{"name": x.name, "state": x.state, "bias": pct(x.bias), "before": format_value(x.relmse_before),
                    "after": format_value(x.relmse_after), "change": pct(x.relative_d)}
                   for x in r.change.regions if x.state != "same"]
    return {"name": r.check.name, "label": r.verdict.label, "text": "\n".join(lines),
            "thumbs": {k: p.name for k, p in thumbs.items()} or None, "regions": regions}


def write_html(folder: Path, results: list[CheckResult], budget_path: str = "BUDGET.toml") -> Path:
    """``--html DIR``: ``DIR/index.html`` (``templates/page.html``) with the slider (baseline /
    current), the difference and the region table for every check that is not ``pass``. Atomic."""
    import jinja2

    folder = Path(folder)
    sections = [_section(r, folder, budget_path) for r in results if r.verdict is not Verdict.PASS]
    env = jinja2.Environment(loader=jinja2.PackageLoader(TEMPLATE_PACKAGE, TEMPLATE_DIR), autoescape=True, keep_trailing_newline=True,
                             undefined=jinja2.StrictUndefined)
    page = env.get_template(TEMPLATE_NAME).render(budget=str(budget_path), sections=sections, relmse=RELMSE.name)
    return write_text_atomic(folder / "index.html", page)
