"""The stimulus path: how (mu, T) move from the as-prepared state to the target as the load
parameter s goes from 0 to 1 (docs/actuator.md, "Stimulus path").

Both paths move (mu, T) along the straight segment from (mu0, T0) to (mu_target, T_target); they
differ only in how fast. ``"linear"``: the position on the segment is s. ``"swelling"``
(default): s is spread (nearly) evenly over the logarithm of the gel's unconfined swelling
stretch (plane strain in 2D, free in 3D) along the segment: s = 0.9 f + 0.1 t with f that share
of the log stretch and t the position on the segment (the 10% of t keeps s -> t one-to-one where
the swelling stalls or reverses). Near mu = 0 the swelling is most sensitive to mu,
so a linear path puts most of the swelling, and of a jammed packing's difficulty, in the last
percent of s; the swelling path gives every load step a similar share of it. Only the speed
changes: the states at s = 0 and s = 1, and the path in the (mu, T) plane, are the same.

A time-resolved stimulus (``stimulus.schedule``, docs/actuator.md "Actuation in time") gives a
:class:`TimedStimulusPath` instead (:func:`timed_stimulus_path`): each particle swells by its own
free-swelling kinetics (:func:`hydrojam.materials.kinetics.mean_log_swelling`), and the path runs
through the stimuli (mu_eff(t), T(t)) at which free swelling holds exactly the particle's mean
swelling at time t (never above the bath's mu). Within each load step the particles keep their
water near what those kinetics allow (:class:`KineticVolumes`, the controller of the model's
"volume" term; docs/kinetics.md "Particles in contact"), so a confined particle departs from
the free kinetics only on their time scale. Every path answers ``path(s) -> (mu, T)`` and
``path.time(s)`` (None on an untimed path).

The gel's physics the paths use (unconfined stretches by continuation, mu_eff, the osmotic
modulus) lives in :mod:`hydrojam.materials.swelling`; this module only lays the paths out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hydrojam.materials.energies import HydrogelParams
from hydrojam.materials.kinetics import mean_log_swelling, time_constant
from hydrojam.materials.swelling import effective_chemical_potential, free_log_volume, free_stretches, osmotic_modulus

_N_KNOTS = 65


@dataclass(frozen=True)
class StimulusPath:
    """(mu, T) as a function of the load parameter s in [0, 1].

    ``path(s)`` gives (mu [k_B T], T [K]). The knots map s to the position t on the straight
    segment from (mu_start, T_start) to (mu_target, T_target), monotone, t(0) = 0, t(1) = 1.

    Parameters
    ----------
    mu_start, T_start : float
        The start of the segment: chemical potential [k_B T], temperature [K].
    mu_target, T_target : float
        The target stimulus [k_B T], [K].
    s_knots, t_knots : ndarray
        The load parameter [-] and the position on the segment [-] at the knots.
    """

    mu_start: float
    T_start: float
    mu_target: float
    T_target: float
    s_knots: np.ndarray
    t_knots: np.ndarray

    def position(self, s: float) -> float:
        """Position t in [0, 1] on the (mu, T) segment at load parameter s."""
        return float(np.interp(min(max(s, 0.0), 1.0), self.s_knots, self.t_knots))

    def __call__(self, s: float) -> tuple[float, float]:
        """(mu [k_B T], T [K]) at load parameter s."""
        t = self.position(s)
        return (self.mu_start + t * (self.mu_target - self.mu_start),
                self.T_start + t * (self.T_target - self.T_start))

    timed = False

    def time(self, s: float) -> None:
        """Time [s] at load parameter s: None, an untimed (quasi-static) path has no time."""
        return None


def stimulus_path(params: HydrogelParams, mu_target: float, T_target: float, kind: str = "swelling",
                  dimension: int = 2, mu_start: float | None = None, T_start: float | None = None) -> StimulusPath:
    """The path from (mu_start, T_start) (default: the as-prepared (mu0, T0)) to the target.

    Parameters
    ----------
    params : HydrogelParams
        The gel.
    mu_target : float
        Target chemical potential [k_B T].
    T_target : float
        Target temperature [K].
    kind : {"swelling", "linear"}, optional
        How s spreads along the segment (see the module docstring).
    dimension : {2, 3}, optional
        Which unconfined swelling the "swelling" path spreads evenly: plane strain (2) or free (3).
    mu_start : float, optional
        Start chemical potential [k_B T] (default ``params.mu0``).
    T_start : float, optional
        Start temperature [K] (default ``params.T0``).

    Returns
    -------
    StimulusPath

    Raises
    ------
    ValueError
        For a ``kind`` other than "swelling" or "linear".
    """
    mu0 = params.mu0 if mu_start is None else float(mu_start)
    T0 = params.T0 if T_start is None else float(T_start)
    t = np.linspace(0.0, 1.0, _N_KNOTS)
    linear = StimulusPath(mu0, T0, float(mu_target), float(T_target), t, t)
    if kind == "linear":
        return linear
    if kind != "swelling":
        raise ValueError(f"stimulus path must be 'swelling' or 'linear' (got {kind!r})")
    lam = free_stretches(params, mu0 + t * (mu_target - mu0), T0 + t * (T_target - T0), dimension)
    logv = np.log(lam)
    total = logv[-1] - logv[0]
    if abs(total) < 1e-6:
        return linear
    frac = (logv - logv[0]) / total
    # a swelling that reverses on the way (or jumps at a transition) is not a usable coordinate:
    # keep its monotone envelope and mix in a little of t so that s -> t stays one-to-one
    frac = np.maximum.accumulate(np.clip(frac, 0.0, 1.0))
    s = 0.9 * frac + 0.1 * t
    return StimulusPath(mu0, T0, float(mu_target), float(T_target), s, t)


# ------------------------------------------------------------------------------------------------
# Time-resolved stimulus (docs/actuator.md, "Actuation in time")

#: samples of each schedule segment, evenly in time, and log-spaced after each schedule point
_SEGMENT_SAMPLES = 32
_LOG_SAMPLES = 160
#: the log-spaced samples after a schedule point start at this fraction of the time constant
_LOG_FIRST = 1e-3
#: share of the load parameter spread evenly over the logarithmic time since each schedule point,
#: ln(1 + (t - t_point) / (_TIME_SCALE tau)) (the rest over the swelling): the particles' water
#: relaxes on the time scale tau within each step (the "volume" term, an implicit flow), so a
#: long hold needs steps that grow with the time since its start, not one step to its end
_TIME_SHARE = 0.5
_TIME_SCALE = 0.3


def schedule_temperature(schedule, times) -> np.ndarray:
    """Temperature [K] of a schedule ((t_s, T_K) points) at ``times`` [s], linear in between."""
    pts = np.asarray(schedule, dtype=float)
    return np.interp(times, pts[:, 0], pts[:, 1])


def sample_times(schedule, tau: float) -> np.ndarray:
    """The times [s] at which a timed path samples the kinetics: the schedule's points, evenly
    inside each segment, and log-spaced from 1e-3 tau after each point (tau the particle's time
    constant [s]), where the swelling changes fastest; from 0 to the last point."""
    t = np.asarray(schedule, dtype=float)[:, 0]
    parts = [t]
    for a, b in zip(t[:-1], t[1:]):
        parts.append(np.linspace(a, b, _SEGMENT_SAMPLES + 1))
        logs = a + tau * np.logspace(np.log10(_LOG_FIRST), np.log10(max((t[-1] - a) / tau, 2 * _LOG_FIRST)),
                                     _LOG_SAMPLES)
        parts.append(logs[logs < t[-1]])
    out = np.unique(np.concatenate(parts))
    # merge samples closer than round-off of the times (the kinetics need strictly increasing times)
    keep = np.concatenate(([True], np.diff(out) > 1e-12 * max(t[-1], 1.0)))
    out = out[keep]
    out[-1] = t[-1]
    return out


@dataclass(frozen=True)
class TimedStimulusPath:
    """A time-resolved stimulus path: (mu [k_B T], T [K]) and time [s] as functions of the load
    parameter s in [0, 1], piecewise linear through the sampled states.

    Parameters
    ----------
    s_knots : ndarray, shape (m,)
        Load parameter at the samples [-], increasing from 0 to 1.
    times : ndarray, shape (m,)
        Time at the samples [s].
    mus : ndarray, shape (m,)
        The effective chemical potential mu_eff [k_B T].
    temperatures : ndarray, shape (m,)
        Temperature [K].
    surface, mean : ndarray, shape (m,)
        The particle's surface and volume-averaged ln J at each time [-].
    radius : float
        Particle radius of the kinetics [mm].
    diffusivity : float
        Collective diffusion coefficient of the kinetics [mm^2/s].
    schedule : tuple
        The ((t_s, T_K), ...) points it follows [s, K].
    """

    s_knots: np.ndarray
    times: np.ndarray
    mus: np.ndarray
    temperatures: np.ndarray
    surface: np.ndarray
    mean: np.ndarray
    radius: float
    diffusivity: float
    schedule: tuple

    timed = True

    def __call__(self, s: float) -> tuple[float, float]:
        """(mu_eff [k_B T], T [K]) at load parameter s."""
        s = min(max(s, 0.0), 1.0)
        return float(np.interp(s, self.s_knots, self.mus)), float(np.interp(s, self.s_knots, self.temperatures))

    def time(self, s: float) -> float:
        """Time [s] since the particles met the solvent, at load parameter s."""
        return float(np.interp(min(max(s, 0.0), 1.0), self.s_knots, self.times))

    @property
    def time_constant_s(self) -> float:
        """Tanaka & Fillmore's tau = a^2 / (pi^2 D) [s] of the path's particle radius."""
        return time_constant(self.radius, self.diffusivity)


def timed_stimulus_path(params: HydrogelParams, mu: float, schedule, particle_diameter: float,
                        diffusivity: float, dimension: int = 2, cells: int = 400) -> TimedStimulusPath:
    """The path of an actuator whose particles meet the solvent at t = 0, as prepared (stretch
    lambda0 of the dry network), while the temperature follows a schedule.

    Each particle follows its own free-swelling kinetics (a cylinder in 2D, a sphere in 3D;
    :func:`~hydrojam.materials.kinetics.mean_log_swelling`): its surface holds the unconfined
    equilibrium at (mu, T(t)) (the branch followed by continuation from lambda0), it starts at
    ln J = ln lambda0^3, and its radius is the largest unconfined radius over the schedule,
    (particle_diameter / 2) x the largest free stretch over lambda0 (Tanaka & Fillmore take the
    swollen radius; the largest is the slowest, a conservative time). Its mean ln J at each
    sampled time is held by free swelling at (mu_eff(t), T(t))
    (:func:`~hydrojam.materials.swelling.effective_chemical_potential`, at most ``mu``); the load parameter is spread over the
    samples half evenly over the (total variation of the) mean log swelling, as the "swelling"
    path does, so every load step gets a similar share of the change, and half evenly over the
    logarithmic time since each schedule point (in units of 0.3 tau), so that long holds get
    steps growing with the time since their start (the particles' water relaxes within them).

    Parameters
    ----------
    params : HydrogelParams
        The gel.
    mu : float
        Chemical potential of the solvent [k_B T].
    schedule : sequence of (float, float)
        (t_s [s], T_K [K]) points, t from 0, strictly increasing; linear in between.
    particle_diameter : float
        As-prepared particle diameter [mm].
    diffusivity : float
        Collective diffusion coefficient D [mm^2/s].
    dimension : {2, 3}, optional
        Cylinders (plane strain) or spheres.
    cells : int, optional
        Radial shells of the kinetics.

    Returns
    -------
    TimedStimulusPath
    """
    pts = np.asarray(schedule, dtype=float)
    lam0 = params.lambda0
    # the radius first (it sets the time constant, hence the samples): the schedule's points
    # and a fine grid between them (the largest free swelling can lie inside a ramp)
    probe = np.unique(np.concatenate([np.linspace(a, b, _SEGMENT_SAMPLES + 1) for a, b in zip(pts[:-1, 0], pts[1:, 0])]))
    lam_probe = free_stretches(params, np.full(probe.size, float(mu)), schedule_temperature(pts, probe), dimension)
    radius = 0.5 * particle_diameter * max(lam_probe.max() / lam0, 1.0)
    times = sample_times(pts, time_constant(radius, diffusivity))
    Ts = schedule_temperature(pts, times)
    lam = free_stretches(params, np.full(times.size, float(mu)), Ts, dimension)  # continuation in time
    surface = free_log_volume(params, lam, dimension)
    shape = "sphere" if dimension == 3 else "cylinder"
    mean = mean_log_swelling(times, surface, radius, diffusivity, shape, initial=3.0 * np.log(lam0), cells=cells)
    # never above the bath's: where the free kinetics hold more water than the bath allows at
    # T(t) (shrinking on the collapsed branch), a gel at mu_eff > mu has no bounded swollen branch,
    # and any point pushed across its barrier would swell without end; at the bath's mu the
    # shrinking is driven by the bath and paced by the volume term (docs/kinetics.md)
    mus = np.minimum(effective_chemical_potential(params, np.exp(mean), Ts, dimension), float(mu))
    step = np.abs(np.diff(mean))
    total = step.sum()
    # time since the start of the segment a sample ends (a schedule point ends the one before it)
    since = times - pts[np.maximum(np.searchsorted(pts[:, 0], times, side="left") - 1, 0), 0]
    log_time = np.log1p(since / (_TIME_SCALE * time_constant(radius, diffusivity)))
    # from one sample to the next: the log time grows within a segment; at a schedule point it restarts
    dlog = np.where(since[1:] > since[:-1], log_time[1:] - log_time[:-1], log_time[1:])
    even = dlog / dlog.sum()
    weight = even if total < 1e-9 else (1.0 - _TIME_SHARE) * step / total + _TIME_SHARE * even
    s = np.concatenate(([0.0], np.cumsum(weight)))
    s /= s[-1]
    return TimedStimulusPath(s, times, mus, Ts, surface, mean, float(radius), float(diffusivity),
                             tuple(map(tuple, pts.tolist())))


# ------------------------------------------------------------------------------------------------
# Water content held within a time step (docs/kinetics.md "Particles in contact: water content within a time step")

#: shortest time step [in units of the particle's tau] the kinetic volume term assumes: a bound
#: on its stiffness (K tau / dt), reached only by a step of no duration
_MIN_STEP_TAU = 1e-6


class KineticVolumes:
    """The controller of a volume term (:class:`~hydrojam.fem.volume.LocalVolumeTerm`, point by
    point, or :class:`~hydrojam.fem.volume.VolumeTerm`, per particle) on the particles of a timed
    run: within a load step from time t0 to t (:meth:`set_time` gives t), each volume V (det F at
    a point, or a particle's area) is drawn to

        Vbar = V(t0) exp(<ln J>(t) - <ln J>(t0))   with stiffness   k = K tau / ((t - t0) V(t0)),

    i.e. the gel changes its water content at the free particle's relative rate (<ln J>(t) of
    ``path``, the free-swelling kinetics) and departs from that only by an implicit (backward
    Euler) gradient flow of its volume with the dissipation K tau / 2 (d ln V / dt)^2: the
    kinetics' tau for a gel of osmotic modulus ``modulus`` K [MPa] (Tanaka & Fillmore's friction
    f = K / D, lumped). A free particle is at the centre at every step (its material at mu_eff(t)
    holds exactly exp<ln J>(t)): it follows the kinetics exactly. As t - t0 grows the stiffness
    vanishes: the end of a long hold is the drained equilibrium, the untimed answer.

    A step starts where the last accepted one ended: the solver says so (:meth:`step_accepted`,
    or :meth:`on_step_accepted` as an observer of the load path,
    :class:`~hydrojam.fem.solver.events.StepAccepted`), and the next ``begin_step`` takes its
    volumes and the time it was accepted at as the new start, once it is at a later time. Any
    other ``begin_step`` (a retry with a smaller increment, a round of a release, the release of
    the stabilisation at s = 1 after the last step) stays within the step that started last.
    """

    def __init__(self, path: TimedStimulusPath, modulus: float):
        self.path = path
        self.modulus = float(modulus)
        self._t = 0.0
        self._start: tuple[float, np.ndarray] | None = None
        self._accepted: float | None = None

    def set_time(self, t: float) -> None:
        """The time [s] the next load step ends at."""
        self._t = float(t)

    def step_accepted(self) -> None:
        """The step to the time last set (:meth:`set_time`) was accepted: the next step starts
        from its state at that time."""
        self._accepted = self._t

    def on_step_accepted(self, event) -> None:
        """The load path accepted a step (an :class:`~hydrojam.fem.solver.events.Observer`'s
        hook): :meth:`step_accepted`."""
        self.step_accepted()

    def mean_log_swelling(self, t: float) -> float:
        """The free particle's <ln J> at time t [s] (linear between the path's samples)."""
        return float(np.interp(t, self.path.times, self.path.mean))

    def __call__(self, volumes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Targets and stiffnesses for a step from the ``volumes`` at its start (any shape: det F
        [-] per point, giving k [MPa]; or areas [mm^2] per particle, giving k [MPa/mm^2])."""
        v = np.array(volumes, dtype=float)
        if self._start is None:
            self._start = (self.path.time(0.0), v)
        elif self._accepted is not None and self._t > self._accepted:
            self._start, self._accepted = (self._accepted, v), None
        t0, v0 = self._start
        tau = self.path.time_constant_s
        dt = max(self._t - t0, _MIN_STEP_TAU * tau)
        targets = v0 * np.exp(self.mean_log_swelling(self._t) - self.mean_log_swelling(t0))
        return targets, self.modulus * tau / (dt * v0)


def kinetic_modulus(params: HydrogelParams, path: TimedStimulusPath, dimension: int = 2) -> float:
    """K [MPa] of :class:`KineticVolumes`: the free gel's osmotic modulus in the state that sets
    the kinetics' radius (the largest free swelling of the schedule), where D is meant to hold,
    or, if larger, the largest negative osmotic modulus along the free kinetics (exp<ln J>(t),
    T(t)): where the free gel is unstable (inside the spinodal, heated through the transition) a
    particle's departure from the kinetics then grows no faster than e^(t/tau)."""
    k = int(np.argmax(path.surface))
    swollen = osmotic_modulus(params, float(np.exp(path.surface[k])), float(path.temperatures[k]), dimension)
    along = [osmotic_modulus(params, float(np.exp(m)), float(T), dimension) for m, T in zip(path.mean, path.temperatures)]
    return max(swollen, -min(along))
