"""Atomic file output: a reader never sees a half-written result."""

from __future__ import annotations

import contextlib
import os
import tempfile
import tomllib
from pathlib import Path


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike):
    """Yield a temporary path beside ``path``; on success it replaces ``path`` in one rename."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    finally:
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
