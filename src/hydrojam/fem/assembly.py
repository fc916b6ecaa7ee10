"""Finite-strain solid bodies as energy terms: element kernels and sparse assembly.

A :class:`Solid` holds the reference geometry of one or more element blocks over one global node
set (blocks that share nodes are bonded), each block with its own material. The sparsity pattern,
the scatter indices and the shape-function gradients are built once. An evaluation runs on one
of two paths with the same mathematics (results equal up to round-off):

- compiled (the default): numba-compiled element loops (fem/_kernels.py) compute F, form each
  element's vector or matrix (PSD-projected per element if asked) and add it straight into the
  gradient or the CSR data array; the material is evaluated between them by its
  ``evaluate_compiled`` where it has one, by ``evaluate`` otherwise;
- numpy: a few batched numpy kernels and one ``bincount`` per output (``kernels="numpy"``, or
  ``HYDROJAM_COMPILED=0`` in the environment); the reference the compiled path is tested against.

The FE layer knows nothing about what a material models: it only calls ``energy(F)`` and
``evaluate(F)`` (or ``evaluate_compiled(F, order)``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from hydrojam.fem._env import flag
from hydrojam.fem.elements import ReferenceElement, physical_gradients
from hydrojam.fem.terms import EnergyTerm
from hydrojam.materials.energies import Material


@dataclass(frozen=True)
class Block:
    """Cells of one element type and one material, in global node numbers.

    Parameters
    ----------
    cells : ndarray, shape (ne, nen)
        The cells, in global node numbers.
    element : ReferenceElement
        Their element type.
    material : Material
        Their material (energy densities [MPa]).
    name : str, optional
        Addresses the block in its Solid (unique there).
    """

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
    return _Geometry(cells, np.ascontiguousarray(dNdX), np.ascontiguousarray(dV), edofs)


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
    """Elastic energy of element blocks over reference positions; an energy term.

    Blocks are addressed by their (unique) names: :meth:`with_materials` takes, and the per-block
    results return, mappings block name -> value, in block order. In 2D (plane strain) energies
    are per unit thickness [mJ/mm] and forces [N/mm].

    Parameters
    ----------
    X : ndarray, shape (n_nodes, d)
        Reference positions [mm].
    blocks : list of Block
        The element blocks, with unique names.
    name : str, optional
        The term's name.
    kernels : {"compiled", "numpy"}, optional
        The element kernels (see the module docstring); None: "compiled" unless the environment
        sets HYDROJAM_COMPILED=0.

    Raises
    ------
    ValueError
        For unknown ``kernels`` or block names that are not unique.
    """

    def __init__(self, X: np.ndarray, blocks: list[Block], name: str = "elastic", kernels: str | None = None):
        """``kernels``: "compiled" or "numpy" (see the module docstring); None: "compiled" unless
        the environment sets HYDROJAM_COMPILED=0."""
        if kernels is None:
            kernels = "compiled" if flag("HYDROJAM_COMPILED", True) else "numpy"
        if kernels not in ("compiled", "numpy"):
            raise ValueError(f'kernels must be "compiled" or "numpy" (got {kernels!r})')
        self.kernels = kernels
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

    @property
    def compiled(self) -> bool:
        """Whether evaluations take the compiled path."""
        return self.kernels == "compiled"

    def _F(self, x: np.ndarray, g: _Geometry) -> np.ndarray:
        if self.compiled:
            x = np.ascontiguousarray(x, dtype=float).reshape(-1, self.dim)
            return _kernels().deformation_gradients(x, g.cells, g.dNdX, (0,) * self.dim)
        return np.einsum("eai,eqaj->eqij", x[g.cells], g.dNdX, optimize=True)

    def _response(self, material: Material, F: np.ndarray, order: int):
        """W (order 0), P (order 1) or A (order 2) of ``material`` at F, by the path's means."""
        if self.compiled and hasattr(material, "evaluate_compiled"):
            r = material.evaluate_compiled(F, order)
        elif order == 0:
            return material.energy(F)
        else:
            r = material.evaluate(F, tangent=order == 2)
        return (r.energy, r.stress, r.tangent)[order]

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
            W = self._response(b.material, self._F(x, g), 0)
            e = float(np.sum(W * g.dV))
            if not np.isfinite(e):
                return np.inf
            total += e
        return total

    def block_energies(self, x: np.ndarray) -> dict[str, float]:
        """Energy of each block [mJ; mJ/mm in 2D], per block name."""
        return {b.name: float(np.sum(self._response(b.material, self._F(x, g), 0) * g.dV))
                for b, g in zip(self.blocks, self._geoms)}

    def gradient(self, x: np.ndarray) -> np.ndarray:
        out = np.zeros(self.ndof)
        flux = np.zeros(self.ndof)
        for b, g in zip(self.blocks, self._geoms):
            P = self._response(b.material, self._F(x, g), 1)
            if self.compiled:
                _kernels().scatter_forces(np.ascontiguousarray(P), g.dNdX, g.dV, g.edofs, out, flux, (0,) * self.dim)
                continue
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
            A = self._response(b.material, self._F(x, g), 2)
            ne, nq, nen, d = g.dNdX.shape
            if self.compiled:
                Ke = np.empty((ne, nen * d, nen * d))
                _element_matrices(project)(np.ascontiguousarray(A), g.dNdX, g.dV, _NO_SLOTS, _NO_DATA, Ke, (0,) * d)
                out.append(Ke)
                continue
            AG = np.einsum("eqijkl,eqbl->eqijkb", A, g.dNdX, optimize=True)
            Ke = np.einsum("eq,eqaj,eqijkb->eaibk", g.dV, g.dNdX, AG, optimize=True).reshape(ne, nen * d, nen * d)
            out.append(project_psd(Ke) if project else Ke)
        return out

    def hessian(self, x: np.ndarray, project: bool = False) -> sp.csr_matrix:
        if not self.compiled:
            return self._pat.matrix(self.element_hessians(x, project))
        data = np.zeros(len(self._pat.indices))
        for b, g, slots in zip(self.blocks, self._geoms, self._pat.slots):
            A = np.ascontiguousarray(self._response(b.material, self._F(x, g), 2))
            m = g.edofs.shape[1]
            _element_matrices(project)(A, g.dNdX, g.dV, slots.reshape(-1, m, m), data, _NO_K, (0,) * self.dim)
        return sp.csr_matrix((data, self._pat.indices, self._pat.indptr), shape=(self.ndof, self.ndof))


def _kernels():
    """fem/_kernels.py, imported on first use: ``import hydrojam`` does not load numba."""
    from hydrojam.fem import _kernels as k

    return k


def _element_matrices(project: bool):
    return _kernels().element_matrices_psd if project else _kernels().element_matrices


# Empty stand-ins for the outputs a compiled element loop is not asked for.
_NO_SLOTS = np.zeros((0, 0, 0), dtype=np.int64)
_NO_DATA = np.zeros(0)
_NO_K = np.zeros((0, 0, 0))
