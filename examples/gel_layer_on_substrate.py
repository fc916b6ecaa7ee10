"""The finite-element core alone: a gel layer bonded to a rigid substrate swells into water.

A 4 mm x 1 mm plane-strain layer of PNIPAM gel, as prepared (stress-free at mu0, T0 = 300 K), is
bonded to a rigid substrate along its bottom edge and free on top; its sides slide along the
walls of a trough, so it can only thicken. The load-path solver brings it to pure water
(mu = 0) at 275 K. The swollen layer is homogeneous, so its thickness stretch must equal the
material-point answer of `constrained_swelling` with both in-plane stretches held at lambda0
(Hong, Liu & Suo 2009).

Swollen this far, the homogeneous layer is an unstable equilibrium: a layer bonded to a rigid
substrate wrinkles at its free surface once it has swollen enough, and the path's stability
check finds negative eigenvalues there. The comparison is with the homogeneous branch, so the
path keeps it (``settle="never"``) instead of moving the state off it; the wrinkled layer would
fold into itself, and this example has no self-contact.

    python examples/gel_layer_on_substrate.py [OUT_DIR]      # writes OUT_DIR/gel_layer.csv
"""

import csv
import sys
from pathlib import Path

from hydrojam import Hydrogel, HydrogelParams, constrained_swelling
from hydrojam.fem import Block, PathOptions, Problem, Solid, element_for_meshio_type, fixed, rectangle, solve_path

T_WATER = 275.0  # K
WIDTH, THICKNESS, MESH_SIZE = 4.0, 1.0, 0.3  # mm


def main(out: Path) -> int:
    out.mkdir(parents=True, exist_ok=True)
    p = HydrogelParams()
    gel = Hydrogel(p)  # at the as-prepared stimulus (mu0, T0)
    mesh = rectangle(WIDTH, THICKNESS, MESH_SIZE, order=2)  # quadratic triangles
    solid = Solid(mesh.points, [Block(mesh.cells, element_for_meshio_type(mesh.cell_type), gel, "gel")])

    def terms(s):  # the stimulus moves linearly from (mu0, T0) at s = 0 to (0, 275 K) at s = 1
        return [solid.with_materials({"gel": gel.at(p.mu0 * (1 - s), p.T0 + s * (T_WATER - p.T0))})]

    g = mesh.group_nodes
    bcs = [fixed(g("bottom"), 2), fixed(g("left"), 2, [0]), fixed(g("right"), 2, [0])]
    result = solve_path(Problem(mesh.points, terms, bcs, force_scale=gel.shear_modulus_ref), PathOptions(settle="never"))

    fe = float(result.x[g("top"), 1].mean()) / THICKNESS  # from the as-prepared state
    exact = constrained_swelling(p, 0.0, T_WATER, held=(p.lambda0, p.lambda0)).stretch / p.lambda0
    rel_error = abs(fe - exact) / exact

    print(f"gel layer on a rigid substrate, mu = 0, T = {T_WATER:g} K: {mesh.n_cells} quadratic "
          f"triangles, {result.newton_iterations} Newton iterations, converged: {result.converged}")
    print(f"thickness stretch, finite elements: {fe:.8f}")
    print(f"thickness stretch, analytic:        {exact:.8f}")
    print(f"relative error:                     {rel_error:.2e}")
    print(f"negative eigenvalues of the swollen homogeneous state: {result.history[-1].negative_eigenvalues}")
    with open(out / "gel_layer.csv", "w", newline="") as f:
        csv.writer(f).writerows([["quantity", "value"], ["fe_thickness_stretch", fe],
                                 ["analytic_thickness_stretch", exact], ["relative_error", rel_error],
                                 ["newton_iterations", result.newton_iterations]])
    return 0 if result.converged else 1


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1] if len(sys.argv) > 1 else ".")))
