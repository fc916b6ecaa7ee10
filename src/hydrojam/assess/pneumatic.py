"""The pneumatic baseline (docs/assess.md): the design's chamber, empty, pressurised from inside
until it bends as far as the active-particle actuator; the pressure that takes, the chamber's
tangent tip stiffness there (the pressure held) and its blocked force at that pressure. Units:
mm, MPa, deg; forces N/mm per unit depth in 2D, N on the model in 3D."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hydrojam.actuator.design import Design
from hydrojam.actuator.geometry import MEMBRANE, STRAIN_LIMIT_LAYER
from hydrojam.actuator.metrics import bending_angle_3d_deg, bending_angle_deg
from hydrojam.assess.chamber import BLOCK_STIFFNESS_PER_MODULUS, empty_chamber, empty_chamber_mesh
from hydrojam.assess.loading import Structure, tangent_stiffness
from hydrojam.fem import NewtonOptions, PathOptions
from hydrojam.fem.terms import CentroidSpring, PressureTerm, ScaledTerm

#: the pressure ramp's levels up to the largest pressure, before the angle is bracketed
LEVELS = 8
#: the angle is matched to this share of the target (or 0.1 deg, whichever is larger)
ANGLE_TOLERANCE = 0.01
#: the pressure ramp's load path: an empty chamber has no contact, so Newton converges in a few
#: iterations where an equilibrium exists; past a balloon's limit point none does, and the path
#: gives up after a short search (increments down to 1 % of a level, no enlarged last attempt)
#: instead of spending the contact paths' budget (10 x 200 iterations) on it
PNEUMATIC_PATH = PathOptions(ds0=0.5, ds_min=1e-2, ds_max=1.0, easy_iterations=15,
                             newton=NewtonOptions(max_iter=25), last_resort_factor=1)


def inflation_term(mesh, pressure: float = 1.0) -> PressureTerm:
    """A follower pressure ``pressure`` [MPa] inside the cavity (its wall's facets, oriented out
    of the walls: a positive pressure pushes the walls outward, inflates the chamber). In a 3D
    half model the wall's rim lies on y = 0, through the origin, so the enclosed volume, and with
    it the pressure's work, is the half cavity's."""
    walls = np.concatenate([mesh.cell_groups[MEMBRANE], mesh.cell_groups[STRAIN_LIMIT_LAYER]])
    return PressureTerm(mesh.points, mesh.facet_groups["cavity"], pressure, follower=True, cells=mesh.cells[walls],
                        name="inflation")


def tip_angle(structure: Structure, x: np.ndarray) -> float:
    """Bending angle [deg] of the free-end face (positive toward the strain-limit side), as the
    actuator's metric measures it (:func:`~hydrojam.actuator.metrics.bending_angle_3d_deg` in 3D)."""
    nodes = np.unique(structure.free_end)
    X, x = structure.X[nodes], np.asarray(x, dtype=float)[nodes]
    return bending_angle_3d_deg(X, x) if structure.dim == 3 else bending_angle_deg(X, x)


@dataclass(frozen=True)
class PneumaticState:
    """The empty chamber pressurised to ``pressure`` [MPa]: ``structure`` (the empty chamber
    without the pressure), ``held`` (with it), the equilibrium ``x`` (n, d) [mm], its bending
    ``angle_deg`` against ``target_deg``, ``converged`` (the target matched), ``message`` and
    ``newton_iterations``."""

    structure: Structure
    held: Structure
    x: np.ndarray
    pressure: float
    angle_deg: float
    target_deg: float
    converged: bool
    message: str
    newton_iterations: int


