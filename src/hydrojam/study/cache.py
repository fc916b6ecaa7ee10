"""A study's points on disk, the cache of a sweep: what became of each point
(:class:`PointStatus`), its record, and where an unfinished one stands.

Each distinct design has its folder ``OUT/points/<key>/`` (key: :func:`hydrojam.study.design_key`)::

    point.json          the outcome, written last: the point is finished when it exists
    design.toml metrics.json history.csv centreline.csv final.png
                        as ``hydrojam run --no-vtu`` writes them
    final.vtu           the final state (points (x, 0, z) mm; cell data body_id: 0 membrane,
                        1 strain-limit layer, 2 + k particle k)
    error.txt           the traceback of a failed point

``point.json``: ``{"key", "status": "ok" | "not_converged" | "failed", "error", "metrics",
"wall_time_s", "point_time_s", "hydrojam_version", "files"}`` (:func:`point_record`); ``files``
maps each result file of a finished point to its SHA-256 (:func:`result_checksums`), so that a
rerun finds a damaged or missing one (:func:`damaged_files`) and computes the point again
(records written without it, by earlier versions, are loaded as they are); ``wall_time_s`` is
the wall time the point function reports in its metrics (hydrojam's: the load path, without
meshing and writing), else the point's whole time, ``point_time_s``, measured on the worker. A
rerun into the same ``OUT`` loads the points whose status is ok or not_converged
(:func:`finished_records`) and runs the others again (failed ones, and those a kill left without
point.json). The cache key is the resolved design only: a change of hydrojam's code is not
noticed (delete ``OUT/points``). A point not finished stands where its history.csv's last
accepted state and its checkpoint leave it (:func:`running_point`).
"""

from __future__ import annotations

import csv
import enum
import hashlib
import io
import json
import os
from dataclasses import dataclass
from pathlib import Path

from hydrojam._io import finite_number, finite_or_none, read_json_dict, write_text_atomic
from hydrojam.actuator.checkpoint import CHECKPOINT, ReleaseProgress, release_progress
from hydrojam.study.spec import Point

__all__ = [
    "FINISHED",
    "PointStatus",
    "ROW_STATUSES",
    "RunningPoint",
    "damaged_files",
    "finished_records",
    "point_progress",
    "point_record",
    "read_record",
    "result_checksums",
    "running_point",
    "single_line",
    "unfinished_text",
    "write_record",
]


class PointStatus(enum.StrEnum):
    """What became of a point: one run of one design. Each member is the text the files hold
    (point.json's ``status``, the table's ``status`` column), and equal to it as a string.

    Attributes
    ----------
    OK : str
        "ok": the run reached the target stimulus.
    NOT_CONVERGED : str
        "not_converged": the run stopped early; its metrics are its last converged state's.
    FAILED : str
        "failed": the run raised (or its worker died); no metrics.
    UNFINISHED : str
        "unfinished": not finished yet, started or not (a table written without running, and
        ``hydrojam status`` for a run with a checkpoint or an accepted state).
    NOT_STARTED : str
        "not started": nothing written yet (``hydrojam status`` only).
    """

    OK = "ok"
    NOT_CONVERGED = "not_converged"
    FAILED = "failed"
    UNFINISHED = "unfinished"
    NOT_STARTED = "not started"


#: the statuses of a finished point: its point.json is loaded, not run again
FINISHED = frozenset({PointStatus.OK, PointStatus.NOT_CONVERGED})

#: the statuses a results table's row may hold, in the order the summaries count them
#: (NOT_STARTED is ``hydrojam status``'s alone)
ROW_STATUSES = (PointStatus.OK, PointStatus.NOT_CONVERGED, PointStatus.FAILED, PointStatus.UNFINISHED)


# -------------------------------------------------------------------- a point's record


def single_line(text: str) -> str:
    """``text`` on one line: each run of whitespace (newlines too) one space (a point's error
    record, a refusal's message).

    Parameters
    ----------
    text : str
        Any text (or an object, taken as ``str(text)``).

    Returns
    -------
    str
    """
    return " ".join(str(text).split())


