"""Simulate an actuator along its stimulus path: the load-path solver on the model's energy terms,
with the metrics measured at every accepted step (docs/actuator.md, "Solving").

:func:`simulate` returns a :class:`SimulationResult`: the accepted states, their metrics, whether
s = 1 was reached (if not, why, with the last converged state kept) and where the time went.
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from hydrojam._io import finite_or_none
from hydrojam.actuator.checkpoint import (ReleaseCheckpoint, ReleaseProgress, RunCheckpoint, design_digest,
                                         save_checkpoint)
from hydrojam.actuator.metrics import RUN_FIELDS, branch_gap, time_to_fraction
from hydrojam.actuator.model import MEMBRANE, STRAIN_LIMIT_LAYER, ActuatorModel, measure
from hydrojam.actuator.stimulus import KineticVolumes, schedule_temperature
from hydrojam.fem import (LinearSolver, NewtonOptions, NewtonStatus, PathCheckpoint, PathOptions, ReleaseState, Timings,
                          Observer, first_unstable_s, minimize, negative_curvature, physical_residual, release,
                          solve_path)
from hydrojam.fem.terms import TimedTerm, ViscousStabilisation, by_name, lumped_volumes

#: viscous stabilisation c = STABILISATION x G_membrane / d [N/mm^3] (docs/actuator.md)
STABILISATION = 0.01

#: load-path settings for actuators: many contacts change during a step, so a step may take
#: many Newton iterations; a long attempt is cheaper than halving the step and starting over.
#: A step of up to 30 iterations counts as easy (the next one grows): with the generic 6 the
#: increment of a long chamber never grew again after one halving.
#: A step is first tried undamped, in up to 3 blocks of 200 iterations, before the damping
#: comes in, from where the blocks stopped (docs/solver.md, "Undamped first").
#: A step the energy's round-off cannot judge must lower the residual (``residual_search``):
#: long chambers' rounds cycled between states just above the tolerance (docs/solver.md, "Newton").
#: Where the full K shows negative curvature, the state goes on along it, at most twice the
#: step's move (``curvature_step``): fewer iterations, the same distributions; 8x moved the
#: default designs' tips (docs/solver.md, "Choices").
ACTUATOR_PATH = PathOptions(ds0=0.05, ds_min=1e-4, ds_max=0.1, easy_iterations=30,
                            newton=NewtonOptions(max_iter=200, definite=True, fallback_start="krylov_detect",
                                                 residual_search=True, curvature_step=1.0, curvature_doublings=1),
                            damping_start=0.0,
                            damping_relax_after=1, undamped_blocks=3, damped_from_blocks=True)

#: load-path settings with a time-resolved stimulus: steps of at most 0.025 in s from the first
#: (40 or more states), so that theta(t) is resolved (s is spread over the particles' swelling
#: and the log time) and no step is long against the particles' tau (their water relaxes within
#: a step: the "volume" term is an implicit flow, first order in the step). Without the
#: negative-curvature step: theta(t) is the answer here, and the step's extra move along a
#: near-neutral mode (a frictionless particle's rolling) shows in it as a dip of 4e-4 of the angle
#: on a hold (docs/kinetics.md); the time-resolved path's small steps need little of its saving.
TIMED_PATH = dataclasses.replace(ACTUATOR_PATH, ds0=0.025, ds_max=0.025,
                                 newton=dataclasses.replace(ACTUATOR_PATH.newton, curvature_step=0.0))


@dataclass(frozen=True)
class StepState:
    """One accepted equilibrium: load parameter s, stimulus (mu [k_B T], T [K]), positions
    x (n, 2) [mm], metrics (see :func:`hydrojam.actuator.model.measure`), Newton iterations of the step
    and the wall time since the start [s]; ``time_s``: the stimulus's time [s] on a
    time-resolved path, None on an untimed one."""

    index: int
    s: float
    mu: float
    T: float
    x: np.ndarray
    metrics: dict
    iterations: int
    wall_time_s: float
    time_s: float | None = None
    negative_eigenvalues: int | None = None
    """Negative eigenvalues of the physical Hessian at this state (the stabilisation left out;
    :attr:`hydrojam.fem.solver.path.StepRecord.negative_eigenvalues`): 0 stable, > 0 the path is
    passing an instability here; None where not checked (s = 0) or not available."""
    residual: float | None = None
    """Residual of the physics alone at this state (the stabilisation left out) [N; N/mm in 2D]:
    within ``tolerance`` at an equilibrium."""
    tolerance: float | None = None
    """The Newton tolerance the residual is held to (rtol x the forces in play) [N; N/mm in 2D]."""


@dataclass
class _Clock:
    """Seconds and calls spent in one kind of term (a :class:`TimedTerm`'s record), in all and
    by method."""

    seconds: float = 0.0
    calls: int = 0
    methods: dict = field(default_factory=dict)

    def add(self, method: str, seconds: float) -> None:
        self.seconds += seconds
        self.calls += 1
        spent, calls = self.methods.get(method, (0.0, 0))
        self.methods[method] = (spent + seconds, calls + 1)


@dataclass
class SimulationResult:
    """Outcome of :func:`simulate`.

    ``states``: every accepted step from s = 0; ``converged``: s = 1 reached; ``message``: why
    not, otherwise "converged"; ``timings``: seconds in elastic terms (``elastic``), contact
    (``contact``), linear solves (``linear_solve``) and in total (``total``).
    """

    model: ActuatorModel
    states: list[StepState]
    converged: bool
    message: str
    wall_time_s: float
    newton_iterations: int
    rejected_steps: int
    timings: dict = field(default_factory=dict)
    stabilisation: dict = field(default_factory=dict)
    resumed: tuple = ()
    """One record per resumption from a checkpoint (``s`` and ``state`` it went on from, the
    ``version`` of hydrojam that went on); empty for a run in one go."""
    term_timings: dict = field(default_factory=dict)
    """Seconds and calls of the elastic and contact terms' methods: "elastic.hessian" ->
    (seconds, calls), ... (since the last resumption; for benchmarks)."""

    @property
    def final(self) -> StepState:
        """The last converged state."""
        return self.states[-1]

    @property
    def metrics(self) -> dict:
        """Final metrics (:data:`~hydrojam.actuator.metrics.STATE_METRICS`) plus the run fields
        (:data:`~hydrojam.actuator.metrics.RUN_FIELDS`), in the registry's order; undefined values
        are None, never NaN."""
        run = {
            "converged": self.converged,
            "message": self.message,
            "s_reached": self.final.s,
            "temperature_K": self.final.T,
            "mu_kT": self.final.mu,
            "load_steps": len(self.states) - 1,
            "newton_iterations": self.newton_iterations,
            "rejected_steps": self.rejected_steps,
            "wall_time_s": self.wall_time_s,
            "stabilisation_energy_ratio": self.stabilisation.get("max_energy_ratio", 0.0),
            "stabilisation_released": self.stabilisation.get("released", True),
            "buckled_at_s": first_unstable_s(self.states),
            "unstable_states": sum(1 for st in self.states if st.negative_eigenvalues),
        }
        run.update(time_metrics(self.states, self.model.path))
        return finite_or_none({**self.final.metrics, **{m.name: run[m.name] for m in RUN_FIELDS}})


def checkpoint_states(ck: RunCheckpoint) -> list[StepState]:
    """The accepted states that checkpoint ``ck`` holds (positions copied)."""
    return [StepState(**st, x=np.array(x, dtype=float)) for st, x in zip(ck.states, ck.xs)]


def time_metrics(states: list[StepState], path) -> dict:
    """The time-resolved run fields (:data:`~hydrojam.actuator.metrics.RUN_FIELDS`, docs/actuator.md
    "Actuation in time") of accepted ``states`` on ``path``; all None on an untimed path.

    ``cycle_return_deg`` needs a schedule whose last temperature equals its first; the angle
    "when the temperature first left its start" is interpolated in time at the end of the
    schedule's first hold. ``hysteresis_deg`` compares theta(t) (linear between the states) along
    the rising and along the falling segments of the schedule, at equal temperature
    (:func:`~hydrojam.actuator.metrics.branch_gap`)."""
    out = dict.fromkeys(("time_s", "particle_time_constant_s", "time_to_90_percent_angle_s",
                         "swelling_time_to_90_percent_s", "max_bending_angle_deg", "cycle_return_deg", "hysteresis_deg"))
    if not path.timed or not states:
        return out
    t = np.array([st.time_s for st in states], dtype=float)
    theta = np.array([st.metrics["bending_angle_deg"] for st in states], dtype=float)
    out["time_s"] = float(t[-1])
    out["particle_time_constant_s"] = path.time_constant_s
    out["swelling_time_to_90_percent_s"] = time_to_fraction(path.times, path.mean, 0.9)
    out["max_bending_angle_deg"] = float(theta.max())
    if len(states) >= 2:
        out["time_to_90_percent_angle_s"] = time_to_fraction(t, theta, 0.9)
    pts = np.asarray(path.schedule, dtype=float)
    moves = np.nonzero(pts[1:, 1] != pts[:-1, 1])[0]
    if len(moves) and pts[-1, 1] == pts[0, 1] and states[-1].s >= 1.0:
        t_leave = pts[moves[0], 0]
        out["cycle_return_deg"] = float(theta[-1] - np.interp(t_leave, t, theta))
    # theta(t), linear between the states, read along every ramp of the schedule (the solver may
    # put few states on a ramp: at fixed particle volume little moves there)
    branches = {1: ([], []), -1: ([], [])}
    for (t0, T0), (t1, T1) in zip(pts[:-1], pts[1:]):
        if T1 != T0 and t1 <= t[-1]:
            tt = np.linspace(t0, t1, 101)
            temperatures, angles = branches[int(np.sign(T1 - T0))]
            temperatures.append(schedule_temperature(pts, tt))
            angles.append(np.interp(tt, t, theta))
    if branches[1][0] and branches[-1][0]:
        out["hysteresis_deg"] = branch_gap(np.concatenate(branches[1][0]), np.concatenate(branches[1][1]),
                                           np.concatenate(branches[-1][0]), np.concatenate(branches[-1][1]))
    return out


def simulate(
    model: ActuatorModel,
    options: PathOptions | None = None,
    on_step: Callable[[StepState], None] | None = None,
    on_progress: Callable[[float], None] | None = None,
    stabilisation: float = STABILISATION,
    extra_terms: tuple = (),
    checkpoint: str | os.PathLike | None = None,
    resume: RunCheckpoint | None = None,
    on_release: Callable[[ReleaseProgress], None] | None = None,
    observers: Sequence[Observer] = (),
) -> SimulationResult:
    """Follow the stimulus from the as-prepared state (s = 0) to the target (s = 1): the load
    path (:func:`hydrojam.fem.solve_path`) on the model's energy terms, every accepted state an
    equilibrium of the physics, measured (:func:`~hydrojam.actuator.model.measure`) and reported.

    Parameters
    ----------
    model : ActuatorModel
        The actuator (:func:`~hydrojam.actuator.model.build_model`).
    options : PathOptions, optional
        The load path's settings: :data:`TIMED_PATH` where the design has a ``stimulus.schedule``
        (a time-resolved path), otherwise :data:`ACTUATOR_PATH` (the default, None).
    on_step : callable, optional
        ``on_step(state)`` after every accepted step (including s = 0) with its
        :class:`StepState`, e.g. to write results as they come. A state released at s = 1
        after the path (``options.release.each_step`` off) replaces the last one (same index,
        passed again).
    on_progress : callable, optional
        ``on_progress(s)`` after every attempt (a progress bar).
    stabilisation : float, optional
        Viscous damping c = stabilisation x G_membrane / d [N/mm^3] of every node's motion within
        a load step (:class:`hydrojam.fem.terms.ViscousStabilisation`), released so that every
        reported state is an equilibrium without it; 0: none (default :data:`STABILISATION`).
    extra_terms : tuple of EnergyTerm, optional
        Energy terms added to the model's (e.g. a spring that blocks the tip,
        :mod:`hydrojam.assess`), kept through the release.
    checkpoint : str or os.PathLike, optional
        A file (:mod:`hydrojam.actuator.checkpoint`) rewritten after every accepted step and every
        round of a release at s = 1.
    resume : RunCheckpoint, optional
        A checkpoint of this model's design to go on from (its states are not passed to
        ``on_step`` again): the same computation as a run in one go, bit for bit on one machine
        with the same thread settings (the linear solvers' union patterns are part of it;
        docs/actuator.md, "Checkpoints").
    on_release : callable, optional
        ``on_release(progress)`` after every round of a release at s = 1 that goes on
        (:class:`~hydrojam.actuator.checkpoint.ReleaseProgress`): a 3D chamber's can take hours.
    observers : sequence of Observer, optional
        Told what the solver does (:mod:`hydrojam.fem.solver.events`: every linear solve,
        Newton direction, line search, iteration, release round and accepted step); none by
        default, at no cost.

    Returns
    -------
    SimulationResult
        The accepted states from s = 0 with their metrics, whether s = 1 was reached
        (``converged``; if not, ``message`` says where and why, and the last converged state is
        kept), the Newton iterations, the rejected attempts and where the time went [s].

    Raises
    ------
    RuntimeError
        Only for a solver fault (non-finite positions), which the solver's own checks rule out:
        a path that cannot converge does not raise.
    """
    if options is None:
        options = TIMED_PATH if model.path.timed else ACTUATOR_PATH
    run = _Run(model, options, stabilisation, extra_terms, on_step, checkpoint, resume)
    # a timed path's kinetic volumes start each step where the last accepted one ended
    kinetics = [t.controller for t in run.problem.terms(0.0)
                if isinstance(getattr(t, "controller", None), KineticVolumes)] if model.path.timed else []
    watching = (*kinetics, *observers)

    def attempt(s, ds, res):
        if on_progress is not None:
            on_progress(float(s - ds) if not res.converged else float(s))

    res = solve_path(run.problem, options, callback=run.on_accepted, on_attempt=attempt,
                     resume=None if resume is None else resume.path, on_checkpoint=run.on_path_checkpoint,
                     observers=watching)
    if not np.all(np.isfinite(res.x)):  # pragma: no cover - the solver never accepts such a state
        raise RuntimeError("the solver returned non-finite positions")
    released = run.stab is None or options.release.each_step
    newton_iterations = res.newton_iterations
    release_seconds, rounds = 0.0, []
    if run.stab is not None and res.converged and not options.release.each_step:
        its, released, rounds, release_seconds = _release_at_end(run, res, resume, on_release, watching)
        newton_iterations += its
    return run.result(res, released, newton_iterations, release_seconds, rounds)


class _Run:
    """One simulation's bookkeeping around its load path: the timed terms and the stabilisation,
    the reported states (each passed to ``on_step``), the largest share of the elastomers' energy
    the stabilisation held back, and the run's checkpoint."""

    def __init__(self, model: ActuatorModel, options: PathOptions, stabilisation: float, extra_terms: tuple,
                 on_step: Callable[[StepState], None] | None, checkpoint: str | os.PathLike | None,
                 resume: RunCheckpoint | None):
        self.model, self.options, self.on_step, self.checkpoint = model, options, on_step, checkpoint
        self.t_start = time.perf_counter() - (0.0 if resume is None else resume.elapsed_s)
        self.elastic, self.contact = _Clock(), _Clock()
        self._clocks = {"elastic": self.elastic, "contact": self.contact}
        if resume is not None:
            self.elastic.seconds = float(resume.clocks.get("elastic", 0.0))
            self.contact.seconds = float(resume.clocks.get("contact", 0.0))
        self.stab = None
        if stabilisation > 0:
            mesh = model.mesh
            w = lumped_volumes(mesh.points, mesh.cells, mesh.cell_volumes())
            c = stabilisation * model.membrane.shear_modulus_ref / model.design.particle_diameter
            self.stab = ViscousStabilisation(w, c, mesh.dim)
        self._base = model.problem(tuple(extra_terms) + (() if self.stab is None else (self.stab,)))
        self.problem = dataclasses.replace(self._base, terms=self.terms)
        self.states: list[StepState] = []
        self.digest = design_digest(model.design)
        self.resumed: tuple = ()
        self.ratio = 0.0
        self.path_ck: PathCheckpoint | None = None if resume is None else resume.path
        if resume is None:
            self.record(0.0, model.mesh.points, 0)
        else:
            from hydrojam._version import __version__

            self.states.extend(checkpoint_states(resume))
            self.ratio = resume.energy_ratio
            self.resumed = tuple(resume.resumed) + ({"s": self.states[-1].s, "state": self.states[-1].index,
                                                     "version": __version__},)

    def terms(self, s: float) -> list:
        """The model's terms at s, the elastic and contact ones timed."""
        clocks = self._clocks
        return [TimedTerm(t, clocks[t.name].add) if t.name in clocks else t for t in self._base.terms(s)]

    def record(self, s: float, x: np.ndarray, iterations: int, negative: int | None = None,
               residual: tuple[float, float] | None = None) -> None:
        """Report the state x at s: measured, kept and passed to ``on_step``."""
        model, options = self.model, self.options
        mu, T = model.stimulus(s)
        if residual is None:  # the physics alone at x: every reported state is an equilibrium of it
            residual = physical_residual(self.terms(s), x, self.problem.free_mask(), self.problem.force_scale,
                                         options.newton.rtol, options.unphysical_terms, options.newton.residual_floor)
        st = StepState(len(self.states), float(s), float(mu), float(T), np.array(x, dtype=float),
                       measure(model, x), int(iterations), time.perf_counter() - self.t_start, model.path.time(s),
                       negative, float(residual[0]), float(residual[1]))
        self.states.append(st)
        if self.on_step is not None:
            self.on_step(st)

    def save(self, release: ReleaseCheckpoint | None = None) -> None:
        """Rewrite the run's checkpoint (where one is kept and the path has given one)."""
        if self.checkpoint is None or self.path_ck is None:
            return
        plain = [{f.name: getattr(st, f.name) for f in dataclasses.fields(StepState) if f.name != "x"}
                 for st in self.states]
        save_checkpoint(self.checkpoint, RunCheckpoint(
            self.digest, tuple(plain), np.stack([st.x for st in self.states]), self.path_ck, release,
            time.perf_counter() - self.t_start, {"elastic": self.elastic.seconds, "contact": self.contact.seconds},
            self.ratio, self.resumed))

    def on_path_checkpoint(self, ck: PathCheckpoint) -> None:
        """The path's checkpoint after an accepted step: kept and saved."""
        self.path_ck = ck
        self.save()

    def on_accepted(self, s: float, x: np.ndarray, rec) -> None:
        """An accepted load step (:class:`~hydrojam.fem.solver.path.StepRecord` ``rec``): the energy the
        stabilisation held back, and the state reported."""
        stab, options = self.stab, self.options
        if stab is not None:
            energies = self.model.solid.with_materials(self.model.materials_at(s)).block_energies(x)
            e_el = sum([energies[MEMBRANE], energies.get(STRAIN_LIMIT_LAYER, 0.0)])  # the elastomers
            if e_el > 0:
                held = rec.damped_energy if options.release.each_step else stab.energy(x)
                self.ratio = max(self.ratio, held / e_el)
        # a stabilised state (released only at s = 1): its physics' residual is measured in record
        equilibrium = stab is None or options.release.each_step
        self.record(s, x, rec.iterations, rec.negative_eigenvalues,
                    (rec.residual, rec.tolerance) if equilibrium else None)

    def result(self, res, released: bool, newton_iterations: int, release_seconds: float,
               rounds: list) -> SimulationResult:
        """The simulation's result after its path ``res`` (and its release at the end)."""
        wall = time.perf_counter() - self.t_start
        timings = {
            "total": wall,
            "elastic": self.elastic.seconds,
            "contact": self.contact.seconds,
            "linear_solve": res.timings.linear_solve,
            "release": release_seconds,
            "newton_iterations": res.timings.iterations,
        }
        message = res.message
        if not released:
            message += ("; the stabilisation could not be fully released at s = 1: the final state keeps "
                        "a viscous force above the tolerance")
        stabilisation_info = {"damping_N_per_mm3": 0.0 if self.stab is None else self.stab.damping,
                              "max_energy_ratio": self.ratio, "released": released,
                              "release_rounds": [{"scale": sc, "iterations": n, "converged": ok}
                                                 for sc, n, ok in rounds]}
        terms = {f"{name}.{method}": spent for name, clock in self._clocks.items()
                 for method, spent in clock.methods.items()}
        return SimulationResult(self.model, self.states, res.converged, message, wall, newton_iterations,
                                res.rejected_steps, timings, stabilisation_info, self.resumed, terms)


