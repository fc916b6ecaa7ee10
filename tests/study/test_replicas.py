"""Replicas of a design (study.replicas, study.spread): the statistics against numpy, the cache
keys, the sweep table of replicated points, a resumable run with its summary, and the CLI."""

from __future__ import annotations

import json
import logging
import math
import sys
from pathlib import Path

import cloudpickle
import numpy as np
import pytest

from hydrojam.actuator.design import Design, default_design, with_replicas, write_design
from hydrojam.cli import main
from hydrojam.study.replicas import REPLICA_STUDY, run_replicas
from hydrojam.study.spec import design_key, study_from_dict, write_study
from hydrojam.study.spread import spread
from hydrojam.study.table import SweepTable, build_table

cloudpickle.register_pickle_by_value(sys.modules[__name__])

TINY = {"particle_layers": 1, "mesh": {"size": 4.0}}


@pytest.fixture(scope="module")
def scheduler():
    """A real dask scheduler with two single-threaded worker processes; yields its address."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                      silence_logs=logging.ERROR) as cluster:
        yield cluster.scheduler_address


def by_replica(design, point_dir):
    """A stand-in for a simulation whose metrics depend on the replica and the temperature;
    replica 2 stops early. Logs each call to OUT.calls."""
    with open(str(Path(point_dir).parents[1]) + ".calls", "a") as f:
        f.write(Path(point_dir).name + "\n")
    k, T = design.replicas.index, design.stimulus.temperature
    angle = 300.0 - T + [0.0, 3.0, -9.0, 1.5][k % 4]
    return {"bending_angle_deg": angle, "tip_dx_mm": -angle / 2, "tip_dz_mm": -1.0 - k, "curling_index": None,
            "converged": k != 2, "stabilisation_released": True, "s_reached": 1.0 if k != 2 else 0.5,
            "load_steps": 10, "newton_iterations": 100 + k, "wall_time_s": 2.0}


def calls(out: Path) -> list[str]:
    path = Path(str(out) + ".calls")
    return path.read_text().split() if path.exists() else []


def _cli(capsys, *args):
    rc = main(list(args))
    out, err = capsys.readouterr()
    return rc, out, err


# -------------------------------------------------------------------- statistics and keys


def test_spread_against_numpy():
    """Mean, sample standard deviation (n - 1), min, max and their replicas, with undefined values
    (None, NaN, a string) left out but keeping their places."""
    rng = np.random.default_rng(1)
    xs = list(rng.normal(50.0, 7.0, 9))
    values = xs[:3] + [None] + xs[3:6] + [math.nan, "x"] + xs[6:]
    sp = spread(values)
    assert sp.n == 9 and len(sp.values) == 12
    assert sp.mean == pytest.approx(np.mean(xs), rel=1e-14)
    assert sp.std == pytest.approx(np.std(xs, ddof=1), rel=1e-12)
    assert (sp.min, sp.max) == (min(xs), max(xs))
    assert sp.values[sp.argmin] == min(xs) and sp.values[sp.argmax] == max(xs)
    assert sp.values[3] is None and sp.values[7] is None
    one = spread([None, 4.25])
    assert (one.n, one.mean, one.std, one.min, one.argmin) == (1, 4.25, None, 4.25, 1)
    assert spread([None]).mean is None and spread([]).n == 0
    ties = spread([2.0, 1.0, 1.0, 2.0])
    assert (ties.argmin, ties.argmax, ties.std) == (1, 0, pytest.approx(np.std([2, 1, 1, 2], ddof=1)))


def test_cache_keys_of_replicas():
    """Replica 0 keeps the key of the design as drawn (a finished single-run point is reused);
    the count never changes a key; seed and jitter change only the perturbed replicas'."""
    d = default_design()
    many = with_replicas(d, 8)
    assert design_key(many.replica(0)) == design_key(d) == design_key(many)
    keys = [design_key(many.replica(k)) for k in range(8)]
    assert len(set(keys)) == 8
    assert design_key(with_replicas(d, 3).replica(2)) == keys[2]
    reseeded = d.model_copy(update={"replicas": d.replicas.model_copy(update={"seed": 1, "count": 8})})
    assert design_key(reseeded.replica(0)) == keys[0] and design_key(reseeded.replica(1)) != keys[1]


