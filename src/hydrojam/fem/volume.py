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

import numpy as np
import scipy.sparse as sp

from hydrojam.fem.terms import EnergyTerm, PressureTerm

#: ``controller(volumes) -> (targets, stiffnesses)``: both (n_bodies,), from the bodies' volumes
#: at the start of a load step
Controller = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


class VolumeTerm(EnergyTerm):
    """E = sum_b k_b/2 (V_b(x) - Vbar_b)^2 over bodies (see the module docstring), named "volume".

    ``reference`` (n, d) [mm]; ``bodies``: per body its (cells, boundary facets), facets
    line2/line3 in 2D, tri3/tri6 in 3D, each set closing the body's surface (oriented here with
    the body's cells). ``controller``: called at every ``begin_step`` with the bodies' volumes
    there; it returns the targets [mm^2 or mm^3] and stiffnesses (>= 0) for the step. Before the
    first step (and with no controller) the stiffnesses are 0: the term is zero.
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
