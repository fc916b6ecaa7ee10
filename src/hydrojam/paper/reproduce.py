"""``hydrojam reproduce``: the paper's Section IV study run end to end.

:func:`reproduce` runs the three sweeps of :func:`hydrojam.paper.study.paper_study` with
:func:`hydrojam.study.sweep.run_sweep`, draws their figures (:mod:`hydrojam.paper.figures`) into
``OUT/figures/`` and writes ``OUT/report.md`` (:mod:`hydrojam.paper.report`), which checks the
paper's statements (:mod:`hydrojam.paper.claims`) against hydrojam's numbers, and the same as one
self-contained page ``OUT/report.html`` (:mod:`hydrojam.paper.page`). With
``dimension=3`` it runs the same points in 3D (spheres, the half model: the study "paper-3d" or
"paper-3d-quick", never mixed with a 2D one in one folder), and the report compares them with the
2D study of the same kind in ``compare_2d`` (:mod:`hydrojam.paper.compare`).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from hydrojam.paper.claims import check_claims
from hydrojam.paper._rows import rows_of
from hydrojam.paper.compare import comparison_lines, read_2d_results
from hydrojam.paper.figures import figure_names, write_figures
from hydrojam.paper.page import write_report_page
from hydrojam.paper.report import write_report
from hydrojam.paper.sections import (check_page, compare_lines, results_lines, run_commits, sensitivity_row, time_lines,
                                     verdict_lines, write_figure_section, write_sections,
                                     write_sensitivity_row)
from hydrojam.paper.study import paper_study, paper_sweeps
from hydrojam.study.sweep import PointOutcome, run_sweep
from hydrojam.study.table import SweepTable, state_tables

__all__ = ["reproduce"]


def reproduce(out: str | os.PathLike, *, quick: bool = False, workers: int | None = None,
              scheduler: str | None = None, sweeps: Sequence[str] | None = None,
              on_point: Callable[[PointOutcome, int, int], None] | None = None,
              replicas: int = 1, dimension: int = 2,
              compare_2d: str | os.PathLike | None = None, on_running=None,
              report_only: bool = False,
              results_pages: Sequence[str | os.PathLike] = (),
              overrides: Sequence[str] = ()) -> tuple[SweepTable, Path]:
    """Run the Section IV study into ``out``, write its figures and report.

    The study runs with :func:`hydrojam.study.sweep.run_sweep`; the figures go into
    ``OUT/figures/`` and the report to ``OUT/report.md``. The report's wall time [s] is this
    call's, with how many points it computed (the others reused).

    Parameters
    ----------
    out : str or os.PathLike
        The output folder OUT.
    quick : bool, optional
        A subset of the points on a 4 mm mesh.
    workers, scheduler, on_point, on_running
        As for :func:`hydrojam.study.sweep.run_sweep`.
    sweeps : sequence of str, optional
        Only the sweeps named; the others can be added by a later call into the same folder.
    replicas : int, optional
        Runs per point: the table, figures and verdicts then use their mean and spread.
    dimension : {2, 3}, optional
        Plane strain or 3D (spheres, the half model).
    compare_2d : str or os.PathLike, optional
        With dimension 3, a folder holding the 2D study of the same kind, read before anything runs
        (:func:`hydrojam.paper.compare.read_2d_results`), for the report's 2D-against-3D table.
    report_only : bool, optional
        Run nothing: the table, figures and report of the points finished in ``out`` so far, the
        others shown as not finished (``run_sweep(run=False)``).
    results_pages : sequence of str or os.PathLike, optional
        Markdown pages whose sections of this study (:mod:`hydrojam.paper.sections`) take its
        results table and verdicts, written after the report.
    overrides : sequence of str, optional
        Model choices changed for every point ("friction=0.1", as ``--set``): a study of its own
        (:func:`hydrojam.paper.study.study_name`), for its own output folder.

    Returns
    -------
    table : SweepTable
        The study's results.
    report : Path
        The report written.

    Raises
    ------
    ValueError
        For a dimension other than 2 or 3, an unknown sweep, or ``compare_2d`` with dimension 2.
    CompareError
        (a ValueError) When ``compare_2d`` is unusable.
    StudyError
        Nothing run, for an OUT holding the other dimension's or kind's study, or with
        ``report_only`` where ``out`` holds no study yet.
    SectionError
        (a ValueError) Nothing run, for a page of ``results_pages`` without a section of the study.
    """
    out = Path(out)
    t0 = time.perf_counter()
    study = paper_study(quick, sweeps, replicas, dimension, overrides)
    if compare_2d is not None and dimension != 3:
        raise ValueError("compare_2d: only with dimension 3 (it compares a 3D study with a 2D one)")
    table_2d = read_2d_results(compare_2d, quick) if compare_2d is not None else None
    for page in results_pages:  # before anything runs: a page that cannot take the results
        check_page(page, study.name)
    computed = []

    def point_done(outcome: PointOutcome, done: int, total: int) -> None:
        if not outcome.cached:
            computed.append(outcome.key)
        if on_point is not None:
            on_point(outcome, done, total)

    table = run_sweep(study, out, workers=workers, scheduler=scheduler, on_point=point_done, on_running=on_running,
                      run=not report_only)
    states = state_tables(study, out)
    write_figures(out, table, states)
    report = write_report(out, table, quick, time.perf_counter() - t0, workers=workers, scheduler=scheduler,
                          base=study.base, compare_2d=table_2d, compare_source=compare_2d,
                          computed=None if report_only else len(computed), ran=not report_only,
                          states=states, overrides=overrides)
    write_report_page(out, table, report)
    if results_pages:
        # the statements of the sweeps this study ran (a study of some sweeps says nothing of the others)
        results = [c for c in check_claims(table, dimension) if rows_of(table, c.claim.sweep)]
        commits = run_commits(study, out)
        lines = results_lines(table, study.base, quick, replicas, workers, states, results, commits, overrides)
        cost = time_lines(table, study.base, quick, replicas, workers, commits, overrides)
        row = sensitivity_row(table, dimension, replicas, overrides, states, results, commits)
        compare = None
        if table_2d is not None:
            results_2d = [c for c in check_claims(table_2d, 2) if rows_of(table_2d, c.claim.sweep)]
            compare = compare_lines(results, results_2d, comparison_lines(table, table_2d, study.base, quick=quick,
                                                                          out=out, source=compare_2d),
                                    str(compare_2d))
        trends = [(f"{study.name}: θ and the free end's |δx|, |δz|"
                   f"{' and the curling index' if sw.field == 'particle_layers' else ''} against the {sw.label} "
                   f"(the paper's {sw.figures})", out / figure_names(sw)[1])
                  for sw in paper_sweeps(dimension) if rows_of(table, sw.name)]
        for page in results_pages:
            write_sections(page, study.name, lines, verdict_lines(results, study.name), cost, compare)
            write_sensitivity_row(page, study.name, dimension, row)
            write_figure_section(page, study.name, trends)
    return table, report
