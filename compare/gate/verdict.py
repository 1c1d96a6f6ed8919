"""What one gate check concluded: the :class:`Verdict` enum, the frozen :class:`CheckResult` and the
exit code, a pure function of the verdicts.

Verdicts, in the order the totals line counts them (label: printed word; exit: the code it maps to):

=================  =============  ====  ==========================================================
member             label          exit  when
=================  =============  ====  ==========================================================
PASS               pass           0     within budget, unchanged against the accepted baseline
OVER_BUDGET        fail           1     a metric outside its ``[check.max]`` / ``[check.min]``
REGRESSED          regressed      1     a region significantly worse against the reference
IMPROVED           improved       0     a region better, none worse (prints the accept command)
CHANGED            changed        1     beyond the renderer's noise, neither better nor worse
CHANGE_ALLOWED     changed        0     the same, in a check with ``on_change = "pass"``
ERROR              error          2     missing / unreadable data, bad scene, no required baseline
BACKEND_ERROR      error          3     no GL / Dr.Jit backend, or a shipped shader that fails
NOT_JUDGED         not judged     2     the gate refuses to judge the check (:class:`NotJudged`)
=================  =============  ====  ==========================================================

The gate's exit status is :func:`exit_code`: the largest exit of the verdicts (0 with none). A
check never passes on missing data: ERROR, BACKEND_ERROR and NOT_JUDGED are all >= 2.

API
---
- :class:`Verdict` -- the enum (``label``, ``exit``, ``judged``).
- :class:`CheckResult` -- one check's verdict and figures (frozen).
- :class:`NotJudged` -- raised inside a check's evaluation when the gate must not judge it.
- :func:`exit_code` -- the gate's exit status from the verdicts.
- :func:`judged_verdict`, :func:`error_verdict` -- the verdict of an evaluated check, of one that raised.
"""

from __future__ import annotations

import enum
from collections.abc import Iterable
from dataclasses import dataclass, field

from pbrcheck.errors import PbrcheckError
from pbrcheck.exr import Image

from ..baseline import Baseline, Change
from ..verdict_spp import VerdictSpp
from .budget import Check


class NotJudged(PbrcheckError):
    """A check the gate refuses to judge (its verdict would mean nothing); the message says why."""


class Verdict(enum.Enum):
    """A check's verdict: ``value`` is the member's identity, :attr:`label` the word printed and
    :attr:`exit` the exit status it maps to (module docstring's table)."""

    PASS = "pass"
    OVER_BUDGET = "fail"
    REGRESSED = "regressed"
    IMPROVED = "improved"
    CHANGED = "changed"
    CHANGE_ALLOWED = "changed, allowed"
    ERROR = "error"
    BACKEND_ERROR = "error, backend"
    NOT_JUDGED = "not judged"

    @property
    def label(self) -> str:
        """The word the gate's lines, totals, JUnit and summary show."""
        return _LABEL.get(self, self.value)

    @property
    def exit(self) -> int:
        """The exit status this verdict maps to."""
        return _EXIT[self]

    @property
    def judged(self) -> bool:
        """False for a check that was not evaluated (error, backend error, not judged)."""
        return self.exit < 2


_LABEL = {Verdict.CHANGE_ALLOWED: "changed", Verdict.BACKEND_ERROR: "error"}
_EXIT = {Verdict.PASS: 0, Verdict.OVER_BUDGET: 1, Verdict.REGRESSED: 1, Verdict.IMPROVED: 0, Verdict.CHANGED: 1,
         Verdict.CHANGE_ALLOWED: 0, Verdict.ERROR: 2, Verdict.BACKEND_ERROR: 3, Verdict.NOT_JUDGED: 2}
#: The labels in the order of the gate's totals line (``gate: 3 pass, 1 regressed``).
TOTALS_ORDER = ("pass", "fail", "regressed", "improved", "changed", "error", "not judged")


def exit_code(verdicts: Iterable[Verdict]) -> int:
    """The gate's exit status: the largest :attr:`Verdict.exit` (0 for no verdict)."""
    return max((v.exit for v in verdicts), default=0)


def error_verdict(err: BaseException) -> Verdict:
    """The verdict of a check whose evaluation raised ``err``: NOT_JUDGED for :class:`NotJudged`,
    BACKEND_ERROR for an error of exit status 3 (a missing backend, a shipped shader that does not
    compile), else ERROR (a renderer's bug must not read as "over budget")."""
    if isinstance(err, NotJudged):
        return Verdict.NOT_JUDGED
    if isinstance(err, PbrcheckError) and err.exit_code >= Verdict.BACKEND_ERROR.exit:
        return Verdict.BACKEND_ERROR
    return Verdict.ERROR


@dataclass(frozen=True)
class CheckResult:
    """One check's :class:`Verdict` and what it was read from.

    ``failures``: per broken bound ``{"metric", "value", "budget", "kind", "worst_objects",
    "within_noise"}``; ``error``: the message of an ERROR / BACKEND_ERROR / NOT_JUDGED verdict;
    ``reference_spp``: the reference's spp and noise floor against the error (:class:`VerdictSpp`);
    ``budget_noise``: per ``max`` budget, the reference's noise in its metric
    (:func:`compare.gate.evaluate.budget_noise`); ``change`` against the accepted ``baseline``
    (None without one); ``likely``: the term a change most likely comes from; the images are kept
    for ``--accept``, the thumbnails and ``--html``; ``names``: object id -> name; ``materials``:
    region name -> material."""

    check: Check
    verdict: Verdict
    metrics: dict | None = None
    failures: tuple[dict, ...] = ()
    error: str | None = None
    seconds: float = 0.0
    maps: dict = field(default_factory=dict)
    reference_spp: VerdictSpp | None = None
    budget_noise: tuple[dict, ...] = ()
    change: Change | None = None
    baseline: Baseline | None = None
    sensitivity: dict | None = None
    likely: str | None = None
    ref_image: Image | None = None
    test_image: Image | None = None
    names: dict = field(default_factory=dict)
    materials: dict = field(default_factory=dict)


def judged_verdict(over_budget: bool, change: Change | None, on_change: str) -> Verdict:
    """The verdict of an evaluated check: over budget first, then its change against the baseline
    (``compare.baseline``'s ``pass | regressed | improved | changed``; none without a baseline)."""
    if over_budget:
        return Verdict.OVER_BUDGET
    if change is None:
        return Verdict.PASS
    if change.verdict == "changed":
        return Verdict.CHANGE_ALLOWED if on_change == "pass" else Verdict.CHANGED
    return {"pass": Verdict.PASS, "regressed": Verdict.REGRESSED, "improved": Verdict.IMPROVED}[change.verdict]
