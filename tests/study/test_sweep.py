"""Sweeps on dask.distributed: the per-point cache, failures, resuming after an interruption, the
table (CSV and Parquet), a real simulation through a scheduler, and `hydrojam sweep`."""

import json
import logging
import math
import os
import sys
import time
from pathlib import Path

import cloudpickle
import pyarrow.parquet as pq
import pytest

from hydrojam.cli import main
from hydrojam.study.spec import Study, StudyError, study_from_dict, write_study
from hydrojam.study.sweep import SchedulerError, run_sweep
from hydrojam.study.table import SweepTable

# the point functions below travel to the workers by value: no need for the workers to import this file
cloudpickle.register_pickle_by_value(sys.modules[__name__])


@pytest.fixture(scope="module")
def scheduler():
    """A real dask scheduler with two single-threaded worker processes; yields its address."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                      silence_logs=logging.ERROR) as cluster:
        yield cluster.scheduler_address


# -------------------------------------------------------------------- cheap point functions


def _log_call(point_dir: Path) -> None:
    """Append the point's key to OUT.calls (OUT = point_dir/../..), one line per call."""
    with open(str(point_dir.parents[1]) + ".calls", "a") as f:
        f.write(point_dir.name + "\n")


def calls(out: Path) -> list[str]:
    path = Path(str(out) + ".calls")
    return path.read_text().split() if path.exists() else []


def cheap(design, point_dir):
    """A stand-in for a simulation: metrics that depend on the design, a fixed wall time."""
    _log_call(point_dir)
    T = design.stimulus.temperature
    (point_dir / "partial.txt").write_text("written while running\n")
    return {"bending_angle_deg": 300.0 - T, "tip_dx_mm": -(300.0 - T) / 10, "tip_dz_mm": -1.0,
            "curling_index": None, "max_curvature_per_mm": math.nan, "packing_fraction": 0.9,
            "contacts_per_particle": 2, "mean_swelling_ratio": 1.5, "converged": True,
            "stabilisation_released": True, "s_reached": 1.0, "load_steps": design.particle_layers,
            "newton_iterations": 10 * design.particle_layers, "wall_time_s": 0.25}


def cheap_failing_285(design, point_dir):
    """As :func:`cheap`, but the point at 285 K raises."""
    if design.stimulus.temperature == 285.0:
        _log_call(point_dir)
        raise RuntimeError("solver exploded\n(on purpose)")
    return cheap(design, point_dir)


def cheap_slow(design, point_dir):
    """As :func:`cheap_failing_285`, slow enough to be interrupted midway."""
    time.sleep(0.3)
    return cheap_failing_285(design, point_dir)


def cheap_not_converged_295(design, point_dir):
    m = cheap(design, point_dir)
    if design.stimulus.temperature == 295.0:
        m.update(converged=False, s_reached=0.6, message="the load step fell below ds_min at s = 0.6")
    return m


def small_study() -> Study:
    """7 rows, 6 distinct designs: the base point (275 K, 1 layer) is in both sweeps."""
    return study_from_dict({
        "name": "small",
        "design": {"particle_layers": 1, "mesh": {"size": 4.0}},
        "sweep": [{"name": "temperature", "vary": {"stimulus.temperature": [275, 280, 285, 290, 295]}},
                  {"name": "layers", "vary": {"particle_layers": [1, 2]}}],
    })


# -------------------------------------------------------------------- cache, failures, resume


def test_failed_point_is_recorded_and_the_others_finish(scheduler, tmp_path):
    out = tmp_path / "out"
    seen = []
    table = run_sweep(small_study(), out, scheduler=scheduler, point_fn=cheap_failing_285,
                      on_point=lambda o, done, total: seen.append((o.status, done, total)))
    assert [d for _, d, _ in seen] == list(range(1, 7)) and {t for _, _, t in seen} == {6}
    assert [s for s, _, _ in seen].count("failed") == 1
    assert sorted(calls(out)) == sorted({p.key for p in small_study().points()})  # 6 designs, each once
    rows = table.rows
    assert len(rows) == 7
    failed = [r for r in rows if r["status"] == "failed"]
    assert len(failed) == 1 and failed[0]["stimulus.temperature"] == 285.0
    assert failed[0]["error"] == "RuntimeError: solver exploded (on purpose)"
    assert failed[0]["bending_angle_deg"] is None and failed[0]["converged"] is None
    record = json.loads((out / failed[0]["point_dir"] / "point.json").read_text())
    assert record["status"] == "failed" and record["metrics"] is None
    assert "solver exploded" in (out / failed[0]["point_dir"] / "error.txt").read_text()
    ok = [r for r in rows if r["status"] == "ok"]
    assert [r["bending_angle_deg"] for r in ok] == [25.0, 20.0, 10.0, 5.0, 25.0, 25.0]
    assert (out / "study.toml").is_file() and (out / "results.csv").is_file() and (out / "results.parquet").is_file()


