"""The one protocol of everything the solver minimises: an *energy term* (DESIGN.md section 8).

A term is a subclass of :class:`EnergyTerm`. For nodal positions ``x`` of shape (n_nodes, d)
[mm] it gives

* ``energy(x)`` [mJ; mJ/mm in 2D], ``+inf`` for an inadmissible state (required);
* ``gradient(x)`` [N] as a flat vector of length n_nodes*d, dof = node*d + component (required);
* ``hessian(x, project=False)`` [N/mm], sparse (n*d, n*d); with ``project`` made positive
  semi-definite (per element or per contact) (required);

and may override these optional parts, whose defaults are what a term without them means:

* ``max_step(x, dx) -> 1.0``: the largest alpha in (0, 1] for which x + alpha dx is safe for
  this term (contact: continuous collision detection);
* ``begin_step(x) -> None``: freeze quantities lagged over a load step (friction, the centre of
  a viscous stabilisation), called by the load path at the start of every step;
* ``force_flux(x, gradient=None)``: the forces in play for the convergence test, per DOF [N];
  default: this term's own gradient (``gradient`` if the caller has it at x already). A solid
  returns its internal-force flux, summed without the cancellation of assembly;
* ``fallback_projection = False``: True asks the solver to re-assemble this term's Hessian with
  ``project=True`` when the exact Hessian gives no descent, before damping the whole system;
* ``name``: what the term is called in a problem ("elastic", "contact", "stabilisation",
  "load", ...). A problem's terms are a list, summed in order; :func:`by_name` addresses them by
  name (names are unique within a problem).

The solver sums terms and calls only these members, unconditionally: a term that misspells one
gets the default from this class or fails loudly as an abstract class. External loads are terms
too (minus their work), so a new physics is a new term, not a branch in the solver.
"""

from __future__ import annotations

import abc
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from hydrojam.fem.elements import ELEMENTS, facet_measure, physical_gradients


class EnergyTerm(abc.ABC):
    """A contribution to the total potential energy (see the module docstring for the protocol)."""

    name: str = "term"
    """What the term is called in a problem; unique among a problem's terms."""

    fallback_projection: bool = False
    """True: re-assemble this term's Hessian projected when the exact Hessian gives no descent."""

    @abc.abstractmethod
    def energy(self, x: np.ndarray) -> float:
        """Energy [mJ] at positions x (n, d) [mm]; +inf if x is inadmissible."""

    @abc.abstractmethod
    def gradient(self, x: np.ndarray) -> np.ndarray:
        """dE/dx [N], flat (n*d,)."""

    @abc.abstractmethod
    def hessian(self, x: np.ndarray, project: bool = False) -> sp.csr_matrix:
        """d2E/dx2 [N/mm], (n*d, n*d); ``project``: made positive semi-definite."""

    def max_step(self, x: np.ndarray, dx: np.ndarray) -> float:
        """Largest alpha in (0, 1] such that x + alpha dx is safe for this term; 1.0: no limit."""
        return 1.0

    def begin_step(self, x: np.ndarray) -> None:
        """Freeze lagged quantities at the start of a load step at positions x [mm]; none here."""
        return None

    def force_flux(self, x: np.ndarray, gradient: np.ndarray | None = None) -> np.ndarray:
        """Forces in play per DOF [N] for the convergence test: this term's gradient at x
        (``gradient``, when the caller has computed it at x, is returned as it is)."""
        return self.gradient(x) if gradient is None else gradient


def by_name(terms: Iterable[EnergyTerm]) -> dict[str, EnergyTerm]:
    """The terms of a problem keyed by their ``name``, in order; ValueError on a repeated name."""
    out: dict[str, EnergyTerm] = {}
    for t in terms:
        if t.name in out:
            raise ValueError(f"two energy terms are named {t.name!r}; names must be unique in a problem")
        out[t.name] = t
    return out


class LinearTerm(EnergyTerm):
    """A term linear in x: E = -f . (x - X), the negative work of dead nodal forces f [N]."""

    def __init__(self, forces: np.ndarray, reference: np.ndarray, name: str = "load"):
        self.forces = np.asarray(forces, dtype=float).reshape(reference.shape)
        self.reference = np.asarray(reference, dtype=float)
        self.name = name

    def energy(self, x):
        return -float(np.sum(self.forces * (x - self.reference)))

    def gradient(self, x):
        return -self.forces.ravel()

    def hessian(self, x, project=False):
        n = x.size
        return sp.csr_matrix((n, n))


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


