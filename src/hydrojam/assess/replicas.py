"""Replicas of an assessment (``hydrojam assess --replicas N``, docs/assess.md): the design's
replicas (its particles' as-prepared centres jittered from a seed, as ``hydrojam run --replicas``)
each assessed as one point of a replica study on the dask cluster (:func:`hydrojam.study.sweep.run_sweep`:
parallel, cached in ``OUT/points/<key>/``, resumable), and every scalar of the assessment with its
spread over them (:func:`hydrojam.study.spread.spread`). Units: those of :func:`~hydrojam.assess.assessment.assess`."""

from __future__ import annotations

import functools
import json
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path

from hydrojam._io import finite_or_none, write_text_atomic
from hydrojam.actuator.design import Design
from hydrojam.assess.assessment import assess, check_assessable
from hydrojam.assess.spec import AssessError, Loads
from hydrojam.study.replicas import replica_study
from hydrojam.study.spread import Spread, spread
from hydrojam.study.sweep import run_sweep

#: the name of an assessment's replica study (its OUT/study.toml): not ``hydrojam run``'s
#: "replicas", whose points (plain runs) share the keys of these
ASSESS_REPLICA_STUDY = "assessment_replicas"
#: the loads a replica folder's assessments were made under (the points' keys are the designs')
LOADS_FILE = "loads.json"

#: the parts whose convergence decides a replica's status
#: the parts whose stop makes an assessment stopped early (exit status 1), as for a single
#: assessment: the baselines' own stops are answers their messages report (the empty chamber's
#: pneumatic ramp ends at its balloon's limit point short of the active angle)
PARTS = ("actuation_converged", "curves_converged", "blocked_converged")


def assess_point(design: Design, point_dir: Path, loads: Loads) -> dict:
    """One replica: the design's assessment under ``loads``, its report written into
    ``point_dir`` (:func:`~hydrojam.assess.report.write_report`); returns its scalar values
    (numbers and booleans), ``converged`` (every part) and ``message`` (the parts that stopped)."""
    from hydrojam.assess.report import write_report

    a = assess(design, loads)
    write_report(a, point_dir)
    values = {k: v for k, v in a.values.items()
              if isinstance(v, (bool, int, float)) or (k.endswith("_message") and isinstance(v, str))}
    values["curves_converged"] = all(c.converged for c in a.curves.values())
    values["blocked_converged"] = all(b["converged"] for b in a.blocked)
    stopped = [k for k in PARTS if values.get(k) is False]
    values["converged"] = not stopped
    values["message"] = "stopped early: " + ", ".join(stopped) if stopped else "converged"
    return values


@dataclass(frozen=True)
class ReplicaAssessment:
    """The assessments of a design's replicas: ``runs`` (one record per replica: replica, key,
    status, error, values), ``stats`` (value name -> :class:`~hydrojam.study.spread.Spread` over the
    replicas that returned it), ``wall_time_s`` of the whole call (the replicas in parallel)."""

    design: Design
    loads: Loads
    runs: list[dict]
    stats: dict[str, Spread]
    wall_time_s: float

    @property
    def compute_time_s(self) -> float:
        """The replicas' own wall times summed [s]."""
        return math.fsum((r.get("values") or {}).get("wall_time_s") or 0.0 for r in self.runs)

    def mean(self) -> dict:
        """Value name -> its mean over the replicas (None where none has it)."""
        return {k: sp.mean for k, sp in self.stats.items()}

    def to_json(self) -> dict:
        """Plain data: the runs, every value's spread, the wall and compute times."""
        return finite_or_none({
            "replicas": len(self.runs), "seed": self.design.replicas.seed, "jitter": self.design.replicas.jitter,
            "wall_time_s": self.wall_time_s, "compute_time_s": self.compute_time_s,
            "runs": [{k: r.get(k) for k in ("replica", "key", "status", "error")} for r in self.runs],
            "values": {k: sp.as_dict() for k, sp in self.stats.items()},
        })


def check_replica_folder(out: str | os.PathLike, loads: Loads) -> None:
    """AssessError (one line) when ``out`` holds replicas assessed under other loads: their cached
    points would be taken for these. Writes nothing."""
    path = Path(out) / LOADS_FILE
    if path.is_file():
        try:
            held = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            held = None
        if held != json.loads(loads.model_dump_json()):
            raise AssessError(f"--out: {out} holds replicas assessed under other loads ({LOADS_FILE}); "
                              "choose another output folder, or delete this one to start over")


def assess_replicas(design: Design, loads: Loads, out: str | os.PathLike, count: int, *, workers: int | None = None,
                    scheduler: str | None = None, on_point=None) -> ReplicaAssessment:
    """Assess replicas 0 .. ``count`` - 1 of ``design`` in parallel into ``out`` (a replica study's
    folder: ``points/<key>/`` holds each replica's report), and the spread of every value.

    Parameters
    ----------
    design : Design
        The design (its replicas' seed and jitter are ``design.replicas``'s).
    loads : Loads
        What each replica's assessment applies.
    out : str or os.PathLike
        The output folder.
    count : int
        Number of replicas, >= 1.
    workers, scheduler, on_point
        As for :func:`hydrojam.study.sweep.run_sweep`.

    Returns
    -------
    ReplicaAssessment
    """
    check_assessable(design)
    check_replica_folder(out, loads)
    t0 = time.perf_counter()
    study = replica_study(design, count).model_copy(update={"name": ASSESS_REPLICA_STUDY})

    def record_loads():
        write_text_atomic(Path(out) / LOADS_FILE, loads.model_dump_json(indent=1) + "\n")

    def on_each(outcome, done, total):
        # the loads are recorded with the first point (once run_sweep has checked its arguments
        # and made OUT), so that an interrupted folder is never resumed under other loads
        record_loads()
        if on_point is not None:
            on_point(outcome, done, total)

    run_sweep(study, out, workers=workers, scheduler=scheduler, on_point=on_each,
              point_fn=functools.partial(assess_point, loads=loads))
    record_loads()
    runs = []
    for p in study.points():
        try:
            record = json.loads((Path(out) / "points" / p.key / "point.json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            record = {}
        runs.append({"replica": p.replica, "key": p.key, "status": record.get("status"), "error": record.get("error"),
                     "values": record.get("metrics") or {}})
    names = []
    for r in runs:
        names += [k for k, x in r["values"].items() if isinstance(x, (int, float)) and not isinstance(x, bool)
                  and k not in names]
    stats = {k: spread([r["values"].get(k) for r in runs]) for k in names}
    return ReplicaAssessment(study.base, loads, runs, stats, time.perf_counter() - t0)


def write_replica_json(result: ReplicaAssessment, out: str | os.PathLike) -> Path:
    """``out``/assessment.json: :meth:`ReplicaAssessment.to_json`, written atomically."""
    path = Path(out) / "assessment.json"
    write_text_atomic(path, json.dumps(result.to_json(), indent=1, allow_nan=False) + "\n")
    return path
