"""How fast the design actuates, for the assessment: the particles' diffusion-limited swelling
time (docs/kinetics.md) at their swollen size. Units: mm, s, mm^2/s."""

from __future__ import annotations

import numpy as np

from hydrojam.materials.kinetics import mean_log_swelling, time_constant

#: share of a step the free particle's mean ln J has made at the reported swelling time
SHARE = 0.9


def swelling_time(radius: float, diffusivity: float, dimension: int) -> tuple[float, float]:
    """(tau, t90) [s] of a free particle of swollen radius ``radius`` [mm] after a step of its
    stimulus: tau = a^2/(pi^2 D) and the time its mean ln J has made 90% of the step, for a
    cylinder (``dimension`` 2, plane strain) or a sphere (3). The share does not depend on the
    step's size (the kinetics are linear in ln J)."""
    if dimension not in (2, 3):
        raise ValueError(f"dimension must be 2 or 3 (got {dimension})")
    tau = time_constant(radius, diffusivity)
    times = tau * np.concatenate([[0.0], np.geomspace(1e-4, 10.0, 2000)])
    surface = np.ones_like(times)
    share = mean_log_swelling(times, surface, radius, diffusivity, "cylinder" if dimension == 2 else "sphere",
                              initial=0.0)
    i = int(np.argmax(share >= SHARE))
    t90 = float(np.interp(SHARE, share[i - 1:i + 1], times[i - 1:i + 1]))
    return tau, t90


