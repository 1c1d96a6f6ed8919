"""CI error-budget gate: ``pbrcheck gate BUDGET.toml`` (docs/compare.md).

A package of one job per module, lowest first:

- :mod:`compare.gate.budget` -- the budget file, parsed and validated once (:class:`Budget`, :class:`Check`).
- :mod:`compare.gate.verdict` -- :class:`Verdict`, the frozen :class:`CheckResult`, :func:`exit_code`.
- :mod:`compare.gate.evaluate` -- one check: accuracy against the reference, change against the
  accepted baseline, the budgets against the reference's noise (:func:`run_check`); the one call of
  the renderer under test (:func:`render_test`).
- :mod:`compare.gate.text` -- the lines (terminal output escaped).
- :mod:`compare.gate.writers` -- JUnit XML, the Markdown summary, the HTML page (``templates/page.html``).
- :mod:`compare.gate.accept` -- ``--accept``: stage every baseline and the history, switch in one rename.
- :mod:`compare.gate.run` -- :func:`run_gate`: a budget, printed and written, the exit code.

Exit status (:func:`exit_code`, the largest of the verdicts'): 0 pass / improved / changed with
``on_change = "pass"``; 1 over budget, regressed, changed; 2 an error (missing or unreadable data,
bad scene, a missing required baseline) or a check the gate refuses to judge; 3 no backend. A
malformed budget is an error before any check runs (exit 2, nothing written).

References: JUnit XML as read by CI systems; Filament's renderdiff and model-viewer's fidelity test
(golden images: a change, not its direction).
"""

from .accept import accept
from .budget import Budget, BudgetError, Check, load_budget, scene_arg
from .evaluate import BUDGET_NOISE_FACTOR, budget_noise, render_test, run_check, takes_hooks
from .run import run_gate
from .text import change_lines, check_line, failure_lines, noise_note, region_text, sensitivity_text
from .verdict import CheckResult, NotJudged, Verdict, exit_code
from .writers import write_html, write_junit, write_summary, write_thumbnails

__all__ = ["BUDGET_NOISE_FACTOR", "Budget", "BudgetError", "Check", "CheckResult", "NotJudged", "Verdict", "accept",
           "budget_noise", "change_lines", "check_line", "exit_code", "failure_lines", "load_budget", "noise_note",
           "region_text", "render_test", "run_check", "run_gate", "scene_arg", "sensitivity_text", "takes_hooks",
           "write_html", "write_junit", "write_summary", "write_thumbnails"]
