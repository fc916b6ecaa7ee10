"""Finite-strain solid bodies as energy terms: vectorised element kernels and sparse assembly.

A :class:`Solid` holds the reference geometry of one or more element blocks over one global node
set (blocks that share nodes are bonded), each block with its own material. The sparsity pattern,
the scatter indices and the shape-function gradients are built once; every evaluation is a few
batched numpy kernels and one ``bincount`` per output. The FE layer knows nothing about what a
material models: it only calls ``energy(F)`` and ``evaluate(F)``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from hydrojam.fem.elements import ReferenceElement, physical_gradients
from hydrojam.fem.terms import EnergyTerm
from hydrojam.materials.energies import Material


@dataclass(frozen=True)
class Block:
    """Cells (ne, nen) of one element type and one material, in global node numbers; ``name``
    addresses the block in its Solid (unique there)."""

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


class Solid(EnergyTerm):
    """Elastic energy of element blocks over reference positions X (n_nodes, d) [mm]; an energy term.

    Blocks are addressed by their (unique) names: :meth:`with_materials` takes, and the per-block
    results return, mappings block name -> value, in block order. In 2D (plane strain) energies
    are per unit thickness [mJ/mm] and forces [N/mm].
    """

    def __init__(self, X: np.ndarray, blocks: list[Block], name: str = "elastic"):
        names = [b.name for b in blocks]
        if len(set(names)) != len(names):
            raise ValueError(f"block names must be unique in a Solid (got {names})")
        self.name = name
        self.X = np.asarray(X, dtype=float)
        self.blocks = list(blocks)
        self._geoms = [_block_geometry(self.X, b) for b in self.blocks]
        self.ndof = self.X.size
        self._pat = _pattern(self._geoms, self.ndof)
        self._flux = None

    @property
    def dim(self) -> int:
        return self.X.shape[1]

    @property
    def block_names(self) -> list[str]:
        """Names of the blocks, in order."""
        return [b.name for b in self.blocks]

    def with_materials(self, materials: Mapping[str, Material]) -> "Solid":
        """The same geometry with other materials, given by block name ({name: Material}), e.g. at
        a new stimulus; a block not named keeps its material. KeyError for an unknown name."""
        if not isinstance(materials, Mapping):
            raise TypeError(f"materials must be a mapping block name -> Material (got {type(materials).__name__})")
        unknown = set(materials) - set(self.block_names)
        if unknown:
            raise KeyError(f"no block named {sorted(unknown)}; blocks: {self.block_names}")
        new = object.__new__(Solid)
        new.__dict__.update(self.__dict__)
        new.blocks = [dataclasses.replace(b, material=materials[b.name]) if b.name in materials else b
                      for b in self.blocks]
        new._flux = None  # computed with the old materials
        return new

    def _F(self, x: np.ndarray, g: _Geometry) -> np.ndarray:
        return np.einsum("eai,eqaj->eqij", x[g.cells], g.dNdX, optimize=True)

    def deformation_gradients(self, x: np.ndarray) -> dict[str, np.ndarray]:
        """F at every quadrature point, per block name: {name: (ne, nq, d, d)}."""
        return {b.name: self._F(x, g) for b, g in zip(self.blocks, self._geoms)}

    def current_volumes(self, x: np.ndarray) -> dict[str, np.ndarray]:
        """Current volume of each cell, per block name: {name: (ne,)}, the integral of det F over
        the reference [mm^3, or mm^2 in 2D]."""
        return {b.name: np.sum(np.linalg.det(self._F(x, g)) * g.dV, axis=1) for b, g in zip(self.blocks, self._geoms)}

    def energy(self, x: np.ndarray) -> float:
        total = 0.0
        for b, g in zip(self.blocks, self._geoms):
            W = b.material.energy(self._F(x, g))
            e = float(np.sum(W * g.dV))
            if not np.isfinite(e):
                return np.inf
            total += e
        return total

    def block_energies(self, x: np.ndarray) -> dict[str, float]:
        """Energy of each block [mJ; mJ/mm in 2D], per block name."""
        return {b.name: float(np.sum(b.material.energy(self._F(x, g)) * g.dV)) for b, g in zip(self.blocks, self._geoms)}

    def gradient(self, x: np.ndarray) -> np.ndarray:
        out = np.zeros(self.ndof)
        flux = np.zeros(self.ndof)
        for b, g in zip(self.blocks, self._geoms):
            P = b.material.evaluate(self._F(x, g), tangent=False).stress
            fe = np.einsum("eq,eqij,eqaj->eai", g.dV, P, g.dNdX, optimize=True)  # element forces [N]
            out += np.bincount(g.edofs.ravel(), weights=fe.ravel(), minlength=self.ndof)
            flux += np.bincount(g.edofs.ravel(), weights=np.abs(fe).ravel(), minlength=self.ndof)
        self._flux = (np.asarray(x).tobytes(), flux)  # the solver asks for it at the same x next
        return out

    def force_flux(self, x: np.ndarray, gradient: np.ndarray | None = None) -> np.ndarray:
        """Nodal sums of |element internal forces| [N], per DOF: the forces flowing through the
        body without the cancellation of assembly (large in a swollen body whose net force is 0).
        ``gradient`` is not needed."""
        if self._flux is None or self._flux[0] != np.asarray(x).tobytes():
            self.gradient(x)
        return self._flux[1]

    def element_hessians(self, x: np.ndarray, project: bool = False) -> list[np.ndarray]:
        """Element stiffness matrices per block, in block order [(ne, nen*d, nen*d)] [N/mm]."""
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