def test_table_of_replicated_points():
    """Per point: the mean and spread over the replicas that converged (numpy), summed wall time,
    the others' errors; a point of one run stays a single-run row and a study of single runs
    keeps its columns."""
    study = study_from_dict({"name": "rep", "design": {**TINY, "replicas": {"count": 4}},
                             "sweep": [{"name": "temperature", "vary": {"stimulus.temperature": [275, 285]}}]})
    records = {}
    for p in study.points():
        k, T = p.replica, p.design.stimulus.temperature
        m = {"bending_angle_deg": 300.0 - T + [0.0, 3.0, -9.0, 1.5][k], "tip_dx_mm": -1.0 * k, "tip_dz_mm": -2.0,
             "converged": k != 2, "newton_iterations": 100 + k}
        if T == 285 and k > 0:
            records[p.key] = {"status": "failed", "error": "boom", "metrics": None, "wall_time_s": 1.0}
        else:
            records[p.key] = {"status": "ok" if k != 2 else "not_converged", "error": None if k != 2 else "early",
                              "metrics": m, "wall_time_s": 2.0}
    table = build_table(study, records)
    assert len(table) == 2 and "bending_angle_deg_std" in table.columns and "replica_dirs" in table.columns
    r275, r285 = table.rows
    used = [25.0, 28.0, 26.5]  # replicas 0, 1, 3 (replica 2 stopped early)
    assert r275["bending_angle_deg"] == pytest.approx(np.mean(used))
    assert r275["bending_angle_deg_std"] == pytest.approx(np.std(used, ddof=1))
    assert (r275["bending_angle_deg_min"], r275["bending_angle_deg_max"]) == (25.0, 28.0)
    assert r275["newton_iterations"] == round(np.mean([100, 101, 103]))
    assert r275["converged"] is True and r275["status"] == "ok"
    assert (r275["replicas"], r275["replicas_used"], r275["wall_time_s"]) == (4, 3, 8.0)
    assert r275["error"] == "replica 2: early"
    assert r275["point_dir"] == r275["replica_dirs"].split(";")[0]
    assert r285["bending_angle_deg"] == 15.0 and r285["bending_angle_deg_std"] is None  # one replica left
    assert r285["replicas_used"] == 1 and "replica 1: boom" in r285["error"]
    single = study_from_dict({"name": "one", "design": TINY,
                              "sweep": [{"name": "temperature", "vary": {"stimulus.temperature": [275]}}]})
    p, = single.points()
    plain = build_table(single, {p.key: {"status": "ok", "metrics": {"bending_angle_deg": 1.5}, "wall_time_s": 3.0}})
    assert not any(c.endswith("_std") or c.startswith("replica") for c in plain.columns)
    assert plain.rows[0]["bending_angle_deg"] == 1.5 and plain.rows[0]["wall_time_s"] == 3.0
    # written without running (run_sweep(run=False)): a replica not finished leaves its point
    # unfinished, with the finished replicas' mean so far
    records[next(p.key for p in study.points() if p.replica == 3 and p.design.stimulus.temperature == 275)] = {
        "status": "unfinished", "error": "not finished: s = 0.500 reached"}
    r275 = build_table(study, records).rows[0]
    assert r275["status"] == "unfinished" and r275["replicas_used"] == 2
    assert r275["bending_angle_deg"] == pytest.approx(26.5)
    assert r275["error"] == "replica 2: early; replica 3: not finished: s = 0.500 reached"


