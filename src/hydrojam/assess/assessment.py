"""One design assessed (docs/assess.md): bending, the stiffness ratio, the blocked force
against temperature, the vacuum-jamming baseline and the confinement, from one function,
:func:`assess`. Units: mm, N/mm and MPa (2D: forces and stiffnesses per unit depth), K."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from hydrojam._io import finite_or_none
from hydrojam.actuator.design import Design, DesignError
from hydrojam.actuator.model import build_model, check_supported
from hydrojam.actuator.simulate import simulate
from hydrojam.assess.chamber import actuator_structure, blocked_actuation, vacuum_jamming
from hydrojam.assess.confinement import confined_swelling_pressure, wall_contact_pressure
from hydrojam.assess.loading import TipCurve, tangent_stiffness, tip_curve
from hydrojam.assess.spec import Loads
from hydrojam.assess.speed import swelling_time

#: the default largest tip force deflects the unactuated actuator by this share of its length
#: (at its tangent stiffness): past the linear range, short of folding it
AUTO_DEFLECTION = 0.05


@dataclass
class Assessment:
    """The numbers of one assessment (see :func:`assess`).

    Every force is per unit depth [N/mm], every stiffness [N/mm per mm of depth], pressures
    [MPa], times [s].

    Parameters
    ----------
    design : Design
        The design assessed (resolved).
    loads : Loads
        What was applied.
    values : dict, optional
        Name -> value of every scalar result, in the units above.
    curves : dict of str to TipCurve, optional
        The tip load-deflection curves by name: forces [N/mm], deflections [mm].
    blocked : list of dict, optional
        The blocked force at each temperature.
    states : dict of str to ndarray, optional
        The states computed, by name: positions [mm].
    model : object, optional
        The actuator model.
    """

    design: Design
    loads: Loads
    values: dict = field(default_factory=dict)
    curves: dict[str, TipCurve] = field(default_factory=dict)
    blocked: list[dict] = field(default_factory=list)
    states: dict[str, np.ndarray] = field(default_factory=dict)
    model: object = None

    def summary(self) -> dict:
        """Plain data for JSON: the values, the curves and the blocked forces (None for undefined)."""
        curves = {k: {"force_N_per_mm": c.forces.tolist(), "deflection_mm": c.deflections.tolist(),
                      "converged": c.converged, "message": c.message, "newton_iterations": c.newton_iterations}
                  for k, c in self.curves.items()}
        return finite_or_none({"values": self.values, "curves": curves, "blocked_force": self.blocked})


def _stiffness(structure, x) -> float | None:
    """Tangent stiffness, None where x is not a stable equilibrium (reported, never raised)."""
    try:
        return tangent_stiffness(structure, x)
    except RuntimeError:
        return None


def _ratio(a, b):
    return None if a is None or b is None else a / b


def check_assessable(design: Design) -> None:
    """Refuse, before any work, a design that :func:`assess` cannot assess (DesignError naming the
    field): a 3D one, since the empty chamber, the vacuum's outer surface and the contact pressure
    on the membrane are built for 2D only (docs/assess.md, "Limitations")."""
    check_supported(design)
    if design.chambers is not None:
        raise DesignError(f"chambers: an assessment takes one chamber (its empty chamber and vacuum load are built for "
                          f"one; got {len(design.chambers)} chambers)")
    if design.dimension != 2:
        raise DesignError(f"dimension: allowed for an assessment: 2 (got {design.dimension}): the empty chamber, "
                          "the vacuum load and the contact pressure on the membrane are built in 2D only")


def assess(design: Design, loads: Loads = Loads(), on_progress: Callable[[str], None] | None = None) -> Assessment:
    """Assess a design as a jamming actuator under the given loads.

    Actuate it (s = 1), then from the actuated and from the as-prepared (s = 0) state a tip
    load-deflection curve in +x and -x up to ``loads.max_force`` and the tangent stiffness there;
    the blocked force at each of ``loads.temperatures``; the vacuum-jamming baseline at
    ``loads.vacuum_pressure``; and the confinement (mean and largest contact pressure on the
    membrane against the gel's confined swelling pressure); and how fast: the swollen particles'
    diffusion-limited swelling time (and, for a design with a temperature schedule, the run's time
    to 90% of its final angle).

    Parameters
    ----------
    design : Design
        The design (2D).
    loads : Loads, optional
        What to apply (default: :class:`Loads`'s defaults).
    on_progress : callable, optional
        ``on_progress(message)``, told what starts (the long parts take minutes).

    Returns
    -------
    Assessment

    Raises
    ------
    DesignError
        For a design it cannot assess (:func:`check_assessable`), before any work.
    """
    check_assessable(design)
    say = on_progress or (lambda message: None)
    out = Assessment(design.resolved(), loads)
    v = out.values
    t0 = time.perf_counter()
    say("meshing")
    model = build_model(design)
    out.model = model
    say(f"actuating to T = {design.stimulus.temperature:g} K")
    t = time.perf_counter()
    quarter = [0.25]

    def progress(s: float) -> None:
        if s >= quarter[0] and s < 1.0:
            say(f"actuation at s = {s:.2f}")
            quarter[0] = 0.25 * (int(s / 0.25) + 1)

    run = simulate(model, on_progress=progress)
    v.update(bending_angle_deg=run.metrics["bending_angle_deg"], tip_dx_mm=run.metrics["tip_dx_mm"],
             tip_dz_mm=run.metrics["tip_dz_mm"], actuation_converged=run.converged,
             actuation_newton_iterations=run.newton_iterations, actuation_wall_time_s=time.perf_counter() - t)
    ratio = run.metrics["mean_swelling_ratio"]
    if ratio is not None and ratio > 0:
        # the swollen particle sets the diffusion time (Tanaka & Fillmore take the final radius)
        radius = 0.5 * design.particle_diameter * ratio ** (1.0 / design.dimension)
        tau, t90 = swelling_time(radius, design.hydrogel.diffusivity, design.dimension)
        v.update(particle_time_constant_s=tau, particle_swelling_t90_s=t90,
                 angle_t90_s=run.metrics.get("time_to_90_percent_angle_s"))
    x1 = run.final.x
    out.states["actuated"] = x1
    unactuated, actuated = actuator_structure(model, 0.0), actuator_structure(model, 1.0)
    X = model.mesh.points
    k0 = tangent_stiffness(unactuated, X)  # as prepared: stress-free, always stable
    k1 = _stiffness(actuated, x1)
    v.update(stiffness_unactuated=k0, stiffness_actuated=k1, stiffness_ratio=_ratio(k1, k0))
    max_force = loads.max_force if loads.max_force is not None else AUTO_DEFLECTION * design.resolved().length * k0
    v["max_force"] = max_force
    for name, structure, x in (("unactuated", unactuated, X), ("actuated", actuated, x1)):
        say(f"tip load-deflection, {name}, up to +-{max_force:.3g} N/mm")
        t = time.perf_counter()
        curve = tip_curve(structure, x, max_force)
        out.curves[name] = curve
        v[f"secant_{name}_plus"] = curve.secant(1)
        v[f"secant_{name}_minus"] = curve.secant(-1)
        v[f"curve_{name}_wall_time_s"] = time.perf_counter() - t
    contact = wall_contact_pressure(model, x1)
    mu, T = model.stimulus(1.0)
    v.update(contact_pressure_mean=contact.mean, contact_pressure_max=contact.maximum,
             contact_length_mm=contact.contact_length,
             swelling_pressure=confined_swelling_pressure(model.gel.params, mu, T),
             mean_swelling_ratio=run.metrics["mean_swelling_ratio"])
    if loads.blocking:
        for T_b in loads.temperatures:
            say(f"blocked actuation at T = {T_b:g} K")
            t = time.perf_counter()
            # a steady stimulus at T_b (a schedule, if any, is the actuation's, not the blocked test's)
            stimulus = design.stimulus.model_copy(update={"temperature": T_b, "schedule": None})
            m_b = build_model(design.model_copy(update={"stimulus": stimulus}))
            res, force, give = blocked_actuation(m_b)
            out.blocked.append({"temperature_K": T_b, "force_x_N_per_mm": float(force[0]), "give_mm": give,
                                "converged": res.converged, "newton_iterations": res.newton_iterations,
                                "wall_time_s": time.perf_counter() - t,
                                "swelling_pressure_MPa": confined_swelling_pressure(m_b.gel.params, 0.0, T_b)})
    if loads.vacuum:
        p = loads.vacuum_pressure / 1e3
        particles = None if loads.baseline_particles is None else loads.baseline_particles.material()
        say(f"vacuum jamming up to {loads.vacuum_pressure:g} kPa")
        t = time.perf_counter()
        vac = vacuum_jamming(model, p, particles)
        unjammed = actuator_structure(model, 0.0, particles)
        kv0 = tangent_stiffness(unjammed, X)
        kv = _stiffness(vac.structure, vac.x)
        out.states["vacuum"] = vac.x
        say("tip load-deflection, vacuum-jammed")
        curve = tip_curve(vac.structure, vac.x, max_force)
        out.curves["vacuum"] = curve
        vc = wall_contact_pressure(model, vac.x)
        v.update(vacuum_pressure_target_kPa=loads.vacuum_pressure, vacuum_pressure_kPa=1e3 * vac.pressure,
                 vacuum_converged=vac.converged, vacuum_message=vac.message,
                 stiffness_vacuum_unjammed=kv0, stiffness_vacuum=kv, stiffness_ratio_vacuum=_ratio(kv, kv0),
                 vacuum_contact_pressure_mean=vc.mean, vacuum_contact_pressure_max=vc.maximum,
                 vacuum_newton_iterations=vac.newton_iterations, vacuum_wall_time_s=time.perf_counter() - t)
    v["wall_time_s"] = time.perf_counter() - t0
    return out