class TimedTerm(EnergyTerm):
    """Another term with every protocol member passed through, and the wall time [s] of each call
    reported as ``record(method_name, seconds)`` (the time shares of simulations and benchmarks)."""

    def __init__(self, term: EnergyTerm, record: Callable[[str, float], None]):
        self._term, self._record = term, record

    @property
    def name(self) -> str:
        return self._term.name

    @property
    def fallback_projection(self) -> bool:
        return self._term.fallback_projection

    def _timed(self, method: str, *args):
        t0 = time.perf_counter()
        try:
            return getattr(self._term, method)(*args)
        finally:
            self._record(method, time.perf_counter() - t0)

    def energy(self, x):
        return self._timed("energy", x)

    def gradient(self, x):
        return self._timed("gradient", x)

    def hessian(self, x, project=False):
        return self._timed("hessian", x, project)

    def max_step(self, x, dx):
        return self._timed("max_step", x, dx)

    def begin_step(self, x):
        return self._timed("begin_step", x)

    def force_flux(self, x, gradient=None):
        return self._timed("force_flux", x, gradient)


@dataclass(frozen=True)
class ScaledTerm(EnergyTerm):
    """``scale`` times another term (e.g. a load ramped with the load parameter s); every
    optional part is the wrapped term's (its forces in play scaled too), and so is its name."""

    term: EnergyTerm
    scale: float

    @property
    def name(self) -> str:
        return self.term.name

    @property
    def fallback_projection(self) -> bool:
        return self.term.fallback_projection

    def energy(self, x):
        return self.scale * self.term.energy(x)

    def gradient(self, x):
        return self.scale * self.term.gradient(x)

    def hessian(self, x, project=False):
        return self.scale * self.term.hessian(x, project)

    def max_step(self, x, dx):
        return self.term.max_step(x, dx)

    def begin_step(self, x):
        self.term.begin_step(x)

    def force_flux(self, x, gradient=None):
        return self.scale * self.term.force_flux(x)


def body_load(reference: np.ndarray, cells: np.ndarray, element, force_density) -> LinearTerm:
    """Dead body force ``force_density`` [N/mm^3] (length d), e.g. density x gravity, on cells
    (ne, nen) of ``element``: consistent nodal forces f_a = integral of N_a b dV."""
    cells = np.asarray(cells)
    _, dV = physical_gradients(element, reference[cells])
    N = element.shape(element.quad_points)
    nodal = np.einsum("qa,eq->ea", N, dV)
    f = np.zeros_like(reference, dtype=float)
    np.add.at(f, cells.ravel(), nodal.ravel()[:, None] * np.asarray(force_density, dtype=float)[None, :])
    return LinearTerm(f, reference)


class ViscousStabilisation(EnergyTerm):
    """Artificial viscous damping of a load step (as ABAQUS's *STATIC, STABILIZE): the energy
    c/2 sum_a w_a |x_a - x_a^n|^2, with x^n the state at the start of the step (``begin_step``),
    w_a [mm^2 in 2D, mm^3 in 3D] the nodal share of the reference volume and c [N/mm^4 in 3D;
    N/mm^3 per unit depth in 2D] the damping.

    It stiffens only what has no stiffness of its own (a buckling particle column, a particle's
    rigid rotation, a soft membrane's bending) so that a step through a snap travels gradually
    instead of being a Newton step into the unknown; its force c w (x - x^n) is not part of the
    physics and must be released at the end (``scale`` = 0) or shown to be small.
    """

    def __init__(self, weights: np.ndarray, damping: float, dim: int, name: str = "stabilisation"):
        self.name = name
        self.weights = np.repeat(np.asarray(weights, dtype=float), dim)
        self.damping = float(damping)
        self.scale = 1.0
        self.x_start: np.ndarray | None = None

    def begin_step(self, x: np.ndarray) -> None:
        """Centre the damping on the state x [mm] at the start of the step."""
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


def lumped_volumes(points: np.ndarray, cells: np.ndarray, cell_volumes: np.ndarray) -> np.ndarray:
    """Nodal share of the volume [mm^3, mm^2 in 2D]: each cell's volume split evenly over its nodes."""
    n_per = cells.shape[1]
    return np.bincount(cells.ravel(), weights=np.repeat(cell_volumes / n_per, n_per), minlength=len(points))
