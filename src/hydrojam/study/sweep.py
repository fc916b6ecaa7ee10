"""Run a study's points in parallel with dask.distributed, cached on disk and resumable.

Layout of an output folder ``OUT``::

    study.toml              the study, self-contained (the base design inline)
    points/<key>/           one folder per distinct design: the cache (:mod:`hydrojam.study.cache`)
    results.csv             one row per (sweep, point): the table (:mod:`hydrojam.study.table`)
    results.parquet         the same, typed columns, nulls for undefined values
    replicas.csv            with replicas (a design's ``replicas.count`` > 1): one row per run

A rerun into the same ``OUT`` loads the finished points and runs the others again; a point's
folder is cleared before it runs (but a run's checkpoint, which the run resumes). An ``OUT``
whose study.toml names another study is refused: the two studies' points would mix.

With a ``scheduler`` address the points run on that dask cluster; its workers must see ``OUT`` at
the same path (a shared file system) and should run one thread each (``--nthreads 1``).
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import shutil
import threading
import time
import traceback
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from hydrojam._interrupt import signals_blocked
from hydrojam._io import (FOLDER_LOCK, FolderKind, FolderKindError, LockHeld, check_folder_kind, finite_or_none,
                          hold_lock, make_folder, read_toml, remove_stale_temporaries, write_text_atomic)
from hydrojam.actuator.checkpoint import CHECKPOINT
from hydrojam.actuator.design import Design, DesignError
from hydrojam.study.cache import (PointStatus, RunningPoint, finished_records, point_record, result_checksums,
                                  running_point, single_line, unfinished_text, write_record)
from hydrojam.study.spec import Point, Study, StudyError, write_study
from hydrojam.study.table import SweepTable, write_table

#: seconds to wait for a dask scheduler given by address
CONNECT_TIMEOUT_S = 10.0

#: seconds between two reports of the running points (``on_running`` of :func:`run_sweep`)
PROGRESS_INTERVAL_S = 15.0

__all__ = [
    "CONNECT_TIMEOUT_S",
    "PROGRESS_INTERVAL_S",
    "PointOutcome",
    "SchedulerError",
    "estimated_cost",
    "check_address",
    "run_point",
    "run_sweep",
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


def _execute(point_fn: Callable[[Design, Path], dict], design: Design, point_dir: str, key: str) -> dict:
    """Worker side: clear the point's folder (but a run's checkpoint, which the run resumes), run
    ``point_fn``, write point.json last, with the checksums of the result files of a finished
    point; never raises for the point's own failure (recorded as status "failed" with
    error.txt)."""
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
        record = point_record(key, PointStatus.FAILED, single_line(f"{type(err).__name__}: {err}"), None, elapsed, elapsed)
    else:
        elapsed = time.perf_counter() - t0
        converged = metrics.get("converged", True) is not False
        error = None if converged else single_line(metrics.get("message") or "the solver stopped early")
        wall = metrics.get("wall_time_s")
        wall = wall if isinstance(wall, (int, float)) and not isinstance(wall, bool) else elapsed
        record = point_record(key, PointStatus.OK if converged else PointStatus.NOT_CONVERGED, error, metrics, wall, elapsed,
                              result_checksums(folder))
    write_record(folder, record)
    return record


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
    damaged : tuple of str
        For a point finished earlier and computed again: its result files found damaged or
        missing (:func:`~hydrojam.study.cache.damaged_files`); else empty.
    """

    record: dict
    cached: bool
    points: tuple[Point, ...]
    point_dir: Path
    damaged: tuple[str, ...] = ()

    @classmethod
    def from_record(cls, record: dict, points: list[Point], point_dir: Path, cached: bool,
                    damaged=()) -> PointOutcome:
        return cls(record, cached, tuple(points), point_dir, tuple(damaged))

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


# -------------------------------------------------------------------- the sweep


def estimated_cost(design: Design) -> float:
    """A rough relative cost of simulating a design: particles / mesh.size^2."""
    return design.particle_layers * design.particles_per_layer / design.mesh_size**2


def check_address(address: str) -> None:
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
            f"{address}: not a scheduler address, e.g. tcp://10.0.0.5:8786 ({single_line(err)})") from None


