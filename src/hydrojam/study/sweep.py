"""Run a study's points in parallel with dask.distributed, cached on disk and resumable.

Layout of an output folder ``OUT``::

    study.toml              the study, self-contained (the base design inline)
    points/<key>/           one folder per distinct design (key: hydrojam.study.design_key)
        point.json          the outcome, written last: the point is finished when it exists
        design.toml metrics.json history.csv centreline.csv final.png
                            as ``hydrojam run --no-vtu`` writes them
        final.vtu           the final state (points (x, 0, z) mm; cell data body_id: 0 membrane,
                            1 strain-limit layer, 2 + k particle k)
        error.txt           the traceback of a failed point
    results.csv             one row per (sweep, point), see :class:`SweepTable`
    results.parquet         the same, typed columns, nulls for undefined values
    replicas.csv            with replicas (a design's ``replicas.count`` > 1): one row per run

A point whose design asks for N replicas is N runs (:meth:`hydrojam.study.spec.Study.points`),
each its own design and folder; its row holds their mean and spread (:func:`build_table`).

A table written without running (:func:`run_sweep` ``run=False``) has the status
``unfinished`` for a point not finished yet, where it stands as its error.

``point.json``: ``{"key", "status": "ok" | "not_converged" | "failed", "error", "metrics",
"wall_time_s", "point_time_s", "hydrojam_version"}``; ``wall_time_s`` is the wall time the point
function reports in its metrics (hydrojam's: the load path, without meshing and writing), else
the point's whole time, ``point_time_s``, measured on the worker. A rerun into the same ``OUT`` loads the
points whose status is ok or not_converged and runs the others again (failed ones, and those a
kill left without point.json); a point's folder is cleared before it runs. The cache key is the
resolved design only: a change of hydrojam's code is not noticed (delete ``OUT/points``). An
``OUT`` whose study.toml names another study is refused: the two studies' points would mix.

With a ``scheduler`` address the points run on that dask cluster; its workers must see ``OUT`` at
the same path (a shared file system) and should run one thread each (``--nthreads 1``).
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import logging
import math
import os
import shutil
import threading
import time
import traceback
import types
import typing
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hydrojam._io import (FOLDER_LOCK, FolderKind, FolderKindError, LockHeld, atomic_path, check_folder_kind, finite_number,
                          finite_or_none, hold_lock, make_folder, read_json_dict, read_toml, write_text_atomic)
from hydrojam._validation import owner_model
from hydrojam.actuator.checkpoint import CHECKPOINT, ReleaseProgress, release_progress
from hydrojam.actuator.design import Design, DesignError
from hydrojam.actuator.metrics import STATE_METRICS, metric
from hydrojam.study.cache import FINISHED, PointStatus
from hydrojam.study.spec import Point, Study, StudyError, write_study
from hydrojam.study.spread import spread

#: seconds to wait for a dask scheduler given by address
CONNECT_TIMEOUT_S = 10.0

#: the run fields the table carries after the state metrics, in column order
TABLE_RUN_FIELDS = ("converged", "stabilisation_released", "s_reached", "load_steps", "newton_iterations")

#: metric columns of the table, with their types: every state metric, then TABLE_RUN_FIELDS
#: (:mod:`hydrojam.actuator.metrics`; the values from metrics.json / SimulationResult.metrics)
METRIC_COLUMNS: dict[str, type] = {m.name: m.type for m in (*STATE_METRICS, *map(metric, TABLE_RUN_FIELDS))}
_HEAD: dict[str, type] = {"sweep": str, "point": int, "key": str}
_TAIL: dict[str, type] = {"wall_time_s": metric("wall_time_s").type, "status": str, "error": str, "point_dir": str}
#: the metrics whose spread over a point's replicas the table carries (``<name>_std``, ``_min``, ``_max``)
SPREAD_METRICS: tuple[str, ...] = tuple(m.name for m in STATE_METRICS if m.type is float)
_SPREAD: dict[str, type] = {f"{name}_{stat}": float for name in SPREAD_METRICS for stat in ("std", "min", "max")}
#: columns of a table of replicated points, after the others: replicas run, replicas in the
#: statistics, and every replica's folder (";"-separated, relative to OUT)
_REPLICA_TAIL: dict[str, type] = {"replicas": int, "replicas_used": int, "replica_dirs": str}

__all__ = [
    "CONNECT_TIMEOUT_S",
    "METRIC_COLUMNS",
    "PointOutcome",
    "RunningPoint",
    "SPREAD_METRICS",
    "SchedulerError",
    "SweepTable",
    "TABLE_RUN_FIELDS",
    "build_table",
    "replica_table",
    "run_point",
    "point_progress",
    "running_point",
    "run_states",
    "run_sweep",
    "unfinished_text",
]


class SchedulerError(ConnectionError):
    """The dask scheduler given by address cannot be reached."""


# -------------------------------------------------------------------- one point


def run_point(design: Design, point_dir: Path) -> dict:
    """Simulate one design into ``point_dir`` (the files of ``hydrojam run --no-vtu`` plus
    ``final.vtu``), going on from the folder's checkpoint where it holds one of this design;
    returns the metrics written to metrics.json. Raises what the run raises."""
    from hydrojam.actuator.model import build_model
    from hydrojam.actuator.results import ResultWriter, write_vtu
    from hydrojam.actuator.simulate import simulate

    model = build_model(design)
    writer = ResultWriter(point_dir, model, vtu=False)
    ck = writer.start(resume=True)
    result = simulate(model, on_step=writer.step, checkpoint=writer.checkpoint_path, resume=ck)
    metrics = writer.finish(result)
    write_vtu(Path(point_dir) / "final.vtu", model, result.final)
    return metrics


def _single_line(text: str) -> str:
    """text on one line: each run of whitespace (newlines too) one space (a point's error record)."""
    return " ".join(str(text).split())


def _write_record(point_dir: Path, record: dict) -> None:
    write_text_atomic(point_dir / "point.json", json.dumps(record, indent=2, allow_nan=False) + "\n")


def _record(key: str, status: str, error: str | None, metrics: dict | None, wall: float | None,
            point_time: float | None) -> dict:
    from hydrojam._version import __version__

    return finite_or_none({"key": key, "status": status, "error": error, "metrics": metrics, "wall_time_s": wall,
                       "point_time_s": point_time, "hydrojam_version": __version__})


def _execute(point_fn: Callable[[Design, Path], dict], design: Design, point_dir: str, key: str) -> dict:
    """Worker side: clear the point's folder (but a run's checkpoint, which the run resumes), run
    ``point_fn``, write point.json last; never raises for the point's own failure (recorded as
    status "failed" with error.txt)."""
    folder = Path(point_dir)
    if (folder / CHECKPOINT).is_file():
        for name in ("point.json", "error.txt", "final.vtu"):
            (folder / name).unlink(missing_ok=True)
    elif folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    try:
        metrics = point_fn(design, folder)
        if not isinstance(metrics, dict):
            raise TypeError(f"the point function returned {type(metrics).__name__}, not a dict of metrics")
        metrics = finite_or_none(dict(metrics))
        json.dumps(metrics, allow_nan=False)
    except Exception as err:  # a failing point never stops the others
        elapsed = time.perf_counter() - t0
        write_text_atomic(folder / "error.txt", traceback.format_exc())
        record = _record(key, PointStatus.FAILED, _single_line(f"{type(err).__name__}: {err}"), None, elapsed, elapsed)
    else:
        elapsed = time.perf_counter() - t0
        converged = metrics.get("converged", True) is not False
        error = None if converged else _single_line(metrics.get("message") or "the solver stopped early")
        wall = metrics.get("wall_time_s")
        wall = wall if isinstance(wall, (int, float)) and not isinstance(wall, bool) else elapsed
        record = _record(key, PointStatus.OK if converged else PointStatus.NOT_CONVERGED, error, metrics, wall, elapsed)
    _write_record(folder, record)
    return record


def _read_record(point_dir: Path) -> dict | None:
    return read_json_dict(point_dir / "point.json")


# -------------------------------------------------------------------- the table


def _field_type(path: str) -> type:
    """The Python type (bool, int, float, str) of a dotted Design field."""
    owner = owner_model(Design, path)
    ann = owner[0].model_fields[owner[1]].annotation if owner else str
    if typing.get_origin(ann) in (typing.Union, types.UnionType):  # Optional[X]: X
        ann = next((a for a in typing.get_args(ann) if a is not type(None)), str)
    if typing.get_origin(ann) is typing.Literal:
        ann = type(typing.get_args(ann)[0])
    return ann if ann in (bool, int, float, str) else str


def _column_type(name: str) -> type:
    for group in (_HEAD, METRIC_COLUMNS, _TAIL, _SPREAD, _REPLICA_TAIL, {"replica": int}):
        if name in group:
            return group[name]
    return _field_type(name)


def _coerce(value: Any, kind: type) -> Any:
    if value is None:
        return None
    try:
        if kind is bool:
            return value if isinstance(value, bool) else None
        if isinstance(value, bool):
            return None if kind in (int, float) else str(value).lower()
        if kind is int:
            return int(value) if float(value) == int(value) else None
        if kind is float:
            return finite_or_none(float(value))
        return str(value)
    except (TypeError, ValueError, OverflowError):
        return None


def _csv_cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return str(value)


def _parse_cell(text: str, kind: type) -> Any:
    if text == "":
        return None
    if kind is bool:
        return {"true": True, "false": False}[text]
    return kind(text)


@dataclass(frozen=True)
class SweepTable:
    """A study's results: one row per (sweep, point), in study order.

    Columns: ``sweep``, ``point`` (index within the sweep), ``key`` (the cache folder), one column
    per dotted design field varied anywhere in the study (that row's design value, resolved), the
    :data:`METRIC_COLUMNS`, ``wall_time_s``, ``status`` (ok, not_converged, failed; unfinished in
    a table written without running), ``error`` and ``point_dir`` (relative to OUT). Undefined
    values are None (empty in CSV, null in Parquet), never NaN.
    """

    rows: list[dict]
    columns: list[str]

    def __len__(self) -> int:
        return len(self.rows)

    def select(self, sweep: str) -> SweepTable:
        """The rows of one sweep."""
        return SweepTable([r for r in self.rows if r["sweep"] == sweep], list(self.columns))

    def column(self, name: str) -> list:
        """One column's values, row by row."""
        if name not in self.columns:
            raise KeyError(f"{name}: no such column (columns: {', '.join(self.columns)})")
        return [r[name] for r in self.rows]

    def to_csv(self) -> str:
        """The table as CSV text (booleans true/false, undefined values empty)."""
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(self.columns)
        w.writerows([_csv_cell(r[c]) for c in self.columns] for r in self.rows)
        return buf.getvalue()

    def to_arrow(self):
        """The table as a ``pyarrow.Table``: float64, int64, bool and string columns, nullable."""
        import pyarrow as pa

        arrow = {bool: pa.bool_(), int: pa.int64(), float: pa.float64(), str: pa.string()}
        fields = [pa.field(c, arrow[_column_type(c)], nullable=True) for c in self.columns]
        return pa.table({c: pa.array([r[c] for r in self.rows], type=f.type) for c, f in zip(self.columns, fields)},
                        schema=pa.schema(fields))

    def write(self, out: str | os.PathLike) -> None:
        """Write ``OUT/results.csv`` and ``OUT/results.parquet``, each atomically."""
        import pyarrow.parquet as pq

        out = Path(out)
        write_text_atomic(out / "results.csv", self.to_csv())
        with atomic_path(out / "results.parquet") as tmp:
            pq.write_table(self.to_arrow(), tmp)

    @classmethod
    def read(cls, out: str | os.PathLike) -> SweepTable:
        """Load ``OUT/results.csv`` (or a CSV file's path) back, the column types restored."""
        path = Path(out)
        if path.is_dir():
            path = path / "results.csv"
        with path.open(newline="", encoding="utf-8") as f:
            reader = csv.reader(f)
            columns = next(reader)
            kinds = [_column_type(c) for c in columns]
            rows = [{c: _parse_cell(v, k) for c, k, v in zip(columns, kinds, line)} for line in reader]
        return cls(rows, columns)


def _walk(design: Design, path: str) -> Any:
    value: Any = design
    for name in path.split("."):
        value = getattr(value, name)
    return value


def build_table(study: Study, records: dict[str, dict]) -> SweepTable:
    """The table of a study from its runs' outcome records (point.json), keyed by design key:
    one row per (sweep, point).

    A point of one run gives that run's values. A point of several replicas gives statistics over
    the replicas that reached the target (status ok; if none did, over those that stopped early,
    and the row is not_converged; if none has metrics, failed): the metric columns hold the mean
    (integers rounded, flags true only if true for every replica), ``<metric>_std``, ``_min``
    and ``_max`` the spread of the :data:`SPREAD_METRICS`, ``wall_time_s`` the replicas' summed
    wall time, ``error`` each other replica's error, ``key`` and ``point_dir`` replica 0's; the
    spread columns and ``replicas``, ``replicas_used``, ``replica_dirs`` are there when any point
    of the study has more than one replica. A point with a replica not finished (status
    ``unfinished``: a table written without running, :func:`run_sweep` ``run=False``) is
    unfinished, its metrics those of the replicas finished so far.
    """
    varied = study.varied_fields()
    replicated = study.replicas > 1
    columns = [*_HEAD, *varied, *METRIC_COLUMNS, *(_SPREAD if replicated else ()), *_TAIL,
               *(_REPLICA_TAIL if replicated else ())]
    groups: dict[tuple[str, int], list[Point]] = {}
    for p in study.points():
        groups.setdefault((p.sweep, p.index), []).append(p)
    rows = []
    for points in groups.values():
        p = points[0]
        recs = [records.get(q.key) or {"status": PointStatus.FAILED, "error": "no outcome recorded"} for q in points]
        row = _point_row(p, varied)
        row.update(_aggregate(recs, [q.replica for q in points], replicated))
        row["point_dir"] = f"points/{p.key}"
        if replicated:
            row["replica_dirs"] = ";".join(f"points/{q.key}" for q in points)
        rows.append(row)
    return SweepTable(rows, columns)


def _point_row(p: Point, varied: list[str]) -> dict[str, Any]:
    """The head of a point's row: sweep, point, key and the varied fields' values (resolved)."""
    resolved = p.design.resolved()
    row: dict[str, Any] = {"sweep": p.sweep, "point": p.index, "key": p.key}
    for k in varied:  # the replicas table of a replica's design is its own (count 1): the point's is asked
        value = p.replicas if k == "replicas.count" else _walk(resolved, k)
        row[k] = _coerce(value, _field_type(k))
    return row


def _aggregate(recs: list[dict], replicas: list[int], replicated: bool) -> dict[str, Any]:
    """The metric and tail columns of a point from its replicas' records (see :func:`build_table`)."""
    statuses = [r.get("status") for r in recs]
    if len(recs) == 1:
        used = [0] if recs[0].get("metrics") else []
        status = statuses[0]
    else:
        used = [i for i, st in enumerate(statuses) if st == PointStatus.OK]
        used = used or [i for i, st in enumerate(statuses) if st == PointStatus.NOT_CONVERGED and recs[i].get("metrics")]
        # a replica not finished yet (a table written without running) leaves the point unfinished
        status = (PointStatus.UNFINISHED if PointStatus.UNFINISHED in statuses
                  else statuses[used[0]] if used else PointStatus.FAILED)
    out: dict[str, Any] = {}
    for k, kind in METRIC_COLUMNS.items():
        values = [(recs[i].get("metrics") or {}).get(k) for i in used]
        if kind is bool or len(values) == 1:
            flags = [_coerce(v, kind) for v in values]
            out[k] = None if not flags or None in flags else (all(flags) if kind is bool else flags[0])
            continue
        sp = spread([_coerce(v, kind) for v in values])
        out[k] = _coerce(None if sp.mean is None else (round(sp.mean) if kind is int else sp.mean), kind)
    if replicated:
        for name in SPREAD_METRICS:
            sp = spread([_coerce((recs[i].get("metrics") or {}).get(name), float) for i in used])
            out.update({f"{name}_std": sp.std, f"{name}_min": sp.min, f"{name}_max": sp.max})
        out.update(replicas=len(recs), replicas_used=len(used))
    walls = [_coerce(r.get("wall_time_s"), float) for r in recs]
    out["wall_time_s"] = None if all(w is None for w in walls) else math.fsum(w for w in walls if w is not None)
    out["status"] = _coerce(status, str)
    if len(recs) == 1:
        out["error"] = _coerce(recs[0].get("error"), str)
    else:
        errors = [f"replica {k}: {r.get('error') or r.get('status')}" for k, r in zip(replicas, recs)
                  if r.get("status") != PointStatus.OK]
        out["error"] = "; ".join(errors) or None
    return out


def replica_table(study: Study, records: dict[str, dict]) -> SweepTable:
    """One row per run (every replica of every point): the columns of a single-run table with
    ``replica`` after ``point``; what ``OUT/replicas.csv`` holds."""
    varied = study.varied_fields()
    columns = [*_HEAD, "replica", *varied, *METRIC_COLUMNS, *_TAIL]
    rows = []
    for p in study.points():
        rec = records.get(p.key) or {"status": PointStatus.FAILED, "error": "no outcome recorded"}
        row = _point_row(p, varied)
        row["replica"] = p.replica
        row = {c: row[c] for c in columns if c in row}
        row.update(_aggregate([rec], [p.replica], False))
        row["point_dir"] = f"points/{p.key}"
        rows.append(row)
    return SweepTable(rows, columns)


# -------------------------------------------------------------------- the sweep


@dataclass(frozen=True)
class PointOutcome:
    """The outcome of one distinct design: its record (point.json) and the study points sharing it.

    Parameters
    ----------
    record : dict
        The point's record (point.json): key, status, error, metrics, wall time [s].
    cached : bool
        Whether it was loaded from ``OUT`` rather than run.
    points : tuple of Point
        The study points sharing this design.
    point_dir : Path
        The point's folder.
    """

    record: dict
    cached: bool
    points: tuple[Point, ...]
    point_dir: Path

    @classmethod
    def from_record(cls, record: dict, points: list[Point], point_dir: Path, cached: bool) -> PointOutcome:
        return cls(record, cached, tuple(points), point_dir)

    @property
    def key(self) -> str:
        return self.record.get("key", self.points[0].key)

    @property
    def status(self) -> str:
        """The point's status (a :class:`~hydrojam.study.cache.PointStatus` value)."""
        return self.record.get("status", PointStatus.FAILED)

    @property
    def error(self) -> str | None:
        return self.record.get("error")

    @property
    def metrics(self) -> dict | None:
        return self.record.get("metrics")

    @property
    def wall_time_s(self) -> float | None:
        return self.record.get("wall_time_s")


@dataclass(frozen=True)
class RunningPoint:
    """A distinct design being computed: the study points sharing it, the load parameter ``s``
    [-] of its run's last accepted state, the run's wall time so far [s] (a run resumed from
    its checkpoint counts its earlier part), once at s = 1 how far its release has gone (None
    before, or where its checkpoint does not say) and the last accepted state's bending angle
    [deg] (at s = 1 the stabilised state's; None where history.csv has no such column)."""

    points: tuple[Point, ...]
    s: float
    wall_time_s: float
    release: ReleaseProgress | None = None
    bending_angle_deg: float | None = None


def running_point(points: tuple[Point, ...], point_dir: str | os.PathLike) -> RunningPoint | None:
    """The progress of the run in ``point_dir``: from its history.csv's last accepted state and,
    at s = 1, its checkpoint's release (the wall time then counts the release's rounds so far);
    None where it has no accepted state yet."""
    row = _last_state(point_dir)
    progress = _progress(row)
    if progress is None:
        return None
    s, wall = progress
    release = release_progress(Path(point_dir) / CHECKPOINT) if s >= 1.0 else None
    return RunningPoint(points, s, wall + (0.0 if release is None else release.seconds), release,
                        finite_number(row.get("bending_angle_deg")))


def _last_state(point_dir: str | os.PathLike) -> dict | None:
    """The last row of ``point_dir``/history.csv (the last accepted state), or None."""
    try:
        rows = list(csv.DictReader(io.StringIO((Path(point_dir) / "history.csv").read_text(encoding="utf-8"))))
    except (OSError, ValueError, csv.Error):
        return None
    return rows[-1] if rows else None


def _progress(row: dict | None) -> tuple[float, float] | None:
    try:
        return float(row["s"]), float(row["wall_time_s"])
    except (ValueError, KeyError, TypeError):
        return None


def point_progress(point_dir: str | os.PathLike) -> tuple[float, float] | None:
    """(s, wall time [s]) of the last accepted state in ``point_dir``/history.csv; None where
    there is none yet (or it cannot be read)."""
    return _progress(_last_state(point_dir))


#: seconds between two reports of the running points (``on_running`` of :func:`run_sweep`)
PROGRESS_INTERVAL_S = 15.0


def estimated_cost(design: Design) -> float:
    """A rough relative cost of simulating a design: particles / mesh.size^2."""
    return design.particle_layers * design.particles_per_layer / design.mesh.size**2


def _check_address(address: str) -> None:
    """SchedulerError at once for a malformed address (a Client made of one hangs 20 s when
    collected)."""
    from distributed.comm.addressing import get_address_host_port
    from distributed.comm.registry import backends

    scheme = address.split("://", 1)[0] if "://" in address else "tcp"
    try:
        if scheme not in backends:
            raise ValueError(f"unknown scheme {scheme!r} (known: {', '.join(sorted(backends))})")
        if scheme in ("tcp", "tls", "ws", "wss"):
            get_address_host_port(address)
    except ValueError as err:
        raise SchedulerError(
            f"{address}: not a scheduler address, e.g. tcp://10.0.0.5:8786 ({_single_line(err)})") from None


def _connect(address: str):
    from distributed import Client

    _check_address(address)
    try:
        return Client(address, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
    except (OSError, ValueError, TypeError) as err:
        raise SchedulerError(f"{address}: cannot connect within {CONNECT_TIMEOUT_S:g} s ({_single_line(err)})") from None


def _local_cluster(n_workers: int):
    import dask
    from distributed import Client, LocalCluster

    # one single-threaded process per core: hydrojam's PARDISO and IPC run one thread each
    # ":0": its HTTP server (which starts even without a dashboard) on a free port, not 8787
    # allowed-failures 0: a point that kills its worker (memory, a crash) is recorded as failed
    # at once, not retried 3 more times on fresh workers (a rerun of the sweep retries it)
    # MALLOC_TRIM_THRESHOLD_ unset: dask's 64 KiB makes glibc return every large numpy temporary
    # to the kernel, and the page faults of taking it back cost a simulation 40% more wall time
    # (docs/sweeps.md); the single-thread settings for BLAS and OpenMP stay
    environ = {k: v for k, v in dask.config.get("distributed.nanny.pre-spawn-environ").items()
               if k != "MALLOC_TRIM_THRESHOLD_"}
    with dask.config.set({"distributed.scheduler.allowed-failures": 0,
                          "distributed.nanny.pre-spawn-environ": environ}):
        cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True, dashboard_address=":0",
                               silence_logs=logging.ERROR, memory_limit=0)
    try:
        return cluster, Client(cluster, set_as_default=False)
    except BaseException:
        cluster.close()
        raise


def run_sweep(
    study: Study,
    out: str | os.PathLike,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    on_point: Callable[[PointOutcome, int, int], None] | None = None,
    point_fn: Callable[[Design, Path], dict] = run_point,
    on_running: Callable[[list[RunningPoint], int, int], None] | None = None,
    progress_interval_s: float | None = None,
    run: bool = True,
) -> SweepTable:
    """Run every distinct design of ``study`` into ``OUT/points/<key>/`` and write the table.

    Finished points (point.json ok or not_converged) are loaded, not run; the others run on a
    dask cluster, the most expensive points first. On KeyboardInterrupt the futures are
    cancelled, the cluster closed, and the interrupt re-raised: finished points are on disk. One
    run at a time writes ``OUT``: it holds the lock file ``OUT/.hydrojam.lock`` while it runs
    (:data:`hydrojam._io.FOLDER_LOCK`; a lock left by a killed process of this host is taken over).

    Parameters
    ----------
    study : Study
        The study to run.
    out : str or os.PathLike
        The output folder OUT.
    workers : int, optional
        Single-threaded processes of a local cluster, >= 1 (default: one per CPU, at most one per
        point to run).
    scheduler : str, optional
        Address of a dask scheduler to use instead of a local cluster.
    on_point : callable, optional
        ``on_point(outcome, done, total)``, called for every distinct design, the cached ones
        first, then each as it finishes.
    point_fn : callable, optional
        ``point_fn(design, point_dir) -> metrics``, what a point runs (default :func:`run_point`);
        its exceptions are recorded as failed points.
    on_running : callable, optional
        ``on_running(points, done, total)``, called every ``progress_interval_s`` while points run,
        from another thread, with the points started by this call that have an accepted state and
        no result yet (:class:`RunningPoint`; read from their history.csv, so only where the workers
        share OUT's file system).
    progress_interval_s : float, optional
        Seconds between ``on_running`` calls [s] (default :data:`PROGRESS_INTERVAL_S`).
    run : bool, optional
        False runs nothing: the table of the points finished so far, a point failed earlier as
        failed, every other one with status ``unfinished`` and where it stands as its error
        (:func:`unfinished_text`); ``OUT`` must already hold this study with as many replicas per
        point, and only the table is written.

    Returns
    -------
    SweepTable
        One row per (sweep, point), also written to ``OUT/results.csv`` and
        ``OUT/results.parquet``.

    Raises
    ------
    StudyError
        For a point the simulator does not support, an ``OUT`` that holds another study
        (``OUT/study.toml`` with another name; the same name resumes) or that another run is
        writing (its lock file), or (``run=False``) an ``OUT`` without this study.
    ValueError
        For ``workers`` < 1.
    SchedulerError
        When the scheduler cannot be reached.

    Notes
    -----
    None of the errors above writes anything.
    """
    from hydrojam.actuator.model import check_supported

    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise ValueError(f"workers: must be an integer >= 1 (got {workers!r})")
    for p in study.points():
        try:
            check_supported(p.design)
        except DesignError as err:
            raise StudyError(f"sweep '{p.sweep}' point {p.index}: {err}") from None
    out = Path(out).absolute()
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(f"{out}: exists and is not a folder")
    _check_kind(out)
    _check_same_study(out, study)
    if not run:
        _check_held_study(out, study)
    groups: dict[str, list[Point]] = {}
    for p in study.points():
        groups.setdefault(p.key, []).append(p)
    records = _finished_records(out, groups, failed=not run)
    pending = [key for key in groups if key not in records]
    if not run:
        for key in pending:
            folder = out / "points" / key
            records[key] = {"status": PointStatus.UNFINISHED, "error": unfinished_text(
                running_point(tuple(groups[key]), folder), (folder / CHECKPOINT).is_file())}
        return _write_table(study, out, records)

    client = cluster = None
    lock = contextlib.ExitStack()
    try:
        if scheduler is not None:  # connected only when there is something to run
            client = _connect(scheduler) if pending else _check_address(scheduler)
        try:
            lock.enter_context(hold_lock(make_folder(out) / FOLDER_LOCK))
        except LockHeld as err:
            raise StudyError(str(err)) from None
        _check_kind(out)  # again, under the lock
        records = _finished_records(out, groups)  # again: a run that held the lock may have finished some
        pending = [key for key in groups if key not in records]
        write_study(out / "study.toml", study)
        total, done = len(groups), 0
        for key in groups:
            if key in records:
                done += 1
                if on_point is not None:
                    outcome = PointOutcome.from_record(records[key], groups[key], out / "points" / key, True)
                    on_point(outcome, done, total)
        if pending:
            if client is None:
                cluster, client = _local_cluster(min(workers or os.cpu_count() or 1, len(pending)))
            interval = PROGRESS_INTERVAL_S if progress_interval_s is None else progress_interval_s
            done = _compute(client, groups, pending, out, point_fn, records, on_point, done, total, on_running,
                            interval)
        return _write_table(study, out, records)
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
        lock.close()


def _finished_records(out: Path, groups: dict[str, list[Point]], failed: bool = False) -> dict[str, dict]:
    """The outcome records (point.json) of the points of ``groups`` finished in ``out`` (ok or
    not converged; with ``failed``, failed ones too), by key."""
    records = {}
    for key in groups:
        rec = _read_record(out / "points" / key)
        if rec is not None and (rec.get("status") in FINISHED or (failed and rec.get("status") == PointStatus.FAILED)):
            records[key] = rec
    return records


def _write_table(study: Study, out: Path, records: dict[str, dict]) -> SweepTable:
    """The study's table from ``records``, written to OUT/results.csv and .parquet (and
    replicas.csv with replicas)."""
    table = build_table(study, records)
    table.write(out)
    if study.replicas > 1:
        write_text_atomic(out / "replicas.csv", replica_table(study, records).to_csv())
    return table


def _check_held_study(out: Path, study: Study) -> None:
    """A table without running needs ``OUT`` to hold ``study`` already (its study.toml, the same
    name: :func:`_check_same_study`) with the same replicas per point: with fewer, the table
    would show replica 0 alone as the point, without its spread. StudyError otherwise."""
    from hydrojam.study.spec import load_study

    if not (out / "study.toml").is_file():
        raise StudyError(f"{out}: holds no study yet (no study.toml): nothing finished to write a table from")
    held = load_study(out / "study.toml").replicas
    if held != study.replicas:
        raise StudyError(f"replicas: {out} holds its study with {held} per point (got {study.replicas}); "
                         f"a table of it without running needs the same (--replicas {held})")


def run_states(out: str | os.PathLike, table: SweepTable) -> dict[str, str]:
    """The state of every run of ``table`` (each replica's folder, relative to ``out``): its
    point.json's status (ok, not_converged, failed), else unfinished. How many distinct designs
    a table written without running holds in each state, as a run counts them."""
    states = {}
    for row in table.rows:
        dirs = str(row.get("replica_dirs") or row.get("point_dir") or "").split(";")
        for d in filter(None, dirs):
            if d not in states:
                rec = _read_record(Path(out) / d)
                status = None if rec is None else rec.get("status")
                states[d] = status if status in (*FINISHED, PointStatus.FAILED) else PointStatus.UNFINISHED
    return states


def unfinished_text(running: RunningPoint | None, started: bool = False) -> str:
    """Where an unfinished run stands, in a few words, from its :func:`running_point` (None: no
    accepted state read; ``started``: its checkpoint exists): "not started", "not finished: s =
    0.789 reached (47.0 deg)" or, at s = 1, "not finished: releasing the stabilisation
    (stabilised at 92.4 deg), 21 rounds, ...".
    """
    if running is None:
        return "not finished: no accepted state read yet" if started else "not started"
    angle = "" if running.bending_angle_deg is None else f"{running.bending_angle_deg:.1f} deg"
    if running.s < 1.0:
        return f"not finished: s = {running.s:.3f} reached" + (f" ({angle})" if angle else "")
    text = "not finished: releasing the stabilisation" + (f" (stabilised at {angle})" if angle else "")
    return text + ("" if running.release is None else f", {running.release.summary()}")


def _check_kind(out: Path) -> None:
    """StudyError when ``OUT`` holds another kind of output than a study's (a single run's, an
    assessment's, one point of a study): the study's files would mix with it."""
    try:
        check_folder_kind(out, FolderKind.STUDY)
    except FolderKindError as err:
        raise StudyError(str(err)) from None


def _check_same_study(out: Path, study: Study) -> None:
    """StudyError when ``OUT/study.toml`` is another study's (another name): its points would mix
    with this study's in ``OUT/points``. The same name is the same study, resumed or extended."""
    path = out / "study.toml"
    if not path.exists():
        return
    other = read_toml(path, "study", StudyError).get("name", "study")
    if other != study.name:
        raise StudyError(
            f"{out}: holds the points of another study, {other!r} (its study.toml), not {study.name!r}; "
            "choose another output folder, or delete this one to start over")


def _watch_running(groups, order, out, records, on_running, interval_s, since) -> threading.Event:
    """Start a thread that calls ``on_running`` every ``interval_s`` with the points of ``order``
    without a record whose history.csv was written at or after ``since`` (a time.time()); set the
    returned event to stop it."""
    stop = threading.Event()

    def watch():
        while not stop.wait(interval_s):
            running = []
            for key in order:
                folder = out / "points" / key
                if key in records:
                    continue
                try:
                    if (folder / "history.csv").stat().st_mtime < since:
                        continue
                except OSError:
                    continue
                point = running_point(tuple(groups[key]), folder)
                if point is not None:
                    running.append(point)
            if not stop.is_set():
                on_running(running, len(records), len(groups))

    threading.Thread(target=watch, name="hydrojam-sweep-progress", daemon=True).start()
    return stop


def _compute(client, groups, pending, out, point_fn, records, on_point, done, total, on_running=None,
             progress_interval_s=PROGRESS_INTERVAL_S) -> int:
    from distributed import as_completed

    order = sorted(pending, key=lambda k: -estimated_cost(groups[k][0].design))  # stable: study order on ties
    token = uuid.uuid4().hex[:8]
    # a second's slack: file systems that keep mtimes in whole seconds
    watcher = None if on_running is None else _watch_running(groups, order, out, records, on_running,
                                                             progress_interval_s, time.time() - 1.0)
    futures = {}
    for rank, key in enumerate(order):
        fut = client.submit(_execute, point_fn, groups[key][0].design, str(out / "points" / key), key,
                            key=f"hydrojam-point-{key}-{token}", priority=len(order) - rank, pure=False)
        futures[fut] = key
    try:
        for fut in as_completed(list(futures), loop=client.loop):
            key = futures[fut]
            folder = out / "points" / key
            if fut.status == "finished":
                rec = fut.result()
                if not (folder / "point.json").exists():  # a worker without our file system
                    _write_record(folder, rec)
            else:  # the worker died or the task was lost: record it as a failed point
                exc = fut.exception() if fut.status == "error" else None
                error = _single_line(f"{type(exc).__name__}: {exc}") if exc is not None else f"task {fut.status}"
                rec = _record(key, PointStatus.FAILED, error, None, None, None)
                folder.mkdir(parents=True, exist_ok=True)
                _write_record(folder, rec)
            records[key] = json.loads(json.dumps(rec, allow_nan=False))  # as it reads back from point.json
            done += 1
            if on_point is not None:
                on_point(PointOutcome.from_record(records[key], groups[key], folder, False), done, total)
    except BaseException:
        client.cancel(list(futures))
        raise
    finally:
        if watcher is not None:
            watcher.set()
    return done
