"""The actuator as a loaded structure (docs/assess.md): its terms at a stimulus (or with
other particles), the empty chamber, the membrane's outer surface for a vacuum, and the blocked
actuation. Units: mm, MPa; forces N/mm per unit depth in 2D, N in 3D (of the model: the half
model's are half the whole actuator's)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from hydrojam.actuator.design import Design
from hydrojam.actuator.model import MEMBRANE, PARTICLES, STRAIN_LIMIT_LAYER, ActuatorModel, outer_faces
from hydrojam.actuator.simulate import ACTUATOR_PATH, STABILISATION, SimulationResult, simulate
from hydrojam.assess.loading import Structure, tip_compliance
from hydrojam.fem.assembly import Block, Solid
from hydrojam.fem.contact import Contact
from hydrojam.fem.elements import element_for_meshio_type
from hydrojam.fem import PathOptions, minimize, release
from hydrojam.fem.problem import fixed
from hydrojam.fem.terms import CentroidSpring, PressureTerm, ScaledTerm, ViscousStabilisation, lumped_volumes
from hydrojam.materials.energies import Material

#: stiffness of the spring that blocks the tip, times the membrane's shear modulus [N/mm per mm
#: of depth per MPa; in 3D times the particle diameter too, N/mm per MPa mm]: 100 G = 2.3
#: N/mm/mm for Ecoflex 00-30, above 1e3 x the actuators' bending stiffness (docs/assess.md), so
#: the blocked tip stays within F/k of its place
BLOCK_STIFFNESS_PER_MODULUS = 100.0


def clamp_conditions(nodes_clamped: np.ndarray, dim: int, symmetry_nodes: np.ndarray | None = None) -> tuple:
    """The Dirichlet conditions of a clamped chamber: the clamped nodes held in every component
    and, in a 3D half model, the other nodes on the symmetry plane y = 0 held in y."""
    bcs = [fixed(nodes_clamped, dim)]
    if symmetry_nodes is not None:
        bcs.append(fixed(np.setdiff1d(symmetry_nodes, nodes_clamped), dim, [1]))
    return tuple(bcs)


def force_scale(shear_modulus: float, diameter: float, dim: int) -> float:
    """The residual floor's force scale [N/mm in 2D, N in 3D]: G d^(dim - 1)."""
    return shear_modulus * diameter ** (dim - 1)


def self_contact(model: ActuatorModel, walls_meet: bool = True) -> Contact:
    """The model's contact with the walls' full self-contact (IPC's: any two wall segments
    that share no node), so the membrane folding into the voids between particles meets itself
    at a barrier like any other contact; or, with ``walls_meet`` False, with none (the walls
    pass through each other). The model's own contact lets only walls of different bands along
    the axis touch (a chamber curling onto itself), which a vacuum's folds are not. Same barrier
    settings and collision surfaces as the model's (in 3D: the cavity, the particles and the
    walls' outer faces). The particles' forces on the walls are the particle-wall pairs'
    alone either way (the barrier is a sum over pairs)."""
    regions = np.arange(model.mesh.n_nodes) if walls_meet else None
    return Contact(model.mesh.points, model.contact.facets, model.components, model.contact.settings,
                   regions=regions)


def actuator_structure(model: ActuatorModel, s: float = 1.0, particles: Material | None = None,
                       contact: Contact | None = None) -> Structure:
    """The actuator at load parameter s (materials at the stimulus of s; s = 0: the as-prepared
    state (mu0, T0)), optionally with another ``particles`` material or ``contact`` term: the
    solid ("elastic") and "contact", clamped top, the free-end face loaded. The contact term is
    a fresh one (no friction frozen): a tangent stiffness at a state is the frictionless one
    (full slip), and a tip curve's load steps freeze friction as a run's do."""
    materials = model.materials_at(s)
    if particles is not None:
        materials[PARTICLES] = particles
    terms = (model.solid.with_materials(materials), (model.contact if contact is None else contact).fresh())
    dim = model.mesh.dim
    return Structure(model.mesh.points, terms, clamp_conditions(model.clamp_nodes, dim, model.symmetry_nodes),
                     model.mesh.facet_groups["free_end"],
                     force_scale(model.membrane.shear_modulus_ref, model.design.particle_diameter, dim))


