"""Volumes of bodies held near targets: the energy term :class:`VolumeTerm`.

Each body b (a set of cells, e.g. one gel particle) encloses the area (2D) or volume (3D)
V_b(x) of its boundary facets (:meth:`~hydrojam.fem.terms.PressureTerm.volume`: exact, with an
exact gradient and Hessian). The term is

    E(x) = sum_b k_b / 2 (V_b(x) - Vbar_b)^2

with a stiffness k_b [MPa/mm^2 in 2D per unit depth, MPa/mm^3 in 3D] and a target Vbar_b
[mm^2, mm^3] per body, both set at the start of every load step by a ``controller`` (``begin_step``):
a quadratic penalty (or the proximal term of an implicit gradient flow) on each body's volume. Its
Hessian is k_b grad V_b grad V_b^T (a dense block over the body's boundary DOFs, rank one, positive
semi-definite) plus k_b (V_b - Vbar_b) times the Hessian of V_b (per facet; ``project`` clips it
per facet as :class:`~hydrojam.fem.terms.PressureTerm` does). The dense block has (d m)^2 entries
for m boundary nodes: about 1e4 for a 2D particle of the actuator, but about 1e7 for a 3D sphere
of 900 boundary nodes, where it would dominate the sparse factorisation (see docs/kinetics.md).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from hydrojam.fem.assembly import Block, Solid
from hydrojam.fem.terms import EnergyTerm, PressureTerm
from hydrojam.materials.energies import MaterialResponse

#: ``controller(volumes) -> (targets, stiffnesses)``: both (n_bodies,), from the bodies' volumes
#: at the start of a load step
Controller = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


class VolumeTerm(EnergyTerm):
    """E = sum_b k_b/2 (V_b(x) - Vbar_b)^2 over bodies (see the module docstring), named "volume".

    Before the first step (and with no controller) the stiffnesses are 0: the term is zero.

    Parameters
    ----------
    reference : ndarray, shape (n, d)
        Reference positions [mm].
    bodies : sequence of (ndarray, ndarray)
        Per body its (cells, boundary facets); facets line2/line3 in 2D, tri3/tri6 in 3D, each
        set closing the body's surface (oriented here with the body's cells).
    controller : callable, optional
        ``controller(volumes) -> (targets, stiffnesses)``, called at every ``begin_step`` with
        the bodies' volumes there [mm^2 or mm^3]; it returns the targets [mm^2 or mm^3] and
        stiffnesses (>= 0) for the step.
    name : str, optional
        The term's name.
    """

    def __init__(self, reference: np.ndarray, bodies: Sequence[tuple[np.ndarray, np.ndarray]],
                 controller: Controller | None = None, name: str = "volume"):
        self.name = name
        reference = np.asarray(reference, dtype=float)
        # V and its derivatives through the follower pressure's exact formulas: p = +1 gives V,
        # grad V and the Hessian of V; p = -1 its negative, projected when k (V - Vbar) < 0
        self._plus = [PressureTerm(reference, facets, 1.0, cells=cells) for cells, facets in bodies]
        self._minus = [PressureTerm(reference, t.facets, -1.0) for t in self._plus]
        d = reference.shape[1]
        # every boundary DOF of a body: a fixed pattern for the rank-one block (a gradient entry
        # that happens to be zero must not change the sparsity pattern the linear solver sees)
        self._dofs = [np.unique(t.facets[:, :, None] * d + np.arange(d)) for t in self._plus]
        self.controller = controller
        n_b = len(self._plus)
        self.targets = np.zeros(n_b)
        self.stiffness = np.zeros(n_b)

    @property
    def n_bodies(self) -> int:
        return len(self._plus)

    def volumes(self, x: np.ndarray) -> np.ndarray:
        """Area [mm^2] (2D) or volume [mm^3] (3D) of every body at positions x (n, d) [mm]."""
        return np.array([t.volume(x) for t in self._plus])

    def begin_step(self, x: np.ndarray) -> None:
        """Targets and stiffnesses for the step from the controller, given the volumes at x."""
        if self.controller is not None:
            targets, stiffness = self.controller(self.volumes(x))
            self.targets = np.asarray(targets, dtype=float).copy()
            self.stiffness = np.asarray(stiffness, dtype=float).copy()
            if self.targets.shape != (self.n_bodies,) or self.stiffness.shape != (self.n_bodies,) \
                    or np.any(self.stiffness < 0):
                raise ValueError("the volume controller must return one target and one stiffness >= 0 per body")

    def _active(self):
        return [b for b in range(self.n_bodies) if self.stiffness[b] > 0]

    def energy(self, x):
        e = 0.0
        for b in self._active():
            e += 0.5 * self.stiffness[b] * (self._plus[b].volume(x) - self.targets[b]) ** 2
        return float(e)

    def gradient(self, x):
        g = np.zeros(np.size(x))
        for b in self._active():
            t = self._plus[b]
            g += self.stiffness[b] * (t.volume(x) - self.targets[b]) * t.gradient(x)
        return g

    def hessian(self, x, project=False):
        n = np.size(x)
        H = sp.csr_matrix((n, n))
        for b in self._active():
            t, k = self._plus[b], self.stiffness[b]
            idx = self._dofs[b]
            gv = t.gradient(x)
            rank_one = sp.coo_matrix((k * np.outer(gv[idx], gv[idx]).ravel(),
                                      (np.repeat(idx, idx.size), np.tile(idx, idx.size))), shape=(n, n))
            c = k * (t.volume(x) - self.targets[b])
            curvature = (t if c >= 0 else self._minus[b]).hessian(x, project)
            H = H + rank_one.tocsr() + abs(c) * curvature
        return H.tocsr()


# ----------------------------------------------------------------------------------------------
# The same, held point by point


def _cofactor(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """det F and its derivative, the cofactor matrix cof F = det F F^-T, for stacks of 2x2 or 3x3."""
    d = F.shape[-1]
    if d == 2:
        a, b, c, e = F[..., 0, 0], F[..., 0, 1], F[..., 1, 0], F[..., 1, 1]
        return a * e - b * c, np.stack([np.stack([e, -c], -1), np.stack([-b, a], -1)], -2)
    cof = np.stack([np.cross(F[..., 1, :], F[..., 2, :]), np.cross(F[..., 2, :], F[..., 0, :]),
                    np.cross(F[..., 0, :], F[..., 1, :])], -2)
    return np.einsum("...j,...j->...", F[..., 0, :], cof[..., 0, :]), cof


def _levi_civita(d: int) -> np.ndarray:
    if d == 2:
        return np.array([[0.0, 1.0], [-1.0, 0.0]])
    eps = np.zeros((3, 3, 3))
    eps[0, 1, 2] = eps[1, 2, 0] = eps[2, 0, 1] = 1.0
    eps[0, 2, 1] = eps[2, 1, 0] = eps[1, 0, 2] = -1.0
    return eps


@dataclass(frozen=True)
class _VolumePenalty:
    """The material W(F) = k/2 (det F - Jbar)^2 per reference volume [MPa], with k [MPa] and Jbar
    given per quadrature point, arrays (ne, nq) of the block it is evaluated on."""

    stiffness: np.ndarray
    targets: np.ndarray

    shear_modulus_ref = 0.0

    def energy(self, F):
        J, _ = _cofactor(F)
        return 0.5 * self.stiffness * (J - self.targets) ** 2

    def evaluate(self, F, tangent=True):
        J, cof = _cofactor(F)
        r = self.stiffness * (J - self.targets)
        W = 0.5 * r * (J - self.targets)
        P = r[..., None, None] * cof
        A = None
        if tangent:
            d = F.shape[-1]
            k = self.stiffness[..., None, None, None, None]
            A = k * np.einsum("...ij,...kl->...ijkl", cof, cof)
            eps = _levi_civita(d)
            if d == 2:  # cof_iJ = eps_ik eps_JL F_kL: d cof_iJ / d F_kL = eps_ik eps_JL
                dcof = np.einsum("ik,jl->ijkl", eps, eps)
                A = A + r[..., None, None, None, None] * dcof
            else:  # cof_iJ = 1/2 eps_ikm eps_JLN F_kL F_mN: d cof_iJ / d F_kL = eps_ikm eps_JLN F_mN
                A = A + r[..., None, None, None, None] * np.einsum("ikm,jln,...mn->...ijkl", eps, eps, F)
        return MaterialResponse(W, P, A)


#: ``controller(J) -> (targets, stiffnesses)``: both (ne, nq), from det F at the quadrature points
#: at the start of a load step
LocalController = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


class LocalVolumeTerm(EnergyTerm):
    """E = sum over quadrature points of k/2 (det F - Jbar)^2 dV over the cells of one element type,
    named "volume": the volume held point by point (every element's own water content, say).

    k and Jbar (det F from the reference) per quadrature point are set at every ``begin_step``
    by the controller from det F there (before the first step: k = 0, E = 0). Its Hessian has
    the sparsity of the cells' element matrices (no dense block, in 2D or 3D).

    Parameters
    ----------
    reference : ndarray, shape (n, d)
        Reference positions [mm].
    cells : ndarray, shape (ne, nen)
        The cells, in node numbers.
    element : ReferenceElement
        Their element type.
    controller : callable, optional
        ``controller(J) -> (Jbar, k)``, all of shape (ne, nq): from det F at the quadrature
        points at the start of a load step [-], the targets Jbar [-] and stiffnesses k [MPa].
    name : str, optional
        The term's name.
    """

    def __init__(self, reference: np.ndarray, cells: np.ndarray, element, controller: LocalController | None = None,
                 name: str = "volume"):
        self.name = name
        self.controller = controller
        cells = np.asarray(cells, dtype=np.int64)
        nq = len(element.quad_weights)
        zero = _VolumePenalty(np.zeros((len(cells), nq)), np.ones((len(cells), nq)))
        self._solid = Solid(reference, [Block(cells, element, zero, name)], name=name)

    def det_f(self, x: np.ndarray) -> np.ndarray:
        """det F at every quadrature point (ne, nq) at positions x (n, d) [mm]."""
        F = next(iter(self._solid.deformation_gradients(x).values()))
        return _cofactor(F)[0]

    def begin_step(self, x: np.ndarray) -> None:
        """Targets and stiffnesses for the step from the controller, given det F at x."""
        if self.controller is None:
            return
        J = self.det_f(x)
        targets, stiffness = (np.asarray(a, dtype=float) for a in self.controller(J))
        if targets.shape != J.shape or stiffness.shape != J.shape or np.any(stiffness < 0):
            raise ValueError("the local volume controller must return one target and one stiffness >= 0 per point")
        self._solid = self._solid.with_materials({self.name: _VolumePenalty(stiffness.copy(), targets.copy())})

    def energy(self, x):
        return self._solid.energy(x)

    def gradient(self, x):
        return self._solid.gradient(x)

    def hessian(self, x, project=False):
        return self._solid.hessian(x, project)