def test_interrupted_then_resumed_equals_uninterrupted(scheduler, tmp_path):
    """Ctrl-C after two points (a local cluster of one worker, closed on the interrupt), then a
    rerun: only the failed and the unfinished points run, and the table is byte-identical to that
    of an uninterrupted run in a fresh folder."""
    study, out = small_study(), tmp_path / "resumed"

    def interrupt(outcome, done, total):
        if done == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_sweep(study, out, workers=1, point_fn=cheap_slow, on_point=interrupt)
    assert not (out / "results.csv").exists()
    keys = list(dict.fromkeys(p.key for p in study.points()))
    statuses = {}
    for key in keys:
        f = out / "points" / key / "point.json"
        statuses[key] = json.loads(f.read_text())["status"] if f.exists() else None
    finished_ok = {k for k, s in statuses.items() if s == "ok"}
    assert 1 <= len(finished_ok) < len(keys), statuses
    # a point killed midway leaves files but no point.json: it is unfinished and will be cleared
    unfinished = next(k for k in keys if statuses[k] is None)
    (out / "points" / unfinished).mkdir(parents=True, exist_ok=True)
    (out / "points" / unfinished / "stale.txt").write_text("left by a kill\n")
    before = len(calls(out))

    seen = []
    run_sweep(study, out, scheduler=scheduler, point_fn=cheap, on_point=lambda o, d, t: seen.append(o.cached))
    rerun = calls(out)[before:]
    assert sorted(rerun) == sorted(set(keys) - finished_ok)  # failed and unfinished ones, each once
    assert seen == [True] * len(finished_ok) + [False] * (len(keys) - len(finished_ok))  # cached first
    assert not (out / "points" / unfinished / "stale.txt").exists()

    fresh = tmp_path / "fresh"
    run_sweep(study, fresh, scheduler=scheduler, point_fn=cheap)
    assert (out / "results.csv").read_bytes() == (fresh / "results.csv").read_bytes()
    assert pq.read_table(out / "results.parquet").equals(pq.read_table(fresh / "results.parquet"))
    assert (out / "study.toml").read_bytes() == (fresh / "study.toml").read_bytes()


def test_finished_points_are_loaded_not_run(scheduler, tmp_path):
    out = tmp_path / "out"
    first = run_sweep(small_study(), out, scheduler=scheduler, point_fn=cheap_not_converged_295)
    n = len(calls(out))
    t0 = time.perf_counter()
    seen = []
    # no scheduler given: nothing to run, so no local cluster is started either
    again = run_sweep(small_study(), out, point_fn=cheap, on_point=lambda o, d, t: seen.append((o.cached, o.status)))
    assert time.perf_counter() - t0 < 2.0
    assert len(calls(out)) == n  # the not-converged point is a result: kept, not rerun
    assert all(c for c, _ in seen) and sorted(s for _, s in seen).count("not_converged") == 1
    assert again.to_csv() == first.to_csv()
    row = next(r for r in again.rows if r["stimulus.temperature"] == 295.0)
    assert row["status"] == "not_converged" and row["converged"] is False
    assert row["error"] == "the load step fell below ds_min at s = 0.6"
    # with every point cached a scheduler is not needed: an unreachable one is not contacted
    assert run_sweep(small_study(), out, scheduler="tcp://127.0.0.1:1", point_fn=cheap).to_csv() == first.to_csv()


