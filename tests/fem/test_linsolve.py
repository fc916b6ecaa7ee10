"""The linear solver: singular systems are reported as LinearSolveError, bugs are not, and the
environment variables that tune it are validated."""

import numpy as np
import pytest
import scipy.sparse as sp

from hydrojam.fem.solver.linsolve import LinearSolver, LinearSolveError, _pardiso_available

METHODS = ["scipy"] + (["pardiso"] if _pardiso_available() else [])


@pytest.mark.parametrize("method", METHODS)
def test_solves_a_symmetric_indefinite_system(method):
    """A small symmetric indefinite matrix against numpy's dense solve."""
    K = np.array([[2.0, 1.0, 0.0], [1.0, -3.0, 1.0], [0.0, 1.0, 4.0]])
    b = np.array([1.0, 2.0, 3.0])
    x = LinearSolver(method).solve(sp.csr_matrix(K), b)
    assert np.allclose(x, np.linalg.solve(K, b), rtol=1e-12, atol=0)


@pytest.mark.parametrize("method", METHODS)
def test_resolve_reuses_the_last_matrix_for_new_right_hand_sides(method):
    """After a solve, ``resolve`` solves the same indefinite matrix for other right-hand sides (a
    preconditioner's use), to a backward-stable solve's round-off (100 eps cond(K) in the
    solution); before any solve it refuses."""
    solver = LinearSolver(method)
    with pytest.raises(ValueError, match="nothing factorised"):
        solver.resolve(np.ones(3))
    K = np.array([[2.0, 1.0, 0.0], [1.0, -3.0, 1.0], [0.0, 1.0, 4.0]])
    solver.solve(sp.csr_matrix(K), np.ones(3))
    bound = 100 * np.finfo(float).eps * np.linalg.cond(K)
    for b in (np.array([1.0, 0.0, 0.0]), np.array([-2.0, 5.0, 1.0])):
        x, ref = solver.resolve(b), np.linalg.solve(K, b)
        assert np.linalg.norm(x - ref) <= bound * np.linalg.norm(ref)
    with pytest.raises(ValueError, match="shape"):
        solver.resolve(np.ones(4))


@pytest.mark.parametrize("method", METHODS)
def test_a_structurally_singular_matrix_is_a_linear_solve_error(method):
    """A row with no entry at all (PARDISO would crash on it)."""
    K = sp.csr_matrix(np.array([[1.0, 0.0], [0.0, 0.0]]))
    with pytest.raises(LinearSolveError, match=method):
        LinearSolver(method).solve(K, np.array([1.0, 2.0]))


def test_a_numerically_singular_matrix_is_a_linear_solve_error_in_scipy():
    """SuperLU finds the zero pivot. (PARDISO perturbs tiny pivots and returns a finite answer,
    which the Newton solver's linear-residual check rejects.)"""
    K = sp.csr_matrix(np.array([[1.0, 1.0], [1.0, 1.0]]))
    with pytest.raises(LinearSolveError, match="scipy"):
        LinearSolver("scipy").solve(K, np.array([1.0, 2.0]))


@pytest.mark.parametrize("method", METHODS)
def test_a_bug_is_not_reported_as_a_singular_matrix(method):
    """A right-hand side of the wrong length is a caller's bug: it propagates as it is."""
    with pytest.raises(ValueError):
        LinearSolver(method).solve(sp.identity(3, format="csr"), np.ones(4))


@pytest.mark.parametrize("value", ["abc", "0", "-1", "1.5", ""])
def test_invalid_thread_counts_are_refused_by_name(monkeypatch, value):
    monkeypatch.setenv("HYDROJAM_SOLVER_THREADS", value)
    with pytest.raises(ValueError, match="HYDROJAM_SOLVER_THREADS must be a positive integer"):
        LinearSolver("scipy")


@pytest.mark.parametrize("value", ["abc", "2", "-1", "yes", ""])
def test_invalid_analysis_switches_are_refused_by_name(monkeypatch, value):
    monkeypatch.setenv("HYDROJAM_REUSE_ANALYSIS", value)
    with pytest.raises(ValueError, match="HYDROJAM_REUSE_ANALYSIS must be 0 or 1"):
        LinearSolver("scipy")


