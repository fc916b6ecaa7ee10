"""Pieces of the Newton solver (hydrojam.fem.newton) checked on their own."""

import numpy as np
import pytest
import scipy.sparse as sp

from hydrojam.fem.newton import _sum_hessians


def _random(n, density, seed, zeros=0):
    A = sp.random(n, n, density=density, random_state=np.random.default_rng(seed), format="csr")
    A = (A + A.T).tocsr()
    if zeros:  # stored entries whose value is exactly 0 (SciPy's addition drops them)
        A.data[:zeros] = 0.0
    return A


@pytest.mark.parametrize("count", [1, 2, 3, 4])
def test_the_hessian_sum_has_the_values_and_entries_of_pythons_sum(count):
    """With a stiffness that stores exact zeros, a contact-like coupling, a stabilisation at scale
    0 (a zero diagonal) and one at a positive scale: the same values to the bit and the same
    stored entries as sum(), which the linear solver's pattern (hence its round-off) follows."""
    n = 60
    mats = [_random(n, 0.1, 1, zeros=5), _random(n, 0.02, 2), sp.diags(np.zeros(n), format="csr"),
            sp.diags(np.linspace(0.5, 1.0, n), format="csr")][:count]
    got, ref = _sum_hessians(mats), sum(mats)
    assert np.array_equal(got.indptr, ref.indptr) and np.array_equal(got.indices, ref.indices)
    assert np.array_equal(got.data, ref.data)
    assert got is not mats[0]


@pytest.mark.parametrize("sort", [True, False])
def test_the_free_block_is_scipys_fancy_index(sort):
    """The free DOFs' block of a matrix with stored zeros: the same entries, in the same order,
    with the same values as SciPy's H[fidx][:, fidx] (rows with unsorted indices take SciPy's
    route)."""
    from hydrojam.fem.newton import _free_block

    H = _random(80, 0.1, 3, zeros=7)
    if not sort:  # every row's entries reversed: unsorted rows
        order = np.concatenate([np.arange(a, b)[::-1] for a, b in zip(H.indptr[:-1], H.indptr[1:])])
        H = sp.csr_matrix((H.data[order], H.indices[order], H.indptr), shape=H.shape)
        assert not H.has_sorted_indices
    fidx = np.flatnonzero(np.random.default_rng(4).random(80) < 0.7)
    got, ref = _free_block(H, fidx), H[fidx][:, fidx]
    assert got.shape == ref.shape
    assert np.array_equal(got.indptr, ref.indptr) and np.array_equal(got.indices, ref.indices)
    assert np.array_equal(got.data, ref.data)
