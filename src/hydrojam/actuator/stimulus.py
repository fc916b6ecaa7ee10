"""The stimulus path: how (mu, T) move from the as-prepared state to the target as the load
parameter s goes from 0 to 1 (DESIGN.md section 3).

Both paths move (mu, T) along the straight segment from (mu0, T0) to (mu_target, T_target); they
differ only in how fast. ``"linear"``: the position on the segment is s. ``"swelling"``
(default): s is spread (nearly) evenly over the logarithm of the gel's unconfined swelling
stretch (plane strain in 2D, free in 3D) along the segment: s = 0.9 f + 0.1 t with f that share
of the log stretch and t the position on the segment (the 10% of t keeps s -> t one-to-one where
the swelling stalls or reverses). Near mu = 0 the swelling is most sensitive to mu,
so a linear path puts most of the swelling, and of a jammed packing's difficulty, in the last
percent of s; the swelling path gives every load step a similar share of it. Only the speed
changes: the states at s = 0 and s = 1, and the path in the (mu, T) plane, are the same.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hydrojam.materials.energies import HydrogelParams
from hydrojam.materials.swelling import equilibrium_stretches

_N_KNOTS = 65


def _free_stretches(params: HydrogelParams, mus, Ts, dimension: int) -> np.ndarray:
    """Unconfined stretch from the dry network along a sequence of stimuli, followed by
    continuation (the stable equilibrium nearest to the previous one): the branch the particles
    follow. Plane strain in 2D (out-of-plane stretch held at lambda0), free in 3D."""
    held = (params.lambda0,) if dimension == 2 else ()
    out, prev = [], params.lambda0
    for mu, T in zip(mus, Ts):
        try:
            roots = equilibrium_stretches(params, mu, T, held)
        except ValueError:  # no equilibrium (unbounded swelling): the coordinate stays where it was
            roots = np.empty(0)
        if len(roots):
            prev = float(roots[np.argmin(np.abs(np.log(roots / prev)))])
        out.append(prev)
    return np.asarray(out)


@dataclass(frozen=True)
class StimulusPath:
    """(mu, T) as a function of the load parameter s in [0, 1].

    mu in k_B T, T in K. ``knots`` maps s to the position t on the straight segment from
    (mu0, T0) to (mu_target, T_target), monotone, t(0) = 0, t(1) = 1.
    """

    mu_start: float
    T_start: float
    mu_target: float
    T_target: float
    s_knots: np.ndarray
    t_knots: np.ndarray

    def position(self, s: float) -> float:
        """Position t in [0, 1] on the (mu, T) segment at load parameter s."""
        return float(np.interp(min(max(s, 0.0), 1.0), self.s_knots, self.t_knots))

    def __call__(self, s: float) -> tuple[float, float]:
        """(mu [k_B T], T [K]) at load parameter s."""
        t = self.position(s)
        return (self.mu_start + t * (self.mu_target - self.mu_start),
                self.T_start + t * (self.T_target - self.T_start))


def stimulus_path(params: HydrogelParams, mu_target: float, T_target: float, kind: str = "swelling",
                  dimension: int = 2, mu_start: float | None = None, T_start: float | None = None) -> StimulusPath:
    """The path from (mu_start, T_start) (default: the as-prepared (mu0, T0)) to the target.

    ``kind`` "linear" or "swelling" (see the module docstring); ``dimension`` 2 (plane strain)
    or 3 sets which unconfined swelling the "swelling" path spreads evenly.
    """
    mu0 = params.mu0 if mu_start is None else float(mu_start)
    T0 = params.T0 if T_start is None else float(T_start)
    t = np.linspace(0.0, 1.0, _N_KNOTS)
    linear = StimulusPath(mu0, T0, float(mu_target), float(T_target), t, t)
    if kind == "linear":
        return linear
    if kind != "swelling":
        raise ValueError(f"stimulus path must be 'swelling' or 'linear' (got {kind!r})")
    lam = _free_stretches(params, mu0 + t * (mu_target - mu0), T0 + t * (T_target - T0), dimension)
    logv = np.log(lam)
    total = logv[-1] - logv[0]
    if abs(total) < 1e-6:
        return linear
    frac = (logv - logv[0]) / total
    # a swelling that reverses on the way (or jumps at a transition) is not a usable coordinate:
    # keep its monotone envelope and mix in a little of t so that s -> t stays one-to-one
    frac = np.maximum.accumulate(np.clip(frac, 0.0, 1.0))
    s = 0.9 * frac + 0.1 * t
    return StimulusPath(mu0, T0, float(mu_target), float(T_target), s, t)
