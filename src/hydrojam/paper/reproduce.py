"""``hydrojam reproduce``: the paper's Section IV study run end to end.

:func:`reproduce` runs the three sweeps of :func:`hydrojam.paper.study.paper_study` with
:func:`hydrojam.study.sweep.run_sweep`, draws their figures (:mod:`hydrojam.paper.figures`) into
``OUT/figures/`` and writes ``OUT/report.md`` (:mod:`hydrojam.paper.report`), which checks the
paper's statements (:mod:`hydrojam.paper.claims`) against hydrojam's numbers.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from hydrojam.paper.figures import write_figures
from hydrojam.paper.report import write_report
from hydrojam.paper.study import paper_study
from hydrojam.study.sweep import PointOutcome, SweepTable, run_sweep

__all__ = ["reproduce"]


def reproduce(out: str | os.PathLike, *, quick: bool = False, workers: int | None = None,
              scheduler: str | None = None, sweeps: Sequence[str] | None = None,
              on_point: Callable[[PointOutcome, int, int], None] | None = None,
              replicas: int = 1) -> tuple[SweepTable, Path]:
    """Run the Section IV study into ``out`` (:func:`hydrojam.study.sweep.run_sweep` with
    ``workers``, ``scheduler`` and ``on_point``; quick: a subset on a 4 mm mesh; ``sweeps``: only
    those named, the others can be added by a later call into the same folder; ``replicas`` per
    point: the table, figures and verdicts then use their mean and spread), write the
    figures into ``OUT/figures/`` and ``OUT/report.md``; returns (SweepTable, report path).
    The report's wall time [s] is this call's."""
    out = Path(out)
    t0 = time.perf_counter()
    study = paper_study(quick, sweeps, replicas)
    table = run_sweep(study, out, workers=workers, scheduler=scheduler, on_point=on_point)
    write_figures(out, table)
    report = write_report(out, table, quick, time.perf_counter() - t0, workers=workers, scheduler=scheduler,
                          base=study.base)
    return table, report
