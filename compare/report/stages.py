"""The report's work as one list of stages: the list runs the work and drives the progress bar.

Each :class:`ReportStage` names itself (the run log's stage, :mod:`compare.report.runlog`), says how
many steps of the progress bar it is and does its work. :func:`run_stages` runs a list in order under
one bar whose total is :func:`total_steps` of that same list: a stage's updates beyond its steps are
dropped and the steps it did not use are added when it ends (a convergence study at a lower spp than
counted), so the bar ends at 100 % and is never counted apart from the work it counts.

API: :class:`ReportStage`, :func:`total_steps`, :func:`run_stages`.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass

from pbrcheck.progress import Progress

from .runlog import RunLog


@dataclass(frozen=True)
class ReportStage:
    """One stage: ``run(progress)`` does its work, advancing ``progress`` by at most ``steps``.
    ``record``: recorded in the run log under ``name`` (a stage that only writes files is not)."""

    name: str
    steps: int
    run: Callable[[object], None]
    record: bool = True


class _StageBar:
    """The report's bar as one stage sees it: at most ``steps`` units, the rest on :meth:`finish`."""

    def __init__(self, bar: Progress, steps: int, name: str):
        self.bar, self.left, self.name = bar, steps, name

    def update(self, n: float = 1.0, note: str = "") -> None:
        n = min(n, self.left)
        if n > 0:
            self.left -= n
            self.bar.update(n, note)

    def finish(self) -> None:
        self.update(self.left, self.name)


def total_steps(stages: list[ReportStage]) -> int:
    """The progress bar's total: the steps of every stage."""
    return sum(s.steps for s in stages)


def run_stages(stages: list[ReportStage], label: str = "report", *, enabled: bool = True,
               log: RunLog | None = None) -> None:
    """Run ``stages`` in order under one progress bar (``label``, total :func:`total_steps`),
    recording each (its ``record``) into ``log`` when given."""
    with Progress(label, total=total_steps(stages), enabled=enabled) as bar:
        for s in stages:
            sub = _StageBar(bar, s.steps, s.name)
            with log.stage(s.name) if s.record and log is not None else contextlib.nullcontext():
                s.run(sub)
            sub.finish()


__all__ = ["ReportStage", "run_stages", "total_steps"]
