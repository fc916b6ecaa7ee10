"""Environment variables that tune the FE core, read and validated in one place."""

from __future__ import annotations

import os


def positive_int(name: str, default: int) -> int:
    """The positive integer in environment variable ``name`` (``default`` when unset); a
    ValueError naming the variable and the allowed values for anything else (abc, 0, -1)."""
    raw = os.environ.get(name)
    if raw is None:
        return default
    try:
        value = int(raw.strip())
    except ValueError:
        value = 0
    if value < 1:
        raise ValueError(f"{name} must be a positive integer (1, 2, ...); got {raw!r}")
    return value


def flag(name: str, default: bool) -> bool:
    """The switch in environment variable ``name``: "1" on, "0" off (``default`` when unset); a
    ValueError naming the variable and the allowed values for anything else."""
    raw = os.environ.get(name)
    if raw is None:
        return default
    if raw.strip() not in ("0", "1"):
        raise ValueError(f"{name} must be 0 or 1; got {raw!r}")
    return raw.strip() == "1"
