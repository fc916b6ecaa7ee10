"""The one protocol of everything the solver minimises: an *energy term* (docs/solver.md, "The energy and its terms").

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
* ``hessian_pattern(x) -> None``: a sparsity pattern (n*d, n*d) that holds this term's Hessian
  at x and at the states near x, where the Hessian's own pattern changes from state to state
  (contact: every coupling of the pairs within reach); None: the Hessian's own pattern. The
  solver hands it to the linear solver as a hint (:meth:`hydrojam.fem.solver.linsolve.LinearSolver.solve`);
  no result depends on it;
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
import itertools
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

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

    def hessian_pattern(self, x: np.ndarray) -> sp.spmatrix | None:
        """A sparsity pattern (n*d, n*d) holding the Hessian at x [mm] and near it; None: the
        Hessian's own pattern, the same at every state."""
        return None

    def force_flux(self, x: np.ndarray, gradient: np.ndarray | None = None) -> np.ndarray:
        """Forces in play per DOF [N] for the convergence test: this term's gradient at x
        (``gradient``, when the caller has computed it at x, is returned as it is)."""
        return self.gradient(x) if gradient is None else gradient


@runtime_checkable
class DampedTerm(Protocol):
    """A term whose weight the load path adapts (the term named "stabilisation" of a load path,
    a :class:`ViscousStabilisation`): ``scale`` [-] multiplies its energy, 0 switches it off."""

    name: str
    scale: float

    def energy(self, x: np.ndarray) -> float: ...

    def begin_step(self, x: np.ndarray) -> None: ...


def by_name(terms: Iterable[EnergyTerm]) -> dict[str, EnergyTerm]:
    """The terms of a problem keyed by their ``name``, in order; ValueError on a repeated name."""
    out: dict[str, EnergyTerm] = {}
    for t in terms:
        if t.name in out:
            raise ValueError(f"two energy terms are named {t.name!r}; names must be unique in a problem")
        out[t.name] = t
    return out


class LinearTerm(EnergyTerm):
    """A term linear in x: E = -f . (x - X), the negative work of dead nodal forces f.

    Parameters
    ----------
    forces : ndarray, shape (n, d)
        Nodal forces f [N; N/mm per unit depth in 2D].
    reference : ndarray, shape (n, d)
        Reference positions X [mm].
    name : str, optional
        The term's name.
    """

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


_FACET_TYPES = {(2, 2): "line2", (2, 3): "line3", (3, 3): "tri3", (3, 6): "tri6"}
# node permutation that reverses a facet's orientation (meshio order: corners, then mid-edge
# nodes of edges (0,1), (1,2), (2,0) for a triangle)
_REVERSED = {"line2": [1, 0], "line3": [1, 0, 2], "tri3": [0, 2, 1], "tri6": [0, 2, 1, 5, 4, 3]}


def _facet_type_of(d: int, nfn: int) -> str:
    try:
        return _FACET_TYPES[(d, nfn)]
    except KeyError:
        raise ValueError(f"no facet type with {nfn} nodes in {d}D (expected line2/line3 in 2D, tri3/tri6 in 3D)") from None


def nodal_areas(reference: np.ndarray, facets: np.ndarray, facet_type: str | None = None) -> np.ndarray:
    """Consistent nodal areas (n,) of boundary ``facets`` (nf, nfn) at reference positions (n, d):
    a_a = sum over facets of the integral of N_a dA [mm^2; mm in 2D, per unit depth]."""
    reference = np.asarray(reference, dtype=float)
    facets = np.asarray(facets, dtype=np.int64)
    if facet_type is None:
        facet_type = _facet_type_of(reference.shape[1], facets.shape[1])
    N, dA, _ = facet_measure(ELEMENTS[facet_type], reference[facets])
    nodal = np.einsum("qa,fq->fa", N, dA)  # integral of N_a over each facet
    return np.bincount(facets.ravel(), weights=nodal.ravel(), minlength=len(reference))


def surface_load(reference: np.ndarray, facets: np.ndarray, traction, facet_type: str | None = None) -> LinearTerm:
    """Dead traction on reference boundary facets, as a linear term.

    Consistent nodal forces f_a = sum over facets of the integral of N_a t dA (reference area):
    :func:`nodal_areas` times t.

    Parameters
    ----------
    reference : ndarray, shape (n, d)
        Reference positions [mm].
    facets : ndarray, shape (nf, nfn)
        Boundary facets in node numbers.
    traction : array_like, shape (d,)
        The traction t [MPa].
    facet_type : str, optional
        The facets' element name (default: inferred from d and nfn).

    Returns
    -------
    LinearTerm
        Named "load"; nodal forces [N; N/mm per unit depth in 2D].
    """
    areas = nodal_areas(reference, facets, facet_type)
    return LinearTerm(areas[:, None] * np.asarray(traction, dtype=float)[None, :], reference)


