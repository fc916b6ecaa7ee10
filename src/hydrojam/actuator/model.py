"""The actuator model: a :class:`~hydrojam.actuator.design.Design` turned into bodies, materials,
the clamp and contact (docs/actuator.md, "Model"), and the measurements taken on a state ("Metrics").

Data flow: design -> geometry and mesh (gmsh, in ``actuator.geometry`` and ``fem.meshing``) ->
:class:`ActuatorModel` (this module) -> :func:`hydrojam.actuator.simulate.simulate`. Lengths mm,
stresses MPa, forces N/mm (2D, per unit depth).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from hydrojam.fem.assembly import Block, Solid
from hydrojam.fem.contact import Contact, default_settings
from hydrojam.actuator.design import Design, DesignError
from hydrojam.fem.elements import element_for_meshio_type, straight_pieces
from hydrojam.materials.energies import Hydrogel, Material
from hydrojam.fem.mesh import Mesh
from hydrojam.actuator.geometry import MEMBRANE, STRAIN_LIMIT_LAYER, jitter_particles, mesh_design
from hydrojam.actuator.metrics import Gauges, particle_volumes
from hydrojam.actuator.metrics import measure as measure_state
from hydrojam.fem.problem import Problem, fixed
from hydrojam.actuator.stimulus import (
    KineticVolumes,
    StimulusPath,
    TimedStimulusPath,
    kinetic_modulus,
    stimulus_path,
    timed_stimulus_path,
)
from hydrojam.fem.volume import LocalVolumeTerm

DHAT_PER_CLEARANCE = 0.8  # barrier activation distance / initial clearance
KAPPA_PER_MEMBRANE_MODULUS = 1.0  # barrier stiffness / membrane shear modulus (see build_model)
#: 3D continuous collision detection: Tight Inclusion at tolerance 1e-3, at most 1e5 iterations
#: (ipctk's 1e-6 and 1e7 spent over half of a 3D run in CCD; docs/actuator.md "3D"). Still
#: conservative: every step stays collision-free. 2D keeps ipctk's defaults.
CCD_3D = {"ccd_tolerance": 1e-3, "ccd_max_iterations": 100_000}
WALL_COMPONENT = -1  # contact component of the membrane and strain-limit layer (one bonded body)

#: the walls' self-contact: their nodes fall into bands along the actuator's axis (reference z),
#: each as long as the actuator is wide (``Design.width``), and only walls of different bands may
#: touch. A wall curls onto itself over a full turn, whose centreline is at least pi x the width
#: long, so that contact is never between neighbours in one band; the bands spare the CCD the
#: pairs of neighbouring wall triangles (docs/actuator.md, "Choices").
SELF_CONTACT_BAND_PER_WIDTH = 1.0

#: body ids written to results (cell data ``body_id``): particles are PARTICLE_BODY + k
MEMBRANE_BODY, STRAIN_LIMIT_BODY, PARTICLE_BODY = 0, 1, 2

#: names of the solid's blocks: MEMBRANE and STRAIN_LIMIT_LAYER (from ``actuator.geometry``: the
#: mesh's cell groups of the membrane and the strain-limit layer) and PARTICLES, the block that
#: holds every particle's cells, particle by particle
PARTICLES = "particles"


def particle_block(chamber: int) -> str:
    """The name of the solid's block holding chamber ``chamber``'s particles: PARTICLES for the
    first (a single chamber's), then "particles1", ..."""
    return PARTICLES if chamber == 0 else f"{PARTICLES}{chamber}"


def check_supported(design: Design) -> None:
    """Refuse, before any work, what the schema holds but the simulator does not do (nothing at
    present: 2D and 3D designs are both simulated; the design's own checks refuse bad ones)."""
    if design.dimension not in (2, 3):  # pragma: no cover - the schema allows only 2 and 3
        raise DesignError(f"dimension: allowed: 2, 3 (got {design.dimension})")


@dataclass(frozen=True)
class ActuatorModel:
    """Everything a simulation needs, built once from a design.

    ``solid`` holds three blocks, named ``MEMBRANE``, ``STRAIN_LIMIT_LAYER`` and ``PARTICLES`` (all
    particles, in order), whose materials :meth:`materials_at` sets for a load parameter s; ``contact`` couples the particles with each
    other and with the membrane; the clamp holds every node of the top face.
    """

    design: Design
    mesh: Mesh
    solid: Solid
    contact: Contact
    path: StimulusPath | TimedStimulusPath
    membrane: Material
    strain_limit: Material
    gel: Hydrogel
    clamp_nodes: np.ndarray
    free_end_nodes: np.ndarray
    centreline_nodes: np.ndarray  # strain-limit layer mid-line, ordered from the clamp
    particle_cells: list[np.ndarray]  # cell indices of each particle
    cavity_segments: np.ndarray  # straight pieces of the cavity wall, node indices: (k, 2) segments in 2D, (k, 3) triangles in 3D
    body_id: np.ndarray  # (n_cells,) MEMBRANE_BODY, STRAIN_LIMIT_BODY, PARTICLE_BODY + k
    components: np.ndarray  # (n_nodes,) contact component of every node
    gauges: Gauges  # what the state metrics read (actuator.metrics.measure)
    #: 3D half model: the nodes on the symmetry plane y = 0, held at u_y = 0 (None otherwise)
    symmetry_nodes: np.ndarray | None = None
    #: multi-chamber designs: each chamber's gel and stimulus path (its own temperature), in the
    #: order of the blocks of its particles (:func:`particle_block`); empty for one chamber
    chamber_gels: tuple[Hydrogel, ...] = ()
    chamber_paths: tuple[StimulusPath, ...] = ()

    @property
    def half(self) -> bool:
        """True for the 3D half model (y >= 0; the results are mirrored about y = 0)."""
        return self.symmetry_nodes is not None

    @property
    def n_particles(self) -> int:
        return len(self.particle_cells)

    def block_cells(self) -> dict[str, np.ndarray]:
        """The cell indices of every block of the solid, by name (MEMBRANE, STRAIN_LIMIT_LAYER where
        the design has one, and each chamber's particles, :func:`particle_block`)."""
        groups = self.mesh.cell_groups
        out = {name: groups[name] for name in (MEMBRANE, STRAIN_LIMIT_LAYER) if name in groups}
        counts = [len(self.particle_cells)] if not self.chamber_gels else [
            ch.particle_layers * ch.particles_per_layer for ch in self.design.resolved_chambers]
        starts = np.concatenate([[0], np.cumsum(counts)])
        for k in range(len(counts)):
            out[particle_block(k)] = np.concatenate(self.particle_cells[starts[k]:starts[k + 1]])
        return out

    def stimulus(self, s: float) -> tuple[float, float]:
        """(mu [k_B T], T [K]) at load parameter s."""
        return self.path(s)

    def materials_at(self, s: float) -> dict[str, Material]:
        """Material of every block by name (MEMBRANE, STRAIN_LIMIT_LAYER, PARTICLES) at load
        parameter s (the gel at the stimulus of s; with chambers each chamber's gel at its own
        stimulus of s, and no STRAIN_LIMIT_LAYER where the design has none)."""
        if self.chamber_gels:  # each chamber's gel at its own stimulus; a design may have no strain-limit layer
            out = {MEMBRANE: self.membrane}
            if STRAIN_LIMIT_LAYER in self.solid.block_names:
                out[STRAIN_LIMIT_LAYER] = self.strain_limit
            for k, (gel, path) in enumerate(zip(self.chamber_gels, self.chamber_paths)):
                out[particle_block(k)] = gel.at(*path(s))
            return out
        mu, T = self.path(s)
        return {MEMBRANE: self.membrane, STRAIN_LIMIT_LAYER: self.strain_limit, PARTICLES: self.gel.at(mu, T)}

    def problem(self, extra_terms: tuple = ()) -> Problem:
        """The load-path problem, clamped top: the terms "elastic" (the solid at the stimulus of
        s), "contact" and, on a timed path only, "volume" (:meth:`kinetic_volume_term`: each
        particle's water content within a time step), plus ``extra_terms`` (e.g.
        "stabilisation"), in that order. Every call makes a fresh "volume" term and a fresh
        "contact" term (:meth:`~hydrojam.fem.contact.Contact.fresh`: no friction lag from an
        earlier run on this model)."""
        solid, contact = self.solid, self.contact.fresh()
        volume = self.kinetic_volume_term() if self.path.timed else None

        def terms(s: float):
            if volume is None:
                return [solid.with_materials(self.materials_at(s)), contact, *extra_terms]
            volume.controller.set_time(self.path.time(s))
            return [solid.with_materials(self.materials_at(s)), contact, volume, *extra_terms]

        G = self.membrane.shear_modulus_ref
        dim = self.mesh.dim
        bcs = [fixed(self.clamp_nodes, dim)]
        if self.symmetry_nodes is not None:
            bcs.append(fixed(np.setdiff1d(self.symmetry_nodes, self.clamp_nodes), dim, [1]))
        return Problem(self.mesh.points, terms, bcs, force_scale=G * self.design.particle_diameter ** (dim - 1))

    def kinetic_volume_term(self) -> LocalVolumeTerm:
        """On a timed path: the term "volume" holding the particles' water content (their volume,
        the constituents being incompressible) within a load step, point by point, near what the
        kinetics allow (:class:`~hydrojam.actuator.stimulus.KineticVolumes`, docs/kinetics.md)."""
        if not self.path.timed:
            raise ValueError("the kinetic volume term needs a time-resolved stimulus (stimulus.schedule)")
        cells = self.mesh.cells[np.concatenate(self.particle_cells)]
        el = element_for_meshio_type(self.mesh.cell_type)
        modulus = kinetic_modulus(self.design.hydrogel, self.path, self.design.dimension)
        return LocalVolumeTerm(self.mesh.points, cells, el, KineticVolumes(self.path, modulus))


def centreline_x(design: Design) -> float:
    """x [mm] of the strain-limit layer's mid-line (mid-surface in 3D), the centreline of the
    metrics; it runs from the clamp at z = 0 to the free end at z = -length. With a helical strip
    (which leaves the plane y = 0): the membrane's -x face, x = -cavity_width/2 - t0."""
    design = design.resolved()
    if design.chambers is not None:  # the shared wall's mid-line
        return 0.0
    if design.helix_angle_deg != 0.0:
        return -design.resolved_cavity_width / 2 - design.side_wall_thickness
    return -design.resolved_cavity_width / 2 - design.side_wall_thickness - design.strain_limit_thickness / 2


def _wall_bands(mesh: Mesh, design: Design, components: np.ndarray) -> np.ndarray:
    """Self-contact regions: the walls' nodes by band along the axis
    (:data:`SELF_CONTACT_BAND_PER_WIDTH`), every particle one region (0)."""
    band = SELF_CONTACT_BAND_PER_WIDTH * design.width
    bands = np.floor(-mesh.points[:, -1] / band).astype(np.int64)
    return np.where(components == WALL_COMPONENT, bands, 0)


def outer_faces(mesh: Mesh) -> np.ndarray:
    """The walls' outer surface, outward (nf, nfn): the membrane's and the strain-limit layer's
    boundary facets but the cavity's, the clamped face and the cut faces on a symmetry plane."""
    walls = np.concatenate([mesh.cell_groups[MEMBRANE], mesh.cell_groups.get(STRAIN_LIMIT_LAYER, [])])
    facets = mesh.boundary_facets(walls.astype(np.int64))
    corners = mesh.dim

    def keys(f):
        return {tuple(k) for k in np.sort(np.asarray(f)[:, :corners], axis=1)}

    skip = keys(mesh.facet_groups["cavity"]) | keys(mesh.facet_groups["clamp"])
    if "symmetry" in mesh.facet_groups:
        skip |= keys(mesh.facet_groups["symmetry"])
    keep = [tuple(k) not in skip for k in np.sort(facets[:, :corners], axis=1)]
    return facets[np.asarray(keep, dtype=bool)]


def _centreline(mesh: Mesh, design: Design) -> np.ndarray:
    x_mid = centreline_x(design)
    if design.chambers is not None or design.helix_angle_deg != 0.0:  # through the end walls / the membrane
        nodes = np.unique(mesh.cells[np.concatenate([mesh.cell_groups[g] for g in (MEMBRANE, STRAIN_LIMIT_LAYER)
                                                     if g in mesh.cell_groups])])
    else:
        nodes = np.unique(mesh.cells[mesh.cell_groups[STRAIN_LIMIT_LAYER]])
    tol = 1e-6 * design.length
    on = nodes[np.abs(mesh.points[nodes, 0] - x_mid) < tol]
    if mesh.dim == 3:  # the mid-surface's line on the plane y = 0
        on = on[np.abs(mesh.points[on, 1]) < tol]
    return on[np.argsort(-mesh.points[on, -1])]


def build_model(design: Design) -> ActuatorModel:
    """Mesh the design and set up bodies, materials, clamp, contact and the stimulus path.

    Parameters
    ----------
    design : Design
        The design (lengths [mm]).

    Returns
    -------
    ActuatorModel
    """
    design = design.resolved()
    check_supported(design)
    mesh = jitter_particles(mesh_design(design), design)
    el = element_for_meshio_type(mesh.cell_type)
    gel = Hydrogel(design.hydrogel)
    membrane = design.membrane.material()
    strain_limit = design.strain_limit_layer.material()
    chambers = design.resolved_chambers
    if chambers is None:
        counts, chamber_gels = [design.particle_layers * design.particles_per_layer], ()
        gels = [gel]
    else:
        counts = [ch.particle_layers * ch.particles_per_layer for ch in chambers]
        chamber_gels = tuple(Hydrogel(ch.hydrogel) for ch in chambers)
        gels = list(chamber_gels)
    n_p = sum(counts)
    particle_cells = [mesh.cell_groups[f"particle{k}"] for k in range(n_p)]
    starts = np.concatenate([[0], np.cumsum(counts)])
    blocks = [Block(mesh.cells[mesh.cell_groups[MEMBRANE]], el, membrane, MEMBRANE)]
    if STRAIN_LIMIT_LAYER in mesh.cell_groups:
        blocks.append(Block(mesh.cells[mesh.cell_groups[STRAIN_LIMIT_LAYER]], el, strain_limit, STRAIN_LIMIT_LAYER))
    blocks += [Block(mesh.cells[np.concatenate(particle_cells[starts[k]:starts[k + 1]])], el, g, particle_block(k))
               for k, g in enumerate(gels)]
    solid = Solid(mesh.points, blocks)
    components = np.full(mesh.n_nodes, WALL_COMPONENT)
    body_id = np.full(mesh.n_cells, MEMBRANE_BODY)
    body_id[mesh.cell_groups.get(STRAIN_LIMIT_LAYER, [])] = STRAIN_LIMIT_BODY
    for k, cells in enumerate(particle_cells):
        components[np.unique(mesh.cells[cells])] = k
        body_id[cells] = PARTICLE_BODY + k
    facets = mesh.boundary_facets()
    symmetry_nodes, ccd = None, {}
    if design.dimension == 3:
        # the collision mesh: the cavity's wall, the particles' surfaces and the walls' outer
        # faces, which a long chamber curling past a full turn meets with itself; not the cut
        # faces on y = 0 of a half model (no surfaces of the actuator) nor the clamped face
        facets = np.concatenate([mesh.facet_groups["cavity"]]
                                + [mesh.facet_groups[f"particle{k}_boundary"] for k in range(n_p)]
                                + [outer_faces(mesh)])
        if design.mesh.symmetry:
            symmetry_nodes = mesh.group_nodes("symmetry")
        ccd = CCD_3D
    # dhat: as wide as the clearance allows (the barrier must start inactive, so that the
    # as-prepared state is stress-free): a soft membrane's Newton steps move it by tenths of a mm,
    # far beyond a thin barrier, which then acts only after CCD has cut the step. kappa: the
    # membrane's shear modulus, since every contact pressure in the chamber is held by the
    # membrane's confinement; a stiffer barrier only makes Newton's work harder. The measurements
    # behind both: docs/actuator.md, "Model" and "Choices".
    kappa = KAPPA_PER_MEMBRANE_MODULUS * membrane.shear_modulus_ref
    settings = default_settings(mesh.points, facets, membrane.shear_modulus_ref,
                                dhat=DHAT_PER_CLEARANCE * design.clearance, kappa=kappa, friction=design.friction,
                                friction_eps=design.friction_slip,
                                **ccd)
    contact = Contact(mesh.points, facets, components, settings, regions=_wall_bands(mesh, design, components))
    segments = straight_pieces(mesh.facet_groups["cavity"], mesh.dim - 1)
    centreline = _centreline(mesh, design)
    # the particles' as-prepared total: in 2D the circles' area, in 3D the meshed volume (of their
    # halves in a half model), measured once the gauges can measure it
    circles = n_p * np.pi * design.particle_diameter**2 / 4
    if chambers is None:
        block_names, layer_sizes, diameter = PARTICLES, (), design.particle_diameter
    else:
        circles = sum(n * np.pi * ch.particle_diameter**2 / 4 for n, ch in zip(counts, chambers))
        block_names = tuple(particle_block(k) for k in range(len(chambers)))
        layer_sizes = tuple((ch.particle_layers, ch.particles_per_layer) for ch in chambers)
        diameter = min(ch.particle_diameter for ch in chambers)
    gauges = Gauges(mesh.points, mesh.group_nodes("free_end"), centreline, segments, tuple(range(n_p)), circles,
                    solid, block_names, np.cumsum([len(c) for c in particle_cells])[:-1], contact,
                    tuple(np.unique(mesh.cells[cells]) for cells in particle_cells), design.particles_per_layer,
                    diameter, chamber_layers=layer_sizes, mirror_y=bool(design.dimension == 3 and design.mesh.symmetry),
                    round_axis=design.round_axis)
    if design.dimension == 3:
        gauges = replace(gauges, reference_volume=float(particle_volumes(gauges, mesh.points).sum()))
    if design.stimulus.schedule is not None:  # time-resolved: the particles' kinetics set the path
        path = timed_stimulus_path(design.hydrogel, design.stimulus.mu, design.stimulus.schedule,
                                   design.particle_diameter, design.hydrogel.diffusivity, dimension=design.dimension)
    else:
        path = stimulus_path(design.hydrogel, design.stimulus.mu, design.stimulus.temperature,
                             design.stimulus.path, dimension=design.dimension)
    chamber_paths = () if chambers is None else tuple(
        stimulus_path(ch.hydrogel, design.stimulus.mu, ch.temperature, design.stimulus.path, dimension=design.dimension)
        for ch in chambers)
    return ActuatorModel(
        design=design, mesh=mesh, solid=solid, contact=contact, path=path, membrane=membrane,
        strain_limit=strain_limit, gel=gel, clamp_nodes=mesh.group_nodes("clamp"),
        free_end_nodes=gauges.free_end_nodes, centreline_nodes=centreline,
        particle_cells=particle_cells, cavity_segments=segments, body_id=body_id, components=components,
        gauges=gauges, symmetry_nodes=symmetry_nodes, chamber_gels=chamber_gels, chamber_paths=chamber_paths,
    )


# ------------------------------------------------------------------------------------------------
# Measurements on a state: the metrics read them through the model's gauges, in one pass


def particle_areas(model: ActuatorModel, x: np.ndarray) -> np.ndarray:
    """Current area (2D) [mm^2] or volume (3D) [mm^3] of each particle (n_particles,), integrated
    det F over the reference (the half of each particle in a 3D half model):
    :func:`~hydrojam.actuator.metrics.particle_volumes` of the model's gauges."""
    return particle_volumes(model.gauges, x)


def measure(model: ActuatorModel, x: np.ndarray) -> dict:
    """The metrics (docs/actuator.md, "Metrics") at the nodes' positions ``x`` (n, d) [mm], as metric name
    -> value: :func:`hydrojam.actuator.metrics.measure` of the model's gauges, where they are
    defined (:data:`~hydrojam.actuator.metrics.STATE_METRICS`, in that order).

    Parameters
    ----------
    model : ActuatorModel
        The actuator (its mesh, gauges and design).
    x : ndarray, shape (n, d)
        The nodes' positions [mm] (the reference positions: the as-prepared state).

    Returns
    -------
    dict
        Metric name -> value in the metric's unit (the bending angle [deg], the tip's
        displacement [mm], ...; :func:`hydrojam.actuator.metrics.metric_names`); None where a
        metric is undefined at x, never NaN.

    Raises
    ------
    IndexError
        Where x has fewer nodes than the model's mesh (NumPy's indexing; x is not checked
        otherwise).
    """
    return measure_state(model.gauges, x)
