"""Where an output folder stands (hydrojam.study.status, `hydrojam status OUT`), read from the
files a sweep and a run write: point.json, metrics.json, history.csv and checkpoint.npz. The
folders here are written by hand in those files' formats (the checkpoint by save_checkpoint), so
that every state is covered without running a simulation; the formats themselves are tested with
real runs in tests/actuator/test_checkpoint.py and tests/study/test_sweep.py."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hydrojam.actuator.checkpoint import CHECKPOINT, ReleaseCheckpoint, RunCheckpoint, save_checkpoint
from hydrojam.actuator.design import default_design, write_design
from hydrojam.cli import main
from hydrojam.fem.solver.newton import Timings
from hydrojam.fem.solver.path import PathCheckpoint
from hydrojam.study.spec import study_from_dict, write_study
from hydrojam.study.status import StatusError, folder_status

HISTORY = "step,s,bending_angle_deg,wall_time_s\n0,0.0,0.0,0.1\n1,{s},{angle},{wall}\n"


def _checkpoint(path, release_rounds=None, seconds=0.0):
    """A checkpoint whose release has gone ``release_rounds`` rounds (None: not begun)."""
    x = np.zeros((3, 2))
    release = None if release_rounds is None else ReleaseCheckpoint(
        x, sum(n for _, n, _ in release_rounds), 10.0, False, tuple(release_rounds), seconds)
    save_checkpoint(path, RunCheckpoint("digest", ({"index": 0, "s": 1.0},), x[None], PathCheckpoint(
        x.ravel(), 1.0, 0.05, 100.0, (), 0, Timings()), release, 100.0, {}, 0.0))


@pytest.fixture
def study_folder(tmp_path):
    """A study of five points: ok, failed, unfinished on its path, unfinished in its release, not started."""
    study = study_from_dict({"name": "five", "design": {"particle_layers": 1, "mesh": {"size": 4.0}},
                             "sweep": [{"name": "temperature",
                                        "vary": {"stimulus.temperature": [275, 280, 285, 290, 295]}}]})
    out = tmp_path / "out"
    (out / "points").mkdir(parents=True)
    write_study(out / "study.toml", study)
    keys = [p.key for p in study.points()]
    folders = [out / "points" / k for k in keys]
    for f in folders[:4]:
        f.mkdir()
    (folders[0] / "point.json").write_text(json.dumps(
        {"key": keys[0], "status": "ok", "error": None, "wall_time_s": 61.5,
         "metrics": {"bending_angle_deg": 43.96, "s_reached": 1.0}}))
    (folders[1] / "point.json").write_text(json.dumps(
        {"key": keys[1], "status": "failed", "error": "stopped after state 3", "wall_time_s": 3.0, "metrics": None}))
    (folders[1] / "history.csv").write_text(HISTORY.format(s=0.25, angle=5.0, wall=2.0))
    _checkpoint(folders[1] / CHECKPOINT)
    (folders[2] / "history.csv").write_text(HISTORY.format(s=0.5, angle=20.0, wall=42.0))
    _checkpoint(folders[2] / CHECKPOINT)
    (folders[3] / "history.csv").write_text(HISTORY.format(s=1.0, angle=38.5, wall=100.0))
    _checkpoint(folders[3] / CHECKPOINT, [(100.0, 120, True), (10.0, 200, False), (100.0, 80, True)], seconds=900.0)
    return out, keys


def test_a_study_folder_reads_as_each_points_state(study_folder):
    out, keys = study_folder
    st = folder_status(out)
    assert (st.kind, st.name) == ("study", "five")
    assert [r.key for r in st.runs] == keys
    ok, failed, path, release, fresh = st.runs
    assert (ok.state, ok.s, ok.bending_angle_deg, ok.wall_time_s, ok.release) == ("ok", 1.0, 43.96, 61.5, None)
    assert (failed.state, failed.s, failed.error) == ("failed", 0.25, "stopped after state 3")
    assert (path.state, path.s, path.bending_angle_deg, path.wall_time_s, path.release) == \
        ("unfinished", 0.5, 20.0, 42.0, None)
    assert (release.state, release.s, release.bending_angle_deg) == ("unfinished", 1.0, 38.5)
    assert (release.release.rounds, release.release.iterations, release.release.damping) == (3, 400, 10.0)
    assert release.wall_time_s == 100.0 + 900.0  # the stabilised state's, then the release's rounds
    assert (fresh.state, fresh.s, fresh.updated) == ("not started", None, None)
    assert all(r.updated is not None for r in st.runs[:4])
    assert st.counts() == {"ok": 1, "failed": 1, "unfinished": 2, "not started": 1}
    assert [r.points[0].values["stimulus.temperature"] for r in st.runs] == [275, 280, 285, 290, 295]


def test_point_folders_of_an_earlier_sweep_are_listed_too(study_folder, capsys, monkeypatch):
    """`reproduce --sweep X` into a folder rewrites study.toml with sweep X only: the points of the
    sweeps run before are still there, listed after the study's under their folder's key."""
    out, keys = study_folder
    earlier = out / "points" / "0123456789abcdef"
    earlier.mkdir()
    (earlier / "point.json").write_text(json.dumps({"status": "ok", "wall_time_s": 9.0,
                                                    "metrics": {"bending_angle_deg": 12.0, "s_reached": 1.0}}))
    (out / "points" / f"{keys[2]}.lock").write_text("123")  # not a folder: not a point
    st = folder_status(out)
    assert [r.key for r in st.runs] == [*keys, earlier.name]
    assert (st.runs[-1].state, st.runs[-1].points, st.runs[-1].bending_angle_deg) == ("ok", (), 12.0)
    monkeypatch.setenv("COLUMNS", "200")
    assert main(["status", str(out)]) == 0
    assert f"points/{earlier.name} (not in study.toml)" in capsys.readouterr().out


def test_a_run_folder_reads_finished_or_unfinished(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    write_design(out / "design.toml", default_design())
    (out / "history.csv").write_text(HISTORY.format(s=0.75, angle=30.0, wall=20.0))
    _checkpoint(out / CHECKPOINT)
    (run,) = folder_status(out).runs
    assert (run.state, run.s, run.bending_angle_deg, run.points) == ("unfinished", 0.75, 30.0, ())

    (out / CHECKPOINT).unlink()  # removed when the run ends, with metrics.json written
    (out / "metrics.json").write_text(json.dumps({"converged": False, "s_reached": 0.75, "bending_angle_deg": 30.0,
                                                  "wall_time_s": 20.5}))
    st = folder_status(out)
    assert (st.kind, st.name) == ("run", "run")
    assert [(r.state, r.s, r.wall_time_s) for r in st.runs] == [("not_converged", 0.75, 20.5)]


def test_other_folders_are_refused(tmp_path):
    with pytest.raises(StatusError, match="not an output folder of hydrojam"):
        folder_status(tmp_path)
    write_design(tmp_path / "design.toml", default_design())  # `hydrojam init` alone: no run yet
    with pytest.raises(StatusError, match="not an output folder"):
        folder_status(tmp_path)
    (tmp_path / "study.toml").write_text("name = 3\n")
    with pytest.raises(StatusError, match="study.toml"):
        folder_status(tmp_path)


def test_cli_status_prints_the_table_and_the_counts(study_folder, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")
    out, _ = study_folder
    assert main(["status", str(out)]) == 0
    text = capsys.readouterr().out
    assert "1 ok, 1 failed, 2 unfinished, 1 not started" in text
    assert "3 rounds, 400 iterations, damping 10x" in text and "stopped after state 3" in text
    assert "43.96" in text and "0.500" in text and "not started" in text

    for bad, why in ((out / "points" / "none", "no such folder"), (out / "study.toml", "not a folder"),
                     (out / "points", "not an output folder")):
        assert main(["status", str(bad)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and why in err[0], err


def test_a_table_without_running_reads_each_point_as_it_stands(study_folder, monkeypatch):
    """run_sweep(run=False) (`reproduce --report-only`): the finished point's metrics, the failed
    one as failed, the others "unfinished" with where each stands as its error; nothing runs (no
    cluster), and only the table is written: no point record, study.toml unchanged."""
    from hydrojam.study import sweep as sweep_mod
    from hydrojam.study.spec import StudyError, load_study

    out, keys = study_folder
    monkeypatch.setattr(sweep_mod, "_local_cluster", lambda n: pytest.fail("a point was run"))
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    table = sweep_mod.run_sweep(load_study(out / "study.toml"), out, run=False,
                                point_fn=lambda design, folder: pytest.fail("a point was run"))
    assert [(r["status"], r["error"]) for r in table.rows] == [
        ("ok", None), ("failed", "stopped after state 3"),
        ("unfinished", "not finished: s = 0.500 reached (20.0 deg)"),
        ("unfinished", "not finished: releasing the stabilisation (stabilised at 38.5 deg), 3 rounds, "
                       "400 iterations, damping 10x"),
        ("unfinished", "not started")]
    assert table.rows[0]["bending_angle_deg"] == 43.96
    folders = [out / "points" / k for k in keys]
    folders[4].mkdir()
    _checkpoint(folders[4] / CHECKPOINT)  # a checkpoint, no history.csv: started
    again = sweep_mod.run_sweep(load_study(out / "study.toml"), out, run=False)
    assert again.rows[4]["error"] == "not finished: no accepted state read yet"
    (folders[4] / CHECKPOINT).unlink()
    folders[4].rmdir()
    after = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert {p.relative_to(out).as_posix() for p in set(after) - set(before)} == {"results.csv", "results.parquet"}
    assert all(after[p] == data for p, data in before.items())
    # a folder holding no study yet: refused, nothing written
    empty = out.parent / "empty"
    empty.mkdir()
    with pytest.raises(StudyError, match="holds no study yet"):
        sweep_mod.run_sweep(load_study(out / "study.toml"), empty, run=False)
    assert list(empty.iterdir()) == []


def test_sweep_table_only_writes_the_table_so_far(study_folder, capsys, monkeypatch):
    """`hydrojam sweep STUDY -o OUT --table-only`: the table of the study in progress, nothing
    run; exit status 1 for its failed point; refused (2) with --workers, or where OUT is missing."""
    from hydrojam.study import sweep as sweep_mod

    out, keys = study_folder
    study_file = out.parent / "five.toml"
    study_file.write_bytes((out / "study.toml").read_bytes())
    monkeypatch.setattr(sweep_mod, "_local_cluster", lambda n: pytest.fail("a point was run"))
    assert main(["sweep", str(study_file), "-o", str(out), "--table-only"]) == 1
    assert "5 distinct points (5 rows): 1 ok, 0 not converged, 1 failed, 3 not finished" in capsys.readouterr().err
    assert [r["status"] for r in sweep_mod.SweepTable.read(out).rows] == ["ok", "failed"] + ["unfinished"] * 3
    assert main(["sweep", str(study_file), "-o", str(out), "--table-only", "--workers", "2"]) == 2
    assert "--workers: nothing runs with --table-only" in capsys.readouterr().err
    assert main(["sweep", str(study_file), "-o", str(out.parent / "none"), "--table-only"]) == 2
    assert "no such folder (--table-only writes the results" in capsys.readouterr().err
    assert not (out.parent / "none").exists()


def test_table_only_counts_every_replica_as_a_run_counts_it(tmp_path, capsys):
    """A point of 2 replicas, one ok and one failed: its row is ok (the ok replica's values), but
    the summary counts the failed replica and the exit status is 1, as after a run."""
    from hydrojam.study.table import SweepTable, run_states

    study = study_from_dict({"name": "two", "design": {"particle_layers": 1, "mesh": {"size": 4.0},
                                                       "replicas": {"count": 2}},
                             "sweep": [{"name": "temperature", "vary": {"stimulus.temperature": [295]}}]})
    out = tmp_path / "out"
    write_study(out / "study.toml", study)
    for p, status in zip(study.points(), ("ok", "failed")):
        (out / "points" / p.key).mkdir(parents=True)
        (out / "points" / p.key / "point.json").write_text(json.dumps(
            {"key": p.key, "status": status, "error": None if status == "ok" else "boom", "wall_time_s": 1.0,
             "metrics": {"bending_angle_deg": 5.0} if status == "ok" else None}))
    (out / "two.toml").write_bytes((out / "study.toml").read_bytes())
    assert main(["sweep", str(out / "two.toml"), "-o", str(out), "--table-only"]) == 1
    assert "2 distinct points (1 rows): 1 ok, 0 not converged, 1 failed, 0 not finished" in capsys.readouterr().err
    table = SweepTable.read(out)
    assert table.rows[0]["status"] == "ok" and sorted(run_states(out, table).values()) == ["failed", "ok"]


def test_status_of_a_paper_study_in_progress_names_its_report_and_resume_commands(tmp_path, capsys):
    from hydrojam.paper.study import paper_study

    out = tmp_path / "out3d"
    write_study(out / "study.toml", paper_study(True, replicas=2, dimension=3))
    assert main(["status", str(out)]) == 0
    text = capsys.readouterr().out
    assert f"report so far: hydrojam reproduce --dimension 3 --quick --replicas 2 -o {out} --report-only" in text
    assert f"go on: hydrojam reproduce --dimension 3 --quick --replicas 2 -o {out}\n" in text


def test_one_run_at_a_time_writes_a_study_folder(study_folder):
    """A second run into a folder that a live process is running (its lock file) is refused before
    it writes anything; a lock left by a killed process is taken over, and removed after the run."""
    import os
    import subprocess
    import sys

    from hydrojam._io import FOLDER_LOCK as LOCK_FILE, hold_lock
    from hydrojam.study.spec import StudyError, load_study
    from hydrojam.study.sweep import run_sweep

    out, keys = study_folder
    study = load_study(out / "study.toml")
    def point_fn(design, folder):
        return {"converged": True, "bending_angle_deg": 1.0, "s_reached": 1.0}

    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    with hold_lock(out / LOCK_FILE):  # this live process runs the folder
        assert folder_status(out).lock["pid"] == os.getpid()
        with pytest.raises(StudyError, match=r"in use by process \d+ on .*delete .*\.hydrojam\.lock"):
            run_sweep(study, out, workers=1, point_fn=point_fn)
        assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file() and p.name != LOCK_FILE} == before
    assert not (out / LOCK_FILE).exists()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    pid = int(dead.stdout)  # exited: as a killed run's
    import json
    import socket

    (out / LOCK_FILE).write_text(json.dumps({"pid": pid, "host": socket.gethostname()}))
    table = run_sweep(study, out, workers=1, point_fn=point_fn, progress_interval_s=0.05)
    assert [r["status"] for r in table.rows] == ["ok"] * 5  # the four not finished ran (in the workers)
    assert not (out / LOCK_FILE).exists() and os.getpid() != pid


def test_status_of_a_paper_study_variant_names_its_choices_and_sweeps(tmp_path, capsys):
    """A study run under model choices (``--set``) and a subset of sweeps: the commands `status`
    prints rerun that study, not the default's (its choices read from its base design)."""
    from hydrojam.paper.study import paper_study

    out = tmp_path / "variant"
    overrides = ["friction=0.3", "membrane.shear_modulus=0.046"]
    study = paper_study(True, replicas=2, dimension=3, overrides=overrides, sweeps=["temperature"])
    write_study(out / "study.toml", study)
    assert main(["status", str(out)]) == 0
    text = capsys.readouterr().out
    command = ("hydrojam reproduce --dimension 3 --quick --replicas 2 --set friction=0.3 "
               "--set membrane.shear_modulus=0.046 --sweep temperature")
    assert f"go on: {command} -o {out}\n" in text
