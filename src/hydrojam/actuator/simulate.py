"""Simulate an actuator along its stimulus path: the load-path solver on the model's energy terms,
with the metrics measured at every accepted step (DESIGN.md sections 3, 7, 8).

:func:`simulate` returns a :class:`SimulationResult`: the accepted states, their metrics, whether
s = 1 was reached (if not, why, with the last converged state kept) and where the time went.
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from hydrojam._io import finite_or_none
from hydrojam.actuator.checkpoint import (ReleaseCheckpoint, ReleaseProgress, RunCheckpoint, design_digest,
                                         save_checkpoint)
from hydrojam.actuator.metrics import RUN_FIELDS, branch_gap, time_to_fraction
from hydrojam.actuator.model import MEMBRANE, STRAIN_LIMIT_LAYER, ActuatorModel, measure
from hydrojam.actuator.stimulus import schedule_temperature
from hydrojam.fem.linsolve import LinearSolver
from hydrojam.fem.newton import NewtonOptions, NewtonStatus, Timings, minimize, negative_curvature
from hydrojam.fem.path import PathCheckpoint, PathOptions, first_unstable_s, solve_path
from hydrojam.fem.terms import TimedTerm, ViscousStabilisation, by_name, lumped_volumes

#: viscous stabilisation c = STABILISATION x G_membrane / d [N/mm^3] (docs/actuator.md)
STABILISATION = 0.01

#: load-path settings for actuators: many contacts change during a step, so a step may take
#: many Newton iterations; a long attempt is cheaper than halving the step and starting over.
#: A step of up to 30 iterations counts as easy (the next one grows): with the generic 6 the
#: increment never grew again after one halving (19 layers: 0.003 for hundreds of steps).
ACTUATOR_PATH = PathOptions(ds0=0.05, ds_min=1e-4, ds_max=0.1, easy_iterations=30,
                            newton=NewtonOptions(max_iter=200))


#: most proximal rounds of the release at s = 1: a long chamber with friction travels far from
#: its stabilised state, and a cap it reaches reports a state of the damping, not an
#: equilibrium (docs/actuator.md, "The release of the long chambers")
RELEASE_ROUNDS = 240


#: the highest damping scale of the release (x the path's): a round that fails there is not
#: followed by a higher one (see ``_release``, ``beyond_cap``)
RELEASE_CAP = 1e3

#: after a failed round at the cap, the damping is lowered after this many x 2^(f-1) converged
#: rounds in a row at its level, f the failed rounds so far (the ``backoff_rounds`` variant)
CAP_BACKOFF_ROUNDS = 4


#: the loosest Newton tolerance of an inexact release round (``_release(inexact=True)``, a variant)
LOOSE_ROUND_RTOL = 1e-3


#: load-path settings with a time-resolved stimulus: steps of at most 0.025 in s from the first
#: (40 or more states), so that theta(t) is resolved (s is spread over the particles' swelling
#: and the log time) and no step is long against the particles' tau (their water relaxes within
#: a step: the "volume" term is an implicit flow, first order in the step)
TIMED_PATH = dataclasses.replace(ACTUATOR_PATH, ds0=0.025, ds_max=0.025)


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
    :attr:`hydrojam.fem.path.StepRecord.negative_eigenvalues`): 0 stable, > 0 the path is
    passing an instability here; None where not checked (s = 0) or not available."""


