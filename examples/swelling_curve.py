"""The gel's free-swelling curve: stretch against temperature in pure water, and the volume
phase transition.

Cooling a PNIPAM gel in water makes it swell; heating it past the transition temperature makes it
collapse, with a jump in volume. This prints the free-swelling stretch (from the as-prepared
state, the size the particles are moulded at) over 275-315 K at mu = 0, and the transition, and
draws the curve.

    python examples/swelling_curve.py [OUT_DIR]      # writes OUT_DIR/swelling_curve.png
"""

import sys
from pathlib import Path

import numpy as np

from hydrojam import HydrogelParams
from hydrojam.materials.plots import plot_swelling_curve
from hydrojam.materials.swelling import swelling_curve

MU = 0.0  # chemical potential of pure water [k_B T]


def main(out: Path) -> int:
    out.mkdir(parents=True, exist_ok=True)
    params = HydrogelParams()  # the paper's PNIPAM: N nu = 0.01, lambda0 = 1.5, T0 = 300 K
    temperatures = np.arange(275.0, 315.0 + 1e-9, 5.0)
    transition, states = swelling_curve(params, MU, temperatures)

    print(f"PNIPAM free swelling in pure water (mu = {MU:g} kT), as prepared at T0 = {params.T0:g} K")
    print(f"{'T [K]':>7}  {'stretch':>8}  {'volume':>8}  branch")
    for s in states:
        print(f"{s.T:7.1f}  {s.stretch_rel:8.4f}  {s.stretch_rel**3:8.3f}  {s.branch}")
    print("(stretch and volume relative to the as-prepared state)")
    kind = "discontinuous" if transition.discontinuous else "continuous"
    jump = transition.J_swollen / transition.J_collapsed
    print(f"volume phase transition: T = {transition.T:.3f} K ({kind}, the volume jumps {jump:.2f}x)")

    png = out / "swelling_curve.png"
    plot_swelling_curve(params, MU, states, transition, png)
    print(f"figure: {png}")
    return 0


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1] if len(sys.argv) > 1 else ".")))