def test_csv_and_parquet_agree_typed_without_nan(scheduler, tmp_path):
    out = tmp_path / "out"
    table = run_sweep(small_study(), out, scheduler=scheduler, point_fn=cheap_failing_285)
    assert table.columns[:5] == ["sweep", "point", "key", "stimulus.temperature", "particle_layers"]
    assert table.columns[-4:] == ["wall_time_s", "status", "error", "point_dir"]
    # every row is complete: the temperature rows carry particle_layers, the layer rows the temperature
    assert all(r["particle_layers"] is not None and r["stimulus.temperature"] is not None for r in table.rows)
    back = SweepTable.read(out)
    assert back.columns == table.columns and back.rows == table.rows
    assert back.select("layers").column("particle_layers") == [1, 2]
    arrow = pq.read_table(out / "results.parquet")
    types = {f.name: str(f.type) for f in arrow.schema}
    assert types["point"] == "int64" and types["particle_layers"] == "int64" and types["load_steps"] == "int64"
    assert types["stimulus.temperature"] == "double" and types["bending_angle_deg"] == "double"
    assert types["converged"] == "bool" and types["status"] == "string" and types["error"] == "string"
    assert arrow.to_pylist() == table.rows
    for row in arrow.to_pylist():
        assert row["max_curvature_per_mm"] is None and row["curling_index"] is None  # NaN and None -> null
        assert not any(isinstance(v, float) and math.isnan(v) for v in row.values())
    text = (out / "results.csv").read_text()
    assert "nan" not in text.lower() and ",true," in text


def test_bad_arguments_write_nothing(tmp_path):
    out = tmp_path / "out"
    with pytest.raises(ValueError, match="workers: must be an integer >= 1"):
        run_sweep(small_study(), out, workers=0, point_fn=cheap)
    with pytest.raises(SchedulerError, match="not a scheduler address"):
        run_sweep(small_study(), out, scheduler="nowhere", point_fn=cheap)
    # 3D points are simulated; a 3D point whose spheres do not fit the depth is refused when read
    with pytest.raises(StudyError, match=r"sweep 'depth' point 1 .*cavity_depth: the particles do not fit"):
        study_from_dict({"design": {"dimension": 3},
                         "sweep": [{"name": "depth", "vary": {"cavity_depth": [16.2, 15.0]}}]})
    assert not out.exists()


# -------------------------------------------------------------------- a real simulation


def test_real_point_through_a_dask_scheduler(scheduler, tmp_path):
    """One tiny real actuator (1 particle layer, mesh 4 mm, 295 K) run by a worker of the scheduler:
    run_point's files, the final VTU, and the table's metrics from metrics.json."""
    import meshio

    study = study_from_dict({"name": "tiny", "design": {"particle_layers": 1, "mesh": {"size": 4.0}},
                             "sweep": [{"name": "temperature", "vary": {"stimulus.temperature": [295]}}]})
    t0 = time.perf_counter()
    table = run_sweep(study, tmp_path / "out", scheduler=scheduler)
    print(f"one tiny real point through the scheduler: {time.perf_counter() - t0:.1f} s")
    (row,) = table.rows
    assert row["status"] == "ok" and row["error"] is None and row["converged"] is True, row
    folder = tmp_path / "out" / row["point_dir"]
    metrics = json.loads((folder / "metrics.json").read_text())
    assert row["bending_angle_deg"] == metrics["bending_angle_deg"] > 10.0  # bends toward the layer
    assert row["wall_time_s"] == metrics["wall_time_s"]
    for name in ("design.toml", "history.csv", "centreline.csv", "final.png", "final.vtu", "point.json"):
        assert (folder / name).is_file(), name
    assert not (folder / "steps").exists()
    vtu = meshio.read(folder / "final.vtu")
    assert vtu.points.shape[1] == 3 and abs(vtu.points[:, 1]).max() == 0.0
    assert sorted(set(vtu.cell_data["body_id"][0].tolist())) == [0, 1, 2]


def test_local_workers_keep_large_allocations_and_run_single_threaded():
    """The local cluster's workers: no MALLOC_TRIM_THRESHOLD_ (dask's 64 KiB made a simulation 40%
    slower through page faults), but BLAS and OpenMP still one thread each."""
    import os

    from hydrojam.study.sweep import _local_cluster

    cluster, client = _local_cluster(1)
    try:
        env = client.run(lambda: {k: os.environ.get(k) for k in ("MALLOC_TRIM_THRESHOLD_", "OMP_NUM_THREADS",
                                                                  "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")})
    finally:
        client.close()
        cluster.close()
    (worker_env,) = env.values()
    assert worker_env["MALLOC_TRIM_THRESHOLD_"] is None or "MALLOC_TRIM_THRESHOLD_" in os.environ
    assert worker_env["OMP_NUM_THREADS"] == worker_env["OPENBLAS_NUM_THREADS"] == worker_env["MKL_NUM_THREADS"] == "1"


# -------------------------------------------------------------------- the command line


