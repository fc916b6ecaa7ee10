"""Sparse direct solves for the Newton step: MKL PARDISO (pypardiso) by default, SciPy as fallback.

The Newton matrices are symmetric, so PARDISO runs as a real symmetric indefinite solver
(``mtype = -2``) on the upper triangle: half the fill and work of the general LU.

MKL runs single-threaded unless ``HYDROJAM_SOLVER_THREADS`` says otherwise: its OpenMP threads
spin-wait, and beside another busy process (a sweep's second worker) a solve then slows down
many times over (docs/solver.md, "Linear solver").
"""

from __future__ import annotations

import ctypes
import time
import warnings
from collections.abc import Callable, Sequence

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from hydrojam.fem._env import flag, positive_int
from hydrojam.fem.solver.events import LinearSolve, Observer, notify


class LinearSolveError(RuntimeError):
    """The linear system could not be solved (singular or not finite)."""


class NotPositiveDefinite(LinearSolveError):
    """A solve asked for a positive definite matrix (:meth:`LinearSolver.solve`'s ``definite``)
    met a pivot that is not positive: the matrix has a negative (or zero) eigenvalue."""


def _pardiso_available() -> bool:
    try:
        import pypardiso  # noqa: F401
    except ImportError:  # pragma: no cover - missing MKL on exotic platforms
        return False
    return True


