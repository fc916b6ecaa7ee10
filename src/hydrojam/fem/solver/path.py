"""The adaptive load path (docs/solver.md, "Load path"): s from 0 to 1 in increments, each a Newton
minimisation (:mod:`hydrojam.fem.solver.newton`) of a :class:`~hydrojam.fem.problem.Problem`'s terms."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.sparse as sp

from hydrojam.fem._env import blas_limited
from hydrojam.fem.problem import Problem
from hydrojam.fem.solver.events import Observer, StepAccepted, notify
from hydrojam.fem.solver.linsolve import LinearSolver, LinearSolveError
from hydrojam.fem.solver.newton import NewtonOptions, NewtonResult, NewtonStatus, Timings, minimize
from hydrojam.fem.solver.release import ReleaseOptions, ReleaseResult, release
from hydrojam.fem.solver.stability import negative_curvature, settle
from hydrojam.fem.solver.total import physical_residual, sum_energy
from hydrojam.fem.terms import DampedTerm


#: s within this of 1 counts as the end of the path
END_TOLERANCE = 1e-12
#: name of the damped term (a viscous stabilisation) whose ``scale`` the adaptive damping sets
DAMPED_TERM = "stabilisation"
#: settling off a saddle (:func:`~hydrojam.fem.solver.stability.settle`) starts from a largest
#: nodal move of this times the reference's bounding box diagonal along the unstable mode
SETTLE_PERTURBATION = 1e-5


@dataclass(frozen=True)
class PathOptions:
    """Adaptive load stepping in s: grow ``grow`` times after easy steps (<= ``easy_iterations``),
    halve on failure, and after a cut grow back ``grow`` times every accepted step, easy or not, up to
    the largest increment cut (without it a path whose steps all take more than
    ``easy_iterations``, as 3D actuators' do, never recovers from a cut: docs/solver.md); below
    ``ds_min`` one last attempt with ``last_resort_factor`` x the Newton iteration budget, then
    give up. A term named "stabilisation" with a ``scale`` (:class:`~hydrojam.fem.terms.DampedTerm`)
    is damped adaptively and released at every accepted step (``damping_*``, ``release``)."""

    ds0: float = 0.25
    """The first increment of s (default 0.25)."""
    ds_min: float = 1e-4
    """The smallest increment before the last attempt and the end (default 1e-4)."""
    ds_max: float = 1.0
    """The largest increment (default 1)."""
    grow: float = 1.5
    """Factor on the increment after an easy step (default 1.5)."""
    easy_iterations: int = 6
    """A step of at most this many Newton iterations is easy (default 6; the actuator's path 30)."""
    newton: NewtonOptions = NewtonOptions()
    """The Newton settings of every step (default :class:`NewtonOptions`'s)."""
    last_resort_factor: int = 10
    """The last attempt's Newton budget, in units of ``newton.max_iter`` (default 10)."""
    stability_check: bool = True
    """Count the negative eigenvalues of the physical Hessian at every accepted state
    (:func:`~hydrojam.fem.solver.stability.negative_curvature`, one more factorisation a step; see
    :attr:`StepRecord.negative_eigenvalues`). Default True."""
    unphysical_terms: tuple[str, ...] = ("stabilisation",)
    """Names of the terms that are not physics (a viscous stabilisation): left out of the
    stability check (default ("stabilisation",))."""
    settle: Literal["final", "never"] = "final"
    """Whether a final state found unstable by the stability check (a saddle: Newton converges to
    any stationary point) is moved off it to a stable one
    (:func:`~hydrojam.fem.solver.stability.settle`): "final" (default) or "never"."""
    damping_growth: float = 10.0
    """Adaptive damping (as ABAQUS's adaptive automatic stabilisation): a step whose Newton
    minimisation fails (out of iterations, no descent) is retried at the same increment with the
    damped term's scale times this (up to ``max_damping``) before the increment is cut; every
    easy step divides it again, down to where the path started. 1: off (default 10). A snap that
    the weak damping lets travel far within one step then travels in several damped steps."""
    max_damping: float = 100.0
    """Largest scale of the damped term, relative to the scale it was built with (default 100)."""
    damping_start: float = 1.0
    """The damped term's scale where the path starts and to which easy steps lower it again,
    relative to the scale it was built with (default 1). 0 (the actuator's path): every step is
    first tried undamped, and the damping (the built scale, then ``damping_growth`` times more)
    comes in only for a step that fails without it, as ABAQUS's adaptive automatic stabilisation."""
    extrapolate: bool = True
    """Start every step after the first from the linear extrapolation of the last increment (the
    positions' change over the last accepted step, scaled to this one's ds; ABAQUS's default
    predictor), shortened (1, 1/2, 1/4, 0) until admissible and collision-free like any step
    (default True)."""
    undamped_blocks: int = 1
    """An undamped attempt (the damped term at scale 0, :attr:`damping_start` 0) that runs out of
    iterations goes on from its last iterate (admissible, and lower in energy) for up to this many
    blocks of ``newton.max_iter`` iterations in all before the damping comes in: a snap must
    travel, and undamped Newton travels it without the release a damped step then needs. 1: off
    (default; the actuator's path 3)."""
    damped_from_blocks: bool = False
    """Where the last undamped block ran out too, the damped attempts of the step start from its
    last iterate, with the lagged quantities (friction, the damping's centre) frozen there as at
    a step's start, instead of from the step's start: the blocks' travel is kept, and the damping
    does not hold the state back to where the step began (default False; the actuator's path True)."""
    release: ReleaseOptions = ReleaseOptions()
    """How the damped term is taken off at every accepted step (default :class:`ReleaseOptions`'s)."""
    damping_relax_after: int = 0
    """With N > 0, a raised damping is also divided by ``damping_growth`` after N accepted steps
    in a row at its level, easy or not (as the increment after a cut); 0 (default): only easy
    steps lower it. A path whose damping was never raised is not touched, to the bit. The
    actuator's path (:data:`hydrojam.actuator.simulate.ACTUATOR_PATH`) relaxes after every step,
    since it starts every step undamped (docs/solver.md, "Relaxing the damping")."""

    def __post_init__(self):
        if self.settle not in ("final", "never"):
            raise ValueError(f"settle must be final or never, not {self.settle!r}")


@dataclass(frozen=True)
class StepRecord:
    """One accepted load step: s reached, increment ds, Newton iterations, residual [N], energy
    [mJ], wall time [s] and the stability of the state reached (``negative_eigenvalues``)."""

    s: float
    ds: float
    iterations: int
    residual: float
    energy: float
    seconds: float
    negative_eigenvalues: int | None = None
    """Negative eigenvalues of the physical energy's unprojected Hessian over the free DOFs at
    the accepted state (terms in ``PathOptions.unphysical_terms`` left out): 0 for a stable
    equilibrium; > 0 where the state is not a minimum of the physics (the path passes an
    instability: a saddle reached by symmetry, or a state the stabilisation holds while it
    travels through a snap). None without the check or without the inertia (SciPy)."""
    damping: float | None = None
    """Scale of the damped term ("stabilisation") in the step, relative to its scale
    at the start of the path (1 unless the adaptive damping raised it); None without the term."""
    rejected: int = 0
    """Attempts at this step that failed before it was accepted (each raised the damping or cut
    the increment); 0 in a record written before it was kept."""
    tolerance: float | None = None
    """The residual tolerance [N] that ``residual`` is held to (rtol x the forces in play at the
    state); None in a record written before it was kept."""
    release_rounds: int = 0
    """Proximal rounds that took the damped term off at this step (:func:`release`); their Newton
    iterations are counted in ``iterations``."""
    release_iterations: int = 0
    """Newton iterations of those rounds (part of ``iterations``)."""
    damped_energy: float = 0.0
    """Energy [mJ] of the damped term at the stabilised state the step converged to, before its
    release: what the stabilisation held back in the step."""


@dataclass(frozen=True)
class PathResult:
    """Outcome of a load path: the last converged state and the step history."""

    x: np.ndarray  # last converged positions (n, d) [mm]
    s: float  # load parameter reached
    converged: bool  # reached s = 1
    message: str
    history: list[StepRecord]
    timings: Timings
    rejected_steps: int

    @property
    def newton_iterations(self) -> int:
        """Newton iterations of all accepted steps."""
        return sum(h.iterations for h in self.history)

    @property
    def unstable_at_s(self) -> float | None:
        """Load parameter of the first accepted state with a negative eigenvalue of the physical
        Hessian (:attr:`StepRecord.negative_eigenvalues`); None if there is none."""
        return first_unstable_s(self.history)


@dataclass(frozen=True)
class PathCheckpoint:
    """Everything :func:`solve_path` needs to go on from an accepted state as if it had not
    stopped: positions x (flat) [mm], load parameter s, the next increment ds, the damped term's
    scale relative to its start (``damping``), the accepted steps so far, the rejected attempts
    and the time spent."""

    x: np.ndarray
    s: float
    ds: float
    damping: float
    history: tuple[StepRecord, ...]
    rejected: int
    timings: Timings
    solver_pattern: tuple[np.ndarray, np.ndarray] | None = None
    """The linear solver's union pattern (:attr:`~hydrojam.fem.solver.linsolve.LinearSolver.pattern`):
    restored, the resumed path sees the same matrices' patterns, hence the same round-off."""
    ds_cut: float | None = 0.0
    """The largest increment cut so far, to which the increment grows back after a cut (0: none
    cut); None where unknown (a checkpoint written before it was kept): taken as the path's
    first increment ``ds0`` if any step was rejected, else 0."""
    previous: tuple[np.ndarray, float] | None = None
    """The accepted state before this one (flat positions [mm]) and the increment between them: the
    extrapolation's (:attr:`PathOptions.extrapolate`); None at the first step or where unknown."""


def _steps_at(history, damping: float) -> int:
    """Accepted steps in a row, the last ones, whose damping scale is ``damping``, counted back to
    the last step that failed first (where the damping may have been raised back to this level
    after a relaxation that failed: the count starts again there)."""
    n = 0
    for rec in reversed(history):
        if rec.damping is None or abs(rec.damping - damping) > 1e-9 * damping:
            break
        n += 1
        if rec.rejected:
            break
    return n


def first_unstable_s(history) -> float | None:
    """The ``s`` of the first record in ``history`` (:class:`StepRecord`-like: ``s``,
    ``negative_eigenvalues``) with a negative eigenvalue; None if there is none."""
    for h in history:
        if h.negative_eigenvalues:
            return h.s
    return None


def _safe_move(terms, x: np.ndarray, step: np.ndarray) -> bool:
    """Whether the move from x by ``step`` (both (n, d) [mm]) is collision-free in full (no term's
    step cap, contact CCD, cuts it) and lands on a state of finite energy (admissible)."""
    return min([1.0] + [t.max_step(x, step) for t in terms]) >= 1.0 and np.isfinite(sum_energy(terms, x + step))


def _predictor(problem, terms, x, x_bc, free, solver):
    """Start of a load step whose prescribed DOFs move (x -> x_bc on them): the linearised response
    of the free DOFs, shortened until the move from x is admissible and collision-free (every
    term's step cap, so contact CCD sees the predictor like any Newton step). None if even moving
    the prescribed DOFs alone is not."""
    shape = problem.X.shape
    delta = x_bc - x
    if not np.any(delta):
        return x_bc
    fidx = np.flatnonzero(free)
    xs = x.reshape(shape)
    du = None
    H = sp.csr_matrix(sum(t.hessian(xs, True) for t in terms))
    try:
        du = solver.solve(H[fidx][:, fidx], -(H[fidx] @ delta))
    except LinearSolveError:
        pass
    for scale in (1.0, 0.5, 0.25, 0.0) if du is not None else (0.0,):
        trial = x_bc.copy()
        if scale:
            trial[fidx] += scale * du
        if _safe_move(terms, xs, (trial - x).reshape(shape)):
            return trial
    return None


def _extrapolated(terms, x, x_start, previous, ds, free, shape):
    """``x_start`` (flat [mm]) moved on the free DOFs by the last accepted increment (x - x_prev
    over ds_prev, ``previous`` = (x_prev, ds_prev)) scaled to ``ds``, shortened (1, 1/2, 1/4)
    until every term admits it and caps no part of it (contact CCD); ``x_start`` if none does."""
    x_prev, ds_prev = previous
    if ds_prev <= 0:
        return x_start
    delta = np.where(free, (x - np.asarray(x_prev).ravel()) * (ds / ds_prev), 0.0)
    if not np.any(delta):
        return x_start
    xs = x_start.reshape(shape)
    for scale in (1.0, 0.5, 0.25):
        if _safe_move(terms, xs, (scale * delta).reshape(shape)):
            return x_start + scale * delta
    return x_start


@dataclass
class _Walk:
    """What :func:`solve_path` carries from one attempt to the next: the last accepted state, the
    increment and its history, the damped term's level, and an attempt that goes on (a run-out
    undamped block, or the damped attempts' restart)."""

    solver: LinearSolver
    checker: LinearSolver | None
    free: np.ndarray
    shape: tuple
    x: np.ndarray  # the last accepted state, flat [mm]
    newton: NewtonOptions
    damped: DampedTerm | None = None
    base: float | None = None  # the damped term's built scale
    s: float = 0.0
    ds: float = 0.0
    rejected: int = 0
    ds_cut: float = 0.0
    previous: tuple[np.ndarray, float] | None = None  # the last accepted state but one, and ds since
    history: list[StepRecord] = dataclasses.field(default_factory=list)
    timings: Timings = dataclasses.field(default_factory=Timings)
    last_resort: bool = False
    failed_here: int = 0
    carry: np.ndarray | None = None  # an undamped attempt that ran out, going on (undamped_blocks)
    carried: int = 0
    carried_its: int = 0
    restart: np.ndarray | None = None  # where the step's damped attempts start (damped_from_blocks)
    observers: tuple = ()  # told what the path does (hydrojam.fem.solver.events)

    def result(self, converged: bool, message: str) -> PathResult:
        """The path's outcome at the last accepted state."""
        return PathResult(self.x.reshape(self.shape), self.s, converged, message, self.history, self.timings,
                          self.rejected)


@blas_limited
def solve_path(
    problem: Problem,
    options: PathOptions = PathOptions(),
    callback: Callable[[float, np.ndarray, StepRecord], None] | None = None,
    on_attempt: Callable[[float, float, NewtonResult], None] | None = None,
    resume: PathCheckpoint | None = None,
    on_checkpoint: Callable[[PathCheckpoint], None] | None = None,
    observers: Sequence[Observer] = (),
) -> PathResult:
    """Follow the load parameter s from 0 to 1 in adaptive increments, each an energy
    minimisation (:func:`~hydrojam.fem.solver.newton.minimize`), from the reference positions.

    Every term's ``begin_step`` runs at the start of the path (s = 0: nothing lagged survives from
    an earlier path on the same terms) and of every step. A term named "stabilisation" with a
    ``scale`` (a viscous stabilisation) is damped adaptively and released at every accepted step
    (:class:`PathOptions`); its scale is left where the path ended. With
    ``options.stability_check`` every accepted state's physical Hessian is tested for negative
    eigenvalues (:attr:`StepRecord.negative_eigenvalues`), and an unstable final state is settled
    off its saddle (``options.settle``).

    Parameters
    ----------
    problem : Problem
        Reference positions X (n, d) [mm], the terms at each s, the Dirichlet conditions and the
        force scale [N] (the floor of the residual tolerance).
    options : PathOptions, optional
        Step control, Newton settings, damping and its release.
    callback : callable, optional
        ``callback(s, x, record)`` after every accepted step: s, positions x (n, d) [mm] and its
        :class:`StepRecord`.
    on_attempt : callable, optional
        ``on_attempt(s_try, ds, newton_result)`` after every attempt, accepted or not (progress).
    resume : PathCheckpoint, optional
        A checkpoint of this problem's path (given to ``on_checkpoint``) to go on from instead of
        the reference positions (the equilibration at s = 0 skipped): the same path, bit for bit,
        as one in one go.
    on_checkpoint : callable, optional
        ``on_checkpoint(checkpoint)`` after every accepted step (after ``callback``) with what it
        takes to go on from there (:class:`PathCheckpoint`).
    observers : sequence of Observer, optional
        Told every linear solve, Newton direction, line search, iteration, release round and
        accepted step (:mod:`hydrojam.fem.solver.events`); none by default, at no cost.

    Returns
    -------
    PathResult
        The last converged positions x (n, d) [mm], the s reached, whether it is 1
        (``converged``), a message (where and why the path stopped, otherwise "converged"), the
        accepted steps' records and the Newton work.

    Raises
    ------
    ValueError
        For an invalid linear solver setting (``options.newton.linear_solver``, or the
        environment's ``HYDROJAM_SOLVER_THREADS``). A path that cannot go on does not raise: it
        returns its last converged state with ``converged`` False.

    Examples
    --------
    A square of rubber (plane strain, 1 x 1 mm) on rollers at its bottom and left edges, its top
    edge moved up 0.2 mm: the stretch is homogeneous, and the free right edge moves in to the
    lateral stretch at which the plane-strain neo-Hookean stress across it vanishes,
    dW/dlambda1 = 0 at lambda2 = 1.2 (solved here by bisection):

    >>> from scipy.optimize import brentq
    >>> from hydrojam import NeoHookean
    >>> from hydrojam.fem import Block, Problem, Solid, element_for_meshio_type, fixed, prescribed, rectangle
    >>> rubber = NeoHookean()                               # G = 0.023 MPa, Poisson's ratio 0.45
    >>> mesh = rectangle(1.0, 1.0, 0.5, order=2)            # mm, quadratic triangles
    >>> solid = Solid(mesh.points, [Block(mesh.cells, element_for_meshio_type(mesh.cell_type), rubber, "rubber")])
    >>> g = mesh.group_nodes
    >>> bcs = [fixed(g("bottom"), 2, [1]), fixed(g("left"), 2, [0]), prescribed(g("top"), 2, 1, 0.2)]
    >>> result = solve_path(Problem(mesh.points, lambda s: [solid], bcs, force_scale=rubber.shear_modulus))
    >>> result.converged, result.s
    (True, 1.0)
    >>> G, K, lam2 = rubber.shear_modulus, rubber.bulk_modulus, 1.2
    >>> def dW(lam1):                                       # W = G/2 (J^(-2/3) I1 - 3) + K/2 (J - 1)^2
    ...     J, I1 = lam1 * lam2, lam1**2 + lam2**2 + 1.0
    ...     return G / 2 * J ** (-2 / 3) * (2 * lam1 - 2 / 3 * I1 / lam1) + K * (J - 1.0) * lam2
    >>> round(brentq(dW, 0.5, 1.0), 5), round(float(result.x[g("right"), 0].mean()), 5)
    (0.85959, 0.85959)
    """
    walk = _start(problem, options, resume, tuple(observers))
    if isinstance(walk, PathResult):
        return walk
    while walk.s < 1.0 - END_TOLERANCE:
        walk.ds = min(walk.ds, 1.0 - walk.s)
        s_try = walk.s + walk.ds
        t0 = time.perf_counter()
        terms, res = _attempt(problem, walk, s_try, options)
        walk.timings.add(res.timings)
        if on_attempt is not None:
            on_attempt(s_try, walk.ds, res)
        rel = None
        damped = walk.damped
        damped_energy = 0.0 if damped is None or not res.converged else damped.energy(res.x)
        if res.converged and damped is not None and options.release.each_step:
            path_scale = damped.scale
            rel = release(terms, damped, res.x, walk.free, problem.force_scale, options.newton, walk.solver,
                          options.release, walk.base, options.unphysical_terms, observers=walk.observers)
            walk.timings.add(rel.timings)
            damped.scale = path_scale
        if res.converged and (rel is None or rel.released):
            _accept(problem, walk, s_try, terms, res, rel, damped_energy, t0, options, callback, on_checkpoint)
        else:
            stop = _reject(walk, s_try, res, rel, options)
            if stop is not None:
                return stop
    return walk.result(True, "converged")


def _start(problem: Problem, options: PathOptions, resume: PathCheckpoint | None,
           observers: tuple = ()) -> _Walk | PathResult:
    """The walk at s = 0 (the reference positions equilibrated, every lagged quantity begun there)
    or at ``resume``'s state; a PathResult where s = 0 cannot be equilibrated."""
    solver = LinearSolver(options.newton.linear_solver, observers)
    # the stability check's own solver: its matrices never touch the Newton solver's pattern
    # and analysis, so the check leaves the path's round-off as it was
    checker = LinearSolver(options.newton.linear_solver, observers) if options.stability_check else None
    x = problem.X.ravel().copy()
    problem.apply_dirichlet(x, 0.0)
    walk = _Walk(solver, checker, problem.free_mask(), problem.X.shape, x, options.newton, ds=options.ds0,
                 observers=observers)
    terms0 = problem.terms(0.0)
    damped = next((t for t in terms0 if t.name == DAMPED_TERM), None)
    if isinstance(damped, DampedTerm) and damped.scale:  # none, or one switched off: nothing to adapt
        walk.damped, walk.base = damped, damped.scale
        damped.scale = walk.base * options.damping_start
    if resume is None:
        for t in terms0:  # nothing lagged (friction) survives from an earlier path on the same terms
            t.begin_step(x.reshape(walk.shape))
        res0 = minimize(terms0, x.reshape(walk.shape), walk.free, problem.force_scale, options.newton, solver,
                        observers)
        walk.timings.add(res0.timings)
        if not res0.converged:
            return walk.result(False, f"could not equilibrate the initial state (s = 0): {res0.message}")
        walk.x = res0.x.ravel().copy()
        if observers:
            notify(observers, "on_step_accepted", StepAccepted(0.0, res0.x))
        return walk
    walk.x = np.asarray(resume.x, dtype=float).ravel().copy()
    walk.previous = resume.previous
    walk.s, walk.ds, walk.rejected = float(resume.s), float(resume.ds), int(resume.rejected)
    walk.ds_cut = float(resume.ds_cut) if resume.ds_cut is not None else (options.ds0 if walk.rejected else 0.0)
    walk.history.extend(resume.history)
    walk.timings.add(resume.timings)
    solver.restore_pattern(resume.solver_pattern)
    if walk.damped is not None:
        walk.damped.scale = walk.base * resume.damping
    return walk


def _attempt(problem: Problem, walk: _Walk, s_try: float, options: PathOptions):
    """One attempt at the step to ``s_try``: (its terms, Newton's result). Lagged quantities
    (friction, stabilisation) freeze at the step's start, or where its damped attempts restart;
    Newton starts from a run-out block's last iterate, that restart, or the predicted (and
    extrapolated) state."""
    x, shape = walk.x, walk.shape
    terms = problem.terms(s_try)
    x_bc = x.copy()
    problem.apply_dirichlet(x_bc, s_try)
    for t in terms:
        t.begin_step((x if walk.restart is None else walk.restart).reshape(shape))
    if walk.carry is not None:
        x_start = walk.carry
    elif walk.restart is not None:
        x_start = walk.restart
    else:
        x_start = _predictor(problem, terms, x, x_bc, walk.free, walk.solver)
        if x_start is not None and walk.previous is not None and options.extrapolate:
            x_start = _extrapolated(terms, x, x_start, walk.previous, walk.ds, walk.free, shape)
    if x_start is None:
        return terms, NewtonResult(x.reshape(shape), NewtonStatus.INADMISSIBLE_START, 0, np.inf, np.inf,
                                   "the prescribed displacement increment is not admissible", [], Timings())
    return terms, minimize(terms, x_start.reshape(shape), walk.free, problem.force_scale, walk.newton, walk.solver,
                           walk.observers)


def _accept(problem: Problem, walk: _Walk, s_try: float, terms, res: NewtonResult, rel: ReleaseResult | None,
            damped_energy: float, t0: float, options: PathOptions, callback, on_checkpoint) -> None:
    """Accept the step to ``s_try``: its state (released, and settled off a saddle where asked),
    its record and the callbacks, the next increment and damping, the checkpoint."""
    walk.newton, walk.last_resort = options.newton, False
    walk.s = s_try
    x_new = res.x if rel is None else rel.x
    walk.previous = (walk.x, walk.ds)
    walk.x = x_new.ravel().copy()
    negative = None
    its = walk.carried_its + res.iterations + (0 if rel is None else rel.iterations)
    walk.carry, walk.carried, walk.carried_its, walk.restart = None, 0, 0, None
    if rel is not None:
        residual, tolerance = rel.residual, rel.tolerance
    else:  # undamped, or a stabilised state whose residual includes the viscous force
        tolerance = physical_residual(terms, x_new, walk.free, problem.force_scale, options.newton.rtol, (),
                                      options.newton.residual_floor)[1]
        residual = res.residual
    if walk.checker is not None:
        physical = [t for t in terms if t.name not in options.unphysical_terms]
        negative = negative_curvature(physical, x_new, walk.free, walk.checker, options.newton)
        final = walk.s >= 1.0 - END_TOLERANCE
        if negative and options.settle == "final" and final:
            settled = settle(physical, x_new, walk.free, problem.force_scale, options.newton, walk.solver, walk.checker,
                             SETTLE_PERTURBATION, observers=walk.observers)
            walk.timings.add(settled.timings)
            its += settled.iterations
            if settled.negative == 0:
                x_new, negative = settled.x, 0
                walk.x = x_new.ravel().copy()
                residual, tolerance = settled.residual, settled.tolerance
    damped, base = walk.damped, walk.base
    energy = res.energy if x_new is res.x else sum_energy(terms, x_new)
    rec = StepRecord(walk.s, walk.ds, its, residual, energy,
                     time.perf_counter() - t0, negative, None if damped is None else damped.scale / base,
                     walk.failed_here, tolerance, 0 if rel is None else len(rel.rounds),
                     0 if rel is None else rel.iterations, damped_energy)
    walk.failed_here = 0
    walk.history.append(rec)
    if callback is not None:
        callback(walk.s, x_new, rec)
    if walk.observers:
        notify(walk.observers, "on_step_accepted", StepAccepted(walk.s, x_new, rec))
    easy = its <= options.easy_iterations
    if easy:
        walk.ds = min(walk.ds * options.grow, options.ds_max)
    elif walk.ds < walk.ds_cut:
        walk.ds = min(walk.ds * options.grow, walk.ds_cut)
    lowest = None if damped is None else base * options.damping_start
    if damped is not None and damped.scale > lowest and (
            easy or (options.damping_relax_after > 0
                     and _steps_at(walk.history, damped.scale / base) >= options.damping_relax_after)):
        damped.scale = (lowest if damped.scale <= base * (1 + 1e-12)
                        else max(damped.scale / options.damping_growth, base))
    if on_checkpoint is not None:
        on_checkpoint(PathCheckpoint(walk.x.copy(), walk.s, walk.ds, 1.0 if damped is None else damped.scale / base,
                                     tuple(walk.history), walk.rejected, dataclasses.replace(walk.timings),
                                     walk.solver.pattern, walk.ds_cut, walk.previous))


def _reject(walk: _Walk, s_try: float, res: NewtonResult, rel: ReleaseResult | None,
            options: PathOptions) -> PathResult | None:
    """What follows a failed attempt at ``s_try``: an undamped block that ran out goes on, a
    damped retry of the same increment, the increment halved, one last long attempt at the
    smallest one; the path's (failed) result where none is left, else None (try again)."""
    damped, base = walk.damped, walk.base
    ran_out_undamped = damped is not None and damped.scale == 0 and res.status is NewtonStatus.MAX_ITERATIONS
    if ran_out_undamped and walk.carried + 1 < options.undamped_blocks:
        walk.carry, walk.carried = res.x.ravel().copy(), walk.carried + 1
        walk.carried_its += res.iterations
        return None
    if ran_out_undamped and options.damped_from_blocks:
        walk.restart, walk.carried_its = res.x.ravel().copy(), walk.carried_its + res.iterations
    elif walk.restart is None:
        walk.carried_its = 0
    walk.carry, walk.carried = None, 0
    walk.rejected += 1
    walk.failed_here += 1
    if rel is not None:  # the step converged stabilised but could not be released: a shorter one
        res = dataclasses.replace(res, status=NewtonStatus.MAX_ITERATIONS, message=(
            f"the stabilisation could not be released in {len(rel.rounds)} rounds"))
        return _halve(walk, s_try, res, options, long_attempt=False)
    if (damped is not None and res.status is not NewtonStatus.INADMISSIBLE_START and options.damping_growth > 1
            and damped.scale * options.damping_growth <= options.max_damping * base * (1 + 1e-12)):
        # retry the same increment, more damped (an undamped attempt: at the built damping)
        damped.scale = base if damped.scale < base else damped.scale * options.damping_growth
        return None
    return _halve(walk, s_try, res, options, long_attempt=True)


def _halve(walk: _Walk, s_try: float, res: NewtonResult, options: PathOptions,
           long_attempt: bool) -> PathResult | None:
    """Halve the increment after the failed attempt ``res`` at ``s_try``; below ``ds_min`` one last
    attempt with a long Newton budget where Newton ran out (``long_attempt``), else the path ends
    (its result, the last converged state kept). None: try again."""
    walk.ds_cut = max(walk.ds_cut, walk.ds)
    walk.ds *= 0.5
    walk.restart, walk.carried_its = None, 0
    if (long_attempt and walk.ds < options.ds_min and not walk.last_resort
            and res.status is NewtonStatus.MAX_ITERATIONS):
        # A snap (jammed particles rearranging) has no nearby equilibrium: the state must
        # travel, which takes many iterations, not a smaller increment. One long attempt.
        walk.last_resort, walk.ds = True, 2.0 * walk.ds
        walk.newton = dataclasses.replace(options.newton,
                                          max_iter=options.last_resort_factor * options.newton.max_iter)
        return None
    if walk.ds < options.ds_min:
        return walk.result(False, f"load step failed at s = {s_try:.6g} (increment {2 * walk.ds:.3g} < minimum "
                                  f"{options.ds_min:g}): {res.message}; last converged state kept at s = {walk.s:.6g}")
    return None