class TimedTerm(EnergyTerm):
    """Another term with every protocol member passed through, and the wall time of each call
    reported (the time shares of simulations and benchmarks).

    Parameters
    ----------
    term : EnergyTerm
        The term wrapped.
    record : callable
        ``record(method_name, seconds)``, called after each call with its wall time [s].
    """

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

    def hessian_pattern(self, x):
        return self._timed("hessian_pattern", x)

    def begin_step(self, x):
        return self._timed("begin_step", x)

    def force_flux(self, x, gradient=None):
        return self._timed("force_flux", x, gradient)


@dataclass(frozen=True)
class ScaledTerm(EnergyTerm):
    """``scale`` times another term (e.g. a load ramped with the load parameter s).

    Every optional part is the wrapped term's (its forces in play scaled too), and so is its name.

    Parameters
    ----------
    term : EnergyTerm
        The term wrapped.
    scale : float
        The factor [-].
    """

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

    def hessian_pattern(self, x):
        return self.term.hessian_pattern(x)

    def begin_step(self, x):
        self.term.begin_step(x)

    def force_flux(self, x, gradient=None):
        return self.scale * self.term.force_flux(x)


def body_load(reference: np.ndarray, cells: np.ndarray, element, force_density) -> LinearTerm:
    """Dead body force on cells, as a linear term: consistent nodal forces f_a = integral of N_a b dV.

    Parameters
    ----------
    reference : ndarray, shape (n, d)
        Reference positions [mm].
    cells : ndarray, shape (ne, nen)
        The cells in node numbers.
    element : ReferenceElement
        The cells' element type.
    force_density : array_like, shape (d,)
        The body force b [N/mm^3], e.g. density x gravity.

    Returns
    -------
    LinearTerm
        Named "load"; nodal forces [N; N/mm per unit depth in 2D].
    """
    cells = np.asarray(cells)
    _, dV = physical_gradients(element, reference[cells])
    N = element.shape(element.quad_points)
    nodal = np.einsum("qa,eq->ea", N, dV)
    f = np.zeros_like(reference, dtype=float)
    np.add.at(f, cells.ravel(), nodal.ravel()[:, None] * np.asarray(force_density, dtype=float)[None, :])
    return LinearTerm(f, reference)