def _cli(capsys, *args):
    rc = main(list(args))
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.mark.parametrize(
    "args, needles",
    [
        (["--workers", "0"], ["--workers", ">= 1"]),
        (["--workers", "2", "--scheduler", "tcp://127.0.0.1:8786"], ["--workers", "--scheduler"]),
        (["--scheduler", "nowhere"], ["--scheduler", "nowhere", "not a scheduler address"]),
    ],
)
def test_cli_bad_options_exit_2_and_write_nothing(capsys, tmp_path, args, needles):
    write_study(tmp_path / "study.toml", small_study())
    rc, out, err = _cli(capsys, "sweep", str(tmp_path / "study.toml"), "-o", str(tmp_path / "out"), *args)
    assert rc == 2 and out == ""
    assert len(err.strip().splitlines()) == 1, err
    for needle in needles:
        assert needle in err
    assert not (tmp_path / "out").exists()


def test_cli_bad_study_exits_2_naming_sweep_and_field(capsys, tmp_path):
    path = tmp_path / "study.toml"
    path.write_text('[[sweep]]\nname = "layers"\n[sweep.vary]\nparticle_layers = [1, 0]\n')
    rc, _, err = _cli(capsys, "sweep", str(path), "-o", str(tmp_path / "out"))
    assert rc == 2 and "Traceback" not in err
    assert "sweep 'layers' point 1" in err and "particle_layers" in err and "[1, 100]" in err
    assert not (tmp_path / "out").exists()
    rc, _, err = _cli(capsys, "sweep", str(tmp_path / "missing.toml"), "-o", str(tmp_path / "out"))
    assert rc == 2 and "missing.toml" in err


def test_cli_summary_and_exit_status_over_cached_points(capsys, scheduler, tmp_path):
    """The CLI's progress, summary and exit status, on a folder whose points are all cached (the
    real simulation behind `hydrojam sweep` runs in the README's example)."""
    path = tmp_path / "study.toml"
    write_study(path, small_study())
    out = tmp_path / ("long-folder-name-" * 5) / "out"  # a path longer than the console is wide
    run_sweep(small_study(), out, scheduler=scheduler, point_fn=cheap_not_converged_295)
    rc, _, err = _cli(capsys, "sweep", str(path), "-o", str(out))
    assert rc == 1  # one point stopped early
    assert "5 ok, 1 not converged, 0 failed; 6 cached, 0 computed" in " ".join(err.split())
    assert f"table: {out / 'results.csv'}" in err  # paths are printed whole, never wrapped

    ok_study = study_from_dict({"design": {"particle_layers": 1, "mesh": {"size": 4.0}},
                                "sweep": [{"name": "temperature", "vary": {"stimulus.temperature": [275, 280]}}]})
    write_study(path, ok_study)
    run_sweep(ok_study, tmp_path / "ok", scheduler=scheduler, point_fn=cheap)
    rc, out, err = _cli(capsys, "sweep", str(path), "-o", str(tmp_path / "ok"), "--quiet")
    assert rc == 0 and out == "" and err == ""
    assert SweepTable.read(tmp_path / "ok").column("bending_angle_deg") == [25.0, 20.0]


def test_table_column_types_follow_the_design_fields():
    """A varied field's column has its Design field's type: Literal[2, 3] -> int, an optional
    float -> float, a Literal of strings -> str (the Parquet column type follows)."""
    from hydrojam.study.table import _field_type

    assert _field_type("dimension") is int
    assert _field_type("cavity_width") is float
    assert _field_type("stimulus.path") is str
    assert _field_type("particle_layers") is int and _field_type("mesh.size") is float


# -------------------------------------------------------------------- another study's folder, reruns


def test_a_folder_of_another_study_is_refused(scheduler, tmp_path, capsys):
    """A sweep into a folder that holds another study's points (another name in OUT/study.toml)
    is refused before anything is written; the same study resumes."""
    out = tmp_path / "out"
    run_sweep(small_study(), out, scheduler=scheduler, point_fn=cheap)
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    other = study_from_dict({"name": "other", "design": {"particle_layers": 1, "mesh": {"size": 4.0}},
                             "sweep": [{"name": "temperature", "vary": {"stimulus.temperature": [300]}}]})
    with pytest.raises(StudyError, match=r"holds the points of another study, 'small'"):
        run_sweep(other, out, scheduler=scheduler, point_fn=cheap)
    path = tmp_path / "other.toml"
    write_study(path, other)
    rc, stdout, err = _cli(capsys, "sweep", str(path), "-o", str(out))
    assert rc == 2 and stdout == "" and "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and str(out) in lines[0] and "'small'" in lines[0], err
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    # the same study (same name), extended by a point: resumed, the old points reused
    n = len(calls(out))
    more = study_from_dict({"name": "small", "design": {"particle_layers": 1, "mesh": {"size": 4.0}},
                            "sweep": [{"name": "temperature", "vary": {"stimulus.temperature": [275, 300]}}]})
    table = run_sweep(more, out, scheduler=scheduler, point_fn=cheap)
    assert len(calls(out)) == n + 1 and table.column("status") == ["ok", "ok"]


