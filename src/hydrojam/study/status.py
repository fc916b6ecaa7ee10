"""Where an output folder stands, read from its files without running anything (`hydrojam
status OUT`): for a study (a sweep, `reproduce`, `run --replicas`: ``OUT/study.toml``) each
distinct design finished, stopped or unfinished (where its checkpoint left it: s, the release's
rounds) or not started; for one run (`hydrojam run`) the same for the run. A long 3D study goes
on over several working sessions; this says what is left before it is started again.

Read only: a run going on in another process is seen as unfinished, at its last written state.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from pathlib import Path

from hydrojam._io import FOLDER_LOCK, FolderKind, LockState, finite_number, lock_state, read_json_dict
from hydrojam.actuator.checkpoint import CHECKPOINT, ReleaseProgress
from hydrojam.study.cache import FINISHED, PointStatus, running_point
from hydrojam.study.spec import Point, StudyError, load_study

__all__ = ["FolderStatus", "RunStatus", "StatusError", "current_state", "folder_status", "release_metrics"]

#: the states of a run, in the order a summary counts them
STATES = tuple(PointStatus)


class StatusError(ValueError):
    """The folder is neither a study's nor a run's output folder (or its study.toml is unreadable)."""


@dataclass(frozen=True)
class RunStatus:
    """One distinct design of a study, or the run of a run folder.

    Parameters
    ----------
    key : str
        The design key (empty for a run folder).
    points : tuple of Point
        The study points sharing it; empty for a single run, and for a point folder of the study's
        output folder that its study.toml does not name (one of sweeps run earlier into the same
        folder).
    state : PointStatus
        ``ok`` / ``not_converged`` (finished: point.json or metrics.json), ``failed`` (point.json;
        a stopped run keeps its checkpoint and goes on from it), ``unfinished`` (a checkpoint or
        history.csv and no outcome: stopped, or running in another process) or ``not started``.
    s : float, optional
        Load parameter [-]: the outcome's where finished, else the last accepted state's.
    bending_angle_deg : float, optional
        Bending angle [deg], likewise (at s = 1 the stabilised state's).
    wall_time_s : float, optional
        Wall time [s], likewise (at s = 1 counting the release's rounds so far).
    release : ReleaseProgress, optional
        How far the release at s = 1 has gone (unfinished runs only).
    updated : float, optional
        When its folder was last written [s since the epoch].
    error : str, optional
        A failed run's reason.
    release_metrics : dict, optional
        The state metrics of the release's current centre (with ``measure``,
        :func:`folder_status`), else None.
    """

    key: str
    points: tuple[Point, ...]
    state: PointStatus
    s: float | None = None
    bending_angle_deg: float | None = None
    wall_time_s: float | None = None
    release: ReleaseProgress | None = None
    updated: float | None = None
    error: str | None = None
    release_metrics: dict | None = None


@dataclass(frozen=True)
class FolderStatus:
    """Where an output folder stands: its kind, name, runs and lock.

    Parameters
    ----------
    kind : FolderKind
        STUDY (a study's output folder) or RUN (a single run's).
    name : str
        The study's name, or the run folder's.
    runs : tuple of RunStatus
        In the study's order.
    lock : dict, optional
        The folder's lock file as written by the run that holds it (pid, host, started;
        :data:`hydrojam._io.FOLDER_LOCK`; empty where it cannot be read), None when there is none.
    replicas : int, optional
        The study's replicas per point (1 for a run).
    lock_state : LockState, optional
        Whether the lock's process lives (:func:`hydrojam._io.lock_state`): ``dead`` for a run
        that was stopped (killed) and left its lock; None when there is no lock.
    """

    kind: FolderKind
    name: str
    runs: tuple[RunStatus, ...]
    lock: dict | None = None
    replicas: int = 1
    lock_state: LockState | None = None

    def counts(self) -> dict[str, int]:
        """How many runs are in each state (:data:`STATES`), the empty ones left out."""
        return {st: n for st in STATES if (n := sum(r.state == st for r in self.runs))}


def _updated(folder: Path) -> float | None:
    times = []
    for name in ("point.json", "metrics.json", CHECKPOINT, "history.csv"):
        try:
            times.append((folder / name).stat().st_mtime)
        except OSError:
            pass
    return max(times, default=None)


def _status(folder: Path, key: str, points: tuple[Point, ...], outcome: dict | None) -> RunStatus:
    """The status of the run in ``folder`` with ``outcome`` (point.json's fields: status, error,
    metrics, wall_time_s) where it ended."""
    updated = _updated(folder)
    if outcome is not None and outcome.get("status") in FINISHED:
        metrics = outcome.get("metrics") or {}
        s = finite_number(metrics.get("s_reached"))
        state = PointStatus(outcome["status"])
        return RunStatus(key, points, state, 1.0 if s is None and state == PointStatus.OK else s,
                         finite_number(metrics.get("bending_angle_deg")), finite_number(outcome.get("wall_time_s")),
                         None, updated)
    running = running_point(points, folder)
    if outcome is not None:
        state = PointStatus.FAILED
    elif running is not None or (folder / CHECKPOINT).is_file():
        state = PointStatus.UNFINISHED
    else:
        state = PointStatus.NOT_STARTED
    error = None if outcome is None else outcome.get("error")
    if running is None:
        return RunStatus(key, points, state, updated=updated, error=error)
    return RunStatus(key, points, state, running.s, running.bending_angle_deg, running.wall_time_s,
                     running.release, updated, error)


def current_state(folder: str | os.PathLike):
    """(model, state, releasing) of the unfinished run in ``folder`` from its design.toml and
    checkpoint: the last accepted state (a :class:`~hydrojam.actuator.simulate.StepState`), or at
    s = 1 the release's current centre with ``releasing`` True; None where the folder has no
    checkpoint that fits its design (the model is built: seconds in 2D, up to a minute for a long
    3D chamber)."""
    from hydrojam.actuator.checkpoint import CheckpointError, load_checkpoint
    from hydrojam.actuator.design import DesignError, load_design
    from hydrojam.actuator.model import build_model, measure
    from hydrojam.actuator.simulate import StepState

    folder = Path(folder)
    if not (folder / CHECKPOINT).is_file():
        return None
    try:
        model = build_model(load_design(folder / "design.toml"))
        ck = load_checkpoint(folder / CHECKPOINT, model.design, model.mesh.points.shape)
    except (OSError, DesignError, CheckpointError):
        return None
    releasing = ck.release is not None
    x, s = (ck.release.x, 1.0) if releasing else (ck.xs[-1], float(ck.states[-1]["s"]))
    mu, T = model.stimulus(s)
    state = StepState(len(ck.states), s, mu, T, x, measure(model, x), 0, ck.elapsed_s)
    return model, state, releasing


def release_metrics(folder: str | os.PathLike) -> dict | None:
    """The state metrics (:func:`~hydrojam.actuator.model.measure`: bending angle [deg], tip [mm],
    ...) of the current centre of the release in ``folder``'s checkpoint, from the design in its
    design.toml (:func:`current_state`). None where there is no release under way or the
    checkpoint does not fit the design."""
    got = current_state(folder)
    return None if got is None or not got[2] else got[1].metrics


def _run_outcome(folder: Path) -> dict | None:
    """A run folder's outcome in point.json's terms, from its metrics.json (None: not finished)."""
    if (folder / CHECKPOINT).is_file():  # run again into the same folder: going on
        return None
    metrics = read_json_dict(folder / "metrics.json")
    if metrics is None:
        return None
    return {"status": PointStatus.OK if metrics.get("converged") else PointStatus.NOT_CONVERGED, "metrics": metrics,
            "wall_time_s": metrics.get("wall_time_s")}


def folder_status(out: str | os.PathLike, measure: bool = False) -> FolderStatus:
    """Where the output folder ``out`` stands.

    A study's folder holds ``OUT/study.toml`` and its points in ``OUT/points/<key>/``; a run's
    holds ``OUT/design.toml`` with history.csv, checkpoint.npz or metrics.json.

    Parameters
    ----------
    out : str or os.PathLike
        The output folder.
    measure : bool, optional
        Also the metrics of every unfinished release's current centre (:func:`release_metrics`).

    Returns
    -------
    FolderStatus

    Raises
    ------
    StatusError
        For any other folder, or an unreadable study.toml.
    """
    st = _folder_status(Path(out))
    if not measure:
        return st
    folders = {r.key: Path(out) / "points" / r.key if st.kind == FolderKind.STUDY else Path(out) for r in st.runs}
    return dataclasses.replace(st, runs=tuple(
        dataclasses.replace(r, release_metrics=release_metrics(folders[r.key]))
        if r.state == PointStatus.UNFINISHED and r.release is not None else r for r in st.runs))


def _lock(out: Path) -> dict:
    """The folder ``out``'s lock as :class:`FolderStatus` fields: its lock file's content and
    whether its process lives (:func:`hydrojam._io.lock_state`); none where it has no lock."""
    state = lock_state(out / FOLDER_LOCK)
    return {} if state is None else {"lock": state[1], "lock_state": state[0]}


def _folder_status(out: Path) -> FolderStatus:
    if (out / "study.toml").is_file():
        try:
            study = load_study(out / "study.toml")
        except StudyError as err:
            raise StatusError(str(err)) from None
        groups: dict[str, list[Point]] = {}
        for p in study.points():
            groups.setdefault(p.key, []).append(p)
        runs = []
        for key, points in groups.items():
            folder = out / "points" / key
            runs.append(_status(folder, key, tuple(points), read_json_dict(folder / "point.json")))
        # a rerun with fewer sweeps (`reproduce --sweep ...`) rewrites study.toml with those only
        others = sorted(f for f in (out / "points").glob("*") if f.is_dir() and f.name not in groups)
        runs += [_status(f, f.name, (), read_json_dict(f / "point.json")) for f in others]
        return FolderStatus(FolderKind.STUDY, study.name, tuple(runs), replicas=study.replicas, **_lock(out))
    if (out / "design.toml").is_file() and any((out / n).is_file()
                                               for n in ("history.csv", CHECKPOINT, "metrics.json")):
        return FolderStatus(FolderKind.RUN, out.name, (_status(out, "", (), _run_outcome(out)),), **_lock(out))
    raise StatusError(f"{out}: not an output folder of hydrojam (no study.toml, and no design.toml with a run's "
                      "history.csv, checkpoint.npz or metrics.json)")