@dataclass
class _Clock:
    """Seconds and calls spent in one kind of term (a :class:`TimedTerm`'s record)."""

    seconds: float = 0.0
    calls: int = 0

    def add(self, method: str, seconds: float) -> None:
        self.seconds += seconds
        self.calls += 1


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
) -> SimulationResult:
    """Follow the stimulus from the as-prepared state (s = 0) to the target (s = 1).

    ``on_step(state)`` runs after every accepted step (including s = 0), e.g. to write results
    as they come; ``on_progress(s)`` after every attempt (a progress bar). Never raises on
    non-convergence: the result says so and keeps the last converged state. ``on_release(progress)``
    after every round of the release that it goes on from (as its checkpoint; the round that
    ends it is followed by the final state) with
    :class:`~hydrojam.actuator.checkpoint.ReleaseProgress`: a 3D chamber's release can take
    hours at s = 1.

    ``stabilisation``: viscous damping c = stabilisation x G_membrane / d [N/mm^3] of every
    node's motion within a load step (:class:`hydrojam.fem.terms.ViscousStabilisation`), released at
    s = 1 so that the final state is an equilibrium without it (0: none). The final state
    replaces the last stabilised one in ``states`` (same index, passed to ``on_step`` again).

    ``extra_terms``: energy terms added to the model's (e.g. a spring that blocks the tip,
    :mod:`hydrojam.assess`), kept through the release.

    ``checkpoint``: a file (:mod:`hydrojam.actuator.checkpoint`) rewritten after every accepted
    step and every round of the release; ``resume``: a checkpoint of this model's design to go on
    from (its states are not passed to ``on_step`` again). A resumed run is the same computation
    as a run in one go, bit for bit on one machine with the same thread settings: the linear
    solvers' union patterns are part of the checkpoint (docs/actuator.md, "Checkpoints").

    With ``stimulus.schedule`` in the design the path is time-resolved (built by
    :func:`~hydrojam.actuator.model.build_model`) and
    ``options`` defaults to :data:`TIMED_PATH`, otherwise to :data:`ACTUATOR_PATH`.
    """
    if options is None:
        options = TIMED_PATH if model.path.timed else ACTUATOR_PATH
    t_start = time.perf_counter() - (0.0 if resume is None else resume.elapsed_s)
    elastic, contact = _Clock(), _Clock()
    if resume is not None:
        elastic.seconds = float(resume.clocks.get("elastic", 0.0))
        contact.seconds = float(resume.clocks.get("contact", 0.0))
    stab = None
    if stabilisation > 0:
        mesh = model.mesh
        w = lumped_volumes(mesh.points, mesh.cells, mesh.cell_volumes())
        c = stabilisation * model.membrane.shear_modulus_ref / model.design.particle_diameter
        stab = ViscousStabilisation(w, c, mesh.dim)
    base = model.problem(tuple(extra_terms) + (() if stab is None else (stab,)))
    clocks = {"elastic": elastic, "contact": contact}

    def terms(s: float):
        return [TimedTerm(t, clocks[t.name].add) if t.name in clocks else t for t in base.terms(s)]

    problem = dataclasses.replace(base, terms=terms)
    states: list[StepState] = []

    def record(s: float, x: np.ndarray, iterations: int, negative: int | None = None) -> None:
        mu, T = model.stimulus(s)
        st = StepState(len(states), float(s), float(mu), float(T), np.array(x, dtype=float),
                       measure(model, x), int(iterations), time.perf_counter() - t_start, model.path.time(s),
                       negative)
        states.append(st)
        if on_step is not None:
            on_step(st)

    digest = design_digest(model.design)
    resumed: tuple = ()
    ratio = [0.0]
    if resume is None:
        record(0.0, model.mesh.points, 0)
    else:
        from hydrojam import __version__

        states.extend(checkpoint_states(resume))
        ratio[0] = resume.energy_ratio
        resumed = tuple(resume.resumed) + ({"s": states[-1].s, "state": states[-1].index, "version": __version__},)
    path_ck: list[PathCheckpoint | None] = [None if resume is None else resume.path]

    def save(release: ReleaseCheckpoint | None = None) -> None:
        if checkpoint is None or path_ck[0] is None:
            return
        plain = [{f.name: getattr(st, f.name) for f in dataclasses.fields(StepState) if f.name != "x"}
                 for st in states]
        save_checkpoint(checkpoint, RunCheckpoint(
            digest, tuple(plain), np.stack([st.x for st in states]), path_ck[0], release,
            time.perf_counter() - t_start, {"elastic": elastic.seconds, "contact": contact.seconds}, ratio[0],
            resumed))

    def on_path_checkpoint(ck: PathCheckpoint) -> None:
        path_ck[0] = ck
        save()

    def callback(s, x, rec):
        if stab is not None:
            energies = model.solid.with_materials(model.materials_at(s)).block_energies(x)
            e_el = sum([energies[MEMBRANE], energies[STRAIN_LIMIT_LAYER]])  # the elastomers
            if e_el > 0:
                ratio[0] = max(ratio[0], stab.energy(x) / e_el)
        record(s, x, rec.iterations, rec.negative_eigenvalues)

    def attempt(s, ds, res):
        if on_progress is not None:
            on_progress(float(s - ds) if not res.converged else float(s))

    res = solve_path(problem, options, callback=callback, on_attempt=attempt,
                     resume=None if resume is None else resume.path, on_checkpoint=on_path_checkpoint)
    if not np.all(np.isfinite(res.x)):  # pragma: no cover - the solver never accepts such a state
        raise RuntimeError("the solver returned non-finite positions")
    released = stab is None
    newton_iterations = res.newton_iterations
    release_seconds, rounds = 0.0, []
    if stab is not None and res.converged:
        before = resume.release if resume is not None else None
        t_release = time.perf_counter() - (0.0 if before is None else before.seconds)

        def on_round(ck: ReleaseCheckpoint) -> None:
            seconds = time.perf_counter() - t_release
            save(dataclasses.replace(ck, seconds=seconds))
            if on_release is not None:
                on_release(ReleaseProgress(len(ck.rounds), ck.iterations, ck.scale, seconds))

        x, its, released, rounds = _release(problem, stab, res.x, options, terms, res.timings,
                                            resume=before, on_round=on_round)
        newton_iterations += its
        negative = states[-1].negative_eigenvalues
        if options.stability_check:  # the released state is the one reported: check it
            physical = [t for t in terms(1.0) if t.name not in options.unphysical_terms]
            negative = negative_curvature(physical, x, problem.free_mask(), LinearSolver(options.newton.linear_solver),
                                          options.newton)
        release_seconds = time.perf_counter() - t_release
        states.pop()
        record(1.0, x, its, negative)
    wall = time.perf_counter() - t_start
    timings = {
        "total": wall,
        "elastic": elastic.seconds,
        "contact": contact.seconds,
        "linear_solve": res.timings.linear_solve,
        "release": release_seconds,
        "newton_iterations": res.timings.iterations,
    }
    message = res.message
    if not released:
        message += ("; the stabilisation could not be fully released at s = 1: the final state keeps "
                    "a viscous force above the tolerance")
    stabilisation_info = {"damping_N_per_mm3": 0.0 if stab is None else stab.damping,
                          "max_energy_ratio": ratio[0], "released": released,
                          "release_rounds": [{"scale": sc, "iterations": n, "converged": ok} for sc, n, ok in rounds]}
    return SimulationResult(model, states, res.converged, message, wall, newton_iterations,
                            res.rejected_steps, timings, stabilisation_info, resumed)


