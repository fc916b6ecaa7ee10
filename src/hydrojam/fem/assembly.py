"""Finite-strain solid bodies as energy terms: vectorised element kernels and sparse assembly.

A :class:`Solid` holds the reference geometry of one or more element blocks over one global node
set (blocks that share nodes are bonded), each block with its own material. The sparsity pattern,
the scatter indices and the shape-function gradients are built once; every evaluation is a few
batched numpy kernels and one ``bincount`` per output. The FE layer knows nothing about what a
material models: it only calls ``energy(F)`` and ``evaluate(F)``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from hydrojam.fem.elements import ReferenceElement, physical_gradients
from hydrojam.materials.energies import Material


@dataclass(frozen=True)
class Block:
    """Cells (ne, nen) of one element type and one material, in global node numbers."""

    cells: np.ndarray
    element: ReferenceElement
    material: Material
    name: str = ""


@dataclass(frozen=True)
class _Geometry:
    cells: np.ndarray  # (ne, nen)
    dNdX: np.ndarray  # (ne, nq, nen, d)
    dV: np.ndarray  # (ne, nq)
    edofs: np.ndarray  # (ne, nen*d)


def _block_geometry(X: np.ndarray, block: Block) -> _Geometry:
    d = X.shape[1]
    cells = np.asarray(block.cells, dtype=np.int64)
    dNdX, dV = physical_gradients(block.element, X[cells])
    edofs = (cells[:, :, None] * d + np.arange(d)).reshape(len(cells), -1)
    return _Geometry(cells, dNdX, dV, edofs)


@dataclass(frozen=True)
class _Pattern:
    """CSR structure of the sum of all element matrices, and where each entry lands in it."""

    indptr: np.ndarray
    indices: np.ndarray
    slots: list[np.ndarray]  # per block: (ne*nedof*nedof,) positions in the CSR data
    n: int

    def matrix(self, values: list[np.ndarray]) -> sp.csr_matrix:
        data = np.zeros(len(self.indices))
        for slot, v in zip(self.slots, values):
            data += np.bincount(slot, weights=v.ravel(), minlength=len(self.indices))
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))


def _pattern(geoms: list[_Geometry], n: int) -> _Pattern:
    keys = []
    for g in geoms:
        e = g.edofs
        keys.append((e[:, :, None] * n + e[:, None, :]).ravel())
    allkeys = np.concatenate(keys)
    uniq, inv = np.unique(allkeys, return_inverse=True)
    rows, cols = np.divmod(uniq, n)
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.add.at(indptr, rows + 1, 1)
    indptr = np.cumsum(indptr)
    slots, start = [], 0
    for k in keys:
        slots.append(inv[start : start + len(k)])
        start += len(k)
    return _Pattern(indptr, cols.astype(np.int32), slots, n)


def project_psd(K: np.ndarray) -> np.ndarray:
    """Element matrices (ne, m, m) with negative eigenvalues clamped to zero (symmetrised first)."""
    K = 0.5 * (K + np.swapaxes(K, -1, -2))
    w, V = np.linalg.eigh(K)
    if np.all(w >= 0):
        return K
    w = np.maximum(w, 0.0)
    return np.einsum("eij,ej,ekj->eik", V, w, V)


class Solid:
    """Elastic energy of element blocks over reference positions X (n_nodes, d) [mm]; an energy term.

    In 2D (plane strain) energies are per unit thickness [mJ/mm] and forces [N/mm].
    """

    def __init__(self, X: np.ndarray, blocks: list[Block]):
        self.X = np.asarray(X, dtype=float)
        self.blocks = list(blocks)
        self._geoms = [_block_geometry(self.X, b) for b in self.blocks]
        self.ndof = self.X.size
        self._pat = _pattern(self._geoms, self.ndof)
        self._flux = None

    @property
    def dim(self) -> int:
        return self.X.shape[1]

    def with_materials(self, materials: list[Material]) -> "Solid":
        """The same geometry with other materials (one per block), e.g. at a new stimulus."""
        new = object.__new__(Solid)
        new.__dict__.update(self.__dict__)
        new.blocks = [dataclasses.replace(b, material=m) for b, m in zip(self.blocks, materials)]
        new._flux = None  # computed with the old materials
        return new

    def _F(self, x: np.ndarray, g: _Geometry) -> np.ndarray:
        return np.einsum("eai,eqaj->eqij", x[g.cells], g.dNdX, optimize=True)

    def deformation_gradients(self, x: np.ndarray) -> list[np.ndarray]:
        """F at every quadrature point of every block, [(ne, nq, d, d)]."""
        return [self._F(x, g) for g in self._geoms]

    def volumes(self) -> list[np.ndarray]:
        """Reference volume of each cell per block [mm^3, or mm^2 in 2D]."""
        return [g.dV.sum(axis=1) for g in self._geoms]

    def current_volumes(self, x: np.ndarray) -> list[np.ndarray]:
        """Current volume of each cell per block, the integral of det F over the reference
        [mm^3, or mm^2 in 2D]."""
        return [np.sum(np.linalg.det(self._F(x, g)) * g.dV, axis=1) for g in self._geoms]

    def energy(self, x: np.ndarray) -> float:
        total = 0.0
        for b, g in zip(self.blocks, self._geoms):
            W = b.material.energy(self._F(x, g))
            e = float(np.sum(W * g.dV))
            if not np.isfinite(e):
                return np.inf
            total += e
        return total

    def block_energies(self, x: np.ndarray) -> list[float]:
        """Energy of each block [mJ]."""
        return [float(np.sum(b.material.energy(self._F(x, g)) * g.dV)) for b, g in zip(self.blocks, self._geoms)]

    def _element_forces(self, x: np.ndarray):
        """(geometry, element internal forces (ne, nen, d) [N]) for every block."""
        for b, g in zip(self.blocks, self._geoms):
            P = b.material.evaluate(self._F(x, g), tangent=False).stress
            yield g, np.einsum("eq,eqij,eqaj->eai", g.dV, P, g.dNdX, optimize=True)

    def gradient(self, x: np.ndarray) -> np.ndarray:
        out = np.zeros(self.ndof)
        flux = np.zeros(self.ndof)
        for g, fe in self._element_forces(x):
            out += np.bincount(g.edofs.ravel(), weights=fe.ravel(), minlength=self.ndof)
            flux += np.bincount(g.edofs.ravel(), weights=np.abs(fe).ravel(), minlength=self.ndof)
        self._flux = (np.asarray(x).tobytes(), flux)  # the solver asks for it at the same x next
        return out

    def force_flux(self, x: np.ndarray) -> np.ndarray:
        """Nodal sums of |element internal forces| [N], per DOF: the forces flowing through the
        body without the cancellation of assembly (large in a swollen body whose net force is 0)."""
        if self._flux is None or self._flux[0] != np.asarray(x).tobytes():
            self.gradient(x)
        return self._flux[1]

    def element_forces(self, x: np.ndarray) -> list[np.ndarray]:
        """Internal nodal forces of every element, per block [(ne, nen, d)] [N]."""
        return [fe for _, fe in self._element_forces(x)]

    def element_hessians(self, x: np.ndarray, project: bool = False) -> list[np.ndarray]:
        """Element stiffness matrices per block, [(ne, nen*d, nen*d)] [N/mm]."""
        out = []
        for b, g in zip(self.blocks, self._geoms):
            A = b.material.evaluate(self._F(x, g), tangent=True).tangent
            ne, nq, nen, d = g.dNdX.shape
            AG = np.einsum("eqijkl,eqbl->eqijkb", A, g.dNdX, optimize=True)
            Ke = np.einsum("eq,eqaj,eqijkb->eaibk", g.dV, g.dNdX, AG, optimize=True).reshape(ne, nen * d, nen * d)
            out.append(project_psd(Ke) if project else Ke)
        return out

    def hessian(self, x: np.ndarray, project: bool = False) -> sp.csr_matrix:
        return self._pat.matrix(self.element_hessians(x, project))

    def max_step(self, x: np.ndarray, dx: np.ndarray) -> float:
        return 1.0