def _connect(address: str):
    from distributed import Client

    check_address(address)
    try:
        return Client(address, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
    except (OSError, ValueError, TypeError) as err:
        raise SchedulerError(f"{address}: cannot connect within {CONNECT_TIMEOUT_S:g} s ({single_line(err)})") from None


def _local_cluster(n_workers: int):
    import dask
    from distributed import Client, LocalCluster

    # one single-threaded process per core: hydrojam's PARDISO and IPC run one thread each
    # ":0": its HTTP server (which starts even without a dashboard) on a free port, not 8787
    # allowed-failures 1: a point whose worker dies (memory, a crash, a kill) runs once more on
    # the fresh worker the nanny starts, then is recorded as failed (a rerun of the sweep retries
    # it); the sweep submits no more points than there are workers (_compute), so that a worker
    # holds only the point it runs and its death counts against that point alone
    # MALLOC_TRIM_THRESHOLD_ unset: dask's 64 KiB makes glibc return every large numpy temporary
    # to the kernel, and the page faults of taking it back cost a simulation 40% more wall time
    # (docs/sweeps.md); the single-thread settings for BLAS and OpenMP stay
    environ = {k: v for k, v in dask.config.get("distributed.nanny.pre-spawn-environ").items()
               if k != "MALLOC_TRIM_THRESHOLD_"}
    # SIGINT blocked while the cluster starts: its threads, and the worker processes they start
    # (restarted ones too), never get the terminal's Ctrl-C; this process stops them
    with dask.config.set({"distributed.scheduler.allowed-failures": 1,
                          "distributed.nanny.pre-spawn-environ": environ}), signals_blocked():
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

    Finished points (point.json ok or not_converged) are loaded, not run, unless a result file
    no longer matches the checksum its point.json records (damaged: run again, its outcome's
    ``damaged`` naming the files); the others run on a dask cluster, the most expensive points
    first. A point whose worker dies runs once more on a fresh worker before it counts as failed
    (a local cluster's; a scheduler's own ``allowed-failures`` applies there). The temporary
    files of writes a kill interrupted are removed (:func:`hydrojam._io.remove_stale_temporaries`). On KeyboardInterrupt the futures are
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
        no result yet (:class:`~hydrojam.study.cache.RunningPoint`; read from their history.csv, so only where the workers
        share OUT's file system).
    progress_interval_s : float, optional
        Seconds between ``on_running`` calls [s] (default :data:`PROGRESS_INTERVAL_S`).
    run : bool, optional
        False runs nothing: the table of the points finished so far, a point failed earlier as
        failed, every other one with status ``unfinished`` and where it stands as its error
        (:func:`~hydrojam.study.cache.unfinished_text`); ``OUT`` must already hold this study with as many replicas per
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
    records = finished_records(out, groups, failed=not run)
    pending = [key for key in groups if key not in records]
    if not run:
        for key in pending:
            folder = out / "points" / key
            records[key] = {"status": PointStatus.UNFINISHED, "error": unfinished_text(
                running_point(tuple(groups[key]), folder), (folder / CHECKPOINT).is_file())}
        return write_table(study, out, records)

    client = cluster = None
    lock = contextlib.ExitStack()
    try:
        if scheduler is not None:  # connected only when there is something to run
            client = _connect(scheduler) if pending else check_address(scheduler)
        try:
            lock.enter_context(hold_lock(make_folder(out) / FOLDER_LOCK))
        except LockHeld as err:
            raise StudyError(str(err)) from None
        _check_kind(out)  # again, under the lock
        remove_stale_temporaries(out)  # what writes that a kill interrupted left
        damaged: dict[str, list[str]] = {}
        # again: a run that held the lock may have finished some; a damaged point runs again
        records = finished_records(out, groups, damaged=damaged)
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
            in_flight = None  # a scheduler's workers: dask's queue
            if client is None:
                in_flight = min(workers or os.cpu_count() or 1, len(pending))
                cluster, client = _local_cluster(in_flight)
            interval = PROGRESS_INTERVAL_S if progress_interval_s is None else progress_interval_s
            done = _compute(client, groups, pending, out, point_fn, records, on_point, done, total, on_running,
                            interval, damaged, in_flight)
        return write_table(study, out, records)
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
        lock.close()


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
             progress_interval_s=PROGRESS_INTERVAL_S, damaged=None, in_flight=None) -> int:
    """Run the ``pending`` points on ``client``, the most expensive first, recording each outcome
    as it comes; at most ``in_flight`` submitted at once (None: all), so that a local worker
    holds only the point it runs and its death counts against that point alone."""
    from distributed import as_completed

    order = sorted(pending, key=lambda k: -estimated_cost(groups[k][0].design))  # stable: study order on ties
    token = uuid.uuid4().hex[:8]
    # a second's slack: file systems that keep mtimes in whole seconds
    watcher = None if on_running is None else _watch_running(groups, order, out, records, on_running,
                                                             progress_interval_s, time.time() - 1.0)
    futures = {}
    waiting = list(enumerate(order))

    def submit():
        rank, key = waiting.pop(0)
        fut = client.submit(_execute, point_fn, groups[key][0].design, str(out / "points" / key), key,
                            key=f"hydrojam-point-{key}-{token}", priority=len(order) - rank, pure=False)
        futures[fut] = key
        return fut

    try:
        completed = as_completed([submit() for _ in range(min(in_flight or len(waiting), len(waiting)))],
                                 loop=client.loop)
        for fut in completed:
            if waiting:
                completed.add(submit())
            key = futures[fut]
            folder = out / "points" / key
            if fut.status == "finished":
                rec = fut.result()
                if not (folder / "point.json").exists():  # a worker without our file system
                    rec = {k: v for k, v in rec.items() if k != "files"}  # its files are not here to check
                    write_record(folder, rec)
            else:  # the worker died or the task was lost: record it as a failed point
                exc = fut.exception() if fut.status == "error" else None
                error = single_line(f"{type(exc).__name__}: {exc}") if exc is not None else f"task {fut.status}"
                rec = point_record(key, PointStatus.FAILED, error, None, None, None)
                folder.mkdir(parents=True, exist_ok=True)
                write_record(folder, rec)
            records[key] = json.loads(json.dumps(rec, allow_nan=False))  # as it reads back from point.json
            done += 1
            if on_point is not None:
                on_point(PointOutcome.from_record(records[key], groups[key], folder, False,
                                                  (damaged or {}).get(key, ())), done, total)
    except BaseException:
        client.cancel(list(futures))
        raise
    finally:
        if watcher is not None:
            watcher.set()
    return done
