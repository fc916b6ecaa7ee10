"""The finite-element core: reference elements, meshes and the gmsh wrapper, solids, energy
terms, IPC contact, the linear solver, Newton and the load path.

It knows nothing about hydrogels or actuators and imports only :mod:`hydrojam.materials`'
protocol. Everything the solver minimises is an *energy term* (:class:`EnergyTerm`): a solid's
stored energy (:class:`Solid`), loads, the IPC barrier (:class:`Contact`), volume constraints.
A problem is the positions, a function of the load parameter s giving the terms, and the
Dirichlet conditions; :func:`solve_path` follows s from 0 to 1.

The names below are the public API; each lives in the module of its concept
(``hydrojam.fem.solver.newton``, ``hydrojam.fem.solver.path``, ...). They are loaded on first use, so
``import hydrojam.fem`` does not start gmsh or the IPC Toolkit.

Examples
--------
A plane-strain gel layer bonded to a rigid substrate, swelling from its as-prepared state into
water at 275 K, thickens 3.45x (the analytic constrained swelling). Swollen this far, the
homogeneous layer is an unstable equilibrium (its free surface would wrinkle): the path's
stability check counts the negative eigenvalues, and ``settle="never"`` keeps the homogeneous
branch instead of moving off it:

>>> from hydrojam import Hydrogel, HydrogelParams
>>> from hydrojam.fem import Block, PathOptions, Problem, Solid, element_for_meshio_type, fixed, rectangle, solve_path
>>> p = HydrogelParams(); gel = Hydrogel(p)
>>> mesh = rectangle(4.0, 1.0, 0.5, order=2)          # mm, quadratic triangles
>>> solid = Solid(mesh.points, [Block(mesh.cells, element_for_meshio_type(mesh.cell_type), gel, "gel")])
>>> def terms(s):                                     # the stimulus path (mu0, T0) -> (0, 275 K)
...     return [solid.with_materials({"gel": gel.at(p.mu0 * (1 - s), p.T0 + s * (275.0 - p.T0))})]
>>> g = mesh.group_nodes
>>> bcs = [fixed(g("bottom"), 2), fixed(g("left"), 2, [0]), fixed(g("right"), 2, [0])]
>>> problem = Problem(mesh.points, terms, bcs, force_scale=gel.shear_modulus_ref)
>>> result = solve_path(problem, PathOptions(settle="never"))
>>> result.converged, result.history[-1].negative_eigenvalues > 0
(True, True)
>>> round(float(result.x[g("top"), 1].mean()), 2)    # the layer's thickness [mm]
3.45
"""

from __future__ import annotations

from hydrojam._lazy import lazy_api

_PUBLIC = {
    "hydrojam.fem.elements": ["ReferenceElement", "element_for_meshio_type", "quadrature", "physical_gradients",
                              "facet_measure", "ELEMENTS", "straight_pieces"],
    "hydrojam.fem.mesh": ["Mesh", "merge"],
    "hydrojam.fem.meshing": ["rectangle", "disk", "box", "ball", "bonded_rectangles", "disks", "annulus",
                             "shell_sector", "gmsh_session", "extract_mesh", "RANDOM_SEED", "add_groups", "bounding_box", "generate", "set_mesh_size"],
    "hydrojam.fem.assembly": ["Block", "Solid"],
    "hydrojam.fem.terms": ["DampedTerm", "EnergyTerm", "LinearTerm", "ScaledTerm", "TimedTerm", "ViscousStabilisation",
                           "PressureTerm", "CentroidSpring", "body_load", "surface_load", "resultant_load", "by_name", "face_weights", "lumped_volumes"],
    "hydrojam.fem.volume": ["VolumeTerm", "LocalVolumeTerm"],
    "hydrojam.fem.contact": ["Contact", "ContactSettings", "default_settings"],
    "hydrojam.fem.problem": ["Problem", "Dirichlet", "fixed", "prescribed"],
    "hydrojam.fem.solver.events": ["Observer", "LinearSolve", "Direction", "LineSearch", "Iteration",
                                   "StepAccepted", "ReleaseRound"],
    "hydrojam.fem.solver.linsolve": ["LinearSolver", "LinearSolveError"],
    "hydrojam.fem.solver.total": ["sum_energy", "physical_residual"],
    "hydrojam.fem.solver.newton": ["NewtonOptions", "NewtonResult", "NewtonStatus", "Timings", "minimize"],
    "hydrojam.fem.solver.stability": ["negative_curvature", "lowest_mode", "settle", "Settled"],
    "hydrojam.fem.solver.release": ["ReleaseOptions", "ReleaseState", "ReleaseResult", "release"],
    "hydrojam.fem.solver.path": ["PathOptions", "PathResult", "StepRecord", "PathCheckpoint", "solve_path",
                                 "first_unstable_s"],
    "hydrojam.fem._env": ["check_environment", "THREAD_VARIABLES", "SWITCH_VARIABLES"],
}
__all__, __getattr__, __dir__ = lazy_api(__name__, _PUBLIC, globals())
