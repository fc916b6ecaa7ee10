"""The actuator as a loaded structure (issue 15): the empty chamber against Euler-Bernoulli
bounds, the vacuum's outer surface against the closed-surface identity, and the blocked
actuation. A one-layer actuator on the quick mesh (4 mm) keeps it to seconds."""

import numpy as np
import pytest

from hydrojam import Design
from hydrojam.actuator.model import build_model
from hydrojam.actuator.simulate import simulate
from hydrojam.assess.chamber import actuator_structure, blocked_actuation, empty_chamber, outer_facets, vacuum_term
from hydrojam.assess.loading import tangent_stiffness
from hydrojam.fem.terms import PressureTerm

# frictionless: the Hessian's tangent against a small load's secant is a check of the tangent;
# with friction the secant includes the contacts' stick, which the (full-slip) tangent leaves out
DESIGN = Design(particle_layers=1, mesh={"size": 4.0}, friction=0.0)


@pytest.fixture(scope="module")
def model():
    return build_model(DESIGN)


@pytest.fixture(scope="module")
def actuated(model):
    return simulate(model)


def test_tangent_stiffness_of_the_jammed_state_matches_a_small_load(model, actuated):
    """At the actuated (jammed, contact-laden) state, the Hessian's tangent stiffness against
    the secant of a small tip load (2% of the force that deflects the unactuated actuator by 5%
    of L) in +x and -x, solved by Newton from the state: within 3% (the secant of a finite load
    includes its curvature; Newton's tolerance 1e-6 of the forces in play)."""
    from hydrojam.assess.loading import tip_curve

    structure = actuator_structure(model, 1.0)
    k = tangent_stiffness(structure, actuated.final.x)
    k0 = tangent_stiffness(actuator_structure(model, 0.0), model.mesh.points)
    curve = tip_curve(structure, actuated.final.x, 0.02 * 0.05 * DESIGN.length * k0, fractions=(1.0,))
    assert curve.converged
    for sign in (1, -1):
        assert curve.secant(sign) == pytest.approx(k, rel=0.03)


def _plane_strain_modulus(spec):
    return 2 * spec.shear_modulus / (1 - spec.poisson_ratio)


def test_empty_chamber_lies_between_the_euler_bernoulli_bounds(model):
    """Without particles the chamber is a frame: two walls (strain-limit layer + side wall, and
    the other side wall) joined only by the end walls. Euler-Bernoulli bounds its stiffness:
    above the two walls bending apart (sum of their own (EI)'), below the walls acting as one
    composite section. The unactuated actuator has the same stiffness: its particles float in
    their clearance and touch nothing, so they carry none of a small tip load."""
    d = DESIGN.resolved()
    chamber = empty_chamber(DESIGN)
    k = tangent_stiffness(chamber, chamber.X)
    E_sll, E_m = _plane_strain_modulus(d.strain_limit_layer), _plane_strain_modulus(d.membrane)
    h, t0, w = d.strain_limit_thickness, d.side_wall_thickness, d.resolved_cavity_width
    # layers as (E', thickness, centre x) on the section
    layers = [(E_sll, h, -w / 2 - t0 - h / 2), (E_m, t0, -w / 2 - t0 / 2), (E_m, t0, w / 2 + t0 / 2)]
    neutral = sum(E * t * c for E, t, c in layers) / sum(E * t for E, t, _ in layers)
    composite = sum(E * (t**3 / 12 + t * (c - neutral) ** 2) for E, t, c in layers)
    wall_a = layers[:2]
    na = sum(E * t * c for E, t, c in wall_a) / sum(E * t for E, t, _ in wall_a)
    apart = sum(E * (t**3 / 12 + t * (c - na) ** 2) for E, t, c in wall_a) + E_m * t0**3 / 12
    L = d.length
    assert 3 * apart / L**3 < k < 3 * composite / L**3
    unactuated = actuator_structure(model, 0.0)
    assert tangent_stiffness(unactuated, model.mesh.points) == pytest.approx(k, rel=1e-6)


def test_outer_surface_is_the_chamber_less_its_clamped_face(model):
    """The outer facets with the clamped face make a closed surface, whose integral of n ds is
    zero: a uniform (dead) pressure p on the outer facets alone pushes the chamber with
    p x (its width) toward the clamp (+z) and not at all in x. (The follower form's gradient
    differs at the clamped nodes only, where its open ends are held.)"""
    p = 0.01
    X = model.mesh.points
    force = -PressureTerm(X, outer_facets(model), p, follower=False).gradient(X).reshape(-1, 2).sum(axis=0)
    assert force == pytest.approx([0.0, p * DESIGN.width], abs=1e-12 * p * DESIGN.width)
    follower = -vacuum_term(model, p).gradient(X).reshape(-1, 2)
    free = np.setdiff1d(np.arange(len(X)), model.clamp_nodes)
    dead = -PressureTerm(X, outer_facets(model), p, follower=False).gradient(X).reshape(-1, 2)
    assert follower[free] == pytest.approx(dead[free], abs=1e-12 * p * DESIGN.width)
    facets = outer_facets(model)
    assert not set(map(tuple, np.sort(facets[:, :2], axis=1))) & set(
        map(tuple, np.sort(model.mesh.facet_groups["cavity"][:, :2], axis=1)))


def test_blocked_actuation_holds_the_tip(model, actuated):
    """Actuated with a stop at the as-prepared tip, the tip's mean x moves by the stop's give
    F/k_stop only, far less than the free actuator's tip; the stop pushes in +x (the actuator
    bends toward -x), and the force is of the order of the actuated stiffness times the free
    tip displacement (a bending stiffness, not the stop's)."""
    free = actuated
    dx_free = free.metrics["tip_dx_mm"]
    k_act = tangent_stiffness(actuator_structure(model, 1.0), free.final.x)
    result, force, give = blocked_actuation(model)
    assert result.converged
    assert force[0] > 0 and force[1] == 0.0
    assert abs(give) < 0.01 * abs(dx_free)
    assert 0.3 < force[0] / (k_act * abs(dx_free)) < 3.0


def test_vacuum_jams_the_chamber_without_the_walls_passing_through_each_other(model):
    """80 kPa on the outer surface (3.5 G of the membrane): with the walls' self-contact the path
    reaches the target; no boundaries intersect (IPC's guarantee, walls included); the jammed
    chamber is stiffer; and where the membrane rests on the particle it passes the vacuum on:
    the mean contact pressure is of the order of p (a membrane of G = 23 kPa cannot hold 80 kPa
    by itself: between 0.5 p and 2 p)."""
    from hydrojam.assess.chamber import self_contact, vacuum_jamming
    from hydrojam.assess.confinement import wall_contact_pressure

    p = 0.08
    vac = vacuum_jamming(model, p)
    assert vac.converged and vac.pressure == p
    assert not self_contact(model).has_intersections(vac.x)
    k0 = tangent_stiffness(actuator_structure(model, 0.0), model.mesh.points)
    assert tangent_stiffness(vac.structure, vac.x) > 2 * k0
    assert 0.5 * p < wall_contact_pressure(model, vac.x).mean < 2 * p