def _backed_off(rounds, k: int | None) -> bool:
    """With ``k``: whether the converged rounds since the last failed one (``rounds``: (scale,
    iterations, converged)) number k 2^(f-1), f the failed rounds so far."""
    if not k:
        return False
    failures = sum(1 for r in rounds if not r[2])
    held = next((i for i, r in enumerate(reversed(rounds)) if not r[2]), len(rounds))
    return failures > 0 and held >= k * 2 ** (failures - 1)


def _past_cap(rounds, beyond_cap: bool) -> bool:
    """Whether a round has failed at :data:`RELEASE_CAP` (``rounds``: (scale, iterations,
    converged)) and the release goes on beyond it."""
    return beyond_cap and any(not ok and sc >= RELEASE_CAP for sc, _, ok in rounds)


def _release(problem, stab, x, options, terms, timings, max_rounds: int = RELEASE_ROUNDS, first_scale: float = 1.0,
             easy_round: int | None = None, lower: float = 10.0, direct: bool = False, after_failure: int = 20,
             resume: ReleaseCheckpoint | None = None, on_round: Callable[[ReleaseCheckpoint], None] | None = None,
             inexact: bool = False, keep_failed: bool = False, backoff_rounds: int | None = None,
             beyond_cap: bool = True):
    """Take the stabilisation off at s = 1 by proximal rounds: minimise with the damping centred
    on the last state (and lagged friction frozen there, as at a load step's start), again and
    again, the damping (``first_scale`` x the path's at first) lowered ``lower``x after every
    converged round (with ``easy_round``: only after a round of
    at most that many Newton iterations; after a failed round, only after one of at most
    ``after_failure``) and raised 10x after a failed one. ``direct``: first
    minimise the physics alone (damping 0) from the stabilised state, and the rounds only if
    that fails. The viscous force left at the end of a round is exactly the residual of the
    physics alone, so the state is an equilibrium once that force is below the solver's
    tolerance (rtol x the forces in play). Returns (x, Newton iterations, released, rounds): x
    the centre the last round left (a converged round's state, or a kept failed round's),
    released False if the rounds ran out first, rounds a list of (damping scale, Newton
    iterations, converged).

    Where the damping would have to exceed :data:`RELEASE_CAP` (a round failed there), the
    release goes on (``beyond_cap``; without it, it gives up there, the rule before): a
    round that failed by running out of iterations is kept as progress (its last iterate is
    admissible and lower in energy), the damping stays at the cap, and from then on every such
    failed round is kept and the damping is also lowered after :data:`CAP_BACKOFF_ROUNDS` 2^(f-1)
    converged rounds in a row at its level (f: the failed rounds so far). Any other failure at
    the cap (no admissible descent) still gives up. A release that never reaches the cap takes
    the same rounds either way (docs/actuator.md, "Beyond the cap").
    ``on_round(checkpoint)`` after every round (not the direct attempt) with what it takes to go
    on from there; ``resume``: such a checkpoint to go on from (``x`` and ``first_scale`` unused).

    Variants measured, not in use (docs/actuator.md, "Two release variants"): ``inexact``, a
    round's Newton tolerance a tenth of the imbalance (viscous / in play) the last round left,
    within [rtol, :data:`LOOSE_ROUND_RTOL`], released only after a round at rtol; ``keep_failed``,
    a failed round's last state (admissible, lower in energy) is the next round's centre;
    ``backoff_rounds`` k, after a failed round the damping is also lowered after k converged
    rounds in a row at its level (easy or not), k doubling with every failed round (k 2^(f-1)
    after f failures), so that a state that travels at a raised damping is not held there until
    its rounds turn easy, and one that cannot take the lower damping costs about log2(rounds)
    failed rounds. Counted from ``rounds``, so a resumed release goes on as in one go."""
    free = problem.free_mask()
    rtol = options.newton.rtol
    solver = LinearSolver(options.newton.linear_solver)  # one for all rounds: PARDISO's set-up costs 0.4 s
    its, scale, rounds, failed = 0, first_scale * stab.scale, [], False
    round_rtol = LOOSE_ROUND_RTOL if inexact else rtol
    spent = Timings()  # the release's own work, kept in its checkpoints
    if resume is not None:
        x, its, scale, failed, rounds = np.array(resume.x, dtype=float), resume.iterations, resume.scale, \
            resume.failed, list(resume.rounds)
        round_rtol = rtol if resume.round_rtol is None else resume.round_rtol
        solver.restore_pattern(resume.solver_pattern)
        direct = False
        # a checkpoint from before the release's timings were kept: its iterations, times unknown
        spent.add(resume.timings if resume.timings is not None else Timings(iterations=resume.iterations))
        timings.add(spent)
    start = len(rounds)
    if direct:
        stab.scale = 0.0
        res = minimize(terms(1.0), x, free, problem.force_scale, options.newton, solver)
        its += res.iterations
        timings.add(res.timings)
        spent.add(res.timings)
        rounds.append((0.0, res.iterations, res.converged))
        if res.converged:
            return res.x, its, True, rounds

    def done_round() -> None:
        if on_round is not None:
            on_round(ReleaseCheckpoint(np.array(x, dtype=float), its, scale, failed, tuple(rounds), 0.0,
                                       solver.pattern, round_rtol if inexact else None, dataclasses.replace(spent)))

    for _ in range(max_rounds - start):
        stab.scale = scale
        ts = terms(1.0)
        for t in ts:  # each round is a step: the damping centred and friction frozen at its start
            t.begin_step(x)
        newton = options.newton if round_rtol == rtol else dataclasses.replace(options.newton, rtol=round_rtol)
        res = minimize(ts, x, free, problem.force_scale, newton, solver)
        its += res.iterations
        timings.add(res.timings)
        spent.add(res.timings)
        rounds.append((scale, res.iterations, res.converged))
        if not res.converged:
            ran_out = res.status is NewtonStatus.MAX_ITERATIONS
            if scale >= RELEASE_CAP and not (beyond_cap and ran_out):
                break
            if (keep_failed or _past_cap(rounds, beyond_cap)) and ran_out:
                x = res.x
            if scale < RELEASE_CAP:
                scale *= 10.0
            failed = True
            done_round()
            continue
        x = res.x
        viscous = float(np.linalg.norm(stab.gradient(x)[free]))
        in_play = float(np.linalg.norm(by_name(ts)["elastic"].force_flux(x)[free]))
        if viscous <= max(rtol * in_play, options.newton.residual_floor * problem.force_scale) and round_rtol <= rtol:
            return x, its, True, rounds
        if inexact:
            round_rtol = min(LOOSE_ROUND_RTOL, max(rtol, 0.1 * viscous / max(in_play, 1e-300)))
        # after a failed round, lower again only after an easy round: otherwise a state still
        # travelling alternates between a round that converges and a lower one that fails
        limit = easy_round if easy_round is not None else (after_failure if failed else None)
        backoff = CAP_BACKOFF_ROUNDS if _past_cap(rounds, beyond_cap) else backoff_rounds
        if limit is None or res.iterations <= limit or (failed and _backed_off(rounds, backoff)):
            scale = max(scale / lower, 1e-8)
            failed = False
        done_round()
    return x, its, False, rounds
