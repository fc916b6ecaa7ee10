"""Tip loads on a clamped structure: load-deflection curves, the tangent bending
stiffness and the blocked force (docs/assess.md).

A :class:`Structure` is what is loaded: energy terms at a fixed stimulus, the clamp and the
free-end face. Loads are energy terms of :mod:`hydrojam.fem.terms` (a dead resultant force on
the free-end face, a stiff spring on its mean position), added to the structure's terms and
solved by the load-path driver from a converged state: the actuation is never re-run per load.

Units: mm, N. In 2D (plane strain) every force is per unit depth [N/mm] and a stiffness
k = dF/d delta is [N/mm per mm of depth] (docs/assess.md, "Units in 2D").
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from hydrojam.fem import LinearSolver, NewtonOptions, PathOptions, solve_path
from hydrojam.fem.problem import Dirichlet, Problem
from hydrojam.fem.terms import EnergyTerm, face_weights, resultant_load

#: load-path settings of one load increment: a jammed chamber may rearrange under load, so one
#: increment may take many Newton iterations (as the actuation's path, actuator.simulate)
LOAD_PATH = PathOptions(ds0=1.0, ds_min=1e-3, ds_max=1.0, easy_iterations=30, newton=NewtonOptions(max_iter=200))


@dataclass(frozen=True)
class Structure:
    """What a tip load acts on: reference positions ``X`` (n, d) [mm], the energy terms at a
    fixed stimulus (named, summed in order), the ``dirichlet`` conditions (the clamp), the
    free-end face ``free_end`` (boundary facets, (nf, nfn)) and the problem's ``force_scale`` [N]."""

    X: np.ndarray
    terms: tuple[EnergyTerm, ...]
    dirichlet: tuple[Dirichlet, ...]
    free_end: np.ndarray
    force_scale: float

    @property
    def dim(self) -> int:
        """Spatial dimension d (2 or 3)."""
        return self.X.shape[1]

    def weights(self) -> np.ndarray:
        """Nodal weights (n,) of the free-end face's mean position (:func:`face_weights`)."""
        return face_weights(self.X, self.free_end)

    def tip(self, x: np.ndarray) -> np.ndarray:
        """Mean position of the free-end face (d,) [mm] at positions x (n, d)."""
        return self.weights() @ np.asarray(x, dtype=float).reshape(-1, self.dim)

    def with_terms(self, *extra: EnergyTerm) -> "Structure":
        """The same structure with ``extra`` terms added (e.g. a pressure held constant)."""
        return dataclasses.replace(self, terms=self.terms + tuple(extra))

    def free_mask(self) -> np.ndarray:
        """(n*d,) bool: True where no Dirichlet condition holds the DOF."""
        return Problem(self.X, lambda s: list(self.terms), list(self.dirichlet)).free_mask()

    def load(self, x0: np.ndarray, ramped, options: PathOptions = LOAD_PATH):
        """Solve from the equilibrium x0 (n, d) with ``ramped(s)`` (a list of terms added at load
        parameter s in [0, 1]); returns the load path's result (:class:`~hydrojam.fem.solver.path.PathResult`)."""
        x0 = np.asarray(x0, dtype=float)
        problem = Problem(x0, lambda s: [*self.terms, *ramped(s)], list(self.dirichlet), self.force_scale)
        return solve_path(problem, options)


# ----------------------------------------------------------------------------------------------
# Stiffness


def tip_compliance(structure: Structure, x: np.ndarray, component: int = 0) -> float:
    """Tangent compliance w^T K^-1 w [mm per N/mm] of the free-end face at x (n, d), see
    :func:`tangent_stiffness`; <= 0 where x is not a stable equilibrium (K indefinite)."""
    x = np.asarray(x, dtype=float)
    free = structure.free_mask()
    fidx = np.flatnonzero(free)
    K = sp.csr_matrix(sum(t.hessian(x, False) for t in structure.terms))[fidx][:, fidx]
    w = np.zeros(x.size)
    w[np.arange(len(x)) * structure.dim + component] = structure.weights()
    wf = w[fidx]
    return float(wf @ LinearSolver("auto").solve(sp.csr_matrix(K), wf))


