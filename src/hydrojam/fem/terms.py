"""The one protocol of everything the solver minimises: an *energy term* (DESIGN.md section 8).

A term gives, for nodal positions ``x`` of shape (n_nodes, d) [mm], its energy [mJ] (``+inf`` for
an inadmissible state), the gradient [N] as a flat vector of length n_nodes*d (dof = node*d +
component), the Hessian [N/mm] as a sparse matrix, and may cap a step ``x + alpha dx`` (contact
CCD). The solver sums terms and knows nothing else. External loads are terms too (minus their
work), so a new physics is a new term, not a branch in the solver.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
import scipy.sparse as sp

from hydrojam.fem.elements import ELEMENTS, facet_measure


@runtime_checkable
class EnergyTerm(Protocol):
    """A contribution to the total potential energy."""

    def energy(self, x: np.ndarray) -> float:
        """Energy [mJ] at positions x (n, d) [mm]; +inf if x is inadmissible."""

    def gradient(self, x: np.ndarray) -> np.ndarray:
        """dE/dx [N], flat (n*d,)."""

    def hessian(self, x: np.ndarray, project: bool = False) -> sp.csr_matrix:
        """d2E/dx2 [N/mm], (n*d, n*d); ``project``: made positive semi-definite."""

    def max_step(self, x: np.ndarray, dx: np.ndarray) -> float:
        """Largest alpha in (0, 1] such that x + alpha dx is safe for this term (1 if no limit)."""


class LinearTerm:
    """A term linear in x: E = -f . (x - X), the negative work of dead nodal forces f [N]."""

    def __init__(self, forces: np.ndarray, reference: np.ndarray):
        self.forces = np.asarray(forces, dtype=float).reshape(reference.shape)
        self.reference = np.asarray(reference, dtype=float)

    def energy(self, x):
        return -float(np.sum(self.forces * (x - self.reference)))

    def gradient(self, x):
        return -self.forces.ravel()

    def hessian(self, x, project=False):
        n = x.size
        return sp.csr_matrix((n, n))

    def max_step(self, x, dx):
        return 1.0


def nodal_load(reference: np.ndarray, nodes, force) -> LinearTerm:
    """Dead force ``force`` [N] (length d; per unit thickness in 2D: N/mm) on each of ``nodes``."""
    f = np.zeros_like(reference, dtype=float)
    np.add.at(f, np.asarray(nodes), np.asarray(force, dtype=float))
    return LinearTerm(f, reference)


def surface_load(reference: np.ndarray, facets: np.ndarray, traction, facet_type: str | None = None) -> LinearTerm:
    """Dead traction ``traction`` [MPa] (length d) on reference boundary facets (nf, nfn).

    Consistent nodal forces f_a = sum over facets of the integral of N_a t dA (reference area).
    """
    facets = np.asarray(facets)
    d = reference.shape[1]
    if facet_type is None:
        facet_type = {(2, 2): "line2", (2, 3): "line3", (3, 3): "tri3", (3, 6): "tri6"}[(d, facets.shape[1])]
    fe = ELEMENTS[facet_type]
    N, dA, _ = facet_measure(fe, reference[facets])
    t = np.asarray(traction, dtype=float)
    nodal = np.einsum("qa,fq->fa", N, dA)  # integral of N_a over each facet
    f = np.zeros_like(reference, dtype=float)
    np.add.at(f, facets.ravel(), (nodal.ravel()[:, None] * t[None, :]))
    return LinearTerm(f, reference)


@dataclass(frozen=True)
class ScaledTerm:
    """``scale`` times another term (e.g. a load ramped with the load parameter s)."""

    term: EnergyTerm
    scale: float

    def energy(self, x):
        return self.scale * self.term.energy(x)

    def gradient(self, x):
        return self.scale * self.term.gradient(x)

    def hessian(self, x, project=False):
        return self.scale * self.term.hessian(x, project)

    def max_step(self, x, dx):
        return self.term.max_step(x, dx)


def body_load(reference: np.ndarray, cells: np.ndarray, element, force_density) -> LinearTerm:
    """Dead body force ``force_density`` [N/mm^3] (length d), e.g. density x gravity, on cells
    (ne, nen) of ``element``: consistent nodal forces f_a = integral of N_a b dV."""
    from hydrojam.fem.elements import physical_gradients

    cells = np.asarray(cells)
    _, dV = physical_gradients(element, reference[cells])
    N = element.shape(element.quad_points)
    nodal = np.einsum("qa,eq->ea", N, dV)
    f = np.zeros_like(reference, dtype=float)
    np.add.at(f, cells.ravel(), nodal.ravel()[:, None] * np.asarray(force_density, dtype=float)[None, :])
    return LinearTerm(f, reference)


class ViscousStabilization:
    """Artificial viscous damping of a load step (as ABAQUS's *STATIC, STABILIZE): the energy
    c/2 sum_a w_a |x_a - x_a^n|^2, with x^n the state at the start of the step (``begin_step``),
    w_a [mm^2 in 2D, mm^3 in 3D] the nodal share of the reference volume and c [N/mm^4 in 3D;
    N/mm^3 per unit depth in 2D] the damping.

    It stiffens only what has no stiffness of its own (a buckling particle column, a particle's
    rigid rotation, a soft membrane's bending) so that a step through a snap travels gradually
    instead of being a Newton step into the unknown; its force c w (x - x^n) is not part of the
    physics and must be released at the end (``scale`` = 0) or shown to be small.
    """

    def __init__(self, weights: np.ndarray, damping: float, dim: int):
        self.weights = np.repeat(np.asarray(weights, dtype=float), dim)
        self.damping = float(damping)
        self.scale = 1.0
        self.x_start: np.ndarray | None = None

    def begin_step(self, x: np.ndarray) -> None:
        self.x_start = np.array(x, dtype=float).ravel()

    def _c(self) -> np.ndarray:
        return self.scale * self.damping * self.weights

    def energy(self, x):
        if self.x_start is None:
            return 0.0
        dx = np.ravel(x) - self.x_start
        return 0.5 * float(np.sum(self._c() * dx * dx))

    def gradient(self, x):
        if self.x_start is None:
            return np.zeros(np.size(x))
        return self._c() * (np.ravel(x) - self.x_start)

    def hessian(self, x, project=False):
        c = self._c() if self.x_start is not None else np.zeros(np.size(x))
        return sp.diags(c, format="csr")

    def max_step(self, x, dx):
        return 1.0


def lumped_volumes(points: np.ndarray, cells: np.ndarray, cell_volumes: np.ndarray) -> np.ndarray:
    """Nodal share of the volume [mm^3, mm^2 in 2D]: each cell's volume split evenly over its nodes."""
    n_per = cells.shape[1]
    return np.bincount(cells.ravel(), weights=np.repeat(cell_volumes / n_per, n_per), minlength=len(points))