class _Pardiso:
    """MKL PARDISO through pypardiso (pinned 0.4.7): every use of pypardiso's private functions
    and attributes (``_mkl_pardiso``, ``_call_pardiso``, ``pt``, ``iparm``, ``libmkl``) lives in
    this class, so an upgrade is reviewed here. Real symmetric indefinite (``mtype`` -2: LDL^T
    with Bunch-Kaufman pivots, reporting the inertia) or positive definite (2: Cholesky, which
    fails at the first pivot that is not positive) on the upper triangle, called with the
    1-based index arrays of the pattern prepared once per pattern."""

    settings: dict[int, int] = {2: 0, 34: 1}
    """PARDISO's iparm (1-based index: value) over MKL's defaults for mtype -2 (pardisoinit):
    iparm(2) = 0, minimum-degree ordering instead of MKL's METIS (iparm(2) = 3): a 40% faster
    analysis and a faster factorisation on these 2D matrices; iparm(34) = 1, MKL's conditional
    numerical reproducibility (CNR): the same bits whatever ``HYDROJAM_SOLVER_THREADS``, where
    MKL's own default (0) makes the parallel factorisation's round-off depend on the thread
    count (the parallel METIS, iparm(2) = 3, would rule CNR out). Each changes round-off only;
    docs/solver.md gives the measurements ({} restores MKL's defaults)."""

    dense_ordering: int = 2
    """iparm(2) for patterns denser than ``dense_row``: MKL's sequential METIS (nested
    dissection), which fills less than minimum degree on a 3D mesh's graph and, being
    sequential, keeps CNR (docs/solver.md, "3D: ordering, threads"). Applied only where
    ``settings`` sets iparm(2)."""

    dense_row: float = 20.0
    """Upper-triangle entries a row above which a pattern counts as dense: tet10 meshes lie
    above it, tri6 meshes below."""

    @classmethod
    def is_dense(cls, upper_entries: int, n: int) -> bool:
        """Whether a pattern of ``upper_entries`` upper-triangle entries on n rows is dense (3D)."""
        return upper_entries > cls.dense_row * n

    forced_refinement: bool = False
    """Whether PARDISO's forced refinement (iparm(8), two steps from pardisoinit) runs after every
    solve. False: only after a factorisation that perturbed pivots (iparm(14) > 0), when the solve
    is redone with it: without perturbed pivots the factor is exact to round-off, and the two
    steps changed no residual measurably for a seventh of a 3D solve and about a tenth of a 2D
    one (docs/solver.md, "A changing contact pattern")."""

    _mkl_rt: str | None = None
    """Path of the MKL runtime found by the first handle: later handles skip pypardiso's search
    of the whole environment for it (a recursive glob)."""

    def __init__(self, threads: int, mtype: int = -2, single: bool = False):
        import os

        import pypardiso
        from pypardiso.pardiso_wrapper import PyPardisoError

        self.error = PyPardisoError
        path = _Pardiso._mkl_rt or getattr(getattr(pypardiso.ps, "libmkl", None), "_name", None)
        if path and "PYPARDISO_MKL_RT" not in os.environ:
            os.environ["PYPARDISO_MKL_RT"] = path  # read only by the constructor below
            try:
                self._ps = pypardiso.PyPardisoSolver(mtype=mtype)
            finally:
                os.environ.pop("PYPARDISO_MKL_RT", None)
        else:
            self._ps = pypardiso.PyPardisoSolver(mtype=mtype)
        self.mtype = mtype
        _Pardiso._mkl_rt = self._ps.libmkl._name
        self._ps.set_statistical_info_off()
        init = self._ps.libmkl.pardisoinit
        init.restype = None
        init(self._ps.pt.ctypes.data_as(ctypes.POINTER(self._ps._pt_type[0])),
             ctypes.byref(ctypes.c_int32(self._ps.mtype)),
             self._ps.iparm.ctypes.data_as(ctypes.POINTER(ctypes.c_int32)))
        self._ps.set_iparm(12, 0)  # CSR input, not transposed (what pypardiso's _check_A sets)
        self.ordering: np.ndarray | None = None
        """The fill-reducing permutation of the last analysis (PARDISO's perm)."""
        for i, value in self.settings.items():
            self._ps.iparm[i - 1] = value
        self.single = single
        """Whether the factorisation and substitutions run in single precision (iparm(28) = 1:
        the matrix, right-hand side and solution are passed as float32); the caller refines the
        solution in double (:meth:`LinearSolver.solve`)."""
        self._ps.iparm[27] = int(single)
        self._refinement = int(self._ps.iparm[7])  # iparm(8): pardisoinit's, or the settings'
        self.calls: list | None = None
        """Where not None, each call is appended as (phase, matrix type, seconds, failed)."""
        self._dense = False  # whether the pattern last analysed is dense
        self._factorised: tuple | None = None  # (data, ia, ja) of the last factorisation
        self.analysis_kept = False
        """Whether the last call that analysed a pattern left its analysis in the handle (also
        where its factorisation then failed: the Cholesky's analysis runs apart, so that a matrix
        refused as not definite leaves it for the next matrix of the pattern)."""
        setter = getattr(self._ps.libmkl, "MKL_Set_Num_Threads", None)
        if setter is not None:
            setter(ctypes.c_int(threads))

    def solve(self, data: np.ndarray, ia: np.ndarray, ja: np.ndarray, b: np.ndarray,
              reuse_analysis: bool, ordering: np.ndarray | None = None, keep_ordering: bool = False) -> np.ndarray:
        """Solution for the upper triangle given as CSR ``data`` with 1-based int32 ``ia``
        (row pointers) and ``ja`` (sorted column indices): phase 23 (numerical factorisation +
        solve) reusing the last analysis, or 13 (analysis too; for the Cholesky, 11 and then 23,
        see :attr:`analysis_kept`). An analysis takes ``ordering``
        (a fill-reducing permutation of these n unknowns, PARDISO's ``perm``) as its ordering
        (iparm(5) = 1: only the symbolic factorisation runs) or, None, computes one (iparm(2)),
        left in :attr:`ordering` where ``keep_ordering`` (iparm(5) = 2; else iparm(5) = 0 and
        :attr:`ordering` None)."""
        ps = self._ps
        n = len(ia) - 1
        if b.shape != (n,):
            raise ValueError(f"right-hand side of shape {b.shape} for a matrix of {n} rows")
        b = np.ascontiguousarray(b, dtype=self._dtype)
        data = np.ascontiguousarray(data, dtype=self._dtype)
        if not reuse_analysis:
            self._dense = self.is_dense(len(ja), n)
            if 2 in self.settings:
                ps.iparm[1] = self.dense_ordering if self._dense else self.settings[2]
            if ordering is not None:
                if ordering.shape != (n,):
                    raise ValueError(f"an ordering of {ordering.shape} for a matrix of {n} rows")
                self.ordering = np.array(ordering, dtype=np.int32)
                ps.iparm[4] = 1  # iparm(5) = 1: perm is the user's ordering
            elif keep_ordering:
                self.ordering = np.zeros(n, dtype=np.int32)
                ps.iparm[4] = 2  # iparm(5) = 2: PARDISO writes the ordering it computed to perm
            else:
                self.ordering = None
                ps.iparm[4] = 0
            ps.perm = self.ordering if self.ordering is not None else np.zeros(0, dtype=np.int32)
            ps.iparm[17] = -1  # iparm(18) < 0: report the factor's entries (overwritten by each report)
        refine_later = not self.forced_refinement
        ps.iparm[7] = 0 if refine_later else self._refinement
        self._factorised = None
        phase = 23 if reuse_analysis else 13
        if not reuse_analysis:
            self.analysis_kept = False
            if self.mtype == 2:
                self._call(11, data, ia, ja, b)
                self.analysis_kept, phase = True, 23
        x = self._call(phase, data, ia, ja, b)
        self.analysis_kept = True
        ps.iparm[4] = 0  # the numerical phases of later calls ignore perm either way
        if refine_later and self._refinement and ps.iparm[13] > 0:  # perturbed pivots: refine
            ps.iparm[7] = self._refinement
            x = self._call(33, data, ia, ja, b)
        self._factorised = (data, ia, ja)
        return x.astype(np.float64, copy=False)

    @property
    def _dtype(self):
        return np.float32 if self.single else np.float64

    def resolve(self, b: np.ndarray) -> np.ndarray:
        """Solution for another right-hand side b (n,) with the last factorisation (phase 33: the
        substitution only)."""
        if self._factorised is None:
            raise ValueError("nothing factorised to solve with")
        data, ia, ja = self._factorised
        if b.shape != (len(ia) - 1,):
            raise ValueError(f"right-hand side of shape {b.shape} for a matrix of {len(ia) - 1} rows")
        return self._call(33, data, ia, ja, np.ascontiguousarray(b, dtype=self._dtype)).astype(np.float64, copy=False)

    def _call(self, phase: int, data: np.ndarray, ia: np.ndarray, ja: np.ndarray, b: np.ndarray) -> np.ndarray:
        """PARDISO's ``phase`` on this handle: the solution x (phases with a solve); each call
        logged in :attr:`calls` where that is a list."""
        if self.calls is None:
            return self._pardiso_call(phase, data, ia, ja, b)
        t0, failed = time.perf_counter(), True
        try:
            x = self._pardiso_call(phase, data, ia, ja, b)
            failed = False
            return x
        finally:
            self.calls.append((phase, "Cholesky" if self.mtype == 2 else "LDL^T", time.perf_counter() - t0, failed))

    def _pardiso_call(self, phase: int, data: np.ndarray, ia: np.ndarray, ja: np.ndarray, b: np.ndarray) -> np.ndarray:
        ps = self._ps
        n = len(ia) - 1
        x = np.zeros_like(b)
        err = ctypes.c_int32(0)
        i32 = ctypes.POINTER(ctypes.c_int32)
        real = ctypes.POINTER(ctypes.c_float if self.single else ctypes.c_double)
        ps._mkl_pardiso(
            ps.pt.ctypes.data_as(ctypes.POINTER(ps._pt_type[0])),
            ctypes.byref(ctypes.c_int32(1)), ctypes.byref(ctypes.c_int32(1)),  # maxfct, mnum
            ctypes.byref(ctypes.c_int32(ps.mtype)),
            ctypes.byref(ctypes.c_int32(phase)),
            ctypes.byref(ctypes.c_int32(n)),
            data.ctypes.data_as(real), ia.ctypes.data_as(i32), ja.ctypes.data_as(i32),
            ps.perm.ctypes.data_as(i32),
            ctypes.byref(ctypes.c_int32(1)),  # nrhs
            ps.iparm.ctypes.data_as(i32),
            ctypes.byref(ctypes.c_int32(ps.msglvl)),
            b.ctypes.data_as(real), x.ctypes.data_as(real),
            ctypes.byref(err),
        )
        if err.value != 0:
            raise self.error(err.value)
        return x

    def release(self) -> None:
        """Free all of MKL's memory for this handle (before analysing a new pattern)."""
        self._factorised = None
        self._ps.free_memory(everything=True)

    def negative_eigenvalues(self) -> int:
        """Inertia of the last factorised matrix: its number of negative eigenvalues (0 after a
        Cholesky factorisation, which exists only for a positive definite matrix)."""
        return 0 if self.mtype == 2 else int(self._ps.get_iparm(23))

    def factor_entries(self) -> int:
        """Entries of the last analysis's factor (iparm(18)): its fill."""
        return int(self._ps.iparm[17])