def _release_at_end(run: _Run, res, resume: RunCheckpoint | None,
                    on_release: Callable[[ReleaseProgress], None] | None, observers: tuple = ()):
    """The stabilisation of a path that kept it on (``release.each_step`` off) released at s = 1:
    the released state replaces the last one. Returns (Newton iterations, released, rounds,
    seconds)."""
    options, problem = run.options, run.problem
    before = resume.release if resume is not None else None
    t_release = time.perf_counter() - (0.0 if before is None else before.seconds)

    def on_round(ck: ReleaseCheckpoint) -> None:
        seconds = time.perf_counter() - t_release
        run.save(dataclasses.replace(ck, seconds=seconds))
        if on_release is not None:
            on_release(ReleaseProgress(len(ck.rounds), ck.iterations, ck.scale, seconds))

    x, its, released, rounds = _release(problem, run.stab, res.x, options, run.terms, res.timings,
                                        resume=before, on_round=on_round, observers=observers)
    negative = run.states[-1].negative_eigenvalues
    if options.stability_check:  # the released state is the one reported: check it
        physical = [t for t in run.terms(1.0) if t.name not in options.unphysical_terms]
        negative = negative_curvature(physical, x, problem.free_mask(),
                                      LinearSolver(options.newton.linear_solver, observers), options.newton)
    release_seconds = time.perf_counter() - t_release
    run.states.pop()
    run.record(1.0, x, its, negative)
    return its, released, rounds, release_seconds