def empty_chamber_mesh(design: Design):
    """The design's membrane and strain-limit layer without particles, meshed by the actuator's
    own geometry code (2D, or 3D: the half model unless ``mesh.symmetry`` is false)."""
    from hydrojam.actuator.geometry import actuator_2d, actuator_3d

    d = design.resolved()
    if d.dimension == 3:
        return actuator_3d(d.resolved_cavity_width, d.resolved_cavity_depth, d.resolved_cavity_length,
                           d.side_wall_thickness, d.end_wall_thickness, d.strain_limit_thickness, np.zeros((0, 3)),
                           d.particle_diameter / 2, d.mesh_size, symmetry=d.mesh.symmetry, order=2)
    return actuator_2d(d.resolved_cavity_width, d.resolved_cavity_length, d.side_wall_thickness, d.end_wall_thickness,
                       d.strain_limit_thickness, np.zeros((0, 2)), d.particle_diameter / 2, d.mesh_size, order=2)


def empty_chamber(design: Design, mesh=None) -> Structure:
    """The design's membrane and strain-limit layer without particles (an empty chamber,
    :func:`empty_chamber_mesh` unless ``mesh`` is given): a structure for tip loads (no contact:
    the cavity's walls do not meet under small loads or under an inner pressure)."""
    d = design.resolved()
    mesh = empty_chamber_mesh(d) if mesh is None else mesh
    el = element_for_meshio_type(mesh.cell_type)
    membrane, sll = d.membrane.material(), d.strain_limit_layer.material()
    solid = Solid(mesh.points, [Block(mesh.cells[mesh.cell_groups[MEMBRANE]], el, membrane, MEMBRANE),
                                Block(mesh.cells[mesh.cell_groups[STRAIN_LIMIT_LAYER]], el, sll, STRAIN_LIMIT_LAYER)])
    sym = mesh.group_nodes("symmetry") if "symmetry" in mesh.facet_groups else None
    return Structure(mesh.points, (solid,), clamp_conditions(mesh.group_nodes("clamp"), mesh.dim, sym),
                     mesh.facet_groups["free_end"], force_scale(membrane.shear_modulus_ref, d.particle_diameter, mesh.dim))


def outer_facets(model: ActuatorModel) -> np.ndarray:
    """The chamber's outer surface (membrane and strain-limit layer), outward: every boundary
    facet of the walls except the cavity's and the clamped face's (nf, 3;
    :func:`hydrojam.actuator.model.outer_faces`). Its only edges are held by the clamp, so a
    follower pressure on it is conservative (PressureTerm)."""
    return outer_faces(model.mesh)


def vacuum_term(model: ActuatorModel, pressure: float) -> PressureTerm:
    """A follower pressure ``pressure`` [MPa] on the chamber's outer surface (:func:`outer_facets`):
    the pressure difference of a vacuum-jammed chamber (positive: pushes the walls inward)."""
    mesh = model.mesh
    walls = np.concatenate([mesh.cell_groups[MEMBRANE], mesh.cell_groups[STRAIN_LIMIT_LAYER]])
    return PressureTerm(mesh.points, outer_facets(model), pressure, follower=True, cells=mesh.cells[walls], name="vacuum")


def blocking_spring(model: ActuatorModel) -> CentroidSpring:
    """A stiff spring that holds the free-end face's mean x position where it was as prepared
    (z free: a frictionless stop in front of the tip), stiffness
    :data:`BLOCK_STIFFNESS_PER_MODULUS` x G_membrane (x the particle diameter in 3D)."""
    X = model.mesh.points
    dim = model.mesh.dim
    k = BLOCK_STIFFNESS_PER_MODULUS * model.membrane.shear_modulus_ref * model.design.particle_diameter ** (dim - 2)
    spring = CentroidSpring(X, model.mesh.facet_groups["free_end"], np.zeros(dim), k, components=(0,),
                            name="tip_stop")
    spring.target = spring.centroid(X)
    return spring


def blocked_actuation(model: ActuatorModel, on_progress=None) -> tuple[SimulationResult, np.ndarray, float]:
    """Actuate with the tip held in x where it was as prepared (:func:`blocking_spring`): the
    blocked force. Returns (the simulation, the force the stop exerts on the tip (d,) [N/mm per
    unit depth in 2D; N on the model in 3D], the stop's give: the tip's remaining x displacement [mm])."""
    spring = blocking_spring(model)
    result = simulate(model, on_progress=on_progress, extra_terms=(spring,))
    x = result.final.x
    return result, spring.reaction(x), float(spring.centroid(x)[0] - spring.target[0])


@dataclass(frozen=True)
class VacuumState:
    """A vacuum-jammed chamber: ``structure`` (the pressure ``pressure`` [MPa] held on the outer
    surface), its equilibrium ``x`` (n, 2) [mm], whether the target pressure was reached
    (``converged``; if not, ``pressure`` is the largest one the chamber held, see
    :func:`vacuum_jamming`), ``message`` and ``newton_iterations``."""

    structure: Structure
    x: np.ndarray
    pressure: float
    target: float
    converged: bool
    message: str
    newton_iterations: int