class _UpperPattern:
    """One sparsity pattern of the upper triangle that PARDISO sees (sorted CSR ``indptr``,
    ``indices``, kept 0-based for the bookkeeping kernels): 1-based int32 ``ia``/``ja`` for
    PARDISO, ``key`` identifying it (the analysis is reused while it stays) and whether some row
    is empty (PARDISO would crash)."""

    def __init__(self, indptr: np.ndarray, indices: np.ndarray, hinted: bool = False):
        self.n, self.nnz = len(indptr) - 1, len(indices)
        self.indptr = np.ascontiguousarray(indptr, dtype=np.int64)
        self.indices = np.ascontiguousarray(indices, dtype=np.int64)
        self.ia = (self.indptr + 1).astype(np.int32)
        self.ja = (self.indices + 1).astype(np.int32)
        self.empty_row = not np.diff(indptr).all()
        self.hinted = hinted
        """Whether it holds a reach pattern (:meth:`LinearSolver.solve`): kept until a matrix
        leaves it, however little of it the matrices fill."""
        self.key = (self.n, hash(self.ia.tobytes()), hash(self.ja.tobytes()))


class _Gather:
    """How a matrix of one sparsity pattern (sorted CSR ``indptr``, ``indices``) lands on an
    :class:`_UpperPattern`: its upper entries ``data[src]`` are stored at ``dst`` of ``pattern``."""

    def __init__(self, indptr: np.ndarray, indices: np.ndarray):
        self.indptr, self.indices = indptr.copy(), indices.copy()
        self.pattern: _UpperPattern | None = None
        self.src: np.ndarray | None = None
        self.dst: np.ndarray | None = None

    def matches(self, K: sp.csr_matrix) -> bool:
        """Whether K has this sparsity pattern."""
        return np.array_equal(self.indptr, K.indptr) and np.array_equal(self.indices, K.indices)