def test_valid_environment_values_are_used(monkeypatch):
    monkeypatch.setenv("HYDROJAM_SOLVER_THREADS", "2")
    monkeypatch.setenv("HYDROJAM_REUSE_ANALYSIS", "0")
    s = LinearSolver("scipy")
    assert s.threads == 2 and s.reuse_analysis is False
    monkeypatch.delenv("HYDROJAM_SOLVER_THREADS")
    monkeypatch.delenv("HYDROJAM_REUSE_ANALYSIS")
    s = LinearSolver("scipy")
    assert s.threads == 1 and s.reuse_analysis is True


def _contact_sequence(seed=0, n_side=12, steps=30):
    """Symmetric indefinite matrices of a 2D grid Laplacian (shifted to be indefinite) plus
    "contact" couplings between random far-apart DOFs that come and go from matrix to matrix,
    as the contact term's entries do between Newton iterations."""
    rng = np.random.default_rng(seed)
    n = n_side * n_side
    lap1 = sp.diags([-np.ones(n_side - 1), 2 * np.ones(n_side), -np.ones(n_side - 1)], [-1, 0, 1])
    L = (sp.kron(lap1, sp.identity(n_side)) + sp.kron(sp.identity(n_side), lap1)).tocsr()
    out = []
    for _ in range(steps):
        pairs = rng.integers(0, n, size=(rng.integers(0, 8), 2))
        pairs = pairs[pairs[:, 0] != pairs[:, 1]]
        k = rng.uniform(0.5, 2.0, len(pairs))
        rows = np.concatenate([pairs[:, 0], pairs[:, 1], pairs[:, 0], pairs[:, 1]])
        cols = np.concatenate([pairs[:, 0], pairs[:, 1], pairs[:, 1], pairs[:, 0]])
        vals = np.concatenate([k, k, -k, -k])
        C = sp.csr_matrix((vals, (rows, cols)), shape=(n, n))
        K = (L + C - 0.3 * sp.identity(n)).tocsr()
        out.append((K, rng.standard_normal(n)))
    return out


@pytest.mark.skipif(not _pardiso_available(), reason="PARDISO not available")
def test_the_union_pattern_solve_equals_a_fresh_solve():
    """One solver over matrices whose contact entries come and go (stored on the union of the
    patterns, explicit zeros where a matrix has no entry, the analysis reused) against numpy's
    dense solve of each matrix; tolerance 100 x eps x cond(K) relative to |x|, the accuracy a
    backward-stable solve promises. The analysis must have been both reused and redone."""
    solver = LinearSolver("pardiso")
    unions = set()
    for K, b in _contact_sequence():
        x = solver.solve(K, b)
        Kd = K.toarray()
        x_ref = np.linalg.solve(Kd, b)
        tol = 100 * np.finfo(float).eps * np.linalg.cond(Kd) * np.linalg.norm(x_ref)
        assert np.linalg.norm(x - x_ref) <= tol
        assert solver._union.nnz >= sp.triu(K).nnz
        unions.add(solver._union.key)
    assert solver.calls == 30 and 1 < solver.analyses < 30  # reused some analyses, redid others
    assert len(unions) == solver.analyses


@pytest.mark.skipif(not _pardiso_available(), reason="PARDISO not available")
def test_the_union_pattern_gives_the_same_solution_as_no_reuse():
    """With the analysis reused on the union pattern and without (each matrix analysed on its
    own pattern): the same matrices, so the same solutions up to the solver's round-off on a
    different pattern (100 x eps x cond(K) relative to |x|)."""
    reuse = LinearSolver("pardiso")
    fresh = LinearSolver("pardiso")
    fresh.reuse_analysis = False
    for K, b in _contact_sequence(seed=1):
        x, y = reuse.solve(K, b), fresh.solve(K, b)
        tol = 100 * np.finfo(float).eps * np.linalg.cond(K.toarray()) * np.linalg.norm(y)
        assert np.linalg.norm(x - y) <= tol
    assert fresh.analyses == fresh.calls and reuse.analyses < reuse.calls