def _release(problem, stab, x, options: PathOptions, terms, timings: Timings,
             resume: ReleaseCheckpoint | None = None, on_round: Callable[[ReleaseCheckpoint], None] | None = None,
             observers: tuple = ()):
    """Take the stabilisation off at s = 1 (:func:`hydrojam.fem.solver.release.release`, ``options.release``),
    for a path that did not release it at every step. Returns (x, Newton iterations, released,
    rounds); ``on_round(checkpoint)`` after every round, ``resume``: such a checkpoint."""
    # one for all rounds: each PARDISO handle's set-up costs
    solver = LinearSolver(options.newton.linear_solver, observers)
    state = None
    if resume is not None:
        state = ReleaseState(resume.x, resume.iterations, resume.scale, resume.failed, resume.rounds,
                             resume.solver_pattern,
                             resume.timings if resume.timings is not None else Timings(iterations=resume.iterations))

    def round_done(st: ReleaseState) -> None:
        if on_round is not None:
            on_round(ReleaseCheckpoint(st.x, st.iterations, st.scale, st.failed, st.rounds, 0.0, st.solver_pattern,
                                       st.timings))

    rel = release(terms(1.0), stab, x, problem.free_mask(), problem.force_scale, options.newton, solver,
                  options.release, 1.0, options.unphysical_terms, state, round_done, observers)
    timings.add(rel.timings)
    return rel.x, rel.iterations, rel.released, rel.rounds