def pressurise_to_angle(design: Design, target_deg: float, max_pressure: float, levels: int = LEVELS,
                        max_refinements: int = 8) -> PneumaticState:
    """Pressurise the design's empty chamber (:func:`~hydrojam.assess.chamber.empty_chamber`)
    until its free end turns by ``target_deg`` [deg] (> 0, toward the strain-limit layer).

    The pressure rises in ``levels`` equal levels up to ``max_pressure`` [MPa], each a load path
    from the last level's state; once a level passes the target, the pressure is found by
    regula falsi on the angle between the two states that bracket it (each trial a load path
    from the bracket's lower state), to :data:`ANGLE_TOLERANCE` of the target. Where the
    chamber does not reach the target (``max_pressure`` too low, or the load path stops at a
    balloon's limit point), ``converged`` is False, and the state is the last one reached.
    """
    mesh = empty_chamber_mesh(design)
    structure = empty_chamber(design, mesh)
    unit = inflation_term(mesh, 1.0)
    tol = max(ANGLE_TOLERANCE * abs(target_deg), 0.1)
    x, p, angle, its = structure.X, 0.0, 0.0, 0

    def solve(x0, p0, p1):
        return structure.load(x0, lambda s: [ScaledTerm(unit, p0 + s * (p1 - p0))], PNEUMATIC_PATH)

    for k in range(1, levels + 1):
        p_next = max_pressure * k / levels
        res = solve(x, p, p_next)
        its += res.newton_iterations
        # the level's end, or where its ramp stopped (its last converged state: at a balloon's
        # limit point, the largest pressure the chamber holds)
        p_reached = p_next if res.converged else p + res.s * (p_next - p)
        a_reached = tip_angle(structure, res.x)
        if abs(a_reached - target_deg) <= tol:
            return _state(structure, unit, res.x, p_reached, a_reached, target_deg, True, "converged", its)
        if a_reached > target_deg:
            return _bracket(structure, unit, solve, (x, p, angle), (res.x, p_reached, a_reached), target_deg, tol,
                            max_refinements, its)
        if not res.converged:
            return _state(structure, unit, res.x, p_reached, a_reached, target_deg, False,
                          f"the pressure ramp stopped at {1e3 * p_reached:.3g} kPa, the chamber bent {a_reached:.3g} deg, "
                          f"short of {target_deg:.3g} deg: no equilibrium at a higher pressure was found (a limit "
                          f"point: the walls balloon) ({res.message})", its)
        x, p, angle = res.x, p_next, a_reached
    return _state(structure, unit, x, p, angle, target_deg, False,
                  f"at the largest pressure, {1e3 * max_pressure:.3g} kPa, the chamber bends {angle:.3g} deg, "
                  f"short of {target_deg:.3g} deg", its)


def _bracket(structure, unit, solve, lo, hi, target_deg, tol, max_refinements, its) -> PneumaticState:
    """The pressure between the states ``lo`` and ``hi`` ((x, p, angle), angles below and above
    the target) where the angle is the target: regula falsi (Illinois: the end that stays twice
    in a row has its weight halved, so that a strongly curved angle-pressure curve, as near a
    limit point, still closes in), each trial a load path from the lower state."""
    (x_lo, p_lo, a_lo), (_, p_hi, a_hi) = lo, hi
    side = 0
    f_lo, f_hi = a_lo - target_deg, a_hi - target_deg
    for _ in range(max_refinements):
        p_try = p_lo + f_lo / (f_lo - f_hi) * (p_hi - p_lo)
        r = solve(x_lo, p_lo, p_try)
        its += r.newton_iterations
        if not r.converged:
            break
        a_try = tip_angle(structure, r.x)
        if abs(a_try - target_deg) <= tol:
            return _state(structure, unit, r.x, p_try, a_try, target_deg, True, "converged", its)
        if a_try < target_deg:
            x_lo, p_lo, f_lo = r.x, p_try, a_try - target_deg
            f_hi = f_hi / 2 if side == -1 else f_hi
            side = -1
        else:
            p_hi, f_hi = p_try, a_try - target_deg
            f_lo = f_lo / 2 if side == 1 else f_lo
            side = 1
    return _state(structure, unit, x_lo, p_lo, tip_angle(structure, x_lo), target_deg, False,
                  f"the angle was not matched to {tol:.2g} deg between {1e3 * p_lo:.3g} and {1e3 * p_hi:.3g} kPa", its)


def _state(structure, unit, x, p, angle, target, converged, message, its) -> PneumaticState:
    return PneumaticState(structure, structure.with_terms(ScaledTerm(unit, p)), x, float(p), float(angle),
                          float(target), converged, message, its)


def pneumatic_stiffness(state: PneumaticState) -> float | None:
    """Tangent tip stiffness [N/mm per mm in 2D; N/mm of the model in 3D] of the pressurised
    chamber at its state, the pressure held (its follower Hessian included); None where the state
    is not stable."""
    try:
        return tangent_stiffness(state.held, state.x)
    except RuntimeError:
        return None


def pneumatic_blocked_force(design: Design, state: PneumaticState) -> tuple[float | None, float | None, bool]:
    """The chamber pressurised to the state's pressure with its tip held in x where it was as
    prepared (the stiff spring of the blocked actuation, :data:`BLOCK_STIFFNESS_PER_MODULUS`):
    returns (the force the stop exerts in x [N/mm per mm in 2D; N of the model in 3D], the
    stop's give [mm], converged)."""
    structure = state.structure
    d = design.resolved()
    k = BLOCK_STIFFNESS_PER_MODULUS * d.membrane.material().shear_modulus_ref * d.particle_diameter ** (structure.dim - 2)
    spring = CentroidSpring(structure.X, structure.free_end, np.zeros(structure.dim), k, components=(0,), name="tip_stop")
    spring.target = spring.centroid(structure.X)
    unit = state.held.terms[-1].term
    res = structure.with_terms(spring).load(structure.X, lambda s: [ScaledTerm(unit, s * state.pressure)],
                                             PNEUMATIC_PATH)
    if not res.converged:
        return None, None, False
    return float(spring.reaction(res.x)[0]), float(spring.centroid(res.x)[0] - spring.target[0]), True