def measured(design, point_dir):
    """As :func:`cheap`, with a wall time measured, as a simulation's is: it differs run to run."""
    t0 = time.perf_counter()
    m = cheap(design, point_dir)
    m["wall_time_s"] = time.perf_counter() - t0 + (time.time_ns() % 10**9) * 1e-9  # the clock's ns: never twice
    return m


def test_the_table_holds_what_the_point_records_hold(scheduler, tmp_path):
    """wall_time_s is each point's own recorded time (point.json), measured when it ran: a rerun
    with every point cached writes the same table byte for byte, while a fresh run of the same
    study measures other times (docs/sweeps.md: only wall_time_s differs)."""
    out, fresh = tmp_path / "out", tmp_path / "fresh"
    first = run_sweep(small_study(), out, scheduler=scheduler, point_fn=measured)
    csv_bytes = (out / "results.csv").read_bytes()
    for row in first.rows:
        record = json.loads((out / row["point_dir"] / "point.json").read_text())
        assert row["wall_time_s"] == record["wall_time_s"] == record["metrics"]["wall_time_s"]
    again = run_sweep(small_study(), out, point_fn=measured)
    assert (out / "results.csv").read_bytes() == csv_bytes and again.rows == first.rows
    other = run_sweep(small_study(), fresh, scheduler=scheduler, point_fn=measured)
    assert other.column("wall_time_s") != first.column("wall_time_s")
    for a, b in zip(first.rows, other.rows):
        assert {k: v for k, v in a.items() if k != "wall_time_s"} == {k: v for k, v in b.items() if k != "wall_time_s"}


def test_table_files_get_the_users_permissions(scheduler, tmp_path):
    """study.toml and the table, written by this process, are 0666 less its umask (not 0600)."""
    import os
    import stat

    old = os.umask(0o027)
    try:
        run_sweep(small_study(), tmp_path / "out", scheduler=scheduler, point_fn=cheap)
    finally:
        os.umask(old)
    for name in ("study.toml", "results.csv", "results.parquet"):
        assert stat.S_IMODE((tmp_path / "out" / name).stat().st_mode) == 0o640, name



class _Stop(Exception):
    """Stands for a crash inside a point's run."""


def stops_after_state_3(design, point_dir):
    """The real run of a point, stopped by an exception once state 3 is written (before its
    checkpoint): what a crash midway leaves."""
    from hydrojam.actuator.model import build_model
    from hydrojam.actuator.results import ResultWriter
    from hydrojam.actuator.simulate import simulate

    model = build_model(design)
    writer = ResultWriter(point_dir, model, vtu=False)
    writer.start()

    def on_step(state):
        writer.step(state)
        if state.index == 3:
            raise _Stop("stopped after state 3")

    simulate(model, on_step=on_step, checkpoint=writer.checkpoint_path)
    raise AssertionError("not stopped")


def test_a_point_stopped_midway_goes_on_from_its_checkpoint(scheduler, tmp_path):
    """A point that stopped midway (recorded failed; its folder keeps history.csv and
    checkpoint.npz) is not started over by the rerun: it goes on from the checkpoint and ends where
    a run in one go ends (the same Newton iterations and angle: the same computation,
    docs/actuator.md "Checkpoints"). Every run here is in a worker: the same thread settings."""
    from hydrojam.actuator.checkpoint import CHECKPOINT

    study = study_from_dict({"name": "tiny", "design": {"particle_layers": 1, "mesh": {"size": 4.0}},
                             "sweep": [{"name": "temperature", "vary": {"stimulus.temperature": [295]}}]})
    (stopped,) = run_sweep(study, tmp_path / "out", scheduler=scheduler, point_fn=stops_after_state_3).rows
    assert stopped["status"] == "failed" and "stopped after state 3" in stopped["error"]
    folder = tmp_path / "out" / stopped["point_dir"]
    assert (folder / CHECKPOINT).is_file()

    (row,) = run_sweep(study, tmp_path / "out", scheduler=scheduler).rows
    (one_go,) = run_sweep(study, tmp_path / "one_go", scheduler=scheduler).rows
    assert row["status"] == one_go["status"] == "ok", row
    metrics = json.loads((folder / "metrics.json").read_text())
    assert [r["state"] for r in metrics["provenance"]["resumed"]] == [2]
    assert not (folder / "error.txt").exists() and not (folder / CHECKPOINT).exists()
    assert row["newton_iterations"] == one_go["newton_iterations"]
    assert row["bending_angle_deg"] == one_go["bending_angle_deg"]


