"""One design assessed (docs/assess.md): bending, the stiffness ratio, the blocked force
against temperature, the vacuum-jamming and pneumatic baselines and the confinement, from one
function, :func:`assess`. Units: mm, MPa, K; 2D: forces N/mm and stiffnesses N/mm per mm of
depth; 3D: forces N and stiffnesses N/mm of the whole actuator (twice the half model's)."""

from __future__ import annotations

import dataclasses
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
from hydrojam.assess.pneumatic import pneumatic_blocked_force, pneumatic_stiffness, pressurise_to_angle
from hydrojam.assess.spec import Loads
from hydrojam.assess.speed import swelling_time

#: the default largest tip force deflects the unactuated actuator by this share of its length
#: (at its tangent stiffness): past the linear range, short of folding it
AUTO_DEFLECTION = 0.05


@dataclass
class Assessment:
    """The numbers of one assessment (see :func:`assess`).

    In 2D every force is per unit depth [N/mm], every stiffness [N/mm per mm of depth]; in 3D
    forces are [N] and stiffnesses [N/mm] of the whole actuator (a half model's twice, under
    symmetric loads). Pressures [MPa], times [s].

    Parameters
    ----------
    design : Design
        The design assessed (resolved).
    loads : Loads
        What was applied.
    values : dict, optional
        Name -> value of every scalar result, in the units above.
    curves : dict of str to TipCurve, optional
        The tip load-deflection curves by name: forces [N/mm in 2D, N in 3D], deflections [mm].
    blocked : list of dict, optional
        The blocked force at each temperature.
    states : dict of str to ndarray, optional
        The states computed, by name: positions [mm].
    model : object, optional
        The actuator model.
    fields : dict of str to ndarray, optional
        Nodal fields on the model's mesh by name, e.g. the contact pressure on the cavity wall
        [MPa] at the actuated state.
    """

    design: Design
    loads: Loads
    values: dict = field(default_factory=dict)
    curves: dict[str, TipCurve] = field(default_factory=dict)
    blocked: list[dict] = field(default_factory=list)
    states: dict[str, np.ndarray] = field(default_factory=dict)
    model: object = None
    fields: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def three_d(self) -> bool:
        return self.design.dimension == 3

    @property
    def force_unit(self) -> str:
        """The unit of every force: "N" (3D, the whole actuator) or "N/mm" (2D, per mm of depth)."""
        return "N" if self.three_d else "N/mm"

    @property
    def stiffness_unit(self) -> str:
        """The unit of every stiffness: "N/mm" (3D, whole actuator) or "N/mm per mm" (2D, of depth)."""
        return "N/mm" if self.three_d else "N/mm per mm"

    def summary(self) -> dict:
        """Plain data for JSON: the values, the curves and the blocked forces (None for undefined)."""
        curves = {k: {"force": c.forces.tolist(), "deflection_mm": c.deflections.tolist(),
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
    field): what the simulator refuses (2D and 3D, half or whole model, are assessed)."""
    check_supported(design)
    if design.chambers is not None:
        raise DesignError(f"chambers: an assessment takes one chamber (its empty chamber and vacuum load are built for "
                          f"one; got {len(design.chambers)} chambers)")


def _scaled(curve: TipCurve, factor: float) -> TipCurve:
    """The curve with its forces times ``factor`` (the half model's to the whole actuator's)."""
    return dataclasses.replace(curve, forces=factor * curve.forces)


def _times(x, factor: float):
    return None if x is None else factor * x


def assess(design: Design, loads: Loads = Loads(), on_progress: Callable[[str], None] | None = None) -> Assessment:
    """Assess a design as a jamming actuator under the given loads.

    Actuate it (s = 1), then from the actuated and from the as-prepared (s = 0) state a tip
    load-deflection curve in +x and -x up to ``loads.max_force`` and the tangent stiffness there;
    the blocked force at each of ``loads.temperatures``; the vacuum-jamming baseline at
    ``loads.vacuum_pressure``; the pneumatic baseline (the empty chamber pressurised until it
    bends as far as the actuator); and the confinement (mean and largest contact pressure on the
    membrane against the gel's confined swelling pressure); and how fast: the swollen particles'
    diffusion-limited swelling time (and, for a design with a temperature schedule, the run's time
    to 90% of its final angle).

    In 3D the half model's forces and stiffnesses are doubled: every reported force [N] and
    stiffness [N/mm] is the whole actuator's under a symmetric load (``loads.max_force`` too is
    the whole actuator's). In 2D they are per mm of depth.

    Parameters
    ----------
    design : Design
        The design (2D or 3D).
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
    # the half model carries half of every symmetric load: the whole actuator's force is twice its own
    whole = 2.0 if model.half else 1.0
    funit = out.force_unit
    v.update(dimension=design.dimension, whole_actuator_factor=whole, temperature_K=design.stimulus.temperature)
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
    v.update(stiffness_unactuated=whole * k0, stiffness_actuated=_times(k1, whole), stiffness_ratio=_ratio(k1, k0))
    model_force = loads.max_force / whole if loads.max_force is not None else AUTO_DEFLECTION * design.resolved().length * k0
    v["max_force"] = whole * model_force
    for name, structure, x in (("unactuated", unactuated, X), ("actuated", actuated, x1)):
        say(f"tip load-deflection, {name}, up to +-{whole * model_force:.3g} {funit}")
        t = time.perf_counter()
        curve = _scaled(tip_curve(structure, x, model_force), whole)
        out.curves[name] = curve
        v[f"secant_{name}_plus"] = curve.secant(1)
        v[f"secant_{name}_minus"] = curve.secant(-1)
        v[f"curve_{name}_wall_time_s"] = time.perf_counter() - t
    contact = wall_contact_pressure(model, x1)
    out.fields["contact_pressure"] = contact.nodal
    mu, T = model.stimulus(1.0)
    v.update(contact_pressure_mean=contact.mean, contact_pressure_max=contact.maximum,
             contact_pressure_mean_kPa=1e3 * contact.mean, contact_pressure_max_kPa=1e3 * contact.maximum,
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
            out.blocked.append({"temperature_K": T_b, "force_x": whole * float(force[0]), "give_mm": give,
                                "converged": res.converged, "newton_iterations": res.newton_iterations,
                                "wall_time_s": time.perf_counter() - t,
                                "swelling_pressure_MPa": confined_swelling_pressure(m_b.gel.params, 0.0, T_b)})
            v[f"blocked_force_{T_b:g}K"] = whole * float(force[0])
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
        curve = _scaled(tip_curve(vac.structure, vac.x, model_force), whole)
        out.curves["vacuum"] = curve
        vc = wall_contact_pressure(model, vac.x)
        out.fields["contact_pressure_vacuum"] = vc.nodal
        v.update(vacuum_pressure_target_kPa=loads.vacuum_pressure, vacuum_pressure_kPa=1e3 * vac.pressure,
                 vacuum_converged=vac.converged, vacuum_message=vac.message,
                 stiffness_vacuum_unjammed=whole * kv0, stiffness_vacuum=_times(kv, whole),
                 stiffness_ratio_vacuum=_ratio(kv, kv0), stiffness_active_over_vacuum=_ratio(k1, kv),
                 vacuum_contact_pressure_mean=vc.mean, vacuum_contact_pressure_max=vc.maximum,
                 vacuum_contact_pressure_mean_kPa=1e3 * vc.mean, vacuum_contact_pressure_max_kPa=1e3 * vc.maximum,
                 vacuum_newton_iterations=vac.newton_iterations, vacuum_wall_time_s=time.perf_counter() - t)
    if loads.pneumatic:
        target = loads.pneumatic_angle if loads.pneumatic_angle is not None else v["bending_angle_deg"]
        t = time.perf_counter()
        if target is None or not target > 0:
            v.update(pneumatic_converged=False, pneumatic_message=f"no positive bending angle to match (got {target})")
        else:
            say(f"pneumatic: pressurising the empty chamber to {target:.3g} deg (up to {loads.pneumatic_max_pressure:g} kPa)")
            pn = pressurise_to_angle(design, float(target), loads.pneumatic_max_pressure / 1e3)
            kp = pneumatic_stiffness(pn)
            ke = tangent_stiffness(pn.structure, pn.structure.X)
            v.update(pneumatic_target_deg=float(target), pneumatic_angle_deg=pn.angle_deg,
                     pneumatic_pressure_kPa=1e3 * pn.pressure, pneumatic_converged=pn.converged,
                     pneumatic_message=pn.message, stiffness_empty=whole * ke,
                     stiffness_pneumatic=_times(kp, whole), stiffness_ratio_pneumatic=_ratio(kp, ke),
                     stiffness_active_over_pneumatic=_ratio(k1, kp), pneumatic_newton_iterations=pn.newton_iterations)
            out.states["pneumatic"] = pn.x
            if pn.pressure > 0:
                say(f"pneumatic: blocked force at {1e3 * pn.pressure:.3g} kPa")
                fb, give, ok = pneumatic_blocked_force(design, pn)
                v.update(pneumatic_blocked_force=_times(fb, whole), pneumatic_blocked_give_mm=give,
                         pneumatic_blocked_converged=ok)
        v["pneumatic_wall_time_s"] = time.perf_counter() - t
    v["wall_time_s"] = time.perf_counter() - t0
    return out
