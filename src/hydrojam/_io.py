"""Atomic file output (a reader never sees a half-written result) with the user's permissions,
the removal of what an interrupted write left, a lock file that keeps two processes from writing
one folder, and the one rule for non-finite values in outputs."""

from __future__ import annotations

import contextlib
import enum
import errno
import json
import math
import os
import re
import socket
import tempfile
import time
import tomllib
from pathlib import Path


def make_folder(path: str | os.PathLike) -> Path:
    """Create the folder ``path`` and its parents where missing; NotADirectoryError naming the
    path when it (or a parent) exists as something else."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError as err:
        raise NotADirectoryError(errno.ENOTDIR, "exists and is not a folder", err.filename or os.fspath(path)) from None
    return path


def check_file_target(path: str | os.PathLike) -> None:
    """Refuse, before anything is created, a file path that cannot be written: an OSError naming
    the path when ``path`` is a folder (IsADirectoryError), when its nearest existing ancestor is
    not a folder (NotADirectoryError: a parent is a regular file) or cannot be written into
    (PermissionError naming the file and that folder). Folders still missing between that ancestor and the file are not made
    here."""
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(errno.EISDIR, "is a folder, not a file", os.fspath(path))
    ancestor = path.parent
    while not os.path.lexists(ancestor) and ancestor != ancestor.parent:
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise NotADirectoryError(errno.ENOTDIR, "a parent of the file is not a folder", os.fspath(ancestor))
    if not os.access(ancestor, os.W_OK | os.X_OK):
        raise PermissionError(errno.EACCES, f"cannot be written (its folder {ancestor} cannot be written into)",
                              os.fspath(path))


def _umask() -> int:
    """The process's umask, read without changing it where the system tells (Linux: a change,
    even restored at once, would race with other threads creating files)."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def file_mode() -> int:
    """The mode a new file gets from ``open(path, "w")``: 0o666 less the umask."""
    return 0o666 & ~_umask()


#: called with the target path after a writer has written its temporary file and before the
#: rename (:func:`atomic_path`); None in use. A fault-injection point for tests: a hook that kills
#: the process at a chosen write leaves what a kill at that moment leaves.
before_replace = None

#: the temporary file of :func:`atomic_path` for a file NAME: ``.NAME.`` + tempfile's 8 random
#: characters + NAME's suffix (checked separately: :func:`is_stale_temporary`)
_TEMPORARY = re.compile(r"\.(?P<name>.+)\.[a-z0-9_]{8}(?P<suffix>\.[^.]*)?")


def is_stale_temporary(name: str) -> bool:
    """Whether the file name ``name`` is that of an atomic write's temporary file,
    ``.NAME.XXXXXXXX.SUFFIX`` with SUFFIX the suffix of NAME (none where NAME has none): what a
    process killed while writing NAME leaves (:func:`atomic_path`)."""
    m = _TEMPORARY.fullmatch(name)
    return m is not None and (m["suffix"] or "") == Path(m["name"]).suffix


#: the subfolders of an output folder where hydrojam writes files (glob patterns), besides the
#: folder itself: a run's steps, a study's figures and points
OUTPUT_SUBFOLDERS = ("steps", "figures", "points/*", "points/*/steps")


