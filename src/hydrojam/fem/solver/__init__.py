"""The solver: energy minimisation along a load path.

One concept per module, and the data flows one way:

- :mod:`~hydrojam.fem.solver.path`: load stepping in s from 0 to 1 (:func:`solve_path`); each
  step is a Newton minimisation, released and checked for stability where asked;
- :mod:`~hydrojam.fem.solver.release`: the one release loop, taking a damped term (a viscous
  stabilisation) off by proximal rounds (:func:`release`);
- :mod:`~hydrojam.fem.solver.stability`: negative curvature, the lowest mode, and settling off a
  saddle (:func:`negative_curvature`, :func:`lowest_mode`, :func:`settle`);
- :mod:`~hydrojam.fem.solver.newton`: projected Newton with its line search and the terms' step
  cap (contact CCD) (:func:`minimize`);
- :mod:`~hydrojam.fem.solver.linsolve`: the sparse direct solves (:class:`LinearSolver`);
- :mod:`~hydrojam.fem.solver.total`: the terms' energy, residual, tolerance and Hessian summed;
- :mod:`~hydrojam.fem.solver.events`: what the solver reports to observers (:class:`Observer`).

path -> (release, stability) -> newton -> linsolve; every module may use ``total`` and ``events``. The public
names are re-exported by :mod:`hydrojam.fem`.
"""

from __future__ import annotations

from hydrojam._lazy import lazy_api

_PUBLIC = {
    "hydrojam.fem.solver.events": ["Observer", "LinearSolve", "Direction", "LineSearch", "Iteration",
                                   "StepAccepted", "ReleaseRound"],
    "hydrojam.fem.solver.linsolve": ["LinearSolver", "LinearSolveError"],
    "hydrojam.fem.solver.total": ["sum_energy", "physical_residual"],
    "hydrojam.fem.solver.newton": ["NewtonOptions", "NewtonResult", "NewtonStatus", "Timings", "minimize"],
    "hydrojam.fem.solver.stability": ["negative_curvature", "lowest_mode", "settle", "Settled"],
    "hydrojam.fem.solver.release": ["ReleaseOptions", "ReleaseState", "ReleaseResult", "release"],
    "hydrojam.fem.solver.path": ["PathOptions", "PathResult", "StepRecord", "PathCheckpoint", "solve_path",
                                 "first_unstable_s"],
}
__all__, __getattr__, __dir__ = lazy_api(__name__, _PUBLIC, globals())
