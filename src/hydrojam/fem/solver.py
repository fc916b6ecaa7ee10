"""The solver's public names in one place: the problem (:mod:`hydrojam.fem.problem`), Newton
(:mod:`hydrojam.fem.newton`) and the load path (:mod:`hydrojam.fem.path`).

``from hydrojam.fem.solver import Problem, fixed, solve_path`` is the import for users; each
name lives in the module of its concept.
"""

from hydrojam.fem.newton import NewtonOptions, NewtonResult, NewtonStatus, Timings, minimize, negative_curvature
from hydrojam.fem.path import PathOptions, PathResult, StepRecord, solve_path
from hydrojam.fem.problem import Dirichlet, Problem, fixed, prescribed

__all__ = [
    "Dirichlet",
    "NewtonOptions",
    "NewtonResult",
    "NewtonStatus",
    "PathOptions",
    "PathResult",
    "Problem",
    "StepRecord",
    "Timings",
    "fixed",
    "minimize",
    "negative_curvature",
    "prescribed",
    "solve_path",
]
