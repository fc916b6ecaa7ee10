"""A study's points under faults: a finished point's damaged result file (found by the checksum
its point.json keeps) is computed again and said so, records without checksums (earlier
versions, docs/data/paper-3d-quick) still load, a worker killed under a point fails that point
alone after one retry on a fresh worker, and a killed sweep's temporary files go."""

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import cloudpickle
import pytest

from hydrojam.study.cache import damaged_files, finished_records, read_record, result_checksums
from hydrojam.study.spec import study_from_dict
from hydrojam.study.sweep import run_sweep

cloudpickle.register_pickle_by_value(sys.modules[__name__])


def three_points():
    return study_from_dict({"name": "faults", "design": {"particle_layers": 1, "mesh": {"size": 4.0}},
                            "sweep": [{"name": "temperature", "vary": {"stimulus.temperature": [285, 290, 295]}}]})


def writes_results(design, point_dir):
    """A stand-in for a run: result files like a run's, metrics from the design."""
    T = design.stimulus.temperature
    (point_dir / "metrics.json").write_text(json.dumps({"bending_angle_deg": 300.0 - T}))
    (point_dir / "history.csv").write_text(f"s,bending_angle_deg\n1.0,{300.0 - T}\n")
    with open(str(point_dir.parents[1]) + ".calls", "a") as f:
        f.write(point_dir.name + "\n")
    return {"bending_angle_deg": 300.0 - T, "converged": True, "s_reached": 1.0}


def _calls(out: Path) -> list[str]:
    path = Path(str(out) + ".calls")
    return path.read_text().split() if path.exists() else []


def test_a_damaged_result_file_of_a_finished_point_is_found_and_the_point_computed_again(tmp_path):
    """point.json keeps each result file's SHA-256; a rerun finds the one truncated or missing,
    computes that point alone again (its outcome names the files) and loads the others."""
    study, out = three_points(), tmp_path / "out"
    run_sweep(study, out, workers=1, point_fn=writes_results)
    keys = sorted(p.name for p in (out / "points").iterdir())
    record = read_record(out / "points" / keys[0])
    assert set(record["files"]) == {"metrics.json", "history.csv"}
    assert record["files"] == result_checksums(out / "points" / keys[0])
    (out / "points" / keys[0] / "metrics.json").write_text('{"bending_an')  # truncated
    (out / "points" / keys[1] / "history.csv").unlink()
    before = len(_calls(out))
    seen = {}
    again = run_sweep(study, out, workers=1, point_fn=writes_results,
                      on_point=lambda o, d, t: seen.setdefault(o.key, (o.cached, o.damaged)))
    assert sorted(_calls(out)[before:]) == keys[:2]
    assert seen[keys[0]] == (False, ("metrics.json",)) and seen[keys[1]] == (False, ("history.csv",))
    assert seen[keys[2]] == (True, ())
    assert all(not damaged_files(out / "points" / k, read_record(out / "points" / k)) for k in keys)
    assert [r["status"] for r in again.rows] == ["ok"] * 3


def test_records_without_checksums_still_load(tmp_path):
    """point.json files written before checksums were kept (earlier versions; the records kept in
    docs/data/) are loaded as they are: nothing to check against."""
    study, out = three_points(), tmp_path / "out"
    run_sweep(study, out, workers=1, point_fn=writes_results)
    for record in (out / "points").glob("*/point.json"):
        legacy = json.loads(record.read_text())
        del legacy["files"]
        record.write_text(json.dumps(legacy))
        (record.parent / "history.csv").unlink()  # not checked: no checksum recorded
    groups = {}
    for p in study.points():
        groups.setdefault(p.key, []).append(p)
    damaged = {}
    records = finished_records(out, groups, damaged=damaged)
    assert len(records) == 3 and damaged == {}
    before = len(_calls(out))
    run_sweep(study, out, workers=1, point_fn=writes_results)
    assert len(_calls(out)) == before  # every point loaded, none run


def kills_its_worker(design, point_dir):
    """285 K kills its worker every time, 290 K the first time only (a marker beside OUT), 295 K
    never."""
    T = design.stimulus.temperature
    marker = Path(str(point_dir.parents[1]) + f".killed-{T:g}")
    if T == 285.0 or (T == 290.0 and not marker.exists()):
        marker.write_text("")
        os.kill(os.getpid(), signal.SIGKILL)
    return writes_results(design, point_dir)


@pytest.mark.slow
def test_a_killed_worker_fails_only_its_own_point_after_one_retry(tmp_path):
    """One local worker runs the points in turn; each kill (SIGKILL) costs the worker, the nanny
    starts a fresh one. The point killed once runs again and finishes; the point that kills every
    worker fails (after its retry); the third, queued meanwhile, never counts a death."""
    out = tmp_path / "out"
    table = run_sweep(three_points(), out, workers=1, point_fn=kills_its_worker)
    status = {r["stimulus.temperature"]: r["status"] for r in table.rows}
    assert status == {285.0: "failed", 290.0: "ok", 295.0: "ok"}, table.rows
    failed = next(r for r in table.rows if r["status"] == "failed")
    assert "KilledWorker" in failed["error"]


_KILLED_SWEEP = """
import os, signal, sys
from hydrojam import _io
from hydrojam.study.spec import study_from_dict
from hydrojam.study.sweep import run_sweep

def point(design, point_dir):
    (point_dir / "metrics.json").write_text("{}")
    return {"converged": True}

def kill(path):
    if path.name == "results.csv":
        os.kill(os.getpid(), signal.SIGKILL)

if __name__ == "__main__":
    _io.before_replace = kill
    study = study_from_dict({"name": "faults", "design": {"particle_layers": 1},
                             "sweep": [{"name": "temperature", "vary": {"stimulus.temperature": [285]}}]})
    run_sweep(study, sys.argv[1], workers=1, point_fn=point)
"""


@pytest.mark.slow
def test_a_sweep_killed_while_it_writes_its_table_leaves_a_temporary_the_rerun_removes(tmp_path):
    script, out = tmp_path / "killed.py", tmp_path / "out"
    script.write_text(_KILLED_SWEEP)
    done = subprocess.run([sys.executable, str(script), str(out)], capture_output=True, text=True, timeout=300)
    assert done.returncode == -9, done.stderr
    (left,) = [p.name for p in out.glob(".results.csv.*.csv")]
    run_sweep(three_points(), out, workers=1, point_fn=writes_results)
    assert not list(out.glob(".results.csv.*")) and (out / "results.csv").is_file()