@pytest.mark.parametrize("method", METHODS)
def test_unsorted_and_duplicate_entries_are_summed(method):
    """A CSR matrix with unsorted column indices and a duplicate entry means the sum of its
    entries, as SciPy reads it: compared with the dense solve."""
    data = np.array([1.0, 4.0, 1.0, 1.0, -3.0, 1.0, 1.0, 4.0])
    indices = np.array([1, 0, 0, 2, 1, 1, 2, 2])  # row 0 unsorted; row 2 holds (2, 2) twice
    indptr = np.array([0, 2, 5, 8])
    K = sp.csr_matrix((data, indices, indptr), shape=(3, 3))
    b = np.array([1.0, 2.0, 3.0])
    x = LinearSolver(method).solve(K, b)
    assert np.allclose(x, np.linalg.solve(K.toarray(), b), rtol=1e-12, atol=0)


@pytest.mark.skipif(not _pardiso_available(), reason="PARDISO not available")
def test_later_handles_reuse_the_mkl_found_first_and_leave_the_environment_alone(monkeypatch):
    """A second handle loads the MKL runtime the first one found (no search of the environment)
    and solves like the first; PYPARDISO_MKL_RT is set only while a handle is constructed."""
    import os

    from hydrojam.fem.solver.linsolve import _Pardiso

    monkeypatch.delenv("PYPARDISO_MKL_RT", raising=False)
    K = sp.csr_matrix(np.array([[2.0, 1.0], [1.0, -3.0]]))
    b = np.array([1.0, 2.0])
    first, second = LinearSolver("pardiso"), LinearSolver("pardiso")
    x1, x2 = first.solve(K, b), second.solve(K, b)
    assert second._pardiso._ps.libmkl._name == _Pardiso._mkl_rt
    assert "PYPARDISO_MKL_RT" not in os.environ
    assert np.array_equal(x1, x2)
    assert np.allclose(x1, np.linalg.solve(K.toarray(), b), rtol=1e-12, atol=0)


@pytest.mark.skipif(not _pardiso_available(), reason="PARDISO not available")
@pytest.mark.parametrize("settings", [{}, {2: 0}, {8: 0}, {2: 0, 8: 0}, {2: 0, 34: 1}])
def test_pardiso_settings_change_round_off_only(monkeypatch, settings):
    """MKL's defaults, minimum-degree ordering and refinement only after perturbed pivots: each
    against numpy's dense solve, to 100 x eps x cond(K) relative to |x|."""
    from hydrojam.fem.solver.linsolve import _Pardiso

    monkeypatch.setattr(_Pardiso, "settings", settings)
    solver = LinearSolver("pardiso")
    for K, b in _contact_sequence(seed=2, steps=8):
        x = solver.solve(K, b)
        Kd = K.toarray()
        x_ref = np.linalg.solve(Kd, b)
        assert np.linalg.norm(x - x_ref) <= 100 * np.finfo(float).eps * np.linalg.cond(Kd) * np.linalg.norm(x_ref)
    for i, value in settings.items():
        assert solver._pardiso._ps.iparm[i - 1] == value


@pytest.mark.skipif(not _pardiso_available(), reason="PARDISO not available")
def test_a_3d_dense_pattern_is_ordered_by_metis_and_a_2d_one_by_minimum_degree(monkeypatch):
    """The ordering follows the pattern's density (``_Pardiso.dense_row`` upper entries a row):
    a 3D grid Laplacian with its 26 neighbours (14 upper entries a row, shifted indefinite,
    dense_row lowered to 10) is analysed with METIS (iparm(2) = 2), the 2D grid of
    :func:`_contact_sequence` (3 a row) with minimum degree (0); both solve to
    100 x eps x cond(K) relative to |x| against numpy's dense solve."""
    from hydrojam.fem.solver.linsolve import _Pardiso

    m = 7
    idx = np.arange(m**3).reshape(m, m, m)
    rows, cols = [], []
    for d in np.ndindex(3, 3, 3):
        a = idx[tuple(slice(max(0, k - 1), m + min(0, k - 1)) for k in d)]
        b = idx[tuple(slice(max(0, 1 - k), m + min(0, 1 - k)) for k in d)]
        rows.append(a.ravel())
        cols.append(b.ravel())
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    A = sp.csr_matrix((-np.ones(len(rows)), (rows, cols)), shape=(m**3, m**3))
    K3 = (A + sp.identity(m**3) * 27.0 - 2.0 * sp.identity(m**3)).tocsr()
    rng = np.random.default_rng(0)
    cases = [(K3, 2), (_contact_sequence(seed=3, steps=1)[0][0], 0)]
    monkeypatch.setattr(_Pardiso, "dense_row", 10.0)
    for K, ordering in cases:
        solver = LinearSolver("pardiso")
        b = rng.standard_normal(K.shape[0])
        x = solver.solve(K, b)
        assert solver._pardiso._ps.iparm[1] == ordering
        Kd = K.toarray()
        x_ref = np.linalg.solve(Kd, b)
        assert np.linalg.norm(x - x_ref) <= 100 * np.finfo(float).eps * np.linalg.cond(Kd) * np.linalg.norm(x_ref)