#: the vacuum's load path: the actuation's, but a failed step below the minimum increment gets
#: one attempt of 2x (not 10x) the Newton budget: where the walls give way no equilibrium is near
VACUUM_PATH = dataclasses.replace(ACTUATOR_PATH, last_resort_factor=2)

#: when the ramp fails, the pressure is lowered to this fraction of the last one held (with the
#: stabilisation on) before the stabilisation is released: the state there is stable
BACK_OFF = 0.9


def vacuum_jamming(model: ActuatorModel, pressure: float, particles: Material | None = None,
                   stabilisation: float = STABILISATION, options: PathOptions = VACUUM_PATH,
                   max_back_offs: int = 6, walls_meet: bool = True) -> VacuumState:
    """Jam the unactuated chamber (particles at (mu0, T0), or ``particles``) by a vacuum: the
    pressure difference on the outer surface ramped from 0 to ``pressure`` [MPa]
    (:func:`vacuum_term`), with the actuation's viscous stabilisation, released at the end (damping
    lowered 10x per converged round, :func:`hydrojam.fem.release`) until the state is an equilibrium
    without it.

    Where the walls give way before the target (the membrane folds into the voids between round
    particles and a square cavity and meets itself; the walls' self-contact is not modelled,
    docs/assess.md), the pressure is lowered to :data:`BACK_OFF` x the last pressure held and the
    state released there, and lowered again (up to ``max_back_offs`` times) while the released
    state is not stable (its tip compliance not positive): ``converged`` is then False and
    ``pressure`` says what was held. ``walls_meet``: with the walls' self-contact
    (:func:`self_contact`; without it the walls pass through each other in the corner voids and
    the path stops near 12-20 kPa, docs/assess.md)."""
    base = actuator_structure(model, 0.0, particles, self_contact(model, walls_meet))
    mesh = model.mesh
    w = lumped_volumes(mesh.points, mesh.cells, mesh.cell_volumes())
    stab = ViscousStabilisation(w, stabilisation * model.membrane.shear_modulus_ref / model.design.particle_diameter,
                                mesh.dim)
    vac = vacuum_term(model, pressure)
    res = base.load(mesh.points, lambda s: [ScaledTerm(vac, s), stab], options)
    its = res.newton_iterations
    if res.converged:
        x, message = _release(base.with_terms(vac), stab, res.x, options)
        its += message[1]
        if x is not None:
            return VacuumState(base.with_terms(vac), x, float(pressure), float(pressure), True, "converged", its)
    held_p, why = res.s * float(pressure), "the load path stopped there" if not res.converged else "not stable there"
    for _ in range(max_back_offs):
        held_p *= BACK_OFF
        vac = vacuum_term(model, held_p)
        stab.scale = 1.0
        stab.begin_step(res.x)
        r = minimize([*base.terms, vac, stab], res.x, base.free_mask(), base.force_scale, options.newton)
        its += r.iterations
        if not r.converged:
            continue
        x, (_, n) = _release(base.with_terms(vac), stab, r.x, options)
        its += n
        if x is not None:
            message = (f"no stable equilibrium up to {1e3 * pressure:.3g} kPa ({why}: "
                       f"{1e3 * res.s * pressure:.3g} kPa); measured at {1e3 * held_p:.3g} kPa")
            return VacuumState(base.with_terms(vac), x, held_p, float(pressure), False, message, its)
    return VacuumState(base, mesh.points, 0.0, float(pressure), False,
                       f"no stable vacuum-jammed state found below {1e3 * res.s * pressure:.3g} kPa", its)


def _release(held: Structure, stab: ViscousStabilisation, x: np.ndarray, options: PathOptions):
    """Take the stabilisation off by the load path's release (:func:`hydrojam.fem.release`,
    ``options.release``: proximal rounds from its present scale until the state is an
    equilibrium without it); returns (x, (message, Newton iterations)) with x None if it cannot
    be released or the end state is not stable (tip compliance <= 0)."""
    rel = release([*held.terms, stab], stab, x, held.free_mask(), held.force_scale, options.newton,
                  options=options.release, unphysical=(stab.name,))
    if not rel.released:
        return None, (f"the stabilisation could not be released in {len(rel.rounds)} rounds", rel.iterations)
    if not tip_compliance(held, rel.x) > 0:
        return None, ("not stable", rel.iterations)
    return rel.x, ("converged", rel.iterations)
