"""A sweep on a real dask cluster started with dask's own commands (a scheduler and two worker
processes on the loopback address) that loses a worker mid-run: the scheduler gives the lost
point to the other worker, the sweep finishes with every point once, and a rerun loads them all
from the cache (docs/sweeps.md, "Running on dask")."""

import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hydrojam.actuator.design import load_design
from hydrojam.study.spec import load_study

pytestmark = pytest.mark.slow

#: the fastest real points of the sweep tests: one layer, mesh 4 mm, near the as-prepared 300 K
TEMPERATURES = [285.0, 290.0, 295.0, 300.0]
#: bound on every wait [s]: a point takes a few seconds on one core
TIMEOUT_S = 120.0
DASK = Path(sys.executable).with_name("dask")


def _environment() -> dict:
    env = dict(os.environ, OMP_NUM_THREADS="1", MKL_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1",
               DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES="3")
    env.pop("MALLOC_TRIM_THRESHOLD_", None)
    return env


def _wait(what: str, ready, procs) -> None:
    """Poll ``ready()`` every 0.1 s up to TIMEOUT_S; fail naming ``what`` (and a cluster process
    that died) otherwise."""
    deadline = time.monotonic() + TIMEOUT_S
    while time.monotonic() < deadline:
        if ready():
            return
        dead = [p.args[1:3] for p in procs if p.poll() is not None]
        if dead:
            pytest.fail(f"waiting for {what}: a cluster process exited: {dead}")
        time.sleep(0.1)
    pytest.fail(f"waiting for {what}: not within {TIMEOUT_S:g} s")


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.kill()
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:  # pragma: no cover
        pass


@pytest.mark.skipif(not DASK.exists(), reason="the dask command is not installed beside this Python")
def test_a_sweep_survives_a_worker_killed_mid_run(tmp_path):
    env = _environment()
    study_file = tmp_path / "study.toml"
    study_file.write_text('name = "cluster"\n[design]\nparticle_layers = 1\nmesh.size = 4.0\n'
                          f'[[sweep]]\nname = "T"\n[sweep.vary]\n"stimulus.temperature" = {TEMPERATURES}\n')
    out, info = tmp_path / "out", tmp_path / "scheduler.json"
    procs: list[subprocess.Popen] = []
    logs = []

    def start(*args) -> subprocess.Popen:
        log = open(tmp_path / f"proc{len(procs)}.log", "w")
        logs.append(log)
        proc = subprocess.Popen([str(DASK), *args], env=env, stdout=log, stderr=subprocess.STDOUT, cwd=tmp_path)
        procs.append(proc)
        return proc

    sweep = None
    try:
        start("scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard", "--scheduler-file", str(info))
        _wait("the scheduler's address", lambda: info.is_file() and "address" in info.read_text(), procs)
        address = json.loads(info.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")
        workers = [start("worker", address, "--host", "127.0.0.1", "--nthreads", "1", "--no-nanny",
                         "--no-dashboard", "--name", f"w{k}") for k in range(2)]

        def n_workers() -> int:
            from distributed import Client

            with Client(address, timeout=10) as client:
                return len(client.scheduler_info()["workers"])

        _wait("two workers", lambda: n_workers() == 2, procs)
        t0 = time.monotonic()
        sweep = subprocess.Popen([sys.executable, "-m", "hydrojam.cli", "sweep", str(study_file), "-o", str(out),
                                  "--scheduler", address], env=env, stdout=subprocess.PIPE,
                                 stderr=subprocess.STDOUT, text=True, cwd=tmp_path)

        def running() -> int:
            return len(list(out.glob("points/*/history.csv"))) - len(list(out.glob("points/*/point.json")))

        # both workers busy (two points with a history and no outcome): the one killed loses its point
        _wait("two points running", lambda: running() >= 2 or sweep.poll() is not None, procs)
        assert sweep.poll() is None, "the sweep ended before a worker could be killed"
        done_before = len(list(out.glob("points/*/point.json")))
        os.kill(workers[0].pid, signal.SIGKILL)
        workers[0].wait(timeout=10)
        try:
            text, _ = sweep.communicate(timeout=TIMEOUT_S)
        except subprocess.TimeoutExpired:
            pytest.fail("the sweep did not finish after a worker was killed")
        wall = time.monotonic() - t0
        print(text)
        print(f"worker w0 killed with {done_before} of {len(TEMPERATURES)} points finished; "
              f"sweep ended with status {sweep.returncode} after {wall:.1f} s")
        assert sweep.returncode == 0, text

        # every point once: one folder per design, each finished ok with valid files
        study = load_study(study_file)
        keys = sorted(p.key for p in study.points())
        assert sorted(d.name for d in (out / "points").iterdir()) == keys
        for p in study.points():
            folder = out / "points" / p.key
            record = json.loads((folder / "point.json").read_text())
            assert record["status"] == "ok", record
            metrics = json.loads((folder / "metrics.json").read_text())
            assert math.isfinite(metrics["bending_angle_deg"]) and metrics["converged"] is True
            assert load_design(folder / "design.toml") == p.design.resolved()
            assert not (folder / "checkpoint.npz").exists() and not (folder / "error.txt").exists()
        table = (out / "results.csv").read_text().splitlines()
        assert len(table) == 1 + len(TEMPERATURES)  # a header and one row per point: none lost, none twice
        assert not (out / ".hydrojam.lock").exists()
    finally:
        if sweep is not None:
            _stop(sweep)
        for proc in reversed(procs):
            _stop(proc)
        for log in logs:
            log.close()

    # the cluster is gone: a rerun finds every point finished, contacts nobody, and writes the same table
    before = (out / "results.csv").read_bytes()
    rerun = subprocess.run([sys.executable, "-m", "hydrojam.cli", "sweep", str(study_file), "-o", str(out),
                            "--scheduler", address], env=env, capture_output=True, text=True, timeout=TIMEOUT_S)
    print(rerun.stderr)
    assert rerun.returncode == 0, rerun.stderr
    assert f"{len(TEMPERATURES)} cached, 0 computed" in " ".join(rerun.stderr.split())
    assert (out / "results.csv").read_bytes() == before
