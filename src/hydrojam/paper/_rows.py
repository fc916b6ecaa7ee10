"""Reading the rows of a sweep table (:class:`hydrojam.study.table.SweepTable` or plain dicts):
numbers that may be missing, a point's status, one sweep's rows, a parameter value as text, the
runs a row stands for."""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from pathlib import Path

from hydrojam._io import finite_number
from hydrojam.study.cache import ROW_STATUSES, PointStatus
from hydrojam.study.states import state_of
from hydrojam.study.table import SweepTable


def number(v) -> float | None:
    """A finite float or None (None, "", NaN, inf, an unreadable string -> None)."""
    return finite_number(v)


def truthy(v) -> bool | None:
    """A table cell read as a flag: None for a missing cell, "true"/"1"/"yes" for a string."""
    if v is None or v == "":
        return None
    if isinstance(v, str):
        return v.strip().lower() in ("true", "1", "yes")
    return bool(v)


def point_status(row: dict) -> PointStatus:
    """OK, NOT_CONVERGED, FAILED or UNFINISHED (not run yet, or still running: a table written
    without running, ``run_sweep(run=False)``); a row without status: from ``converged``."""
    status = row.get("status")
    if status in ROW_STATUSES:
        if status == PointStatus.OK and truthy(row.get("converged")) is False:
            return PointStatus.NOT_CONVERGED
        return PointStatus(status)
    conv = truthy(row.get("converged"))
    return PointStatus.OK if conv else (PointStatus.NOT_CONVERGED if conv is False else PointStatus.FAILED)


def partial_runs(row: dict) -> str | None:
    """"k of n runs" for a point of a study in progress with some of its n replicas finished (its
    values are those k runs'), else None."""
    used, planned = number(row.get("replicas_used")), number(row.get("replicas"))
    if (point_status(row) == PointStatus.UNFINISHED and used and planned
            and number(row.get("bending_angle_deg")) is not None):
        return f"{used:g} of {planned:g} runs"
    return None


def without_result(row: dict) -> bool:
    """True for a point with nothing to draw or compare: failed, or not finished yet (a point with
    some of its replicas finished has their result)."""
    status = point_status(row)
    return status == PointStatus.FAILED or (status == PointStatus.UNFINISHED and partial_runs(row) is None)


def rows_of(table: SweepTable | Sequence[dict], sweep: str) -> list[dict]:
    """The rows of one sweep from a SweepTable (its ``rows``), or from a plain list of rows."""
    rows = table if isinstance(table, Sequence) else table.rows
    return [r for r in rows if r.get("sweep") == sweep]


def sorted_by(rows: Sequence[dict], field: str) -> list[dict]:
    """``rows`` sorted by the number in column ``field``; rows without one last."""
    return sorted(rows, key=lambda r: (number(r.get(field)) is None, number(r.get(field)) or 0.0))


def fmt_param(value: float | None, unit: str = "") -> str:
    """A parameter value with its unit ("285 K", "8 mm"; layers without unit; None: "?")."""
    if value is None:
        return "?"
    text = f"{value:g}"
    return f"{text} {unit}" if unit and unit != "layers" else text


def cell(v, fmt: str = "{:.1f}") -> str:
    """A table cell: the number formatted, or "—" where there is none."""
    f = number(v)
    return "—" if f is None else fmt.format(f)


def cell_pm(r: dict, key: str, fmt: str = "{:.1f}") -> str:
    """A cell with the replicas' spread: "74.2 ± 3.1" (or the plain value of a single run)."""
    sd = number(r.get(f"{key}_std"))
    return cell(r.get(key), fmt) + ("" if sd is None else " ± " + fmt.format(sd))


def runs_of(row: dict) -> int:
    """How many runs (replicas) a row's metrics are the mean of: its replicas used where the row
    says (a point with some replicas failed or not finished), else its replicas (1 for a row of
    one run)."""
    used = number(row.get("replicas_used"))
    if used is not None and used >= 1:
        return int(used)
    return max(1, len([d for d in str(row.get("replica_dirs") or "").split(";") if d]))


def drawn_angle(out: str | os.PathLike, row: dict) -> float | None:
    """The bending angle [deg] of the run a row's pictures show (its ``point_dir``, replica 0 of
    a replicated point), from its metrics.json; None where it cannot be read."""
    try:
        metrics = json.loads((Path(out) / str(row.get("point_dir")) / "metrics.json").read_text(encoding="utf-8"))
        return number(metrics.get("bending_angle_deg"))
    except (OSError, ValueError, AttributeError):
        return None


def drawn_row(out: str | os.PathLike, row: dict) -> dict:
    """The row as its pictures draw it: for a point of several runs, ``point_dir`` set to its
    first run in the state most of its runs reached (replica 0's where they tie, or where no
    run's state can be read), so a shapes panel shows the common state, not a rarer one that
    replica 0 happened to reach. Other rows are returned as they are."""
    dirs = [d for d in str(row.get("replica_dirs") or "").split(";") if d]
    if len(dirs) < 2:
        return row
    states = []
    for d in dirs:
        try:
            metrics = json.loads((Path(out) / d / "metrics.json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            metrics = None
        states.append(state_of(metrics if isinstance(metrics, dict) else None))
    counts = {s: states.count(s) for s in states if s is not None}
    if not counts:
        return row
    most = max(counts.values())
    common = states[0] if counts.get(states[0]) == most else next(s for s in states if counts.get(s) == most)
    return dict(row, point_dir=dirs[states.index(common)])
