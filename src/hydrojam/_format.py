"""Quantities written for people (reports, progress lines)."""

from __future__ import annotations

import math


def duration(seconds: float | None) -> str:
    """A duration [s] in the unit a person reads best (s, min, h or days), 3 significant digits;
    "n/a" for None or a non-finite value."""
    if seconds is None or not math.isfinite(seconds):
        return "n/a"
    for unit, size in (("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if seconds >= 2 * size:
            return f"{seconds / size:.3g} {unit}"
    return f"{seconds:.3g} s"