def reports_half_way(design, point_dir):
    """A point that has an accepted state at s = 0.5 for a while (history.csv as a run writes it)."""
    time.sleep(0.8)  # the folder's old history.csv (if any) is not this run's
    (point_dir / "history.csv").write_text("step,s,wall_time_s\n0,0.0,0.1\n1,0.5,42.0\n")
    time.sleep(1.2)
    return cheap(design, point_dir)


def test_running_points_are_reported_with_the_s_they_reached(scheduler, tmp_path):
    """on_running sees each computed point at the s of its last accepted state, never a point
    with a history older than the call (a stopped run's, not yet going on) or a finished one."""
    from hydrojam.actuator.checkpoint import CHECKPOINT
    from hydrojam.study.cache import point_progress

    study = study_from_dict({"name": "two", "design": {"particle_layers": 1, "mesh": {"size": 4.0}},
                             "sweep": [{"name": "temperature", "vary": {"stimulus.temperature": [285, 295]}}]})
    keys = [p.key for p in study.points()]
    stale = tmp_path / "out" / "points" / keys[0]
    stale.mkdir(parents=True)
    (stale / CHECKPOINT).write_bytes(b"kept: the point goes on from it")
    (stale / "history.csv").write_text("step,s,wall_time_s\n0,0.0,0.1\n1,0.25,10.0\n")
    os.utime(stale / "history.csv", (time.time() - 60, time.time() - 60))
    assert point_progress(stale) == (0.25, 10.0) and point_progress(tmp_path) is None

    seen = []
    table = run_sweep(study, tmp_path / "out", scheduler=scheduler, point_fn=reports_half_way,
                      on_running=lambda running, done, total: seen.append((running, done, total)),
                      progress_interval_s=0.2)
    assert [r["status"] for r in table.rows] == ["ok", "ok"]
    assert {total for _, _, total in seen} == {2} and all(0 <= done <= 2 for _, done, _ in seen)
    reported = [(r.points[0].key, r.s, r.wall_time_s) for batch, _, _ in seen for r in batch]
    assert {key for key, _, _ in reported} == set(keys)
    assert {(s, wall) for _, s, wall in reported} == {(0.5, 42.0)}


def test_cli_log_gets_a_line_per_point_and_the_running_points(capsys, tmp_path, monkeypatch):
    """Where stderr is not a terminal (a log file, as here under capsys) `hydrojam sweep` prints a
    line per finished point and, every RUNNING_LOG_INTERVAL_S, the running points with the s they
    reached (one tiny real point, the intervals shortened)."""
    import hydrojam.cli as cli
    import hydrojam.study.sweep as sweep_module

    monkeypatch.setattr(sweep_module, "PROGRESS_INTERVAL_S", 0.1)
    monkeypatch.setattr(cli, "RUNNING_LOG_INTERVAL_S", 0.0)
    study = study_from_dict({"name": "tiny", "design": {"particle_layers": 1, "mesh": {"size": 4.0}},
                             "sweep": [{"name": "temperature", "vary": {"stimulus.temperature": [295]}}]})
    path = tmp_path / "study.toml"
    write_study(path, study)
    rc, _, err = _cli(capsys, "sweep", str(path), "-o", str(tmp_path / "out"), "--workers", "1")
    assert rc == 0, err
    lines = err.splitlines()
    assert any(" point 1/1 ok after " in ln and "temperature[0] stimulus.temperature=295" in ln and " deg" in ln
               for ln in lines), err
    running = [ln for ln in lines if " running: temperature[0] stimulus.temperature=295: s = " in ln]
    assert running, err
    s_values = [float(ln.split(": s = ")[1].split()[0]) for ln in running]
    assert all(0.0 <= s <= 1.0 for s in s_values) and s_values == sorted(s_values)