@pytest.mark.skipif(not _pardiso_available(), reason="PARDISO (MKL) not installed")
@pytest.mark.parametrize("negative", [0, 1, 7])
def test_pardiso_reports_the_inertia_of_a_symmetric_indefinite_matrix(negative):
    """Sylvester's law of inertia: K = Q diag(lam) Q^T (Q a random orthogonal matrix, a dense
    pattern) has exactly as many negative eigenvalues as lam; every |lam| >= 0.1, far from a
    zero pivot. The scipy backend does not report it (None)."""
    rng = np.random.default_rng(negative)
    n = 40
    lam = rng.uniform(0.1, 2.0, n) * np.where(np.arange(n) < negative, -1.0, 1.0)
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    K = sp.csr_matrix((Q * lam) @ Q.T)
    solver = LinearSolver("pardiso")
    solver.solve(K, np.ones(n))
    assert solver.negative_eigenvalues == negative
    scipy_solver = LinearSolver("scipy")
    scipy_solver.solve(K, np.ones(n))
    assert scipy_solver.negative_eigenvalues is None


def _with_inertia(negative: int, n: int = 40) -> sp.csr_matrix:
    """Q diag(lam) Q^T with ``negative`` of its n eigenvalues negative, every |lam| in [0.1, 2]:
    a dense pattern (more than ``_Pardiso.dense_row`` upper entries a row), far from a zero pivot."""
    rng = np.random.default_rng(negative)
    lam = rng.uniform(0.1, 2.0, n) * np.where(np.arange(n) < negative, -1.0, 1.0)
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return sp.csr_matrix((Q * lam) @ Q.T)


@pytest.mark.skipif(not _pardiso_available(), reason="PARDISO (MKL) not installed")
@pytest.mark.parametrize("negative", [1, 7])
def test_a_definite_solve_refuses_an_indefinite_dense_matrix_and_solves_a_definite_one(negative):
    """Asked for a positive definite K (``definite``) on a dense pattern, the solver factorises
    by Cholesky: an indefinite K raises NotPositiveDefinite (a LinearSolveError), a definite one
    is solved to 100 x eps x cond(K) relative to |x| against numpy's dense solve, with no
    negative eigenvalue, reusing the analysis that the refused matrix of the same pattern made,
    and the LDL^T handle, used again for an indefinite K, still reports its inertia."""
    from hydrojam.fem.solver.linsolve import NotPositiveDefinite

    solver = LinearSolver("pardiso")
    b = np.ones(40)
    with pytest.raises(NotPositiveDefinite):
        solver.solve(_with_inertia(negative), b, definite=True)
    K = _with_inertia(0)
    x = solver.solve(K, b, definite=True)
    assert solver._pardiso.mtype == 2 and solver.negative_eigenvalues == 0
    assert solver.analyses == 1
    x_ref = np.linalg.solve(K.toarray(), b)
    assert np.linalg.norm(x - x_ref) <= 100 * np.finfo(float).eps * np.linalg.cond(K.toarray()) * np.linalg.norm(x_ref)
    assert np.allclose(solver.resolve(2 * b), 2 * x, rtol=0, atol=100 * np.finfo(float).eps * 40 * np.abs(x).max())
    solver.solve(_with_inertia(negative), b)
    assert solver._pardiso.mtype == -2 and solver.negative_eigenvalues == negative


