"""The spread of one quantity over a design's replicas: mean, standard deviation, extremes and
which replica gave them. Pure functions of plain values; a replica without a value (None: failed,
or a metric undefined in its state) is left out of the statistics but keeps its place."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from hydrojam._io import finite_number

__all__ = ["Spread", "spread"]


@dataclass(frozen=True)
class Spread:
    """Statistics of one quantity over a design's replicas.

    All statistics are None when no value is defined.

    Parameters
    ----------
    values : tuple of float or None
        One value per replica, in replica order; None where undefined.
    n : int
        Number of defined values.
    mean : float or None
        Their mean (in the quantity's unit).
    std : float or None
        The sample standard deviation (n - 1 in the denominator: the spread of the population of
        fillings the replicas sample); None for fewer than 2 values.
    min, max : float or None
        The extremes.
    argmin, argmax : int or None
        The replica (position in ``values``) that gave them, the first on ties.
    """

    values: tuple[float | None, ...]
    n: int
    mean: float | None
    std: float | None
    min: float | None
    max: float | None
    argmin: int | None
    argmax: int | None

    def as_dict(self) -> dict:
        """Plain data for JSON: the statistics and the values by replica."""
        return {"n": self.n, "mean": self.mean, "std": self.std, "min": self.min, "min_replica": self.argmin,
                "max": self.max, "max_replica": self.argmax, "values": list(self.values)}


def spread(values: Sequence) -> Spread:
    """The :class:`Spread` of one value per replica.

    A single value is its own mean, with no standard deviation.

    Parameters
    ----------
    values : sequence
        Numbers or None, one per replica; NaN, inf and non-numbers count as None.

    Returns
    -------
    Spread
    """
    vals = tuple(finite_number(v) for v in values)
    defined = [(i, v) for i, v in enumerate(vals) if v is not None]
    n = len(defined)
    if n == 0:
        return Spread(vals, 0, None, None, None, None, None, None)
    xs = [v for _, v in defined]
    mean = math.fsum(xs) / n
    std = math.sqrt(math.fsum((x - mean) ** 2 for x in xs) / (n - 1)) if n > 1 else None
    i_min = min(defined, key=lambda iv: iv[1])[0]
    i_max = max(defined, key=lambda iv: iv[1])[0]
    return Spread(vals, n, mean, std, vals[i_min], vals[i_max], i_min, i_max)
