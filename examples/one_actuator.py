"""One actuator, start to finish: build a design, simulate its cooling in water, read the result.

A one-particle-layer actuator on a coarse mesh (seconds, not minutes) is cooled from the
as-prepared state (300 K) to 275 K in pure water. The particles swell, press on the membrane,
and the strain-limit layer turns the expansion into bending. This prints the bending angle and
the tip displacement, and writes the same files as `hydrojam run` (design.toml, metrics.json,
history.csv, centreline.csv, final.png; no VTU files here) into the output folder.

    python examples/one_actuator.py [OUT_DIR]      # default ./one-actuator-out
"""

import sys
from pathlib import Path

from hydrojam import Design, build_model, simulate
from hydrojam.actuator.results import ResultWriter


def main(out: Path) -> int:
    design = Design(particle_layers=1, mesh={"size": 4.0}, stimulus={"temperature": 275.0})
    model = build_model(design)
    writer = ResultWriter(out, model, vtu=False)  # vtu=True adds steps/*.vtu and results.pvd (ParaView)
    writer.start()
    result = simulate(model, on_step=writer.step)  # every accepted load step goes to history.csv
    m = writer.finish(result)  # the metrics, as written to metrics.json

    print(f"one particle layer, mesh size {design.mesh_size:g} mm, cooled to {design.stimulus.temperature:g} K")
    print(f"bending angle:    {m['bending_angle_deg']:.2f} deg (positive: toward the strain-limit layer)")
    print(f"tip displacement: dx = {m['tip_dx_mm']:.2f} mm, dz = {m['tip_dz_mm']:.2f} mm")
    print(f"converged: {m['converged']} ({m['load_steps']} load steps, {m['newton_iterations']} Newton "
          f"iterations, stabilisation released: {m['stabilisation_released']})")
    print(f"results: {out}/")
    return 0 if result.converged else 1


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1] if len(sys.argv) > 1 else "one-actuator-out")))
