"""Replicas of one design run in parallel, and the spread of their metrics.

:func:`run_replicas` runs replicas 0 .. N-1 of a design (:meth:`hydrojam.actuator.design.Design.replica`:
the same design, its particles' as-prepared centres jittered from a seed) through the sweep
machinery (:func:`hydrojam.study.sweep.run_sweep`: dask, cached, resumable) as a study named
"replicas" with one point, and summarises every metric over the replicas. Layout of ``OUT``::

    study.toml                 the replica study (the design inline, replicas.count = N)
    points/<key>/              one folder per replica, as a sweep's point (final.vtu for ParaView)
    results.csv, .parquet      one row: the means and spreads (a sweep table)
    replicas.csv               one row per replica: its metrics, status and folder
    summary.csv, summary.json  per metric: mean, standard deviation, min, max, and which replica
                               gave which value (:class:`ReplicaSummary`)

The statistics are over the replicas that reached the target stimulus (status ok); the others
are listed with their status and left out. Units: those of the metric registry.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from hydrojam._io import finite_or_none, write_text_atomic
from hydrojam.actuator.design import Design, with_replicas
from hydrojam.actuator.metrics import STATE_METRICS, metric
from hydrojam.study.cache import PointStatus, read_record
from hydrojam.study.spec import Study, SweepSpec
from hydrojam.study.spread import Spread, spread
from hydrojam.study.states import state_counts, states_text
from hydrojam.study.sweep import PointOutcome, run_point, run_sweep
from hydrojam.study.table import SweepTable, replica_table

__all__ = ["REPLICA_STUDY", "SUMMARY_METRICS", "ReplicaSummary", "replica_records", "replica_study", "run_replicas",
           "with_replicas"]

#: the name of a replica study (its OUT/study.toml)
REPLICA_STUDY = "replicas"

#: the metrics a replica summary gives statistics of, in its order: the state metrics, then the
#: run's work
SUMMARY_METRICS: tuple[str, ...] = (*(m.name for m in STATE_METRICS), "s_reached", "load_steps",
                                    "newton_iterations", "wall_time_s")


def replica_study(design: Design, count: int | None = None) -> Study:
    """The study "replicas": one point, the design with ``count`` replicas.

    Parameters
    ----------
    design : Design
        The design.
    count : int, optional
        Number of replicas (default: the design's own ``replicas.count``).

    Returns
    -------
    Study
    """
    design = design if count is None else with_replicas(design, count)
    n = design.replicas.count
    return Study(name=REPLICA_STUDY, base=design, sweeps=[SweepSpec(name=REPLICA_STUDY, vary={"replicas.count": [n]})])


@dataclass(frozen=True)
class ReplicaSummary:
    """The replicas of a design and the spread of every metric over those that reached the target.

    Parameters
    ----------
    design : Design
        The design the replicas are of.
    runs : list of dict
        One row per replica (:func:`hydrojam.study.table.replica_table`: replica, key, metrics,
        status, error, point_dir).
    stats : dict of str to Spread
        Metric name -> :class:`~hydrojam.study.spread.Spread` over the replicas with status ok
        (values by replica, None for the others), in the metric's unit.
    wall_time_s : float or None
        The whole call's wall time [s] (the replicas ran in parallel), None when not measured.
    """

    design: Design
    runs: list[dict]
    stats: dict[str, Spread]
    wall_time_s: float | None

    @property
    def count(self) -> int:
        return len(self.runs)

    @property
    def used(self) -> list[int]:
        """The replicas in the statistics (status ok)."""
        return [r["replica"] for r in self.runs if r.get("status") == PointStatus.OK]

    @property
    def states(self) -> dict[str, int]:
        """How many finished runs reached each state (:mod:`hydrojam.study.states`)."""
        return state_counts([r.get("states") for r in self.runs])

    @property
    def states_text(self) -> str | None:
        """The runs by state in words ("arc 1; folded 3", one state: its name), None unclassified."""
        return states_text(self.states)

    @property
    def compute_time_s(self) -> float:
        """The replicas' wall times summed [s]."""
        return math.fsum(r.get("wall_time_s") or 0.0 for r in self.runs)

    def to_csv(self) -> str:
        """One row per metric: metric, unit, n, mean, std, min, min_replica, max, max_replica,
        then the value of every replica (``replica_<k>``; empty where left out)."""
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(["metric", "unit", "n", "mean", "std", "min", "min_replica", "max", "max_replica",
                    *(f"replica_{r['replica']}" for r in self.runs)])
        for name, sp in self.stats.items():
            cells = [name, metric(name).unit, sp.n, sp.mean, sp.std, sp.min, sp.argmin, sp.max, sp.argmax, *sp.values]
            w.writerow(["" if c is None else (repr(c) if isinstance(c, float) else c) for c in cells])
        return buf.getvalue()

    def to_json(self) -> dict:
        """Plain data: the replica settings, the wall and compute times, the runs by state, every
        run (replica, key, status, error, folder, state) and every metric's statistics
        (:meth:`Spread.as_dict`)."""
        spec = self.design.replicas
        return finite_or_none({
            "replicas": self.count, "seed": spec.seed, "jitter": spec.jitter, "used": self.used,
            "wall_time_s": self.wall_time_s, "compute_time_s": self.compute_time_s,
            "states": self.states,
            "runs": [{**{k: r.get(k) for k in ("replica", "key", "status", "error", "point_dir")}, "state": r.get("states")}
                     for r in self.runs],
            "metrics": {name: {"unit": metric(name).unit, **sp.as_dict()} for name, sp in self.stats.items()},
        })

    def write(self, out: str | os.PathLike) -> None:
        """Write ``OUT/summary.csv`` and ``OUT/summary.json``, each atomically."""
        out = Path(out)
        write_text_atomic(out / "summary.csv", self.to_csv())
        write_text_atomic(out / "summary.json", json.dumps(self.to_json(), indent=2, allow_nan=False) + "\n")


def summarise(design: Design, runs: list[dict], wall_time_s: float | None = None) -> ReplicaSummary:
    """The summary of replica runs: every :data:`SUMMARY_METRICS` over the runs with status ok.

    Parameters
    ----------
    design : Design
        The design the replicas are of.
    runs : list of dict
        Rows of :func:`~hydrojam.study.table.replica_table`, in replica order.
    wall_time_s : float, optional
        The whole call's wall time [s], None when not measured.

    Returns
    -------
    ReplicaSummary
    """
    stats = {name: spread([r.get(name) if r.get("status") == PointStatus.OK else None for r in runs])
             for name in SUMMARY_METRICS}
    return ReplicaSummary(design, runs, stats, wall_time_s)


def run_replicas(design: Design, out: str | os.PathLike, *, count: int | None = None,
                 workers: int | None = None, scheduler: str | None = None,
                 on_point: Callable[[PointOutcome, int, int], None] | None = None,
                 point_fn: Callable[[Design, Path], dict] = run_point,
                 on_running=None) -> tuple[SweepTable, ReplicaSummary]:
    """Run replicas 0 .. N-1 of a design into ``OUT`` as :func:`hydrojam.study.sweep.run_sweep` runs a
    study, write the summary (module docstring) and return it.

    Finished replicas in OUT are loaded, not run.

    Parameters
    ----------
    design : Design
        The design.
    out : str or os.PathLike
        The output folder OUT.
    count : int, optional
        N (default ``design.replicas.count``).
    workers, scheduler, on_point, point_fn, on_running
        As for :func:`hydrojam.study.sweep.run_sweep`.

    Returns
    -------
    table : SweepTable
        The one-row table (means and spreads).
    summary : ReplicaSummary
        The spread of every metric over the replicas with status ok.

    Raises
    ------
    DesignError
        For a bad ``count``.
    StudyError, ValueError, SchedulerError
        As :func:`~hydrojam.study.sweep.run_sweep` raises them for bad arguments.

    Notes
    -----
    Nothing is written when it raises for a bad argument.
    """
    t0 = time.perf_counter()
    study = replica_study(design, count)
    table = run_sweep(study, out, workers=workers, scheduler=scheduler, on_point=on_point, point_fn=point_fn,
                      on_running=on_running)
    records = replica_records(Path(out).absolute(), study)
    runs = replica_table(study, records).rows
    summary = summarise(study.base, runs, time.perf_counter() - t0)
    if study.replicas == 1:  # run_sweep writes replicas.csv only for several
        write_text_atomic(Path(out) / "replicas.csv", replica_table(study, records).to_csv())
    summary.write(out)
    return table, summary


def replica_records(out: Path, study: Study) -> dict[str, dict]:
    """The point.json of every run of ``study`` in the folder ``out``, by key (runs without one,
    unfinished or missing, left out)."""
    records = {p.key: read_record(Path(out) / "points" / p.key) for p in study.points()}
    return {key: rec for key, rec in records.items() if rec is not None}