def point_record(key: str, status: PointStatus, error: str | None, metrics: dict | None, wall: float | None,
                 point_time: float | None, files: dict[str, str] | None = None) -> dict:
    """A point's record, as point.json holds it (non-finite values None, this hydrojam's version).

    Parameters
    ----------
    key : str
        The design key.
    status : PointStatus
        What became of the point.
    error : str or None
        Why it failed or stopped early (one line), else None.
    metrics : dict or None
        The point function's metrics (None for a failed point).
    wall : float or None
        Wall time [s]: the metrics' ``wall_time_s``, else the point's whole time.
    point_time : float or None
        The point's whole time on the worker [s].
    files : dict, optional
        A finished point's result files and their checksums (:func:`result_checksums`); left out
        of the record where None.

    Returns
    -------
    dict
    """
    from hydrojam._version import __version__

    record = finite_or_none({"key": key, "status": status, "error": error, "metrics": metrics, "wall_time_s": wall,
                             "point_time_s": point_time, "hydrojam_version": __version__})
    if files is not None:
        record["files"] = dict(files)
    return record


#: files of a point's folder that are not its results: its record, a failure's traceback, a run's
#: checkpoint (removed when the run ends)
_NOT_RESULTS = frozenset({"point.json", "error.txt", CHECKPOINT})


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return "sha256:" + digest.hexdigest()


def result_checksums(point_dir: str | os.PathLike) -> dict[str, str]:
    """The result files of a finished point in ``point_dir`` (every regular file but its record,
    error.txt, a checkpoint and hidden files), each with its SHA-256 ("sha256:<hex>"), by name.

    Parameters
    ----------
    point_dir : str or os.PathLike
        The point's folder.

    Returns
    -------
    dict
    """
    folder = Path(point_dir)
    return {f.name: _sha256(f) for f in sorted(folder.iterdir())
            if f.is_file() and not f.is_symlink() and f.name not in _NOT_RESULTS and not f.name.startswith(".")}


def damaged_files(point_dir: str | os.PathLike, record: dict) -> list[str]:
    """The result files that ``record`` (a point.json) lists and that are missing from
    ``point_dir``, cannot be read or no longer match their checksum: a damaged point, to compute
    again. Empty for a record without checksums (written by an earlier version: nothing to
    check against).

    Parameters
    ----------
    point_dir : str or os.PathLike
        The point's folder.
    record : dict
        Its record.

    Returns
    -------
    list of str
        The damaged files' names.
    """
    files = record.get("files")
    if not isinstance(files, dict):
        return []
    damaged = []
    for name, checksum in files.items():
        try:
            ok = _sha256(Path(point_dir) / name) == checksum
        except OSError:
            ok = False
        if not ok:
            damaged.append(name)
    return damaged


def write_record(point_dir: Path, record: dict) -> None:
    """Write ``record`` as ``point_dir``/point.json, atomically: the point is then finished."""
    write_text_atomic(point_dir / "point.json", json.dumps(record, indent=2, allow_nan=False) + "\n")


def read_record(point_dir: Path) -> dict | None:
    """The record in ``point_dir``/point.json, or None where there is none (or it is unreadable)."""
    return read_json_dict(point_dir / "point.json")


def finished_records(out: Path, groups: dict[str, list[Point]], failed: bool = False,
                     damaged: dict[str, list[str]] | None = None) -> dict[str, dict]:
    """The outcome records (point.json) of the points of ``groups`` finished in ``out`` (ok or
    not converged; with ``failed``, failed ones too), by key. With a dict ``damaged``, each
    finished point's result files are checked against their checksums (:func:`damaged_files`):
    a damaged point is left out, to be computed again, and its damaged files put in
    ``damaged[key]``."""
    records = {}
    for key in groups:
        rec = read_record(out / "points" / key)
        if rec is not None and (rec.get("status") in FINISHED or (failed and rec.get("status") == PointStatus.FAILED)):
            bad = damaged_files(out / "points" / key, rec) if damaged is not None else []
            if bad:
                damaged[key] = bad
                continue
            records[key] = rec
    return records


# -------------------------------------------------------------------- a point under way


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
