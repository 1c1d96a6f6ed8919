"""``pbrcheck gate BUDGET.toml``: every check of a budget, printed, written, accepted; the exit code.

API
---
- :func:`run_gate` -- run a budget (:func:`compare.gate.budget.load_budget`), print one line per check
  and the totals, write the CI outputs, accept; returns :func:`compare.gate.verdict.exit_code`.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

from pbrcheck.atomic import check_output_path
from pbrcheck.fmt import terminal_safe

from ..baseline import BASELINE_DIR
from ..maps import safe_name
from .accept import accept
from .budget import Budget, load_budget
from .evaluate import run_check
from .text import emit, lines_of, totals_line
from .verdict import CheckResult, Verdict, exit_code
from .writers import write_html, write_junit, write_summary


def _require_baseline(r: CheckResult, budget: Budget) -> CheckResult:
    """``r`` as an ERROR when the budget requires baselines and the check has none."""
    if r.verdict.judged and r.baseline is None:
        return dataclasses.replace(r, verdict=Verdict.ERROR, error=(
            f"no accepted baseline ({budget.base / BASELINE_DIR / safe_name(r.check.name)}.exr) and the budget sets "
            f"require_baselines = true; accept one: pbrcheck gate {budget.path} --accept --reason \"...\""))
    return r


def run_gate(budget: str | Path, *, junit: str | None = None, summary: str | None = None,
             maps_dir: str | None = None, html: str | None = None, accept_reason: str | None = None,
             progress: bool = True, stream=None, only: list[str] | None = None) -> int:
    """Run every check of ``budget``; print one line per check and the totals.

    Parameters
    ----------
    budget : str or Path
        The budget TOML file (:func:`load_budget`).
    junit, summary : str, optional
        Write JUnit XML / a Markdown summary (with thumbnails in ``<stem>-img/``) there.
    maps_dir : str, optional
        Error maps of checks that are not ``pass`` go to ``maps_dir/<check>``.
    html : str, optional
        Write ``html/index.html``: the slider of every check that is not ``pass``.
    accept_reason : str, optional
        Accept the current renders as the baselines (:func:`compare.gate.accept.accept`) with this
        reason; refused (nothing written) when a check was not judged (exit >= 2).
    progress : bool, optional
        Show render progress on stderr.
    stream : file, optional
        Where the lines go (default stdout).
    only : list of str, optional
        Run only the checks of these names (``--check``); with ``accept_reason`` only their
        baselines are rewritten (the others' stay as accepted).

    Returns
    -------
    int
        :func:`compare.gate.verdict.exit_code` of the verdicts (0 after an accept): 0 every check
        passes (or improved, or changed with ``on_change = "pass"``); 1 a budget is broken, a check
        regressed or changed; 2 a check could not be evaluated or was not judged; 3 no backend.

    Raises
    ------
    BudgetError
        The budget file is missing or malformed, or ``only`` names no check (nothing is rendered).
    """
    stream = stream or sys.stdout
    b = load_budget(budget)
    checks = b.only(only)
    # the outputs' paths are checked before any render (a crash after the work helps nobody)
    for out, folder in ((junit, False), (summary, False), (maps_dir, True), (html, True)):
        if out:
            check_output_path(out, folder=folder)
    results = []
    for c in checks:
        r = run_check(c, b.base, maps_dir=Path(maps_dir) if maps_dir else None, progress=progress)
        if b.require_baselines and accept_reason is None:
            r = _require_baseline(r, b)
        results.append(r)
        emit(lines_of(r, str(budget)), stream)
    if junit:
        write_junit(Path(junit), results)
    if summary:
        write_summary(Path(summary), results, str(budget))
    if html:
        print(f"gate: page {terminal_safe(str(write_html(Path(html), results, str(budget))))}", file=stream)
    print(totals_line(results), file=stream)
    code = exit_code(r.verdict for r in results)
    if accept_reason is None:
        return code
    if code >= 2:
        print("gate: nothing accepted (a check was not judged)", file=stream)
        return code
    accept(b, results, accept_reason, progress=progress, stream=stream)
    return 0
