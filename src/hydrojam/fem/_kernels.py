"""numba-compiled element loops of :class:`hydrojam.fem.assembly.Solid` (the compiled path).

Each loop does per element what the numpy path does with batched ``einsum`` calls, and scatters
the element's vector or matrix straight into the assembled gradient or the CSR data array of the
Solid's fixed pattern (no ``bincount`` over all element entries, no array of all element matrices).
The material is not here: the Solid evaluates it between these loops (``evaluate_compiled`` where
the material has it). Same mathematics as the numpy path, so the results differ in round-off only
(another summation order). Compiled on first use and cached on disk (``cache=True``).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def deformation_gradients(x, cells, dNdX, dims):  # pragma: no cover - compiled
    """F (ne, nq, d, d) [-] from current positions x (n_nodes, d) [mm], cells (ne, nen) and the
    reference shape-function gradients dNdX (ne, nq, nen, d) [1/mm]; ``dims`` as in
    :func:`element_matrices`."""
    ne, nq, nen, _ = dNdX.shape
    d = len(dims)
    F = np.zeros((ne, nq, d, d))
    for e in range(ne):
        for a in range(nen):
            na = cells[e, a]
            for q in range(nq):
                for i in range(d):
                    xi = x[na, i]
                    for j in range(d):
                        F[e, q, i, j] += xi * dNdX[e, q, a, j]
    return F


@numba.njit(cache=True)
def scatter_forces(P, dNdX, dV, edofs, out, flux, dims):  # pragma: no cover - compiled
    """Adds the element forces f_ai = sum_q dV P_ij dN_a/dX_j [N] of stresses P (ne, nq, d, d)
    [MPa] into ``out`` (ndof,) at the element DOFs ``edofs`` (ne, nen*d), and their absolute
    values into ``flux``; ``dims`` as in :func:`element_matrices`."""
    ne, nq, nen, _ = dNdX.shape
    d = len(dims)
    fe = np.empty(nen * d)
    for e in range(ne):
        fe[:] = 0.0
        for q in range(nq):
            w = dV[e, q]
            for a in range(nen):
                for i in range(d):
                    s = 0.0
                    for j in range(d):
                        s += P[e, q, i, j] * dNdX[e, q, a, j]
                    fe[a * d + i] += w * s
        for r in range(nen * d):
            out[edofs[e, r]] += fe[r]
            flux[edofs[e, r]] += abs(fe[r])


@numba.njit(cache=True)
def _project_psd(K):  # pragma: no cover - compiled
    """K symmetrised, negative eigenvalues clamped to zero (assembly.project_psd for one matrix)."""
    Ks = 0.5 * (K + K.T)
    w, V = np.linalg.eigh(Ks)
    if w.min() >= 0.0:
        return Ks
    Vw = V * np.maximum(w, 0.0)  # scales column j by w_j
    return Vw @ V.T


@numba.njit(cache=True)
def _element_matrix(A, dNdX, dV, e, K, AG, dims):  # pragma: no cover - compiled
    """K (nen*d, nen*d) of element e: K_(ai)(bk) = sum_q dV dN_a/dX_j A_ijkl dN_b/dX_l [N/mm];
    AG (nen, d, d, d) is scratch."""
    _, nq, nen, _ = dNdX.shape
    d = len(dims)
    K[:, :] = 0.0
    for q in range(nq):
        w = dV[e, q]
        dN = dNdX[e, q]
        Aq = A[e, q]
        for b in range(nen):
            for i in range(d):
                for j in range(d):
                    for k in range(d):
                        s = 0.0
                        for ll in range(d):
                            s += Aq[i, j, k, ll] * dN[b, ll]
                        AG[b, i, j, k] = w * s
        # A has the major symmetry A_ijkl = A_klij, so K is symmetric: the blocks b >= a only
        for a in range(nen):
            for b in range(a, nen):
                for i in range(d):
                    for k in range(d):
                        s = 0.0
                        for j in range(d):
                            s += dN[a, j] * AG[b, i, j, k]
                        K[a * d + i, b * d + k] += s
    for a in range(nen):
        for b in range(a + 1, nen):
            for i in range(d):
                for k in range(d):
                    K[b * d + k, a * d + i] = K[a * d + i, b * d + k]


@numba.njit(cache=True)
def _deposit(Ke, e, slots, data, out):  # pragma: no cover - compiled
    if slots.shape[0] > 0:
        m = Ke.shape[0]
        for r in range(m):
            for c in range(m):
                data[slots[e, r, c]] += Ke[r, c]
    if out.shape[0] > 0:
        out[e] = Ke


@numba.njit(cache=True)
def element_matrices(A, dNdX, dV, slots, data, out, dims):  # pragma: no cover - compiled
    """Element stiffness matrices (see _element_matrix) of tangents A (ne, nq, d, d, d, d) [MPa].
    Each is added into the CSR ``data`` at its positions ``slots`` (ne, nen*d, nen*d) when
    ``slots`` has rows, and stored in ``out`` (ne, nen*d, nen*d) when ``out`` has rows. ``dims``
    is any tuple of d integers: its length is known when compiling, so the loops over d are
    unrolled."""
    ne, _, nen, _ = dNdX.shape
    d = len(dims)
    K = np.empty((nen * d, nen * d))
    AG = np.empty((nen, d, d, d))
    for e in range(ne):
        _element_matrix(A, dNdX, dV, e, K, AG, dims)
        _deposit(K, e, slots, data, out)


@numba.njit(cache=True)
def element_matrices_psd(A, dNdX, dV, slots, data, out, dims):  # pragma: no cover - compiled
    """:func:`element_matrices`, each PSD-projected (apart: LAPACK's eigh takes most of the
    compile time, which the unprojected Hessian then does not pay)."""
    ne, _, nen, _ = dNdX.shape
    d = len(dims)
    K = np.empty((nen * d, nen * d))
    AG = np.empty((nen, d, d, d))
    for e in range(ne):
        _element_matrix(A, dNdX, dV, e, K, AG, dims)
        _deposit(_project_psd(K), e, slots, data, out)


# -- the linear solver's bookkeeping (fem/solver/linsolve.py) ------------------------------------------


@numba.njit(cache=True)
def upper_positions(indptr, indices, uptr, uind):  # pragma: no cover - compiled
    """For every entry of a CSR matrix (``indptr``, ``indices``; rows sorted) its position in the
    upper-triangle pattern (``uptr``, ``uind``; sorted) of the same size: -2 for an entry below
    the diagonal, -1 for an upper entry the pattern lacks. Returns (positions, missing count)."""
    n = len(indptr) - 1
    out = np.empty(len(indices), dtype=np.int64)
    missing = 0
    for i in range(n):
        q, qend = uptr[i], uptr[i + 1]
        for k in range(indptr[i], indptr[i + 1]):
            j = indices[k]
            if j < i:
                out[k] = -2
                continue
            while q < qend and uind[q] < j:
                q += 1
            if q < qend and uind[q] == j:
                out[k] = q
            else:
                out[k] = -1
                missing += 1
    return out, missing


@numba.njit(cache=True)
def merge_upper(indptr, indices, uptr, uind):  # pragma: no cover - compiled
    """The union of an upper-triangle pattern (``uptr``, ``uind``) and the upper entries of a CSR
    matrix (``indptr``, ``indices``), both rows sorted: its (indptr, indices), rows sorted."""
    n = len(indptr) - 1
    ptr = np.zeros(n + 1, dtype=np.int64)
    ind = np.empty(len(uind) + len(indices), dtype=np.int64)
    m = 0
    for i in range(n):
        k, kend = indptr[i], indptr[i + 1]
        while k < kend and indices[k] < i:
            k += 1
        q, qend = uptr[i], uptr[i + 1]
        while k < kend or q < qend:
            if q >= qend or (k < kend and indices[k] < uind[q]):
                ind[m] = indices[k]
                k += 1
            elif k >= kend or uind[q] < indices[k]:
                ind[m] = uind[q]
                q += 1
            else:
                ind[m] = uind[q]
                k += 1
                q += 1
            m += 1
        ptr[i + 1] = m
    return ptr, ind[:m].copy()


@numba.njit(cache=True)
def free_block(indptr, indices, data, rows, position):  # pragma: no cover - compiled
    """The block of a CSR matrix (rows sorted) on the rows ``rows`` (ascending) and on the columns
    j with ``position[j] >= 0`` (their index in the block, ascending with j): (indptr, indices,
    data) of the block, its rows sorted; what SciPy's ``A[rows][:, cols]`` gives, in one pass."""
    nr = len(rows)
    ptr = np.zeros(nr + 1, dtype=np.int64)
    for i in range(nr):
        r = rows[i]
        c = 0
        for k in range(indptr[r], indptr[r + 1]):
            if position[indices[k]] >= 0:
                c += 1
        ptr[i + 1] = ptr[i] + c
    ind = np.empty(ptr[nr], dtype=np.int32)
    val = np.empty(ptr[nr])
    for i in range(nr):
        r = rows[i]
        m = ptr[i]
        for k in range(indptr[r], indptr[r + 1]):
            p = position[indices[k]]
            if p >= 0:
                ind[m] = p
                val[m] = data[k]
                m += 1
    return ptr, ind, val