def remove_stale_temporaries(folder: str | os.PathLike, subfolders=OUTPUT_SUBFOLDERS) -> list[Path]:
    """Remove the temporary files that interrupted atomic writes left (:func:`is_stale_temporary`)
    in ``folder`` and its ``subfolders`` (glob patterns), where hydrojam writes; any other file,
    and any other folder, is left alone. Call it holding the folder's lock (no writer of ours
    is then under way there). Returns the paths removed; one that cannot be removed is left."""
    folder = Path(folder)
    removed = []
    for sub in (folder, *(p for pattern in subfolders for p in sorted(folder.glob(pattern)))):
        try:
            entries = list(os.scandir(sub))
        except OSError:
            continue
        for entry in entries:
            if is_stale_temporary(entry.name) and entry.is_file(follow_symlinks=False):
                with contextlib.suppress(OSError):
                    os.unlink(entry.path)
                    removed.append(Path(entry.path))
    return removed


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike):
    """Yield a temporary path beside ``path``; on success it replaces ``path`` in one rename.

    The file gets the user's usual permissions (:func:`file_mode`), not the temporary file's
    0600. The target is checked first (:func:`check_file_target`: a folder, a parent that is a
    file, a folder that cannot be written), so a refused path leaves its folder unchanged, not
    even a temporary file made and removed. An OSError (not a folder, no permission, no space,
    read-only) names ``path``, not the temporary file; nothing is left behind. A process killed
    while it writes leaves its temporary file, ``.NAME.XXXXXXXX.SUFFIX`` beside ``path``
    (:func:`is_stale_temporary`); the next run that takes the folder removes it
    (:func:`remove_stale_temporaries`).
    """
    path = Path(path)
    tmp = None
    try:
        check_file_target(path)
        make_folder(path.parent)
        try:
            fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent)
        except OSError as err:
            err.filename = os.fspath(path)
            raise
        os.close(fd)
        yield Path(tmp)
        if before_replace is not None:
            before_replace(path)
        os.chmod(tmp, file_mode())  # after the writer: some replace the file they are given
        os.replace(tmp, path)
    except OSError as err:
        if err.filename is None or (tmp is not None and os.fspath(err.filename) == tmp):
            err.filename = os.fspath(path)
        raise
    finally:
        if tmp is not None:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` atomically (UTF-8)."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")


def read_toml(path: str | os.PathLike, kind: str, error: type[Exception]) -> dict:
    """The tables of a TOML file; ``error`` (e.g. DesignError) with one line naming the file and
    the ``kind`` of file ("design", "study") when it is missing, unreadable or not valid TOML."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise error(f"{path}: {kind} file not found") from None
    except OSError as err:
        raise error(f"{path}: cannot read the {kind} file ({err.strerror or err})") from None
    try:
        return tomllib.loads(raw.decode("utf-8"))
    except UnicodeDecodeError:
        raise error(f"{path}: not a UTF-8 text file") from None
    except tomllib.TOMLDecodeError as err:
        raise error(f"{path}: invalid TOML: {err}") from None


def read_json_dict(path: str | os.PathLike) -> dict | None:
    """The JSON object in ``path``, or None where the file is missing, unreadable, not JSON or not
    an object (a record a run may not have written, or written by another version)."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def finite_or_none(value):
    """The one rule for non-finite values in outputs: NaN and +-inf become None (JSON ``null``, an
    empty CSV cell), recursively through dicts, lists and tuples; numpy scalars become Python
    numbers. Every writer of results passes its values through this."""
    if isinstance(value, dict):
        return {k: finite_or_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_or_none(v) for v in value]
    if isinstance(value, bool):
        return value
    if hasattr(value, "item") and callable(value.item) and getattr(value, "ndim", None) == 0:
        value = value.item()  # numpy scalar
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    return value


def finite_number(value) -> float | None:
    """A value read as a finite float, or None (None, a flag, "", NaN, inf, an unreadable string)."""
    if value is None or isinstance(value, bool):
        return None
    try:
        f = float(value)
    except (TypeError, ValueError):
        return None
    return f if math.isfinite(f) else None


#: the lock file a run holds in its output folder while it writes there (:func:`hold_lock`):
#: ``hydrojam run``, and a study's run (``sweep``, ``reproduce``, ...) in the study's folder
FOLDER_LOCK = ".hydrojam.lock"


class LockHeld(RuntimeError):
    """The lock file is held by another live process (or one on another host, which cannot be
    checked); the message names it and how to free a stale lock."""


def _alive(pid: int) -> bool:
    """Whether process ``pid`` of this host lives (signal 0 probes it on POSIX; on Windows
    os.kill would terminate it, so a lock there is taken as held)."""
    if os.name == "nt":
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's live process
        return True
    except OSError:
        return False
    return True


#: seconds after which a lock file that cannot be read (empty, not JSON) is taken as left by a
#: dead process: its writer writes it at once after creating it (:func:`hold_lock`)
UNREADABLE_LOCK_S = 10.0


class LockState(enum.StrEnum):
    """Whether the process that holds a lock file lives (:func:`lock_state`)."""

    LIVE = "live"  # a live process of this host
    DEAD = "dead"  # a process of this host that is gone, or an unreadable lock older than UNREADABLE_LOCK_S
    ELSEWHERE = "elsewhere"  # a process of another host (which cannot be checked)
    UNKNOWN = "unknown"  # a lock that cannot be read yet (being written)


def lock_state(path: str | os.PathLike) -> tuple[LockState, dict] | None:
    """The lock file ``path``'s state and content (pid, host, started; empty where it cannot be
    read): None where there is no lock file. Its process is dead where it is of this host and
    gone, or where the lock cannot be read and has been there over :data:`UNREADABLE_LOCK_S`
    (a killed writer's, or a full disk's)."""
    path = Path(path)
    if not os.path.lexists(path):
        return None
    held = read_json_dict(path) or {}
    pid, host = held.get("pid"), held.get("host")
    if not isinstance(pid, int) or not isinstance(host, str):
        try:
            age = time.time() - path.lstat().st_mtime
        except FileNotFoundError:
            return None
        return (LockState.DEAD if age > UNREADABLE_LOCK_S else LockState.UNKNOWN), {}
    if host != socket.gethostname():
        return LockState.ELSEWHERE, held
    return (LockState.LIVE if _alive(pid) else LockState.DEAD), held


def _create_lock(path: Path, me: dict) -> bool:
    """Create the lock file ``path`` holding ``me`` (JSON), exclusively: False where it exists.
    Where writing it fails (a full disk), it is removed again and the OSError names it."""
    try:
        fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, file_mode())
    except FileExistsError:
        return False
    except OSError as err:
        err.filename = os.fspath(path)
        raise
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            json.dump(me, f)
    except BaseException as err:
        with contextlib.suppress(OSError):
            path.unlink()
        if isinstance(err, OSError) and err.filename is None:
            err.filename = os.fspath(path)
        raise
    return True


@contextlib.contextmanager
def hold_lock(path: str | os.PathLike):
    """Hold the lock file ``path`` (its folder must exist) while the block runs: created
    exclusively with this process's pid, host and start time (JSON), removed at the end. A lock
    whose process is dead (:func:`lock_state`: a killed run of this host, or an unreadable lock
    left by a killed or failed write) is taken over; one held by a live process, or written on
    another host, raises :class:`LockHeld` and is left alone. An OSError creating it (no space,
    no permission) names the lock file, and leaves none."""
    path = Path(path)
    me = {"pid": os.getpid(), "host": socket.gethostname(), "started": time.strftime("%Y-%m-%d %H:%M:%S")}
    for _ in range(2):
        if _create_lock(path, me):
            break
        state = lock_state(path)
        if state is None:
            continue  # removed meanwhile
        state, held = state
        if state == LockState.DEAD:
            with contextlib.suppress(FileNotFoundError):
                path.unlink()  # its process was killed: stale
            continue
        pid, host = held.get("pid"), held.get("host")
        who = (f"process {pid} on {host}" + (f" since {held['started']}" if held.get("started") else "")
               if held else "an unknown process (the lock file cannot be read)")
        raise LockHeld(f"{path.parent}: in use by {who} (its lock file {path.name}); wait for it or stop "
                       f"it, or, if nothing runs there, delete {path}") from None
    else:  # pragma: no cover - another process took the stale lock between our two tries
        raise LockHeld(f"{path.parent}: in use (its lock file {path.name} was taken over by another process)")
    failed = True
    try:
        yield path
        failed = False
    finally:
        try:
            path.unlink(missing_ok=True)
        except OSError:
            # a folder made read-only meanwhile: the lock stays (its process's end makes it
            # stale); the error that stopped the block is the one to report
            if not failed:
                raise


class FolderKind(enum.StrEnum):
    """What an output folder holds; each member is its name in messages, and equal to it as a
    string."""

    STUDY = "study"  # sweep, reproduce, design-map, run --replicas
    STUDY_POINT = "study point"  # one point's folder inside a study's points/
    ASSESSMENT = "assessment"  # hydrojam assess
    RUN = "run"  # hydrojam run
    SNAPSHOTS = "snapshots"  # hydrojam snapshot (no marker file)


#: the files that mark what an output folder holds, first match wins (:func:`folder_kind`)
_KIND_MARKERS = (
    (FolderKind.STUDY, ("study.toml",)),
    (FolderKind.STUDY_POINT, ("point.json",)),
    (FolderKind.ASSESSMENT, ("assessment.json",)),
    (FolderKind.RUN, ("metrics.json", "history.csv", "checkpoint.npz", "results.pvd")),
)
#: what each kind of folder is, in the refusal's words
_KIND_WORDS = {FolderKind.STUDY: "a study (sweep, reproduce, design-map or run --replicas; its study.toml)",
               FolderKind.STUDY_POINT: "one point of a study (its point.json)",
               FolderKind.ASSESSMENT: "an assessment (hydrojam assess; its assessment.json)",
               FolderKind.RUN: "a single run (hydrojam run; its metrics.json, history.csv or checkpoint)",
               FolderKind.SNAPSHOTS: "snapshots (hydrojam snapshot)"}


class FolderKindError(ValueError):
    """The output folder holds another kind of hydrojam output; the message names both."""


def folder_kind(path: str | os.PathLike) -> FolderKind | None:
    """What the folder ``path`` holds, read from its marker files: "study", "study point",
    "assessment" or "run"; None for a missing folder or one without hydrojam output (snapshots
    have no marker)."""
    path = Path(path)
    for kind, names in _KIND_MARKERS:
        if any(os.path.lexists(path / n) for n in names):
            return kind
    return None


def check_folder_kind(path: str | os.PathLike, kind: FolderKind) -> None:
    """FolderKindError when the folder ``path`` holds output of another kind than ``kind`` (one of
    "study", "assessment", "run", "snapshots"): a run's files in a study's folder would be taken
    for the study's, an assessment would overwrite a run's design.toml. Missing and empty
    folders, and folders of the same kind (a rerun, a resume), pass."""
    found = folder_kind(path)
    if found is not None and found != kind:
        raise FolderKindError(
            f"{path}: holds the output of {_KIND_WORDS[found]}, not of {_KIND_WORDS[kind]}; "
            "choose another output folder, or delete this one to start over")


@contextlib.contextmanager
def output_folder(path: str | os.PathLike, kind: FolderKind):
    """Take the output folder ``path`` for writing output of ``kind`` (:func:`check_folder_kind`):
    refused before anything is written when it is not a folder (NotADirectoryError), holds
    another kind (FolderKindError) or another live process holds its lock (LockHeld); then made
    and held (:func:`hold_lock`, the lock file :data:`FOLDER_LOCK`) while the block runs, its kind
    checked again under the lock and the temporary files of interrupted writes removed
    (:func:`remove_stale_temporaries`). Yields the folder's Path."""
    path = Path(path)
    if os.path.lexists(path) and not path.is_dir():
        raise NotADirectoryError(errno.ENOTDIR, "exists and is not a folder", os.fspath(path))
    check_folder_kind(path, kind)
    with hold_lock(make_folder(path) / FOLDER_LOCK):
        check_folder_kind(path, kind)  # another process may have written it meanwhile
        remove_stale_temporaries(path)
        yield path
