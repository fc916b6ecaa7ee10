"""The actuator's geometry (DESIGN.md section 6): the chamber, walls, strain-limit layer and
particles drawn with gmsh through :mod:`hydrojam.fem.meshing`, and meshed. Lengths in mm."""

from __future__ import annotations

from dataclasses import replace

import gmsh
import numpy as np

from hydrojam.actuator.design import Design
from hydrojam.fem.mesh import Mesh
from hydrojam.fem.meshing import add_groups, bounding_box, generate, gmsh_session, set_mesh_size


def actuator_2d(cavity_width: float, cavity_length: float, side_wall: float, end_wall: float,
                strain_limit: float, centres, radius: float, size: float, order: int = 2) -> Mesh:
    """Plane-strain actuator (DESIGN.md section 6), x-z plane, lengths in mm.

    Membrane: the rectangle [-w/2 - t0, w/2 + t0] x [-L, 0] (L = cavity_length + 2 t1) minus the
    cavity [-w/2, w/2] x [-t1 - cavity_length, -t1]; strain-limit layer [-w/2 - t0 - h, -w/2 - t0]
    x [-L, 0], bonded to the membrane (shared nodes) and split at its mid-line so that the
    mid-line is a line of nodes (the centreline of the metrics); particles: separate disks of
    ``radius`` about ``centres`` (no shared nodes).

    Cell groups "membrane", "strain_limit_layer", "particle0", ...; facet groups "clamp"
    (z = 0), "free_end" (z = -L), "cavity" (the cavity's wall) and "particle<k>_boundary".
    """
    w, t0, t1, h = float(cavity_width), float(side_wall), float(end_wall), float(strain_limit)
    length = float(cavity_length) + 2 * t1
    x_out = w / 2 + t0
    centres = np.atleast_2d(np.asarray(centres, dtype=float))
    tol = 1e-6 * length
    with gmsh_session():
        set_mesh_size(size)
        occ = gmsh.model.occ
        outer = occ.addRectangle(-x_out, -length, 0.0, 2 * x_out, length)
        cavity = occ.addRectangle(-w / 2, -t1 - cavity_length, 0.0, w, cavity_length)
        (membrane, _) = occ.cut([(2, outer)], [(2, cavity)])
        halves = [occ.addRectangle(-x_out - h, -length, 0.0, h / 2, length),
                  occ.addRectangle(-x_out - h / 2, -length, 0.0, h / 2, length)]
        (frag, _) = occ.fragment(membrane, [(2, t) for t in halves])
        particles = [occ.addDisk(c[0], c[1], 0.0, radius, radius) for c in centres]
        occ.synchronize()
        body = [t for d, t in frag if d == 2]
        sll = [t for t in body if bounding_box(2, t)[1, 0] <= -x_out + tol]
        mem = [t for t in body if t not in sll]
        walls = gmsh.model.getBoundary([(2, t) for t in body], combined=True, oriented=False)
        clamp, free_end, cavity_curves = [], [], []
        for _, c in walls:
            bb = bounding_box(1, c)
            if abs(bb[0, 1]) < tol and abs(bb[1, 1]) < tol:
                clamp.append(c)
            elif abs(bb[0, 1] + length) < tol and abs(bb[1, 1] + length) < tol:
                free_end.append(c)
            elif bb[0, 0] >= -w / 2 - tol and bb[1, 0] <= w / 2 + tol and bb[0, 1] >= -length + t1 - tol \
                    and bb[1, 1] <= -t1 + tol:
                cavity_curves.append(c)
        cells = {"membrane": mem, "strain_limit_layer": sll}
        facets = {"clamp": clamp, "free_end": free_end, "cavity": cavity_curves}
        for k, p in enumerate(particles):
            cells[f"particle{k}"] = [p]
            facets[f"particle{k}_boundary"] = [t for _, t in gmsh.model.getBoundary([(2, p)], oriented=False)]
        add_groups(2, cells, facets)
        return generate(2, order)


def particle_centres(design: Design) -> np.ndarray:
    """As-prepared particle centres (n, 2) [mm], layer by layer from the clamp, evenly spaced in
    the cavity (the clearance as the gap when the cavity is derived from the particles)."""
    d = design.particle_diameter
    m, pl = design.particles_per_layer, design.particle_layers
    w, lc = design.resolved_cavity_width, design.resolved_cavity_length
    gx = (w - m * d) / (m + 1)
    gz = (lc - pl * d) / (pl + 1)
    xs = -w / 2 + gx + d / 2 + np.arange(m) * (d + gx)
    zs = -design.end_wall_thickness - gz - d / 2 - np.arange(pl) * (d + gz)
    return np.array([(x, z) for z in zs for x in xs])


def mesh_design(design: Design) -> Mesh:
    """The quadratic-triangle mesh of a 2D design (groups as in :func:`actuator_2d`)."""
    return actuator_2d(
        design.resolved_cavity_width, design.resolved_cavity_length, design.side_wall_thickness,
        design.end_wall_thickness, design.strain_limit_thickness, particle_centres(design),
        design.particle_diameter / 2, design.mesh.size, order=2,
    )


def replica_offsets(design: Design) -> np.ndarray:
    """The rigid offset of every particle centre of the design's replica (n_particles, dim) [mm].

    Replica index 0 (``design.replicas.index``): zeros, the design as drawn. Replica k > 0: each
    offset is uniform in a disk (2D; a ball in 3D) of radius ``replicas.jitter`` x clearance,
    drawn particle by particle (the order of :func:`particle_centres`) from PCG64 seeded with
    the SeedSequence of (seed, k) and read as 53-bit uniform numbers, so a replica is the same on
    every machine and NumPy version. Neighbours then keep a gap of at least (1 - 2 jitter) c.
    """
    centres = particle_centres(design)
    n, dim = centres.shape
    spec = design.replicas
    if spec.index == 0:
        return np.zeros((n, dim))
    stream = np.random.PCG64(np.random.SeedSequence([spec.seed, spec.index]))
    u = (stream.random_raw(n * dim) >> np.uint64(11)).astype(np.float64).reshape(n, dim) * 2.0**-53
    radius = spec.jitter * design.clearance
    if dim == 2:
        phi, r = 2.0 * np.pi * u[:, 0], radius * np.sqrt(u[:, 1])
        return np.column_stack([r * np.cos(phi), r * np.sin(phi)])
    cos_t, phi, r = 1.0 - 2.0 * u[:, 0], 2.0 * np.pi * u[:, 1], radius * np.cbrt(u[:, 2])
    sin_t = np.sqrt(np.maximum(1.0 - cos_t**2, 0.0))
    return r[:, None] * np.column_stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t])


def jitter_particles(mesh: Mesh, design: Design) -> Mesh:
    """The mesh of the design as drawn with every particle (cell group ``particle<k>``) moved
    rigidly by its :func:`replica_offsets`: each particle keeps its own mesh, so replicas differ
    only in where the particles start. Replica 0: the mesh itself."""
    offsets = replica_offsets(design)
    if not offsets.any():
        return mesh
    points = np.array(mesh.points)
    for k, offset in enumerate(offsets):
        points[np.unique(mesh.cells[mesh.cell_groups[f"particle{k}"]])] += offset
    return replace(mesh, points=points)