@numba.njit(cache=True)
def free_sum(aptr, aind, adata, bptr, bind, bdata, rows, position):  # pragma: no cover - compiled
    """The block of A + B (CSR, rows sorted, no duplicates) on the rows ``rows`` and the columns
    with ``position[j] >= 0``, as :func:`free_block` takes it from SciPy's A + B: each entry the
    sum a + b (a or b alone where the other lacks it), dropped where that is zero, as SciPy's
    addition drops it. (indptr, indices, data) of the block, its rows sorted."""
    nr = len(rows)
    ptr = np.zeros(nr + 1, dtype=np.int64)
    cap = 0
    for i in range(nr):
        r = rows[i]
        cap += aptr[r + 1] - aptr[r] + bptr[r + 1] - bptr[r]
    ind = np.empty(cap, dtype=np.int32)
    val = np.empty(cap)
    m = 0
    for i in range(nr):
        r = rows[i]
        k, kend = aptr[r], aptr[r + 1]
        q, qend = bptr[r], bptr[r + 1]
        while k < kend or q < qend:
            if q >= qend or (k < kend and aind[k] < bind[q]):
                j = aind[k]
                v = adata[k] + 0.0
                k += 1
            elif k >= kend or bind[q] < aind[k]:
                j = bind[q]
                v = 0.0 + bdata[q]
                q += 1
            else:
                j = aind[k]
                v = adata[k] + bdata[q]
                k += 1
                q += 1
            p = position[j]
            if p >= 0 and v != 0.0:
                ind[m] = p
                val[m] = v
                m += 1
        ptr[i + 1] = m
    return ptr, ind[:m], val[:m]
