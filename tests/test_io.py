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
