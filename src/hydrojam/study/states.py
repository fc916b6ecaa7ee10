"""The states of a design's runs: which distinct equilibrium each replica reached.

A swelling particle column is multistable (docs/replicas.md, "States"): in 3D the column either
stays one arc or folds, tens of degrees apart, and a mean over both describes neither. A run's
state is read from a geometric signature of its final state, the metric ``column_folds``
(:func:`hydrojam.actuator.metrics.column_folds`): "arc" with no fold, "folded" with one,
"multi-folded" with more (a column folded back on itself, which bends far less again).
A run without the metric (a record written before it existed) has no state (None).
"""

from __future__ import annotations

from collections.abc import Sequence

from hydrojam._io import finite_number

__all__ = ["STATES", "state_counts", "state_of", "states_text"]

#: the states a run can be in, in the order tables list them
STATES = ("arc", "folded", "multi-folded")


def state_of(metrics: dict | None) -> str | None:
    """The state of a run from its metrics: "arc" (``column_folds`` 0), "folded" (1),
    "multi-folded" (2 or more), None where the metric is missing."""
    folds = finite_number((metrics or {}).get("column_folds"))
    if folds is None:
        return None
    return STATES[min(int(round(folds)), 2)] if folds >= 0 else None


def state_counts(states: Sequence[str | None]) -> dict[str, int]:
    """How many runs are in each state of :data:`STATES` (states absent left out, None ignored)."""
    return {s: n for s in STATES if (n := sum(1 for x in states if x == s))}


def states_text(counts: dict[str, int]) -> str | None:
    """The table cell of a point's states: "arc" when every classified run is in one state, else
    each state with its runs, "arc 1; folded 2"; None with no run classified."""
    if not counts:
        return None
    if len(counts) == 1:
        return next(iter(counts))
    return "; ".join(f"{s} {n}" for s, n in counts.items())