@pytest.mark.skipif(not _pardiso_available(), reason="PARDISO (MKL) not installed")
def test_a_definite_solve_on_a_sparse_pattern_keeps_the_ldlt():
    """Below ``dense_row`` (2D patterns) a definite solve is an LDL^T solve as before: an
    indefinite K is solved, and its inertia reported, not refused."""
    n = 30
    K = sp.diags([np.r_[-1.0, np.full(n - 1, 4.0)], np.ones(n - 1), np.ones(n - 1)], [0, 1, -1], format="csr")
    solver = LinearSolver("pardiso")
    x = solver.solve(K, np.ones(n), definite=True)
    assert solver._pardiso.mtype == -2 and solver.negative_eigenvalues == 1
    assert np.linalg.norm(K @ x - np.ones(n)) <= 1e-12 * np.sqrt(n) * np.linalg.cond(K.toarray())


@pytest.mark.skipif(not _pardiso_available(), reason="PARDISO not available")
def test_a_reused_ordering_solves_like_a_fresh_one(monkeypatch):
    """New dense patterns (``dense_row`` lowered so that these grid matrices count as dense)
    analysed with the ordering of an earlier analysis (iparm(5) = 1) against
    each pattern ordered afresh: both direct solves of the same matrices, so the same solutions
    to 100 x eps x cond(K) relative to |x|; the ordering was computed only where the fill grew
    past ``reorder_fill`` (here at the first analysis and at most a few more)."""
    from hydrojam.fem.solver.linsolve import _Pardiso

    monkeypatch.setattr(_Pardiso, "dense_row", 1.0)
    reused = LinearSolver("pardiso")
    fresh = LinearSolver("pardiso")
    fresh.reuse_ordering = False
    for K, b in _contact_sequence(seed=4):
        x, y = reused.solve(K, b), fresh.solve(K, b)
        tol = 100 * np.finfo(float).eps * np.linalg.cond(K.toarray()) * np.linalg.norm(y)
        assert np.linalg.norm(x - y) <= tol
    assert reused.analyses == fresh.analyses > 2
    assert fresh.reorderings == fresh.analyses
    assert 1 <= reused.reorderings < reused.analyses
    assert reused._pardiso._ps.iparm[4] == 0  # the user-ordering switch is off between analyses


@pytest.mark.skipif(not _pardiso_available(), reason="PARDISO not available")
def test_an_ordering_whose_fill_grew_is_computed_afresh(monkeypatch):
    """With ``reorder_fill`` below 1 every analysis on a reused ordering counts as filling too
    much: the next analysis orders afresh, so orderings are computed at every other analysis
    (``dense_row`` lowered: these grid matrices count as dense)."""
    from hydrojam.fem.solver.linsolve import _Pardiso

    monkeypatch.setattr(_Pardiso, "dense_row", 1.0)
    solver = LinearSolver("pardiso")
    solver.reorder_fill = 0.0
    for K, b in _contact_sequence(seed=5):
        solver.solve(K, b)
    assert solver.reorderings == (solver.analyses + 1) // 2


@pytest.mark.skipif(not _pardiso_available(), reason="PARDISO not available")
@pytest.mark.parametrize("stop", [3, 11, 20])
def test_a_restored_solver_goes_on_bit_for_bit(monkeypatch, stop):
    """A solver restored from another's :attr:`LinearSolver.pattern` (the union pattern and the
    orderings) solves the rest of a sequence with the same bits as the one that went on: the
    same patterns analysed with the same orderings (``dense_row`` lowered: these grid matrices
    count as dense, so orderings are reused)."""
    from hydrojam.fem.solver.linsolve import _Pardiso

    monkeypatch.setattr(_Pardiso, "dense_row", 1.0)
    seq = _contact_sequence(seed=6)
    first = LinearSolver("pardiso")
    first.reorder_fill = 1.01  # orderings computed afresh now and then, so the state to carry varies
    for K, b in seq[:stop]:
        first.solve(K, b)
    second = LinearSolver("pardiso")
    second.reorder_fill = 1.01
    second.restore_pattern(first.pattern)
    for K, b in seq[stop:]:
        assert np.array_equal(first.solve(K, b), second.solve(K, b))
    assert first._ordering is None or np.array_equal(first._ordering, second._ordering)


