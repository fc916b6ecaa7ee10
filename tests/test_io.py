"""hydrojam._io on its own: atomic writes with the user's permissions, refused targets that leave
nothing behind, the lock file, folder kinds and the one rule for non-finite values."""

import json
import os
import socket
import stat
import subprocess
import sys

import numpy as np
import pytest

from hydrojam import _io


def _listing(folder):
    return sorted(p.name for p in folder.iterdir())


def test_an_atomic_write_replaces_the_file_in_one_piece_with_the_users_mode(tmp_path):
    """The text arrives whole, the file gets 0o666 less the umask (not mkstemp's 0600), and no
    temporary file is left beside it; a second write replaces the first."""
    target = tmp_path / "sub" / "out.txt"
    _io.write_text_atomic(target, "first")
    _io.write_text_atomic(target, "second \u00b0")
    assert target.read_text(encoding="utf-8") == "second \u00b0"
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~_io._umask()
    assert _listing(target.parent) == ["out.txt"]


def test_a_failing_writer_leaves_the_old_file_and_no_temporary(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("kept")
    with pytest.raises(RuntimeError):
        with _io.atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("writer failed")
    assert target.read_text() == "kept" and _listing(tmp_path) == ["out.txt"]


@pytest.mark.parametrize("case", ["folder", "parent_is_file"])
def test_a_target_that_cannot_be_a_file_is_refused_by_name_before_anything_is_made(tmp_path, case):
    if case == "folder":
        target, error = tmp_path / "dir", IsADirectoryError
        target.mkdir()
    else:
        (tmp_path / "plain").write_text("x")
        target, error = tmp_path / "plain" / "deeper" / "out.txt", NotADirectoryError
    before = _listing(tmp_path)
    with pytest.raises(error) as info:
        _io.write_text_atomic(target, "x")
    assert info.value.filename in (os.fspath(target), os.fspath(tmp_path / "plain"))
    assert _listing(tmp_path) == before


def test_make_folder_names_a_path_that_exists_as_a_file(tmp_path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(NotADirectoryError, match="exists and is not a folder"):
        _io.make_folder(tmp_path / "f")
    assert _io.make_folder(tmp_path / "a" / "b").is_dir()


def test_read_toml_names_the_file_and_its_kind(tmp_path):
    class Refused(ValueError):
        pass

    good = tmp_path / "d.toml"
    good.write_text('a = 1\n[b]\nc = "x"\n')
    assert _io.read_toml(good, "design", Refused) == {"a": 1, "b": {"c": "x"}}
    with pytest.raises(Refused, match="design file not found"):
        _io.read_toml(tmp_path / "missing.toml", "design", Refused)
    bad = tmp_path / "bad.toml"
    bad.write_text("a = = 1")
    with pytest.raises(Refused, match="invalid TOML"):
        _io.read_toml(bad, "study", Refused)
    binary = tmp_path / "bin.toml"
    binary.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(Refused, match="not a UTF-8 text file"):
        _io.read_toml(binary, "design", Refused)


def test_read_json_dict_is_none_for_anything_but_a_json_object(tmp_path):
    p = tmp_path / "r.json"
    assert _io.read_json_dict(p) is None
    p.write_text("[1, 2]")
    assert _io.read_json_dict(p) is None
    p.write_text("{not json")
    assert _io.read_json_dict(p) is None
    p.write_text('{"a": 1}')
    assert _io.read_json_dict(p) == {"a": 1}


def test_non_finite_values_become_none_everywhere_in_an_output():
    value = {"a": float("nan"), "b": [1.0, float("inf"), (np.float64(-np.inf), np.float64(2.5))],
             "c": True, "d": np.int64(3), "e": "text"}
    out = _io.finite_or_none(value)
    assert out == {"a": None, "b": [1.0, None, [None, 2.5]], "c": True, "d": 3, "e": "text"}
    assert type(out["d"]) is int and type(out["b"][2][1]) is float
    json.dumps(out, allow_nan=False)  # writable as strict JSON
    assert [_io.finite_number(v) for v in (None, True, "", "nan", "inf", "x", "2.5", 3)] == \
        [None, None, None, None, None, None, 2.5, 3.0]


def test_the_lock_is_exclusive_names_its_holder_and_is_removed_after(tmp_path):
    lock = tmp_path / _io.FOLDER_LOCK
    with _io.hold_lock(lock):
        held = json.loads(lock.read_text())
        assert held["pid"] == os.getpid() and held["host"] == socket.gethostname()
        with pytest.raises(_io.LockHeld, match=f"process {os.getpid()} on"):
            with _io.hold_lock(lock):
                pass
    assert not lock.exists()


def test_a_lock_left_by_a_dead_process_of_this_host_is_taken_over_and_another_hosts_is_not(tmp_path):
    lock = tmp_path / _io.FOLDER_LOCK
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True, check=True)
    lock.write_text(json.dumps({"pid": int(dead.stdout), "host": socket.gethostname()}))
    with _io.hold_lock(lock):
        assert json.loads(lock.read_text())["pid"] == os.getpid()
    lock.write_text(json.dumps({"pid": 1, "host": "another-host.invalid"}))
    with pytest.raises(_io.LockHeld, match="another-host.invalid"):
        with _io.hold_lock(lock):
            pass
    assert lock.exists()  # left alone
    lock.write_text("garbage")
    with pytest.raises(_io.LockHeld, match="unknown process"):
        with _io.hold_lock(lock):
            pass


def test_an_output_folder_of_another_kind_is_refused_and_its_own_kind_reopens(tmp_path):
    study = tmp_path / "study"
    study.mkdir()
    (study / "study.toml").write_text("")
    assert _io.folder_kind(study) == "study" and _io.folder_kind(tmp_path / "none") is None
    with pytest.raises(_io.FolderKindError, match="holds the output of a study"):
        with _io.output_folder(study, "run"):
            pass
    with _io.output_folder(study, "study") as folder:
        assert (folder / _io.FOLDER_LOCK).exists()
    assert not (study / _io.FOLDER_LOCK).exists()
    (tmp_path / "file").write_text("x")
    with pytest.raises(NotADirectoryError):
        with _io.output_folder(tmp_path / "file", "run"):
            pass


# -------------------------------------------------------------------- faults: a kill, a full disk, a read-only folder

#: a process that takes a run's folder and is killed (SIGKILL) while it writes the N-th NAME
#: (argv: OUT NAME N): after the writer, before the rename (the fault-injection hook of _io)
_KILLED_WRITER = """
import os, signal, sys
from pathlib import Path
from hydrojam import _io
out, name, n, count = Path(sys.argv[1]), sys.argv[2], int(sys.argv[3]), {}
def kill(path):
    count[path.name] = count.get(path.name, 0) + 1
    if path.name == name and count[path.name] == n:
        os.kill(os.getpid(), signal.SIGKILL)
_io.before_replace = kill
with _io.output_folder(out, "run"):
    for i in range(3):
        _io.write_text_atomic(out / "history.csv", f"s\\n{i}\\n")
        _io.write_text_atomic(out / "checkpoint.npz", f"state {i}")
        _io.write_text_atomic(out / "steps" / f"step_{i:04d}.vtu", f"state {i}")
"""


def _temporaries(out):
    return sorted(p.relative_to(out).as_posix() for p in out.rglob(".*") if _io.is_stale_temporary(p.name))


@pytest.mark.skipif(os.name != "posix", reason="SIGKILL")
def test_the_temporary_of_a_write_a_kill_interrupted_is_removed_when_the_folder_is_taken(tmp_path):
    """A kill inside an atomic write leaves its temporary file (``.NAME.XXXXXXXX.SUFFIX``) and the
    lock; the next process to take the folder removes those temporaries (there and in its
    steps/, figures/, points/*/), takes the dead process's lock over, and leaves every other file
    alone, hidden or look-alike."""
    out = tmp_path / "out"
    killed = [sys.executable, "-c", _KILLED_WRITER, str(out)]
    done = subprocess.run([*killed, "checkpoint.npz", "2"], capture_output=True, text=True)
    assert done.returncode == -9, done.stderr
    (left,) = _temporaries(out)
    assert left.startswith(".checkpoint.npz.") and left.endswith(".npz"), left
    assert (out / _io.FOLDER_LOCK).exists()  # the killed process's
    done = subprocess.run([*killed, "step_0001.vtu", "1"], capture_output=True, text=True)
    assert done.returncode == -9, done.stderr  # the dead one's lock taken over, its temporary removed
    (left,) = _temporaries(out)
    assert left.startswith("steps/.step_0001.vtu.") and left.endswith(".vtu"), left
    (out / "points" / "k").mkdir(parents=True)
    (out / "points" / "k" / ".final.png.ab_cd123.png").write_text("")  # a study point's
    user = [".notes.txt", ".bashrc", "data.abcd1234.npz", ".final.png.abcd1234.npz", ".final.png.abc.png",
            ".metrics.json.abcd1234"]
    for name in user:
        (out / name).write_text("mine")
    (out / "other").mkdir()
    (out / "other" / ".final.png.abcd1234.png").write_text("mine")  # not a folder hydrojam writes
    with _io.output_folder(out, "run"):
        assert json.loads((out / _io.FOLDER_LOCK).read_text())["pid"] == os.getpid()
        assert _temporaries(out) == ["other/.final.png.abcd1234.png"]
    assert all((out / name).read_text() == "mine" for name in user)
    assert _io.is_stale_temporary(".x.abcd1234") and not _io.is_stale_temporary(".x.txt.abcd1234")


def test_a_lock_that_cannot_be_written_is_not_left_and_the_error_names_it(tmp_path, monkeypatch):
    """A full disk while the lock is written: the OSError names the lock file (so its folder),
    and no lock is left to block the next run."""
    import errno

    real = os.fdopen

    class Full:
        def __init__(self, fd, *args, **kwargs):
            self.f = real(fd, *args, **kwargs)

        def __enter__(self):
            return self

        def write(self, text):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

        def __exit__(self, *exc):
            self.f.close()

    monkeypatch.setattr(_io.os, "fdopen", Full)
    with pytest.raises(OSError, match="No space left") as err:
        with _io.output_folder(tmp_path / "out", "run"):
            pass
    assert err.value.filename == str(tmp_path / "out" / _io.FOLDER_LOCK)
    assert _listing(tmp_path / "out") == []


def test_an_unreadable_lock_is_taken_over_once_it_is_old_and_its_state_says_so(tmp_path):
    """An empty or garbled lock (a process killed or a disk full while it wrote it) blocks only
    while it could still be being written; then it counts as a dead process's and is taken over.
    :func:`lock_state` says whether a lock's process lives."""
    lock = tmp_path / _io.FOLDER_LOCK
    assert _io.lock_state(lock) is None
    lock.write_text("")
    assert _io.lock_state(lock) == (_io.LockState.UNKNOWN, {})
    old = os.stat(lock).st_mtime - _io.UNREADABLE_LOCK_S - 1
    os.utime(lock, (old, old))
    assert _io.lock_state(lock) == (_io.LockState.DEAD, {})
    with _io.hold_lock(lock):
        assert _io.lock_state(lock)[0] == _io.LockState.LIVE
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True, check=True)
    lock.write_text(json.dumps({"pid": int(dead.stdout), "host": socket.gethostname()}))
    assert _io.lock_state(lock)[0] == _io.LockState.DEAD
    lock.write_text(json.dumps({"pid": 1, "host": "another-host.invalid"}))
    assert _io.lock_state(lock)[0] == _io.LockState.ELSEWHERE


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="needs POSIX permissions, not root")
def test_a_folder_made_read_only_midway_reports_the_write_that_failed(tmp_path):
    """The error is the failed write's, naming its file, not the lock file's removal that then
    fails too (the lock stays: its process's end makes it stale)."""
    out = tmp_path / "out"
    try:
        with pytest.raises(PermissionError) as err:
            with _io.output_folder(out, "run"):
                out.chmod(0o555)
                _io.write_text_atomic(out / "metrics.json", "{}")
        assert err.value.filename == str(out / "metrics.json"), err.value
        assert "cannot be written" in str(err.value)
    finally:
        out.chmod(0o755)


def test_a_lock_that_cannot_be_removed_after_a_failed_write_does_not_hide_that_write(tmp_path, monkeypatch):
    """As a read-only folder does to a process that may write anywhere (root): the lock's removal
    fails too, and the write's error is the one raised."""
    import errno
    from pathlib import Path

    def read_only(self, missing_ok=False):
        raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(self))

    with pytest.raises(PermissionError) as err:
        with _io.output_folder(tmp_path / "out", "run"):
            monkeypatch.setattr(Path, "unlink", read_only)
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(tmp_path / "out" / "metrics.json"))
    assert err.value.filename.endswith("metrics.json")
