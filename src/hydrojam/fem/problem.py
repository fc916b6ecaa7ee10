"""What the solver solves: Dirichlet conditions and the load-path problem (docs/solver.md).

Dirichlet conditions eliminate DOFs; a :class:`Problem` gives the energy terms at every load
parameter s in [0, 1] (see :mod:`hydrojam.fem.terms` for the term protocol).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from hydrojam.fem.terms import EnergyTerm


@dataclass(frozen=True)
class Dirichlet:
    """Prescribed DOFs: x[dof] = X[dof] + s * displacement at load parameter s.

    Parameters
    ----------
    dofs : ndarray of int
        Indices into the flat position vector (dof = node*d + component).
    displacement : ndarray of float
        Displacement of each DOF at s = 1 [mm].
    """

    dofs: np.ndarray
    displacement: np.ndarray

    def values(self, X_flat: np.ndarray, s: float) -> np.ndarray:
        """Prescribed positions [mm] of ``dofs`` at load parameter s, from the flat reference X."""
        return X_flat[self.dofs] + s * self.displacement


def fixed(nodes, dim: int, components: Sequence[int] | None = None) -> Dirichlet:
    """Hold nodes at their reference positions (all components, or the given ones).

    Parameters
    ----------
    nodes : array_like of int
        The nodes.
    dim : int
        Spatial dimension d.
    components : sequence of int, optional
        The components held (default: all).

    Returns
    -------
    Dirichlet
    """
    comps = range(dim) if components is None else components
    nodes = np.asarray(nodes, dtype=np.int64)
    dofs = (nodes[:, None] * dim + np.asarray(list(comps))[None, :]).ravel()
    return Dirichlet(dofs, np.zeros(len(dofs)))


def prescribed(nodes, dim: int, component: int, displacement: float) -> Dirichlet:
    """Move one component of nodes by a displacement at s = 1 (linear in s).

    Parameters
    ----------
    nodes : array_like of int
        The nodes.
    dim : int
        Spatial dimension d.
    component : int
        The component moved.
    displacement : float
        The displacement at s = 1 [mm].

    Returns
    -------
    Dirichlet
    """
    nodes = np.asarray(nodes, dtype=np.int64)
    return Dirichlet(nodes * dim + component, np.full(len(nodes), float(displacement)))


@dataclass(frozen=True)
class Problem:
    """What the load-path driver solves.

    Parameters
    ----------
    X : ndarray, shape (n, d)
        Reference positions [mm].
    terms : callable
        ``terms(s)``: the energy terms at load parameter s in [0, 1] (materials at the stimulus of
        s, loads scaled by s, ...), a list summed in order whose ``name`` attributes are unique
        (:func:`hydrojam.fem.terms.by_name` addresses them).
    dirichlet : list of Dirichlet, optional
        The prescribed DOFs.
    force_scale : float, optional
        Sets the floor of the residual tolerance [N].
    """

    X: np.ndarray
    terms: Callable[[float], list[EnergyTerm]]
    dirichlet: list[Dirichlet] = field(default_factory=list)
    force_scale: float = 1.0

    @property
    def ndof(self) -> int:
        """Number of DOFs (n*d)."""
        return self.X.size

    def free_mask(self) -> np.ndarray:
        """(n*d,) bool: True where no Dirichlet condition holds the DOF."""
        free = np.ones(self.ndof, dtype=bool)
        for bc in self.dirichlet:
            free[bc.dofs] = False
        return free

    def apply_dirichlet(self, x_flat: np.ndarray, s: float) -> None:
        """Set the prescribed DOFs of the flat positions ``x_flat`` [mm] to their values at s."""
        X = self.X.ravel()
        for bc in self.dirichlet:
            x_flat[bc.dofs] = bc.values(X, s)