@pytest.mark.skipif(not _pardiso_available(), reason="PARDISO not available")
def test_a_sparse_2d_pattern_computes_its_own_ordering():
    """Below ``dense_row`` (2D tri6-like patterns) every new pattern is ordered afresh, as
    without ordering reuse: the same bits as a solver with ``reuse_ordering`` off."""
    a, b_ = LinearSolver("pardiso"), LinearSolver("pardiso")
    b_.reuse_ordering = False
    for K, b in _contact_sequence(seed=7):
        assert np.array_equal(a.solve(K, b), b_.solve(K, b))
    assert a.reorderings == a.analyses and a._ordering is None


def _dense(monkeypatch):
    """Let the grid matrices count as dense (3D-like): ordered by METIS, the last ordering kept."""
    from hydrojam.fem.solver.linsolve import _Pardiso

    monkeypatch.setattr(_Pardiso, "dense_row", 1.0)


def _pattern_of(matrices):
    """The union of the matrices' sparsity patterns (values 1)."""
    P = sum(abs(K) for K in matrices)
    P = sp.csr_matrix(P)
    P.data[:] = 1.0
    return P


@pytest.mark.skipif(not _pardiso_available(), reason="PARDISO not available")
@pytest.mark.parametrize("dense", [False, True])
def test_a_reach_pattern_holding_every_matrix_is_analysed_once(monkeypatch, dense):
    """A reach that holds the patterns of the whole sequence, on sparse (2D) and dense (3D)
    patterns alike: one analysis, the hint asked for once (at the first solve, nothing analysed
    yet), and every solution as accurate as a dense solve promises (100 x eps x cond(K) relative
    to |x|): the hint changes bookkeeping only."""
    if dense:
        _dense(monkeypatch)
    seq = _contact_sequence(seed=2)
    P = _pattern_of([K for K, _ in seq])
    asked = []

    def reach():
        asked.append(1)
        return P

    solver = LinearSolver("pardiso")
    for K, b in seq:
        x = solver.solve(K, b, reach)
        Kd = K.toarray()
        x_ref = np.linalg.solve(Kd, b)
        assert np.linalg.norm(x - x_ref) <= 100 * np.finfo(float).eps * np.linalg.cond(Kd) * np.linalg.norm(x_ref)
    assert solver.analyses == 1 and len(asked) == 1
    plain = LinearSolver("pardiso")
    for K, b in seq:
        plain.solve(K, b)
    assert plain.analyses > 1