def _kernels():
    """fem/_kernels.py, imported on first use (``import hydrojam`` does not load numba)."""
    from hydrojam.fem import _kernels as k

    return k


class LinearSolver:
    """Solve K u = b for symmetric sparse K.

    ``seconds`` accumulates the wall time spent in solves [s], ``calls`` the solves and
    ``analyses`` PARDISO's symbolic analyses among them (for benchmarks). Reads
    ``HYDROJAM_SOLVER_THREADS`` (MKL threads, a positive integer; default 1) and
    ``HYDROJAM_REUSE_ANALYSIS`` (0 or 1; default 1) when constructed.

    Parameters
    ----------
    method : {"auto", "pardiso", "scipy"}, optional
        PARDISO, SciPy's SuperLU, or "auto": PARDISO where it loads, else SciPy's SuperLU.

    Raises
    ------
    ValueError
        For an unknown ``method`` or an invalid environment setting.
    """

    reuse_ordering: bool = True
    """Whether a new dense pattern (3D: more than ``_Pardiso.dense_row`` upper entries a row,
    ordered by METIS) is analysed with the last fill-reducing ordering (PARDISO's iparm(5) = 1)
    instead of computing one: METIS's ordering is about half of an analysis, and a few new
    contact couplings hardly change what a good one is (docs/solver.md, "Linear solver"). 2D
    patterns (minimum degree, a cheap ordering) keep computing theirs, and their bits."""
    use_reach: bool = True
    """Whether :meth:`solve` heeds its ``reach`` hint (False: the union of the patterns seen
    lately, as without a hint; docs/solver.md, "A changing contact pattern")."""
    use_cholesky: bool = True
    """Whether a solve that asks for a positive definite matrix (``definite``) on a dense pattern
    (3D) runs PARDISO's Cholesky (mtype 2) instead of its LDL^T (-2): a faster factorisation
    that fails fast where the matrix is not positive definite, which is then all such a caller
    needs to know (docs/solver.md, "Linear solver"). 2D patterns keep the LDL^T and their bits."""
    reorder_fill: float = 1.05
    """The ordering is computed afresh at the next analysis once the factor of an analysis on a
    reused ordering holds more than this times the entries per matrix entry of the analysis that
    computed it."""

    mixed_precision: bool = True
    """Whether the Cholesky factorisations (:attr:`use_cholesky`: definite solves on dense
    patterns) run in single precision (PARDISO's iparm(28) = 1), their solutions refined in
    double against the double matrix (:attr:`refinement_tolerance`): about half the time of a
    3D factorisation. The LDL^T (the inertia of the stability check, ``lowest_mode``, 2D) stays
    in double (docs/solver.md, "Mixed precision")."""
    refinement_tolerance: float = 1e-8
    """Relative residual ||K u - b|| / ||b|| to which a single-precision solution is refined in
    double (two decades below Newton's ``linear_residual``, which a direction must meet), at
    most :attr:`refinement_steps` substitutions; a refinement that stops gaining at least half
    the residual a step stops."""
    refinement_steps: int = 6
    """The most refinement steps (substitutions) a single-precision solution takes."""

    def __init__(self, method: str = "auto", observers: Sequence[Observer] = ()):
        if method not in ("auto", "pardiso", "scipy"):
            raise ValueError(f"linear solver must be 'auto', 'pardiso' or 'scipy' (got {method!r})")
        if method == "auto":
            method = "pardiso" if _pardiso_available() else "scipy"
        self.method = method
        self.observers = tuple(observers)
        """Observers of every solve and resolve (:class:`~hydrojam.fem.solver.events.LinearSolve`)."""
        self.log: list | None = None
        """Where not None, every solve's and resolve's :class:`~hydrojam.fem.solver.events.LinearSolve`
        is appended to it too (Newton collects the solves of a direction so while it has observers)."""
        self._watch: list | None = None  # PARDISO's calls of the solve under way, while watched
        self._split = [0.0, 0.0]  # its pattern bookkeeping and refinement seconds, while watched
        self.seconds = 0.0
        self.calls = 0
        self.analyses = 0
        self.refinements = 0
        """Substitutions that refined a single-precision solution (:attr:`mixed_precision`)."""
        self._pardiso: _Pardiso | None = None  # the handle of the last solve
        self._analysed = None  # the pattern key its analysis is of
        self._parked: dict[int, tuple[_Pardiso, object]] = {}  # the other handle and its analysis, by mtype
        self._union: _UpperPattern | None = None
        self._gathers: list[_Gather] = []
        self._kept_patterns = 4
        self.negative_eigenvalues: int | None = None
        """Negative eigenvalues of the last matrix solved (PARDISO's inertia; a diagnostic for
        stability studies); None where the backend does not report it."""
        self.reorderings = 0
        self._ordering: np.ndarray | None = None
        self._ordered_fill_of = (0, 1)  # factor and matrix entries of the analysis that computed it
        self._restored_ordering: tuple[_UpperPattern, np.ndarray] | None = None  # (restored union, its ordering)
        self._scipy_matrix: sp.csr_matrix | None = None  # the last matrix SciPy solved
        self._single_matrix: sp.csr_matrix | None = None  # the last matrix factorised in single precision
        self.threads = positive_int("HYDROJAM_SOLVER_THREADS", 1)
        self.reuse_analysis = flag("HYDROJAM_REUSE_ANALYSIS", True)

    def _take_handle(self, mtype: int) -> None:
        """Make the PARDISO handle of ``mtype`` the current one (each keeps its own analysis)."""
        if self._pardiso is not None and self._pardiso.mtype == mtype:
            return
        if self._pardiso is not None:
            self._parked[self._pardiso.mtype] = (self._pardiso, self._analysed)
        self._pardiso, self._analysed = self._parked.pop(mtype, (None, None))
        if self._pardiso is None:
            self._pardiso = _Pardiso(self.threads, mtype, single=mtype == 2 and self.mixed_precision)

    def _solve_pardiso(self, K: sp.csr_matrix, b: np.ndarray, reach=None, definite: bool = False) -> np.ndarray:
        if not K.has_canonical_format:  # duplicates or unsorted: sum them as triu's COO route does
            K = sp.triu(K, format="csr")
            K.sort_indices()
        t0 = time.perf_counter() if self._watch is not None else 0.0
        pattern, data = self._on_union_pattern(self._gather(K), K, reach)
        if self._watch is not None:
            self._split[0] += time.perf_counter() - t0
        cholesky = definite and self.use_cholesky and _Pardiso.is_dense(pattern.nnz, pattern.n)
        self._take_handle(2 if cholesky else -2)
        self._pardiso.calls = self._watch
        if pattern.empty_row:  # PARDISO would crash on it (pypardiso refuses it too)
            raise LinearSolveError("pardiso: matrix is singular (an empty row)")
        # The symbolic analysis (ordering) depends only on the sparsity pattern: reuse it while the
        # pattern stays (phase 23 = numerical factorisation + solve), redo it when contact changes
        # it (phase 13): the analysis is a large share of a 2D solve.
        if self._analysed is not None and pattern.key != self._analysed:
            # MKL wrote out of bounds when one handle was re-analysed for a new pattern: start clean
            self._pardiso.release()
        reuse = pattern.key == self._analysed and self.reuse_analysis
        self.analyses += not reuse
        ordering = None
        keep = self.reuse_ordering and _Pardiso.is_dense(pattern.nnz, pattern.n)
        if not reuse and self._restored_ordering is not None and pattern is self._restored_ordering[0]:
            ordering = self._restored_ordering[1]  # the analysis the restored solver had made
        elif not reuse and keep and self._ordering is not None and len(self._ordering) == pattern.n:
            ordering = self._ordering
        self._restored_ordering = None
        try:
            x = self._pardiso.solve(data, pattern.ia, pattern.ja, b, reuse, ordering, keep)
        except self._pardiso.error as exc:  # a failed factorisation (zero pivot, ...)
            if not reuse:  # the handle was released for this pattern: its analysis, if it was kept
                self._analysed = pattern.key if self._pardiso.analysis_kept else None
                if self._pardiso.analysis_kept:
                    self._count_analysis(pattern, ordering)
            self.negative_eigenvalues = None
            if cholesky:
                raise NotPositiveDefinite(f"pardiso (Cholesky): {exc}") from exc
            raise LinearSolveError(f"pardiso: {exc}") from exc
        self._analysed = pattern.key
        if not reuse:
            self._count_analysis(pattern, ordering)
        self.negative_eigenvalues = self._pardiso.negative_eigenvalues()
        if not self._pardiso.single:
            return x
        self._single_matrix = K  # what resolve() refines against
        return self._refined(K, b, x)

    def _refined(self, K: sp.csr_matrix, b: np.ndarray, x: np.ndarray) -> np.ndarray:
        """:meth:`_refine`, its time counted while watched."""
        if self._watch is None:
            return self._refine(K, b, x)
        t0 = time.perf_counter()
        try:
            return self._refine(K, b, x)
        finally:
            self._split[1] += time.perf_counter() - t0

    def _refine(self, K: sp.csr_matrix, b: np.ndarray, x: np.ndarray) -> np.ndarray:
        """A single-precision solution x of K x = b refined in double: x += the substitution of
        the residual b - K x, while the relative residual is above :attr:`refinement_tolerance`
        and each step at least halves it (the best x is returned)."""
        target = self.refinement_tolerance * float(np.linalg.norm(b))
        r = b - K @ x
        rn = float(np.linalg.norm(r))
        for _ in range(self.refinement_steps):
            if not rn > target:  # also stops on a NaN, which solve() reports
                break
            self.refinements += 1
            xn = x + self._pardiso.resolve(r)
            r_new = b - K @ xn
            rn_new = float(np.linalg.norm(r_new))
            if not rn_new < rn:  # no gain: keep the best x
                break
            halved = rn_new <= 0.5 * rn
            x, r, rn = xn, r_new, rn_new
            if not halved:
                break
        return x

    def _count_analysis(self, pattern: _UpperPattern, ordering: np.ndarray | None) -> None:
        """After an analysis of ``pattern`` on ``ordering`` (None: one computed): keep a computed
        ordering and its fill, or drop a reused one whose fill grew past ``reorder_fill``."""
        entries = self._pardiso.factor_entries()
        if ordering is None:
            self.reorderings += 1
            self._ordering, self._ordered_fill_of = self._pardiso.ordering, (entries, pattern.nnz)  # None unless kept
        elif entries * self._ordered_fill_of[1] > self.reorder_fill * self._ordered_fill_of[0] * pattern.nnz:
            self._ordering = None  # the next analysis orders afresh

    def _solve_scipy(self, K: sp.csr_matrix, b: np.ndarray) -> np.ndarray:
        self.negative_eigenvalues = None
        self._scipy_matrix = None
        with warnings.catch_warnings():
            warnings.simplefilter("error", spla.MatrixRankWarning)
            try:
                x = spla.spsolve(K.tocsc(), b)
            except (spla.MatrixRankWarning, RuntimeError) as exc:  # SuperLU: singular factor
                raise LinearSolveError(f"scipy: {exc}") from exc
        self._scipy_matrix = K
        return x

    def _gather(self, K: sp.csr_matrix) -> _Gather:
        """The upper-triangle gather of K's sparsity pattern: the last few patterns are kept, as
        contacts come and go between a few sets within a Newton iteration and its retries."""
        for i, g in enumerate(self._gathers):
            if g.matches(K):
                if i:
                    self._gathers.insert(0, self._gathers.pop(i))
                return g
        g = _Gather(K.indptr, K.indices)
        self._gathers = [g] + self._gathers[: self._kept_patterns - 1]
        return g

    def _on_union_pattern(self, g: _Gather, K: sp.csr_matrix, reach=None) -> tuple[_UpperPattern, np.ndarray]:
        """K's upper triangle stored on the union of the sparsity patterns seen lately (explicit
        zeros where it has no entry), so that contacts coming and going do not change the pattern
        and PARDISO's analysis is reused: the pattern and the values on it.

        Without ``reach``, a new entry merges K's pattern into the union, and the union restarts
        from K's own pattern when that fills less than 70% of it (contacts long gone would only
        slow the factorisation). With ``reach`` (see :meth:`solve`), a new entry restarts the
        union from K's pattern and the pattern ``reach()`` gives, and that union stays, however
        little of it later matrices fill, until one leaves it. Without analysis reuse, K's own
        pattern. Where K's entries lie in the union and the merge of the two are compiled
        row-by-row walks of the sorted rows (fem/_kernels.py): exact, so the same patterns as any
        other way of finding them."""
        u = self._union
        if g.pattern is None or g.pattern is not u:
            k = _kernels()
            pos, hint = None, None
            n = K.shape[0]
            reach = reach if self.reuse_analysis and self.use_reach else None
            if self.reuse_analysis and u is not None and u.n == K.shape[0]:
                pos, missing = k.upper_positions(K.indptr, K.indices, u.indptr, u.indices)
                if missing and reach is not None:
                    hint = reach()
                if hint is not None:
                    pos = None  # restart from K's pattern and the reach
                elif not u.hinted and np.count_nonzero(pos != -2) < 0.7 * u.nnz:
                    pos = None  # restart from K's own pattern
                elif missing:  # merge: the union of the two patterns
                    u = _UpperPattern(*k.merge_upper(K.indptr, K.indices, u.indptr, u.indices))
                    pos, _ = k.upper_positions(K.indptr, K.indices, u.indptr, u.indices)
            elif reach is not None:
                hint = reach()
            if pos is None:
                base = (np.zeros(n + 1, dtype=np.int64), np.zeros(0, dtype=np.int64))
                if hint is not None:
                    R = sp.csr_matrix(hint, dtype=np.float64)
                    if R.shape != K.shape:
                        raise ValueError(f"a reach pattern of shape {R.shape} for a matrix of shape {K.shape}")
                    R.sum_duplicates()  # canonical: sorted rows
                    base = k.merge_upper(R.indptr, R.indices.astype(np.int64), *base)
                u = _UpperPattern(*k.merge_upper(K.indptr, K.indices, *base), hinted=hint is not None)
                pos, _ = k.upper_positions(K.indptr, K.indices, u.indptr, u.indices)
            g.src = np.flatnonzero(pos >= 0)
            self._union, g.pattern, g.dst = u, u, pos[g.src]
        data = np.zeros(u.nnz)
        data[g.dst] = K.data[g.src]
        return u, data

    @property
    def pattern(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The state the next solve builds on, as two int64 arrays, or None: the union pattern
        (0-based CSR ``indptr``, ``indices`` of the upper triangle) and, after the pattern's
        ``indptr[-1]`` entries in ``indices``, the orderings (:attr:`reuse_ordering`): the one the
        union was analysed with and the one the next new pattern would reuse, each as its length
        and entries, then the fill that decides when to order afresh (factor entries, matrix
        entries) and whether the union holds a reach pattern (1, else 0; absent in records
        written before there was a reach). With :meth:`restore_pattern`, a new solver goes on as this one would have (the
        same patterns and orderings, hence the same round-off)."""
        if self._union is None:
            return None
        tail = []
        analysed = self._pardiso.ordering if self._pardiso is not None and self._analysed == self._union.key else None
        for ordering in (analysed, self._ordering):
            tail.append(np.array([0 if ordering is None else len(ordering)]))
            if ordering is not None:
                tail.append(ordering)
        tail.append(np.array(self._ordered_fill_of + (int(self._union.hinted),), dtype=np.int64))
        indices = np.concatenate([self._union.ja - 1] + tail).astype(np.int64)
        return (self._union.ia - 1).astype(np.int64), indices

    def restore_pattern(self, pattern: tuple[np.ndarray, np.ndarray] | None) -> None:
        """Start from ``pattern`` (another solver's :attr:`pattern`): its union pattern, the
        ordering its first analysis uses and the orderings state after it."""
        self._gathers = []
        self._restored_ordering = None
        if pattern is None:
            self._union = None
            return
        indptr, indices = np.asarray(pattern[0]), np.asarray(pattern[1])
        nnz = int(indptr[-1])
        self._union = _UpperPattern(indptr, indices[:nnz])
        tail, orderings = indices[nnz:], []
        for _ in range(2):
            if not len(tail):
                orderings.append(None)
                continue
            m = int(tail[0])
            orderings.append(tail[1:1 + m].astype(np.int32) if m else None)
            tail = tail[1 + m:]
        if orderings[0] is not None and len(orderings[0]) == self._union.n:
            self._restored_ordering = (self._union, orderings[0])
        self._ordering = orderings[1]
        if len(tail) >= 2:
            self._ordered_fill_of = (int(tail[0]), int(tail[1]))
        self._union.hinted = len(tail) == 3 and bool(tail[2])

    def solve(self, K: sp.spmatrix, b: np.ndarray, reach: Callable[[], sp.spmatrix] | None = None,
              definite: bool = False) -> np.ndarray:
        """Solution u of K u = b.

        Parameters
        ----------
        K : sparse matrix, shape (n, n)
            Symmetric.
        b : ndarray, shape (n,)
            The right-hand side.
        reach : callable, optional
            Gives a sparsity pattern of K's shape (a sparse matrix; its values are ignored) that
            the matrices to come are likely to lie in: every coupling the contacts within reach
            of the current state could bring. Called only when K brings an entry that the last
            analysis did not have; the new analysis is then made on K's pattern and this one
            together, so that the next matrices within it reuse it. A hint for the factorisation's
            bookkeeping: the solution does not depend on it.
        definite : bool, optional
            The caller needs K positive definite and has no use for a solution otherwise (a
            Newton step with the inertia correction): on dense patterns (3D) K is factorised by
            Cholesky (:attr:`use_cholesky`), and a K that is not positive definite raises
            :class:`NotPositiveDefinite` instead of being solved.

        Returns
        -------
        ndarray, shape (n,)

        Raises
        ------
        LinearSolveError
            If K is singular (the factorisation fails) or u is not finite. Anything else (a wrong
            shape, a bug) propagates as it is.
        NotPositiveDefinite
            With ``definite``, where the Cholesky factorisation meets a pivot that is not positive.
        """
        if self.observers or self.log is not None:
            return self._watched("solve", self._solve, K, b, reach, definite)
        return self._solve(K, b, reach, definite)

    def _solve(self, K, b, reach, definite) -> np.ndarray:
        t0 = time.perf_counter()
        K = sp.csr_matrix(K, dtype=np.float64)
        b = np.asarray(b, dtype=np.float64)
        try:
            x = self._solve_pardiso(K, b, reach, definite) if self.method == "pardiso" else self._solve_scipy(K, b)
        finally:
            self.seconds += time.perf_counter() - t0
            self.calls += 1
        if not np.all(np.isfinite(x)):
            raise LinearSolveError(f"{self.method}: solution is not finite (singular matrix?)")
        return x

    def _watched(self, call: str, function, *args) -> np.ndarray:
        """``function(*args)`` (a solve or resolve) reported to the observers and the log as a
        :class:`~hydrojam.fem.solver.events.LinearSolve`."""
        self._watch, self._split = [], [0.0, 0.0]
        analyses, failed, refused = self.analyses, True, False
        t0 = time.perf_counter()
        try:
            x = function(*args)
            failed = False
            return x
        except NotPositiveDefinite:
            refused = True
            raise
        finally:
            seconds = time.perf_counter() - t0
            calls, self._watch = tuple(self._watch), None
            if self._pardiso is not None:
                self._pardiso.calls = None
            event = LinearSolve(call, self.method, self.analyses > analyses, failed, refused,
                                None if failed else self.negative_eigenvalues, seconds, self._split[0],
                                self._split[1], calls)
            if self.log is not None:
                self.log.append(event)
            notify(self.observers, "on_linear_solve", event)

    def resolve(self, b: np.ndarray, approximate: bool = False) -> np.ndarray:
        """Solution u of K u = b for the matrix K of the last successful :meth:`solve`, reusing its
        factorisation (PARDISO's substitution alone; SciPy solves again): many right-hand sides for
        one matrix, as a preconditioner needs.

        Parameters
        ----------
        b : ndarray, shape (n,)
        approximate : bool, optional
            After a single-precision factorisation (:attr:`mixed_precision`), the substitution
            alone, not refined in double: a relative residual of about 1e-4 or better, enough for a
            preconditioner. Without it (and after a double factorisation) u is as accurate as
            :meth:`solve`'s.

        Returns
        -------
        ndarray, shape (n,)

        Raises
        ------
        ValueError
            If nothing was factorised (no solve yet, or the last one failed) or b has the wrong shape.
        LinearSolveError
            If u is not finite.
        """
        if self.observers or self.log is not None:
            return self._watched("resolve", self._resolve, b, approximate)
        return self._resolve(b, approximate)

    def _resolve(self, b: np.ndarray, approximate: bool) -> np.ndarray:
        t0 = time.perf_counter()
        b = np.asarray(b, dtype=np.float64)
        try:
            if self.method == "pardiso":
                if self._pardiso is None:
                    raise ValueError("nothing factorised to solve with")
                self._pardiso.calls = self._watch
                x = self._pardiso.resolve(b)
                if self._pardiso.single and not approximate:
                    x = self._refined(self._single_matrix, b, x)
            else:
                if self._scipy_matrix is None:
                    raise ValueError("nothing factorised to solve with")
                n = self._scipy_matrix.shape[0]
                if b.shape != (n,):
                    raise ValueError(f"right-hand side of shape {b.shape} for a matrix of {n} rows")
                x = self._solve_scipy(self._scipy_matrix, b)
        finally:
            self.seconds += time.perf_counter() - t0
        if not np.all(np.isfinite(x)):
            raise LinearSolveError(f"{self.method}: solution is not finite (singular matrix?)")
        return x