def tangent_stiffness(structure: Structure, x: np.ndarray, component: int = 0) -> float:
    """Tangent stiffness k = dF/d delta [N/mm; per mm of depth in 2D] of the free-end face at the
    equilibrium x (n, d): F a resultant force on the face in ``component`` (a uniform traction)
    and delta the face's mean displacement in that component (its work-conjugate), so
    k = 1 / (w^T K^-1 w) with K the exact Hessian of all terms over the free DOFs (not projected:
    at a stable equilibrium it is the stiffness the next small load meets) and w the nodal
    weights of the face. No regularisation: Newton's (1e-9 mean |diag K| on every DOF) acts as
    a ground spring under every node, which on a soft slender structure is not small
    (docs/assess.md, "What is computed"). The near-free rotations of
    frictionless round particles are left to the factorisation's pivoting: a tip load does not
    excite them. RuntimeError where x is not a stable equilibrium (compliance <= 0)."""
    compliance = tip_compliance(structure, x, component)
    if not compliance > 0:
        raise RuntimeError(f"the tangent compliance of the tip is {compliance:g} mm/N: the state is not a stable equilibrium")
    return 1.0 / compliance


@dataclass(frozen=True)
class TipCurve:
    """A tip load-deflection curve from one equilibrium: resultant forces on the free-end face
    in x (signed, [N/mm per unit depth in 2D]) and the face's mean displacement in x from the
    start [mm], both sorted by force and with (0, 0) included; ``converged`` False when a level
    was not reached (the curve then ends at the last converged level of that direction, and
    ``message`` says why); ``newton_iterations`` over all levels."""

    forces: np.ndarray
    deflections: np.ndarray
    converged: bool
    message: str
    newton_iterations: int

    def secant(self, sign: int) -> float | None:
        """Secant stiffness F/delta at the largest force reached in direction ``sign`` (+1: +x,
        -1: -x) [N/mm per mm of depth]; None if none was reached."""
        mask = np.sign(self.forces) == sign
        if not np.any(mask):
            return None
        i = np.flatnonzero(mask)[np.argmax(np.abs(self.forces[mask]))]
        return float(self.forces[i] / self.deflections[i])


def tip_curve(structure: Structure, x0: np.ndarray, max_force: float, fractions=(0.25, 0.5, 0.75, 1.0),
              component: int = 0, options: PathOptions = LOAD_PATH) -> TipCurve:
    """Load the free-end face of ``structure`` from the equilibrium x0 (n, d) with a dead
    resultant force in +x and in -x (``component``) up to ``max_force`` [N; N/mm per unit
    depth in 2D], in the levels ``fractions`` of it, each level continued from the last
    (:func:`hydrojam.fem.terms.resultant_load`). A level that fails ends that direction."""
    x0 = np.asarray(x0, dtype=float)
    tip0 = structure.tip(x0)[component]
    forces, deflections, iterations, messages = [0.0], [0.0], 0, []
    for sign in (1, -1):
        x, f_prev = x0, 0.0
        for frac in fractions:
            f_next = sign * frac * float(max_force)

            def ramped(s, a=f_prev, b=f_next):
                force = np.zeros(structure.dim)
                force[component] = a + s * (b - a)
                return [resultant_load(structure.X, structure.free_end, force)]

            res = structure.load(x, ramped, options)
            iterations += res.newton_iterations
            if not res.converged:
                messages.append(f"the tip force {f_next:g} was not reached: {res.message}")
                break
            x, f_prev = res.x, f_next
            forces.append(f_next)
            deflections.append(float(structure.tip(x)[component] - tip0))
    order = np.argsort(forces)
    return TipCurve(np.array(forces)[order], np.array(deflections)[order], not messages,
                    "; ".join(messages) or "converged", iterations)
