"""Deprecated alias: import the solver's names from :mod:`hydrojam.fem`.

Kept only while benchmarks/contact.py and benchmarks/fe_core.py import from here; remove it when
they import from ``hydrojam.fem``.
"""

from hydrojam.fem import (Dirichlet, NewtonOptions, NewtonResult, NewtonStatus, PathOptions, PathResult, Problem,
                          StepRecord, Timings, fixed, minimize, negative_curvature, prescribed, solve_path)

__all__ = ["Dirichlet", "NewtonOptions", "NewtonResult", "NewtonStatus", "PathOptions", "PathResult", "Problem",
           "StepRecord", "Timings", "fixed", "minimize", "negative_curvature", "prescribed", "solve_path"]
