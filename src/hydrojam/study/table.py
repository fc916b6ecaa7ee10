"""A study's table: one row per (sweep, point) from the points' records (:class:`SweepTable`,
:func:`build_table`), written as ``OUT/results.csv`` (see :class:`SweepTable`) and
``OUT/results.parquet`` (the same, typed columns, nulls for undefined values), and with replicas
``OUT/replicas.csv`` (one row per run, :func:`replica_table`).

A point whose design asks for N replicas is N runs (:meth:`hydrojam.study.spec.Study.points`),
each its own design and folder; its row holds their mean and spread (:func:`build_table`). A
table written without running (:func:`hydrojam.study.sweep.run_sweep` ``run=False``) has the
status ``unfinished`` for a point not finished yet, where it stands as its error.
"""

from __future__ import annotations

import csv
import io
import math
import os
import types
import typing
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hydrojam._io import atomic_path, finite_or_none, write_text_atomic
from hydrojam._validation import owner_model
from hydrojam.actuator.design import Design
from hydrojam.actuator.metrics import STATE_METRICS, metric
from hydrojam.study.cache import FINISHED, PointStatus, read_record
from hydrojam.study.spec import Point, Study
from hydrojam.study.spread import spread
from hydrojam.study.states import state_counts, state_of, states_text

#: the run fields the table carries after the state metrics, in column order
TABLE_RUN_FIELDS = ("converged", "stabilisation_released", "s_reached", "load_steps", "newton_iterations")

#: metric columns of the table, with their types: every state metric, then TABLE_RUN_FIELDS
#: (:mod:`hydrojam.actuator.metrics`; the values from metrics.json / SimulationResult.metrics)
METRIC_COLUMNS: dict[str, type] = {m.name: m.type for m in (*STATE_METRICS, *map(metric, TABLE_RUN_FIELDS))}
_HEAD: dict[str, type] = {"sweep": str, "point": int, "key": str}
_TAIL: dict[str, type] = {"states": str, "wall_time_s": metric("wall_time_s").type, "status": str, "error": str,
                          "point_dir": str}
#: the metrics whose spread over a point's replicas the table carries (``<name>_std``, ``_min``, ``_max``)
SPREAD_METRICS: tuple[str, ...] = tuple(m.name for m in STATE_METRICS if m.type is float)
_SPREAD: dict[str, type] = {f"{name}_{stat}": float for name in SPREAD_METRICS for stat in ("std", "min", "max")}
#: columns of a table of replicated points, after the others: replicas run, replicas in the
#: statistics, and every replica's folder (";"-separated, relative to OUT)
_REPLICA_TAIL: dict[str, type] = {"replicas": int, "replicas_used": int, "replica_dirs": str}

__all__ = [
    "METRIC_COLUMNS",
    "NOT_IN_STATE",
    "SPREAD_METRICS",
    "SweepTable",
    "TABLE_RUN_FIELDS",
    "build_table",
    "replica_table",
    "run_states",
    "state_tables",
    "write_table",
]


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


#: the error of a state table's row for a point none of whose replicas reached that state
NOT_IN_STATE = "no replica in state"


def build_table(study: Study, records: dict[str, dict], state: str | None = None) -> SweepTable:
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
    ``unfinished``: a table written without running, :func:`~hydrojam.study.sweep.run_sweep` ``run=False``) is
    unfinished, its metrics those of the replicas finished so far. ``states`` names the state of
    every finished run (:mod:`hydrojam.study.states`): one state, or each with its runs.

    With ``state`` ("arc", "folded", "multi-folded"), the table of that state alone: each point's statistics over
    its replicas in that state, and a point with none failed ("no replica in state ..."); a point with
    replicas not finished stays unfinished (they may still end in the state).
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
        counts = state_counts([state_of(r.get("metrics")) for r in recs if r.get("status") in FINISHED])
        if state is not None:  # a replica not finished yet may still end in the state: it stays
            kept = [(q, r) for q, r in zip(points, recs)
                    if state_of(r.get("metrics")) == state or r.get("status") == PointStatus.UNFINISHED]
            recs = [r for _, r in kept] or [{"status": PointStatus.FAILED, "error": f"{NOT_IN_STATE} {state}"}]
            points = [q for q, _ in kept] or points[:1]
        row = _point_row(p, varied)
        row.update(_aggregate(recs, [q.replica for q in points], replicated))
        row["states"] = states_text(counts)
        row["point_dir"] = f"points/{points[0].key}"  # with ``state``: its first replica in that state
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
        row["states"] = state_of(rec.get("metrics")) if rec.get("status") in FINISHED else None
        row["point_dir"] = f"points/{p.key}"
        rows.append(row)
    return SweepTable(rows, columns)


def write_table(study: Study, out: Path, records: dict[str, dict]) -> SweepTable:
    """The study's table from its points' ``records`` (point.json, by design key): written to
    ``out``/results.csv and results.parquet (and replicas.csv with replicas), and returned.

    Parameters
    ----------
    study : Study
        The study.
    out : Path
        The output folder OUT.
    records : dict
        Design key -> the point's record (:func:`~hydrojam.study.cache.point_record`).

    Returns
    -------
    SweepTable
    """
    table = build_table(study, records)
    table.write(out)
    if study.replicas > 1:
        write_text_atomic(out / "replicas.csv", replica_table(study, records).to_csv())
    return table


def run_states(out: str | os.PathLike, table: SweepTable) -> dict[str, str]:
    """The state of every run of ``table`` (each replica's folder, relative to ``out``): its
    point.json's status (ok, not_converged, failed), else unfinished. How many distinct designs
    a table written without running holds in each state, as a run counts them."""
    states = {}
    for row in table.rows:
        dirs = str(row.get("replica_dirs") or row.get("point_dir") or "").split(";")
        for d in filter(None, dirs):
            if d not in states:
                rec = read_record(Path(out) / d)
                status = None if rec is None else rec.get("status")
                states[d] = status if status in (*FINISHED, PointStatus.FAILED) else PointStatus.UNFINISHED
    return states


def state_tables(study: Study, out: str | os.PathLike) -> dict[str, SweepTable]:
    """One table per state that any finished run of ``study`` in ``out`` reached
    (:func:`build_table` with ``state``), read from the points' records; empty where no run has a
    state (records without ``column_folds``). A point with runs not finished (or not started) stays
    unfinished in every state's table. Nothing is written.

    Parameters
    ----------
    study : Study
        The study.
    out : str or os.PathLike
        Its output folder OUT.

    Returns
    -------
    dict of str to SweepTable
        State -> its table, in the order of :data:`hydrojam.study.states.STATES`.
    """
    records = {}
    for p in study.points():
        rec = read_record(Path(out) / "points" / p.key)
        if rec is not None and rec.get("status") in FINISHED:
            records[p.key] = rec
        elif rec is None or rec.get("status") != PointStatus.FAILED:  # it may still end in any state
            records[p.key] = {"status": PointStatus.UNFINISHED, "error": "not finished"}
    seen = state_counts([state_of(r.get("metrics")) for r in records.values()])  # unfinished: no state
    return {state: build_table(study, records, state) for state in seen}
