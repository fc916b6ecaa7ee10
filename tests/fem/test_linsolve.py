"""The linear solver: singular systems are reported as LinearSolveError, bugs are not, and the
environment variables that tune it are validated."""

import numpy as np
import pytest
import scipy.sparse as sp

from hydrojam.fem.linsolve import LinearSolver, LinearSolveError, _pardiso_available

METHODS = ["scipy"] + (["pardiso"] if _pardiso_available() else [])


@pytest.mark.parametrize("method", METHODS)
def test_solves_a_symmetric_indefinite_system(method):
    """A small symmetric indefinite matrix against numpy's dense solve."""
    K = np.array([[2.0, 1.0, 0.0], [1.0, -3.0, 1.0], [0.0, 1.0, 4.0]])
    b = np.array([1.0, 2.0, 3.0])
    x = LinearSolver(method).solve(sp.csr_matrix(K), b)
    assert np.allclose(x, np.linalg.solve(K, b), rtol=1e-12, atol=0)


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