def test_a_states_table_keeps_a_point_with_replicas_not_finished_unfinished(tmp_path):
    """state_tables: a point with one replica folded and two not started is, in the folded table,
    unfinished with that run (it reads as "1 of 3 runs"), and unfinished in the arc table, since
    the others may still end in either state; a finished point with no run in a state is left out."""
    from hydrojam.paper._rows import partial_runs
    from hydrojam.study.cache import write_record
    from hydrojam.study.table import state_tables

    study = study_from_dict({"name": "st", "design": {**TINY, "replicas": {"count": 3}},
                             "sweep": [{"name": "temperature", "vary": {"stimulus.temperature": [275, 285]}}]})
    for p in study.points():
        T = p.design.stimulus.temperature
        if T == 285 and p.replica > 0:
            continue  # not started
        folds = 1 if T == 285 else 0
        m = {"bending_angle_deg": 100.0 + p.replica, "column_folds": folds, "converged": True}
        write_record(tmp_path / "points" / p.key, {"status": "ok", "metrics": m, "wall_time_s": 1.0})
    tables = state_tables(study, tmp_path)
    assert set(tables) == {"arc", "folded"}
    arc275, arc285 = tables["arc"].rows
    assert arc275["status"] == "ok" and arc275["replicas_used"] == 3
    assert arc285["status"] == "unfinished" and partial_runs(arc285) is None  # no arc run yet, two to come
    fold275, fold285 = tables["folded"].rows
    assert fold275["status"] == "failed" and fold275["error"].startswith("no replica in state")
    assert fold285["status"] == "unfinished" and partial_runs(fold285) == "1 of 3 runs"
    assert fold285["bending_angle_deg"] == 100.0


# -------------------------------------------------------------------- runs


def test_run_replicas_summary_and_resume(scheduler, tmp_path):
    """Four replicas: one folder each, the summary over the three that converged (numpy), which
    replica gave the extremes, CSV and JSON alike; a rerun loads them all, runs none."""
    out = tmp_path / "out"
    design = Design(**TINY)
    table, summary = run_replicas(design, out, count=4, scheduler=scheduler, point_fn=by_replica)
    assert len(calls(out)) == 4 and len(table) == 1
    angles = [25.0, 28.0, None, 26.5]
    stats = json.loads((out / "summary.json").read_text())
    theta = stats["metrics"]["bending_angle_deg"]
    assert theta["values"] == angles and theta["n"] == 3 and stats["used"] == [0, 1, 3]
    assert theta["mean"] == pytest.approx(np.mean([25.0, 28.0, 26.5]))
    assert theta["std"] == pytest.approx(np.std([25.0, 28.0, 26.5], ddof=1))
    assert (theta["min_replica"], theta["max_replica"]) == (0, 1)
    assert [r["status"] for r in stats["runs"]] == ["ok", "ok", "not_converged", "ok"]
    for run in stats["runs"]:
        assert (out / run["point_dir"] / "point.json").is_file()
    lines = (out / "summary.csv").read_text().splitlines()
    assert lines[0].startswith("metric,unit,n,mean,std,min,min_replica,max,max_replica,replica_0")
    row = next(line.split(",") for line in lines if line.startswith("bending_angle_deg,"))
    assert float(row[3]) == theta["mean"] and row[-2] == ""  # replica 2 left out
    per_replica = SweepTable.read(out / "replicas.csv")
    assert per_replica.column("replica") == [0, 1, 2, 3] and per_replica.column("bending_angle_deg")[2] == 16.0
    assert SweepTable.read(out).column("bending_angle_deg") == [pytest.approx(np.mean([25.0, 28.0, 26.5]))]
    again, _ = run_replicas(design, out, count=4, point_fn=by_replica)
    assert len(calls(out)) == 4 and again.to_csv() == table.to_csv()
    run_replicas(design, out, count=5, scheduler=scheduler, point_fn=by_replica)  # one more: only it runs
    assert len(calls(out)) == 5