class ViscousStabilisation(EnergyTerm):
    """Artificial viscous damping of a load step (as ABAQUS's *STATIC, STABILIZE).

    The energy c/2 sum_a w_a |x_a - x_a^n|^2, with x^n the state at the start of the step
    (``begin_step``), w_a the nodal share of the reference volume and c the damping.

    It stiffens only what has no stiffness of its own (a buckling particle column, a particle's
    rigid rotation, a soft membrane's bending) so that a step through a snap travels gradually
    instead of being a Newton step into the unknown; its force c w (x - x^n) is not part of the
    physics and must be released at the end (``scale`` = 0) or shown to be small.

    Parameters
    ----------
    weights : ndarray, shape (n,)
        Nodal shares w_a of the reference volume [mm^2 in 2D, mm^3 in 3D].
    damping : float
        The damping c [N/mm^4 in 3D; N/mm^3 per unit depth in 2D].
    dim : int
        Spatial dimension d.
    name : str, optional
        The term's name.
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


# ----------------------------------------------------------------------------------------------
# Pressure


def outward_facets(reference: np.ndarray, cells: np.ndarray, facets: np.ndarray) -> np.ndarray:
    """The boundary ``facets`` (nf, nfn) of a body with ``cells`` (ne, nen), each reordered if
    needed so that its normal (:func:`~hydrojam.fem.elements.facet_measure`'s convention) points
    out of the cell it bounds, at reference positions (n, d) [mm]. ValueError for a facet that
    bounds no cell or more than one (not on the body's boundary)."""
    X = np.asarray(reference, dtype=float)
    cells = np.asarray(cells, dtype=np.int64)
    facets = np.array(facets, dtype=np.int64)
    d = X.shape[1]
    ftype = _facet_type_of(d, facets.shape[1])
    nc = d  # corners of a facet
    n_cell_corners = d + 1
    # cells x facets count of shared corner nodes: a facet's cell holds all its corners
    def incidence(rows):
        return sp.csr_matrix((np.ones(rows.size), rows.ravel(), np.arange(0, rows.size + 1, rows.shape[1])),
                             shape=(len(rows), len(X)))

    fc = facets[:, :nc]
    shared = (incidence(cells[:, :n_cell_corners]) @ incidence(fc).T).tocoo()
    full = shared.data == nc
    n_owners = np.bincount(shared.col[full], minlength=len(facets))
    if np.any(n_owners != 1):
        bad = int(np.flatnonzero(n_owners != 1)[0])
        raise ValueError(f"facet {bad} bounds {n_owners[bad]} cells; boundary facets bound exactly one")
    owners = np.empty(len(facets), dtype=np.int64)
    owners[shared.col[full]] = shared.row[full]
    centre = X[cells[owners, :n_cell_corners]].mean(axis=1)
    corners = X[fc]
    if d == 2:
        t = corners[:, 1] - corners[:, 0]
        n = np.column_stack([t[:, 1], -t[:, 0]])
    else:
        n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    inward = np.einsum("fi,fi->f", n, corners.mean(axis=1) - centre) < 0
    facets[inward] = facets[inward][:, _REVERSED[ftype]]
    return facets


def _volume_tensor(ftype: str) -> np.ndarray:
    """The symmetric tensor S of a facet type with V_f = (1/d) S x^d (x: the facet's flat nodal
    coordinates), V_f the facet's share of the enclosed area (2D) or volume (3D).

    2D: V_f = 1/2 int (x dz - z dx) = 1/2 sum_q w_q x(q) . R t(q) with t = dx/dxi and R the
    rotation (t_x, t_z) -> (t_z, -t_x): bilinear in the nodal coordinates. 3D: V_f = 1/3 int
    x . (dx/dxi1 x dx/dxi2) dxi, trilinear. The rules integrate the polynomials exactly."""
    fe = ELEMENTS[ftype]
    d, nfn = fe.dim + 1, fe.nen
    if d == 2:
        pts, w = _quadrature_for(fe, 2 * fe.order - 1)
        N, dN = fe.shape(pts), fe.grad(pts)[:, :, 0]
        M = np.einsum("q,qa,qb->ab", w, N, dN)
        eps = np.array([[0.0, 1.0], [-1.0, 0.0]])
        C = np.einsum("ab,ij->aibj", M, eps).reshape(nfn * d, nfn * d)
        return 0.5 * (C + C.T)
    pts, w = _quadrature_for(fe, 3 * fe.order - 2)
    N, dN = fe.shape(pts), fe.grad(pts)
    T = np.einsum("q,qa,qb,qc->abc", w, N, dN[:, :, 0], dN[:, :, 1])
    eps = np.zeros((3, 3, 3))
    eps[0, 1, 2] = eps[1, 2, 0] = eps[2, 0, 1] = 1.0
    eps[0, 2, 1] = eps[2, 1, 0] = eps[1, 0, 2] = -1.0
    K = np.einsum("abc,ijk->aibjck", T, eps).reshape((nfn * d,) * 3)
    return sum(np.transpose(K, p) for p in itertools.permutations(range(3))) / 6.0


def _quadrature_for(fe, degree: int):
    """Points and weights of a rule exact to ``degree`` (at least 1) on the reference ``fe``."""
    rule = fe.with_quadrature(max(int(degree), 1))
    return rule.quad_points, rule.quad_weights


class PressureTerm(EnergyTerm):
    """A uniform pressure on boundary facets of a body; an energy term named "pressure".

    Facets: line2/line3 in 2D (plane strain: energies per unit depth [mJ/mm], forces [N/mm]),
    tri3/tri6 in 3D.

    **Orientation.** The facets must point *out of the body* (normals as in
    :func:`~hydrojam.fem.elements.facet_measure`; mesh facet groups on the boundary are, and
    ``cells`` given here re-orients them with :func:`outward_facets`). Positive p then pushes
    on the body, against the outward normal, on every facet: an external pressure compresses
    the body, a pressure in a cavity inflates it. Negative p pulls (suction).

    **Follower** (``follower=True``, the default): the pressure of a gas or fluid acts on the
    *current* surface, with the force -p n da. It is conservative, E(x) = p V(x), where V is
    the area (2D) or volume (3D) enclosed by the facets' current positions and the origin:
    V = 1/d sum over facets of the integral of x . n da. V is a polynomial of the nodal
    coordinates (quadratic in 2D, cubic in 3D), integrated exactly, so E, its gradient and its
    Hessian (constant in 2D, linear in x in 3D, not symmetric-positive: ``project`` clips it per
    facet) are exact. This E is the pressure's potential when the facets form a closed surface,
    or an open one whose edge is held, or whose edge moves only within lines (2D) or planes
    (3D) through the origin (symmetry planes of a model cut through the origin). Use it for a
    vacuum or pneumatic pressure on the actuator.

    **Dead** (``follower=False``): the traction -p N on the reference normals, fixed nodal forces
    f_a = -p int N_a N dA (a :class:`LinearTerm`); right only while rotations are small.

    Parameters
    ----------
    reference : ndarray, shape (n, d)
        Reference positions [mm].
    facets : ndarray, shape (nf, nfn)
        The boundary facets, in node numbers.
    pressure : float
        The pressure p [MPa].
    follower : bool, optional
        A follower (True) or a dead (False) pressure.
    cells : ndarray, shape (ne, nen), optional
        The body's cells, to orient the facets outward.
    name : str, optional
        The term's name.
    """

    name = "pressure"

    def __init__(self, reference: np.ndarray, facets: np.ndarray, pressure: float, follower: bool = True,
                 cells: np.ndarray | None = None, name: str = "pressure"):
        self.reference = np.asarray(reference, dtype=float)
        facets = np.asarray(facets, dtype=np.int64)
        d = self.reference.shape[1]
        self.facet_type = _facet_type_of(d, facets.shape[1])
        if cells is not None:
            facets = outward_facets(self.reference, cells, facets)
        self.facets = facets
        self.pressure = float(pressure)
        self.follower = bool(follower)
        self.name = name
        self.dim = d
        self._S = _volume_tensor(self.facet_type)
        self._edofs = (facets[:, :, None] * d + np.arange(d)).reshape(len(facets), -1)
        n = len(self._edofs[0]) if len(facets) else 0
        self._rows = np.repeat(self._edofs, n, axis=1).ravel()
        self._cols = np.tile(self._edofs, (1, n)).ravel()
        self._dead = None
        if not self.follower:
            fe = ELEMENTS[self.facet_type]
            N, dA, normal = facet_measure(fe, self.reference[facets])
            f = np.zeros_like(self.reference)
            np.add.at(f, facets.ravel(), -self.pressure * np.einsum("qa,fq,fqi->fai", N, dA, normal).reshape(-1, d))
            self._dead = LinearTerm(f, self.reference, name)

    def volume(self, x: np.ndarray) -> float:
        """Area [mm^2] (2D) or volume [mm^3] (3D) enclosed by the facets at positions x (n, d)
        [mm] and the origin; for a closed outward surface the body's own area or volume."""
        xe = np.asarray(x, dtype=float).reshape(-1)[self._edofs]
        if self.dim == 2:
            return 0.5 * float(np.einsum("fp,pq,fq->", xe, self._S, xe))
        return float(np.einsum("pqr,fp,fq,fr->", self._S, xe, xe, xe)) / 3.0

    def energy(self, x):
        if self._dead is not None:
            return self._dead.energy(x)
        return self.pressure * self.volume(x)

    def gradient(self, x):
        if self._dead is not None:
            return self._dead.gradient(x)
        xe = np.asarray(x, dtype=float).reshape(-1)[self._edofs]
        if self.dim == 2:
            ge = xe @ self._S
        else:
            ge = np.einsum("pqr,fq,fr->fp", self._S, xe, xe)
        return np.bincount(self._edofs.ravel(), weights=self.pressure * ge.ravel(), minlength=np.size(x))

    def hessian(self, x, project=False):
        if self._dead is not None:
            return self._dead.hessian(x)
        n = np.size(x)
        if self.dim == 2:
            He = np.broadcast_to(self.pressure * self._S, (len(self._edofs),) + self._S.shape)
        else:
            xe = np.asarray(x, dtype=float).reshape(-1)[self._edofs]
            He = 2.0 * self.pressure * np.einsum("pqr,fr->fpq", self._S, xe)
        if project:
            lam, Q = np.linalg.eigh(He)
            He = np.einsum("fij,fj,fkj->fik", Q, np.maximum(lam, 0.0), Q)
        return sp.csr_matrix(sp.coo_matrix((np.ravel(He), (self._rows, self._cols)), shape=(n, n)))


# ----------------------------------------------------------------------------------------------
# Loads on a face: a resultant force and a spring on the face's centroid


def face_weights(reference: np.ndarray, facets: np.ndarray) -> np.ndarray:
    """Consistent nodal weights (n,) of boundary ``facets`` (nf, nfn) at reference positions
    (n, d) [mm]: w_a = int N_a dA / A over the facets (:func:`nodal_areas`), summing to 1.
    ``sum_a w_a x_a`` is the face's area-weighted mean position, the work-conjugate of a uniform
    traction on it."""
    areas = nodal_areas(reference, facets)
    return areas / areas.sum()


def resultant_load(reference: np.ndarray, facets: np.ndarray, force, name: str = "tip_force") -> LinearTerm:
    """A dead force spread over boundary facets as a uniform traction on their reference area.

    Nodal forces w_a F with the weights of :func:`face_weights`, so its work is
    F . (mean displacement of the face).

    Parameters
    ----------
    reference : ndarray, shape (n, d)
        Reference positions [mm].
    facets : ndarray, shape (nf, nfn)
        The boundary facets.
    force : array_like, shape (d,)
        The resultant F [N; N/mm per unit depth in 2D].
    name : str, optional
        The term's name.

    Returns
    -------
    LinearTerm
    """
    w = face_weights(reference, facets)
    return LinearTerm(w[:, None] * np.asarray(force, dtype=float)[None, :], reference, name)


class CentroidSpring(EnergyTerm):
    """A stiff linear spring between a face's mean position and a target.

    c(x) = sum_a w_a x_a (weights of :func:`face_weights`), E = k/2 sum_i (c_i - target_i)^2 over
    the ``components`` given. A penalty form of a prescribed face displacement that leaves the
    face free to rotate and deform (a pin or a frictionless stop, not a guided end);
    :meth:`reaction` is the force the spring exerts on the face [N] and the spring's stretch
    (c - target) is the constraint's error, F/k.

    Parameters
    ----------
    reference : ndarray, shape (n, d)
        Reference positions [mm].
    facets : ndarray, shape (nf, nfn)
        The face's boundary facets.
    target : array_like, shape (d,)
        The target position [mm].
    stiffness : float
        The stiffness k [N/mm; N/mm per unit depth in 2D].
    components : sequence of int, optional
        The components held.
    name : str, optional
        The term's name.
    """

    name = "tip_spring"

    def __init__(self, reference: np.ndarray, facets: np.ndarray, target, stiffness: float,
                 components=(0, 1), name: str = "tip_spring"):
        self.reference = np.asarray(reference, dtype=float)
        self.dim = self.reference.shape[1]
        self.weights = face_weights(self.reference, facets)
        self.nodes = np.flatnonzero(self.weights)
        self.components = tuple(int(c) for c in components)
        self.target = np.array(target, dtype=float)
        self.stiffness = float(stiffness)
        self.name = name

    def centroid(self, x: np.ndarray) -> np.ndarray:
        """The face's mean position c(x) (d,) [mm]."""
        return self.weights @ np.asarray(x, dtype=float).reshape(-1, self.dim)

    def _stretch(self, x) -> np.ndarray:
        e = np.zeros(self.dim)
        c = self.centroid(x)
        for i in self.components:
            e[i] = c[i] - self.target[i]
        return e

    def reaction(self, x: np.ndarray) -> np.ndarray:
        """Force (d,) [N; N/mm in 2D] the spring exerts on the face: -k (c - target)."""
        return -self.stiffness * self._stretch(x)

    def energy(self, x):
        e = self._stretch(x)
        return 0.5 * self.stiffness * float(e @ e)

    def gradient(self, x):
        return (self.weights[:, None] * (self.stiffness * self._stretch(x))[None, :]).ravel()

    def hessian(self, x, project=False):
        n = np.size(x)
        rows, cols, vals = [], [], []
        w = self.weights[self.nodes]
        for i in self.components:
            dofs = self.nodes * self.dim + i
            rows.append(np.repeat(dofs, len(dofs)))
            cols.append(np.tile(dofs, len(dofs)))
            vals.append(self.stiffness * np.outer(w, w).ravel())
        if not rows:
            return sp.csr_matrix((n, n))
        return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
