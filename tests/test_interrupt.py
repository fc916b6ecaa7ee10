"""A command stopped by a signal (hydrojam._interrupt): SIGINT and SIGTERM, sent by the test to a
real ``hydrojam`` process at start-up, to a run midway and to a sweep's process group, end it with
one line that says what stopped it, where it stands and how to go on; exit status 130 / 143; no
traceback, no leaked-semaphore warning, no lock left."""

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hydrojam import _io
from hydrojam._interrupt import Interrupted, interruption
from hydrojam.cli import main

pytestmark = pytest.mark.skipif(os.name != "posix" or not Path("/proc/self/status").exists(),
                                reason="POSIX signals, /proc")

STATUS = {signal.SIGINT: 130, signal.SIGTERM: 143}


def _handles_sigterm(pid: int) -> bool:
    """Whether process ``pid`` has a SIGTERM handler (hydrojam's: installed before its imports)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("SigCgt:"):
            return bool(int(line.split()[1], 16) & (1 << (signal.SIGTERM - 1)))
    return False


def _one_line(err: str, *needles: str) -> None:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err and "leaked" not in err, err
    for needle in needles:
        assert needle in err, (needle, err)


def test_interruption_is_found_behind_what_it_caused():
    """A numba kernel interrupted as it returns reports ``SystemError: CPUDispatcher(...) returned
    a result with an exception set`` raised from the KeyboardInterrupt; typer turns one into
    Exit(130): the stop is found behind either, a plain Ctrl-C is SIGINT."""
    try:
        try:
            raise Interrupted(signal.SIGTERM)
        except KeyboardInterrupt as err:
            raise SystemError("CPUDispatcher(<function f>) returned a result with an exception set") from err
    except SystemError as err:
        stop = interruption(err)
    assert stop.signum == signal.SIGTERM and stop.exit_status == 143 and stop.words == "SIGTERM"
    assert interruption(KeyboardInterrupt()).exit_status == 130
    assert interruption(ValueError("x")) is None and interruption(None) is None


def test_a_stop_surfacing_as_a_numba_system_error_is_one_line(capsys, monkeypatch):
    import hydrojam.cli as cli

    def kernel(*args, **kwargs):
        try:
            raise Interrupted(signal.SIGINT)
        except KeyboardInterrupt as err:
            raise SystemError("CPUDispatcher(<function f>) returned a result with an exception set") from err

    monkeypatch.setattr(cli, "_temperatures", kernel)
    rc = main(["swell"])
    captured = capsys.readouterr()
    assert rc == 130 and captured.out == ""
    _one_line(captured.err, "stopped by SIGINT (Ctrl-C)")


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_while_the_command_starts_is_one_line(sig):
    """Sent while its modules are still being imported (its handler is installed before them)."""
    p = subprocess.Popen([sys.executable, "-m", "hydrojam", "swell", "--temperatures", "290"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 30
    while not _handles_sigterm(p.pid) and time.monotonic() < deadline:
        time.sleep(0.001)
    p.send_signal(sig)
    out, err = p.communicate(timeout=60)
    assert p.returncode == STATUS[sig] and out == "", (p.returncode, out, err)
    _one_line(err, f"stopped by {signal.Signals(sig).name}")


#: a sweep whose points sleep (they write started.txt first), run by `hydrojam sweep` with one
#: local worker
_SLOW_SWEEP = """
import sys, time

def slow(design, point_dir):
    (point_dir / "started.txt").write_text("")
    time.sleep(120)
    return {"converged": True}

if __name__ == "__main__":
    import hydrojam.study.sweep as sweep
    sweep.run_sweep.__kwdefaults__["point_fn"] = slow
    from hydrojam.__main__ import run
    sys.argv[0] = "hydrojam"
    run()
"""

_STUDY = """name = "faults"
[design]
particle_layers = 1
[[sweep]]
name = "temperature"
vary = {"stimulus.temperature" = [285, 295]}
"""


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_to_a_sweeps_process_group_is_one_line_and_frees_the_folder(tmp_path, sig):
    """Ctrl-C at a terminal reaches the whole process group, dask's worker processes too; a batch
    system's SIGTERM the command. Either ends the sweep with its one line (points finished, how to
    go on), its workers stopped (no worker's traceback, no leaked semaphores) and its lock gone."""
    script, study, out = tmp_path / "sweep.py", tmp_path / "study.toml", tmp_path / "out"
    script.write_text(_SLOW_SWEEP)
    study.write_text(_STUDY)
    p = subprocess.Popen([sys.executable, str(script), "sweep", str(study), "-o", str(out), "--workers", "1"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    deadline = time.monotonic() + 120
    while not list(out.glob("points/*/started.txt")) and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    if sig == signal.SIGINT:
        os.killpg(p.pid, sig)  # a terminal's Ctrl-C
    else:
        p.send_signal(sig)  # kill, a batch system
    out_text, err = p.communicate(timeout=120)
    assert p.returncode == STATUS[sig], (p.returncode, err)
    _one_line(err, f"stopped by {signal.Signals(sig).name}", "0 points finished", "run the same command again")
    assert not (out / _io.FOLDER_LOCK).exists()


@pytest.mark.slow
def test_sigterm_to_a_run_says_where_it_stands_and_the_rerun_goes_on(tmp_path):
    """SIGTERM to `hydrojam run` (one tiny real design) once its checkpoint exists: exit 143, one
    line with the s reached and the checkpoint kept, no lock left; `hydrojam status` then sees an
    unfinished run, not a live one."""
    design = tmp_path / "d.toml"
    assert main(["init", str(design), "--set", "particle_layers=1", "--set", "mesh.size=4.0"]) == 0
    out = tmp_path / "out"
    p = subprocess.Popen([sys.executable, "-m", "hydrojam", "run", str(design), "-o", str(out), "--quiet", "--no-vtu"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 300
    while not (out / "checkpoint.npz").exists() and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 143, err
    _one_line(err, "stopped by SIGTERM at s = ", f"its checkpoint {out / 'checkpoint.npz'} is kept",
              "run the same command again to go on")
    assert not (out / _io.FOLDER_LOCK).exists() and (out / "checkpoint.npz").is_file()
    assert not [p for p in out.rglob(".*") if _io.is_stale_temporary(p.name)]
    s = float(err.split("at s = ")[1].split(";")[0])
    rows = (out / "history.csv").read_text().splitlines()
    assert 0 < s < 1 and abs(float(rows[-1].split(",")[rows[0].split(",").index("s")]) - s) < 1e-3


def test_status_says_a_run_whose_process_is_gone_was_stopped(tmp_path, capsys):
    """After a kill -9 the lock stays; `hydrojam status` checks its process, as `run` does."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "design.toml").write_text("")
    (out / "history.csv").write_text("s,wall_time_s,bending_angle_deg\n0.25,1.0,10.0\n")
    (out / "checkpoint.npz").write_text("")
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True,
                          check=True)
    (out / _io.FOLDER_LOCK).write_text(json.dumps({"pid": int(dead.stdout), "host": socket.gethostname(),
                                                   "started": "2026-01-01 00:00:00"}))
    assert main(["status", str(out)]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "stopped (its process is gone); rerun to resume" in text and "in use by" not in text
    with _io.hold_lock(out / _io.FOLDER_LOCK):
        assert main(["status", str(out)]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert f"in use by process {os.getpid()}" in text and "stopped" not in text
