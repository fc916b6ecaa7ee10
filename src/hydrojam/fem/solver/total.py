"""The total of a list of energy terms, as the solver uses it: its energy, the residual over
the free DOFs and the tolerance it is held to, and the free block of its Hessian.

Every function here sums the terms in their order, so the same terms give the same bits
wherever the sum is taken (Newton, the stability check, the release).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.sparse as sp

from hydrojam.fem.terms import EnergyTerm

#: floor of the residual tolerance, times the problem's force scale: round-off of the residual
#: (a stress-free mesh of 100 mm already shows 1e-13 N)
RESIDUAL_FLOOR = 1e-10
#: keeps a division by a norm or diagonal finite where it is zero
TINY = 1e-300


def sum_energy(terms: Sequence[EnergyTerm], x: np.ndarray) -> float:
    """Total energy of ``terms`` at x (n, d) [mm]; inf as soon as a partial sum is not finite."""
    e = 0.0
    for t in terms:
        e += t.energy(x)
        if not np.isfinite(e):
            return np.inf
    return e


def tolerance(terms, xs, grads, fidx, force_scale: float, rtol: float, floor: float = RESIDUAL_FLOOR) -> float:
    """Residual tolerance [N] at positions xs (n, d) [mm] given each term's gradient ``grads``: ``rtol`` x
    the largest term's forces in play over the free DOFs ``fidx``, floored at round-off
    (``floor`` x ``force_scale`` [N])."""
    in_play = max(float(np.linalg.norm(t.force_flux(xs, gt)[fidx])) for t, gt in zip(terms, grads))
    return max(rtol * in_play, floor * force_scale)


def physical_residual(terms, x: np.ndarray, free: np.ndarray, force_scale: float, rtol: float,
                      unphysical: tuple[str, ...] = ("stabilisation",),
                      floor: float = RESIDUAL_FLOOR) -> tuple[float, float]:
    """(residual, tolerance) [N] of the physics alone at x (n, d) [mm]: the norm over the free
    DOFs of the summed gradients of ``terms`` whose names are not in ``unphysical``, and the Newton
    tolerance for it (``rtol`` x the largest such term's forces in play, floored at round-off)."""
    xs = np.asarray(x, dtype=float)
    fidx = np.flatnonzero(free)
    physical = [t for t in terms if t.name not in unphysical]
    grads = [t.gradient(xs) for t in physical]
    return float(np.linalg.norm(sum(grads)[fidx])), tolerance(physical, xs, grads, fidx, force_scale, rtol, floor)


def residual_norm(terms, xs: np.ndarray, fidx: np.ndarray) -> float:
    """||g_free|| [N] of ``terms`` at positions xs (n, d) [mm]."""
    return float(np.linalg.norm(sum(t.gradient(xs) for t in terms)[fidx]))


def sum_hessians(matrices) -> sp.csr_matrix:
    """The terms' Hessians summed in order, with the values and stored entries of Python's
    ``sum`` (0 + H1 + H2 + ...), without its passes that change nothing: the copy that 0 + H1
    makes, and the addition of a matrix with only zero values after the first addition (a
    stabilisation at scale 0; x + 0.0 == x, and SciPy's addition drops the entries that sum to
    zero, which the first addition has dropped already)."""
    matrices = list(matrices)
    if len(matrices) == 1:
        return sp.csr_matrix(matrices[0]).copy()
    total = matrices[0] + matrices[1]
    for m in matrices[2:]:
        if m.nnz and np.any(m.data):
            total = total + m
    return total


def free_positions(n: int, fidx: np.ndarray) -> np.ndarray:
    """Each of n DOFs' index among the free DOFs ``fidx`` (ascending), -1 where it is fixed."""
    position = np.full(n, -1, dtype=np.int64)
    position[fidx] = np.arange(len(fidx))
    return position


def free_block(H, fidx: np.ndarray) -> sp.csr_matrix:
    """H's block on the free DOFs ``fidx`` (ascending): SciPy's ``H[fidx][:, fidx]`` (the same
    entries in the same order, so the same bits downstream) in one compiled pass instead of two
    fancy-indexing passes."""
    H = sp.csr_matrix(H)
    if not H.has_sorted_indices:
        return H[fidx][:, fidx]
    from hydrojam.fem import _kernels

    ptr, ind, val = _kernels.free_block(H.indptr, H.indices, H.data, fidx.astype(np.int64),
                                        free_positions(H.shape[1], fidx))
    return sp.csr_matrix((val, ind, ptr), shape=(len(fidx), len(fidx)))


def free_sum(matrices, fidx: np.ndarray) -> sp.csr_matrix:
    """``free_block(sum_hessians(matrices), fidx)``, the same entries to the bit, with the first
    two matrices added and cut to the free block in one compiled pass where both are canonical
    (sorted rows, no duplicates), as the elastic and contact Hessians are: the sum of the whole
    matrices and its block were two passes over every entry of the elastic Hessian."""
    matrices = [sp.csr_matrix(m) for m in matrices]
    if len(matrices) == 1 or not all(m.has_canonical_format for m in matrices[:2]):
        return free_block(sum_hessians(matrices), fidx)
    from hydrojam.fem import _kernels

    a, b = matrices[:2]
    ptr, ind, val = _kernels.free_sum(a.indptr, a.indices, a.data, b.indptr, b.indices, b.data,
                                      fidx.astype(np.int64), free_positions(a.shape[1], fidx))
    total = sp.csr_matrix((val, ind, ptr), shape=(len(fidx), len(fidx)))
    for m in matrices[2:]:
        if m.nnz and np.any(m.data):
            total = total + free_block(m, fidx)
    return total