@pytest.mark.skipif(not _pardiso_available(), reason="PARDISO not available")
def test_a_matrix_leaving_the_reach_restarts_the_union_from_it_and_the_new_reach(monkeypatch):
    """A reach that holds only the next few matrices: a matrix outside it is analysed on its
    own pattern and the reach asked then, with no older pattern kept (a union that grew with
    every contact seen would slow each factorisation); a matrix inside it is not analysed
    again, however little of the reach it fills."""
    _dense(monkeypatch)
    seq = _contact_sequence(seed=3)
    window = 5
    solver = LinearSolver("pardiso")
    for i, (K, b) in enumerate(seq):
        before = solver.analyses
        solver.solve(K, b, lambda i=i: _pattern_of([K for K, _ in seq[i:i + window]]))
        if solver.analyses > before:
            assert solver._union.nnz == sp.triu(_pattern_of([K for K, _ in seq[i:i + window]])).nnz
    assert solver._union.hinted and solver.analyses <= -(-len(seq) // window)


@pytest.mark.skipif(not _pardiso_available(), reason="PARDISO not available")
def test_a_reach_of_another_shape_is_refused(monkeypatch):
    _dense(monkeypatch)
    K, b = _contact_sequence(seed=4, steps=1)[0]
    with pytest.raises(ValueError, match="reach pattern of shape"):
        LinearSolver("pardiso").solve(K, b, lambda: sp.identity(K.shape[0] + 1, format="csr"))


@pytest.mark.skipif(not _pardiso_available(), reason="PARDISO not available")
def test_a_restored_solver_goes_on_bit_for_bit_with_a_reach(monkeypatch):
    """The reach's union survives a checkpoint: a restored solver keeps it (not restarted by the
    fill rule of unions without a reach) and goes on with the same bits."""
    _dense(monkeypatch)
    seq = _contact_sequence(seed=5)
    P = _pattern_of([K for K, _ in seq[:12]])
    first = LinearSolver("pardiso")
    for K, b in seq[:6]:
        first.solve(K, b, lambda: P)
    second = LinearSolver("pardiso")
    second.restore_pattern(first.pattern)
    assert second._union.hinted
    for K, b in seq[6:]:
        assert np.array_equal(first.solve(K, b, lambda: P), second.solve(K, b, lambda: P))
    assert second.analyses == first.analyses  # the restored union analysed once, as first's was


@pytest.mark.skipif(not _pardiso_available(), reason="PARDISO not available")
@pytest.mark.parametrize("dense", [False, True])
@pytest.mark.parametrize("perturbed", [0, 3])
def test_a_solve_is_refined_only_after_perturbed_pivots(monkeypatch, perturbed, dense):
    """On sparse (2D) and dense (3D) patterns the solve skips PARDISO's forced refinement unless
    the factorisation perturbed pivots (iparm(14), set here by the spy as a factorisation would);
    then the solve is redone with the refinement (phase 33, iparm(8) as pardisoinit set it).
    Either way the residual is within 10x of the forced refinement's, or of a backward-stable
    solve's round-off, 100 eps ||K||_1 ||x||, whichever is larger."""
    from hydrojam.fem.solver.linsolve import _Pardiso

    if dense:
        monkeypatch.setattr(_Pardiso, "dense_row", 1.0)
    phases = []
    call = _Pardiso._call

    def spy(self, phase, *args):
        phases.append((phase, int(self._ps.iparm[7])))
        x = call(self, phase, *args)
        if phase in (13, 23):
            self._ps.iparm[13] = perturbed
        return x

    monkeypatch.setattr(_Pardiso, "_call", spy)
    K, b = _contact_sequence(seed=10, steps=1)[0]
    x = LinearSolver("pardiso").solve(K, b)
    assert phases == ([(13, 0)] if not perturbed else [(13, 0), (33, 2)])
    monkeypatch.setattr(_Pardiso, "forced_refinement", True)
    phases.clear()
    y = LinearSolver("pardiso").solve(K, b)
    assert phases == [(13, 2)]
    rx, ry = np.linalg.norm(K @ x - b), np.linalg.norm(K @ y - b)
    roundoff = 100 * np.finfo(float).eps * abs(K).sum(axis=0).max() * np.linalg.norm(y)
    assert rx <= 10 * max(ry, roundoff)


@pytest.mark.skipif(not _pardiso_available(), reason="PARDISO (MKL) not installed")
def test_a_single_precision_cholesky_is_refined_to_its_tolerance_in_double():
    """With ``mixed_precision`` a definite dense solve factorises in single precision and refines
    in double to ``refinement_tolerance``; an approximate resolve stays at single precision's
    accuracy (its solution carries float32's relative errors of about 6e-8, whose residual lies
    decades above the 1e-10 asked; cond(K) = 2e3), an exact one is refined too."""
    rng = np.random.default_rng(3)
    n = 40
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    K = sp.csr_matrix((Q * np.geomspace(1e-3, 2.0, n)) @ Q.T)
    b = rng.standard_normal(n)
    solver = LinearSolver("pardiso")
    x = solver.solve(K, b, definite=True)
    assert solver._pardiso.single and solver.refinements >= 1
    assert np.linalg.norm(K @ x - b) <= solver.refinement_tolerance * np.linalg.norm(b)
    rough = solver.resolve(b, approximate=True)
    assert np.linalg.norm(K @ rough - b) > solver.refinement_tolerance * np.linalg.norm(b)
    exact = solver.resolve(b)
    assert np.linalg.norm(K @ exact - b) <= solver.refinement_tolerance * np.linalg.norm(b)