def test_sweep_and_run_through_the_cli(capsys, scheduler, tmp_path):
    """`hydrojam run --replicas` prints the summary table over cached replicas (exit 1: one stopped
    early); `hydrojam sweep --replicas` gives the table its spread columns."""
    out = tmp_path / "out"
    design = Design(**TINY)
    path = tmp_path / "design.toml"
    write_design(path, design)
    run_replicas(design, out, count=4, scheduler=scheduler, point_fn=by_replica)
    rc, _, err = _cli(capsys, "run", str(path), "-o", str(out), "--replicas", "4")
    text = " ".join(err.split())
    assert rc == 1 and "4 cached, 0 computed" in text
    assert "bending_angle_deg" in text and f"{np.mean([25.0, 28.0, 26.5]):.4g}" in text and "(#1)" in text
    assert "summary.csv" in text

    study = study_from_dict({"name": "rep", "design": TINY,
                             "sweep": [{"name": "temperature", "vary": {"stimulus.temperature": [275, 285]}}]})
    write_study(tmp_path / "study.toml", study)
    from hydrojam.study.sweep import run_sweep

    sweep_out = tmp_path / "sweep"
    run_sweep(study.with_replicas(2), sweep_out, scheduler=scheduler, point_fn=by_replica)
    rc, _, err = _cli(capsys, "sweep", str(tmp_path / "study.toml"), "-o", str(sweep_out), "--replicas", "2", "-q")
    assert rc == 0 and err == ""
    table = SweepTable.read(sweep_out)
    assert table.column("bending_angle_deg") == [26.5, 16.5]
    assert table.column("bending_angle_deg_std") == [pytest.approx(np.std([25, 28], ddof=1))] * 2
    assert SweepTable.read(sweep_out / "replicas.csv").column("replica") == [0, 1, 0, 1]


@pytest.mark.parametrize(
    "args, needles",
    [
        (["run", "{design}", "--replicas", "0"], ["--replicas", "[1, 1000]", "got 0"]),
        (["run", "{design}", "--replicas", "1001"], ["--replicas", "[1, 1000]"]),
        (["run", "{design}", "--workers", "2"], ["--workers", "only with --replicas"]),
        (["run", "{design}", "--replicas", "2", "--workers", "0"], ["--workers", ">= 1"]),
        (["run", "{design}", "--replicas", "2", "--scheduler", "nowhere"], ["--scheduler", "not a scheduler address"]),
        (["run", "{replica}", "--replicas", "2"], ["--replicas", "replicas.index"]),
        (["run", "{bad}"], ["replicas.jitter", "(0, 0.1]"]),
        (["sweep", "{study}", "--replicas", "0"], ["--replicas", "[1, 1000]"]),
        (["reproduce", "--quick", "--replicas", "-1"], ["--replicas", "[1, 1000]"]),
    ],
)
def test_cli_refusals_exit_2_and_write_nothing(capsys, tmp_path, args, needles):
    files = {"design": tmp_path / "d.toml", "replica": tmp_path / "r.toml", "bad": tmp_path / "bad.toml",
             "study": tmp_path / "s.toml"}
    write_design(files["design"], Design(**TINY))
    write_design(files["replica"], Design(**TINY, replicas={"index": 3}))
    files["bad"].write_text("[replicas]\ncount = 4\njitter = 0.5\n")
    write_study(files["study"], study_from_dict({"design": TINY, "sweep": [{"name": "t", "vary": {"friction": [0]}}]}))
    out = tmp_path / "out"
    rc, stdout, err = _cli(capsys, *[a.format(**files) for a in args], "-o", str(out))
    assert rc == 2 and stdout == "" and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1, err
    for needle in needles:
        assert needle in err, err
    assert not out.exists()


@pytest.mark.slow
def test_real_replicas_through_the_cli(capsys, tmp_path):
    """Two replicas of a one-layer design, simulated: each folder holds a final.vtu whose particle
    starts where its replica put it, and the summary's values are the replicas' metrics.json."""
    import meshio

    path = tmp_path / "design.toml"
    write_design(path, Design(**TINY, replicas={"count": 2, "seed": 4}))
    out = tmp_path / "out"
    rc, _, err = _cli(capsys, "run", str(path), "-o", str(out), "--workers", "2")
    assert rc == 0, err
    stats = json.loads((out / "summary.json").read_text())
    assert stats["used"] == [0, 1]
    refs = []
    for k, run in enumerate(stats["runs"]):
        folder = out / run["point_dir"]
        metrics = json.loads((folder / "metrics.json").read_text())
        assert stats["metrics"]["bending_angle_deg"]["values"][k] == metrics["bending_angle_deg"]
        assert (metrics["provenance"]["replica"], metrics["provenance"]["seed"]) == (k, 4 if k else None)
        refs.append(meshio.read(folder / "final.vtu").points)
    moved = np.linalg.norm(refs[1] - refs[0], axis=1)
    assert 0.0 < moved.max() <= 0.1 * 0.1 * (1 + 1e-9)  # only the particle moved, within jitter x c
