"""The actuator's geometry (docs/actuator.md, "Geometry and mesh"): the chamber, walls, strain-limit layer and
particles drawn with gmsh through :mod:`hydrojam.fem.meshing`, and meshed. Lengths in mm."""

from __future__ import annotations

import math
from dataclasses import replace

import gmsh
import numpy as np

from hydrojam.actuator.design import ROUND_AXIS_CHAMBERS, Design
from hydrojam.fem.mesh import Mesh
from hydrojam.fem.meshing import add_groups, bounding_box, generate, gmsh_session, set_mesh_size

#: the cell groups of the membrane and of the strain-limit layer (also the names of their blocks
#: in the model's solid)
MEMBRANE, STRAIN_LIMIT_LAYER = "membrane", "strain_limit_layer"


def actuator_2d(cavity_width: float, cavity_length: float, side_wall: float, end_wall: float,
                strain_limit: float, centres, radius: float, size: float, order: int = 2) -> Mesh:
    """Plane-strain actuator (docs/actuator.md, "Geometry and mesh"), x-z plane, lengths in mm.

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
        cells = {MEMBRANE: mem, STRAIN_LIMIT_LAYER: sll}
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


def chamber_layout(design: Design) -> list[tuple[float, float]]:
    """The cavities of a multi-chamber design along x, as (x_min, x_max) [mm], chamber by chamber
    from -x: side by side, the shared wall's mid-line on x = 0 (2D, two chambers)."""
    half = design.resolved_chamber_wall / 2
    (w0, w1) = (ch.cavity_width for ch in design.resolved_chambers)
    return [(-half - w0, -half), (half, half + w1)]


def chamber_particles(design: Design) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Particle centres (n, 2) [mm] and radii (n,) [mm] of a multi-chamber design, chamber by
    chamber (the first on -x) and within it layer by layer from the clamp as in
    :func:`particle_centres`; and how many particles each chamber holds."""
    lc, t1 = design.resolved_cavity_length, design.end_wall_thickness
    centres, radii, counts = [], [], []
    for ch, (x0, x1) in zip(design.resolved_chambers, chamber_layout(design)):
        d, m, pl = ch.particle_diameter, ch.particles_per_layer, ch.particle_layers
        gx = (x1 - x0 - m * d) / (m + 1)
        gz = (lc - pl * d) / (pl + 1)
        xs = x0 + gx + d / 2 + np.arange(m) * (d + gx)
        zs = -t1 - gz - d / 2 - np.arange(pl) * (d + gz)
        centres += [(x, z) for z in zs for x in xs]
        radii += [d / 2] * (m * pl)
        counts.append(m * pl)
    return np.array(centres), np.array(radii), counts


def actuator_2d_chambers(design: Design, order: int = 2) -> Mesh:
    """Plane-strain actuator of two chambers side by side along x (docs/chambers.md), lengths in mm.

    Cavities as :func:`chamber_layout` (z in [-t1 - cavity_length, -t1]); the membrane round them,
    side walls t0 outside, the shared wall between them; the strain-limit layer (thickness h)
    bonded on the -x or +x outer face over the full length, or the shared wall itself made of
    the strain-limit elastomer (``strain_limit_position`` "middle"), or none. The shared wall is
    split on x = 0, a line of nodes from the clamp to the free end (the metrics' centreline), and
    an outer layer at its mid-line as in :func:`actuator_2d`. Particles: separate disks.

    Cell groups "membrane", "strain_limit_layer" (absent with "none"), "particle0", ... (chamber
    by chamber); facet groups "clamp", "free_end", "cavity" (both cavities' walls) and
    "particle<k>_boundary".
    """
    lc, t0, t1, h = design.resolved_cavity_length, design.side_wall_thickness, design.end_wall_thickness, \
        design.strain_limit_thickness
    half = design.resolved_chamber_wall / 2
    length = lc + 2 * t1
    (a0, a1), (b0, b1) = chamber_layout(design)
    xl, xr = a0 - t0, b1 + t0
    where = design.resolved_strain_limit_position
    centres, radii, _ = chamber_particles(design)
    tol = 1e-6 * length
    with gmsh_session():
        set_mesh_size(design.mesh_size)
        occ = gmsh.model.occ
        left = occ.cut([(2, occ.addRectangle(xl, -length, 0.0, -half - xl, length))],
                       [(2, occ.addRectangle(a0, -t1 - lc, 0.0, a1 - a0, lc))])[0]
        right = occ.cut([(2, occ.addRectangle(half, -length, 0.0, xr - half, length))],
                        [(2, occ.addRectangle(b0, -t1 - lc, 0.0, b1 - b0, lc))])[0]
        pieces = left + right + [(2, occ.addRectangle(-half, -length, 0.0, half, length)),
                                 (2, occ.addRectangle(0.0, -length, 0.0, half, length))]
        if where == "-x":
            pieces += [(2, occ.addRectangle(xl - h, -length, 0.0, h / 2, length)),
                       (2, occ.addRectangle(xl - h / 2, -length, 0.0, h / 2, length))]
        elif where == "+x":
            pieces += [(2, occ.addRectangle(xr, -length, 0.0, h / 2, length)),
                       (2, occ.addRectangle(xr + h / 2, -length, 0.0, h / 2, length))]
        (frag, _) = occ.fragment(pieces, [])
        particles = [occ.addDisk(c[0], c[1], 0.0, r, r) for c, r in zip(centres, radii)]
        occ.synchronize()
        body = [t for d, t in frag if d == 2]

        def is_sll(t):
            bb = bounding_box(2, t)
            if where == "-x":
                return bb[1, 0] <= xl + tol
            if where == "+x":
                return bb[0, 0] >= xr - tol
            return where == "middle" and bb[0, 0] >= -half - tol and bb[1, 0] <= half + tol

        sll = [t for t in body if is_sll(t)]
        mem = [t for t in body if t not in sll]
        walls = gmsh.model.getBoundary([(2, t) for t in body], combined=True, oriented=False)
        clamp, free_end, cavity_curves = [], [], []
        for _, c in walls:
            bb = bounding_box(1, c)
            if abs(bb[0, 1]) < tol and abs(bb[1, 1]) < tol:
                clamp.append(c)
            elif abs(bb[0, 1] + length) < tol and abs(bb[1, 1] + length) < tol:
                free_end.append(c)
            elif bb[0, 1] >= -length + t1 - tol and bb[1, 1] <= -t1 + tol and any(
                    bb[0, 0] >= x0 - tol and bb[1, 0] <= x1 + tol for x0, x1 in ((a0, a1), (b0, b1))):
                cavity_curves.append(c)
        cells = {MEMBRANE: mem}
        if sll:
            cells[STRAIN_LIMIT_LAYER] = sll
        facets = {"clamp": clamp, "free_end": free_end, "cavity": cavity_curves}
        for k, p in enumerate(particles):
            cells[f"particle{k}"] = [p]
            facets[f"particle{k}_boundary"] = [t for _, t in gmsh.model.getBoundary([(2, p)], oriented=False)]
        add_groups(2, cells, facets)
        return generate(2, order)


def _group_3d(body: list[int], sll: list[int], particles: list, cavities: list[tuple[float, float]], D: float,
              lc: float, t1: float, length: float, tol: float, symmetry: bool, order: int) -> Mesh:
    """The cell and facet groups of a synchronised 3D actuator (the walls' volumes ``body``, of
    which ``sll`` the strain-limit layer's; ``particles`` each particle's gmsh dim-tags), then its
    mesh: cells membrane, strain_limit_layer (where ``sll``), particle<k>; facets clamp (z = 0),
    free_end (z = -``length``), cavity (the wall faces inside a cavity: x within one of
    ``cavities``' ranges, |y| <= D/2, z in [-t1 - lc, -t1]), particle<k>_boundary, and symmetry
    (the cut faces on y = 0, half model) or mid_plane (the interior faces on y = 0, whole model).
    Lengths in mm; ``tol`` the geometric tolerance of the face tests."""
    mem = [t for t in body if t not in sll]
    particle_tags = [[t for d, t in part if d == 3] for part in particles]

    def faces_of(volumes, combined=True):
        return [t for _, t in gmsh.model.getBoundary([(3, v) for v in volumes], combined=combined, oriented=False)]

    def on_plane(t, axis, value):
        bb = bounding_box(2, t)
        return abs(bb[0, axis] - value) < tol and abs(bb[1, axis] - value) < tol

    wall_faces = faces_of(body)
    clamp = [t for t in wall_faces if on_plane(t, 2, 0.0)]
    free_end = [t for t in wall_faces if on_plane(t, 2, -length)]
    cut = [t for t in wall_faces if on_plane(t, 1, 0.0)]
    cavity_faces = []
    for t in wall_faces:
        bb = bounding_box(2, t)
        if t not in cut and bb[0, 1] >= -D / 2 - tol and bb[1, 1] <= D / 2 + tol \
                and bb[0, 2] >= -t1 - lc - tol and bb[1, 2] <= -t1 + tol \
                and any(bb[0, 0] >= x0 - tol and bb[1, 0] <= x1 + tol for x0, x1 in cavities):
            cavity_faces.append(t)
    cells = {MEMBRANE: mem}
    if sll:
        cells[STRAIN_LIMIT_LAYER] = sll
    facets = {"clamp": clamp, "free_end": free_end, "cavity": cavity_faces}
    plane_faces = list(cut)
    for k, tags in enumerate(particle_tags):
        cells[f"particle{k}"] = tags
        surface = faces_of(tags)
        flat = [t for t in surface if on_plane(t, 1, 0.0)]
        facets[f"particle{k}_boundary"] = [t for t in surface if t not in flat]
        plane_faces += flat
    if symmetry:
        facets["symmetry"] = plane_faces
    else:  # interior faces on y = 0: shared by the two halves of a body
        inner = set(faces_of(body, combined=False)) - set(wall_faces)
        plane_faces = [t for t in inner if on_plane(t, 1, 0.0)]
        for tags in particle_tags:
            plane_faces += [t for t in set(faces_of(tags, combined=False)) - set(faces_of(tags))
                            if on_plane(t, 1, 0.0)]
        facets["mid_plane"] = plane_faces
    add_groups(3, cells, facets)
    return generate(3, order)


def actuator_3d_chambers(design: Design, order: int = 2) -> Mesh:
    """The two-chamber actuator of :func:`actuator_2d_chambers` in 3D, quadratic tetrahedra, lengths
    in mm: every body extruded over the depth (cavities D = ``resolved_cavity_depth``, walls
    D + 2 t0), particles spheres on y = 0; the half y >= 0 with ``mesh.symmetry`` (half spheres,
    the cut faces on y = 0), else the whole actuator drawn as two halves glued on y = 0.

    Cell and facet groups as :func:`actuator_3d`'s ("strain_limit_layer" absent with
    ``strain_limit_position`` "none"); the shared wall is split on x = 0, so that its mid-surface's
    line on y = 0 is a line of nodes (the metrics' centreline).
    """
    lc, t0, t1, h = design.resolved_cavity_length, design.side_wall_thickness, design.end_wall_thickness, \
        design.strain_limit_thickness
    D = design.resolved_cavity_depth
    half = design.resolved_chamber_wall / 2
    length = lc + 2 * t1
    (a0, a1), (b0, b1) = chamber_layout(design)
    xl, xr, y_out = a0 - t0, b1 + t0, D / 2 + t0
    where = design.resolved_strain_limit_position
    centres, radii, _ = chamber_particles(design)
    symmetry = design.mesh.symmetry
    tol = 0.05 * min(t0, t1, h, 2 * half)
    with gmsh_session():
        set_mesh_size(design.mesh_size)
        occ = gmsh.model.occ

        def box(x0, x1):
            return (3, occ.addBox(x0, 0.0, -length, x1 - x0, y_out, length))

        left = occ.cut([box(xl, -half)], [(3, occ.addBox(a0, 0.0, -t1 - lc, a1 - a0, D / 2, lc))])[0]
        right = occ.cut([box(half, xr)], [(3, occ.addBox(b0, 0.0, -t1 - lc, b1 - b0, D / 2, lc))])[0]
        walls = left + right + [box(-half, 0.0), box(0.0, half)]
        if where == "-x":
            walls += [box(xl - h, xl - h / 2), box(xl - h / 2, xl)]
        elif where == "+x":
            walls += [box(xr, xr + h / 2), box(xr + h / 2, xr + h)]
        particles = []
        for (cx, cz), r in zip(centres, radii):
            ball = occ.addSphere(cx, 0.0, cz, r)
            cut = occ.addBox(cx - 2 * r, 0.0, cz - 2 * r, 4 * r, 2 * r, 4 * r)
            (part, _) = occ.intersect([(3, ball)], [(3, cut)])
            particles.append(part)
        if not symmetry:
            mirrored = occ.copy(walls)
            occ.mirror(mirrored, 0.0, 1.0, 0.0, 0.0)
            walls = walls + mirrored
            for k, part in enumerate(particles):
                other = occ.copy(part)
                occ.mirror(other, 0.0, 1.0, 0.0, 0.0)
                (glued, _) = occ.fragment(part, other)
                particles[k] = glued
        (frag, _) = occ.fragment(walls, [])
        occ.synchronize()
        body = [t for d, t in frag if d == 3]

        def is_sll(t):
            bb = bounding_box(3, t)
            if where == "-x":
                return bb[1, 0] <= xl + tol
            if where == "+x":
                return bb[0, 0] >= xr - tol
            return where == "middle" and bb[0, 0] >= -half - tol and bb[1, 0] <= half + tol

        sll = [t for t in body if is_sll(t)]
        return _group_3d(body, sll, particles, [(a0, a1), (b0, b1)], D, lc, t1, length, tol, symmetry, order)


def chamber_angles_deg(design: Design) -> list[float]:
    """Three chambers round the axis: the direction in x-y of each cavity's axis from the
    actuator's, from +x toward +y [deg]: 0, 120, 240, chamber by chamber."""
    return [360.0 * k / ROUND_AXIS_CHAMBERS for k in range(ROUND_AXIS_CHAMBERS)]


def round_axis_particles(design: Design) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Three chambers round the axis: particle centres (n, 3) [mm] and radii (n,) [mm], chamber by
    chamber (:func:`chamber_angles_deg`) and within it layer by layer from the clamp, each
    column on its cavity's axis, evenly spaced along it; and how many particles each chamber holds."""
    lc, t1, r_c = design.resolved_cavity_length, design.end_wall_thickness, design.chamber_radius
    centres, radii, counts = [], [], []
    for ch, phi in zip(design.resolved_chambers, np.radians(chamber_angles_deg(design))):
        d, pl = ch.particle_diameter, ch.particle_layers
        gz = (lc - pl * d) / (pl + 1)
        zs = -t1 - gz - d / 2 - np.arange(pl) * (d + gz)
        centres += [(r_c * np.cos(phi), r_c * np.sin(phi), z) for z in zs]
        radii += [d / 2] * pl
        counts.append(pl)
    return np.array(centres), np.array(radii), counts


def actuator_3d_round(design: Design, order: int = 2) -> Mesh:
    """Three chambers round the axis z (docs/chambers.md), the whole actuator, quadratic
    tetrahedra, lengths in mm.

    The body is the cylinder r <= R (:attr:`Design.outer_radius`), z in [-L, 0]; chamber k's
    cavity the cylinder of diameter D (:attr:`Design.round_cavity_diameter`: ``resolved_cavity_depth``
    widened so that the contact's straight pieces of its faces keep the clearance) about the line at r_c
    (:attr:`Design.chamber_radius`) in the direction 120 k deg from +x toward +y
    (:func:`chamber_angles_deg`), z in [-t1 - cavity_length, -t1]; with ``strain_limit_position``
    "core", the rod r <= h/2 of the strain-limit elastomer, bonded to the membrane; its particles
    spheres on the cavity's axis (:func:`round_axis_particles`).

    Only the sixth 0 <= angle <= 60 deg is drawn and meshed (gmsh); it is mirrored about y = 0
    and the sector so made turned by 120 and 240 deg, nodes on the planes between the copies
    merged (:func:`turned_copies`). The mesh thus has the design's symmetry - three turns and
    three mirror planes - node for node, the planes between chambers and through them are
    surfaces of nodes, and the axis (the metrics' centreline) a line of nodes.

    Cell groups "membrane", "strain_limit_layer" (with a core), "particle<k>" (chamber by chamber,
    layer by layer); facet groups "clamp", "free_end", "cavity", "particle<k>_boundary".
    """
    lc, t0, t1, h = design.resolved_cavity_length, design.side_wall_thickness, design.end_wall_thickness, \
        design.strain_limit_thickness
    D, r_c, R = design.round_cavity_diameter, design.chamber_radius, design.outer_radius
    length = lc + 2 * t1
    core = design.resolved_strain_limit_position == "core"
    centres, radii, counts = round_axis_particles(design)
    wedge = math.pi / ROUND_AXIS_CHAMBERS  # half a sector
    tol = 0.05 * min(t0, t1, design.resolved_chamber_wall, h if core else t0)
    with gmsh_session():
        set_mesh_size(design.mesh_size)
        occ = gmsh.model.occ
        outer = occ.addCylinder(0.0, 0.0, -length, 0.0, 0.0, length, R, angle=wedge)
        cavity = occ.addCylinder(r_c, 0.0, -t1 - lc, 0.0, 0.0, lc, D / 2, angle=math.pi)  # its half y >= 0
        walls = occ.cut([(3, outer)], [(3, cavity)])[0]
        if core:
            walls = walls + [(3, occ.addCylinder(0.0, 0.0, -length, 0.0, 0.0, length, h / 2, angle=wedge))]
        particles = []
        for (cx, cy, cz), r in zip(centres[:counts[0]], radii[:counts[0]]):
            ball = occ.addSphere(cx, cy, cz, r)
            cut = occ.addBox(cx - 2 * r, 0.0, cz - 2 * r, 4 * r, 2 * r, 4 * r)
            particles.append(occ.intersect([(3, ball)], [(3, cut)])[0])
        frag = occ.fragment(walls, [])[0] if len(walls) > 1 else walls  # OCC fragments nothing alone
        occ.synchronize()
        body = [t for d, t in frag if d == 3]
        sll = [t for t in body if core and np.abs(bounding_box(3, t)[1, :2]).max() <= h / 2 + tol]
        sixth = _group_3d(body, sll, particles, [(r_c - D / 2, r_c + D / 2)], D, lc, t1, length, tol, True, order)
    return turned_copies(sixth, ROUND_AXIS_CHAMBERS, counts[0], 1e-6 * length)


def turned_copies(part: Mesh, turns: int, n_particles: int, tol: float) -> Mesh:
    """The mesh made of the part ``part`` of a body with ``turns``-fold symmetry about z: the part
    lying in 0 <= angle <= 180/turns deg, its mirror image about y = 0, and both turned by 360 k /
    turns deg, k = 1 .. turns - 1; nodes closer than ``tol`` [mm] merged (those on the planes
    between copies). Cells keep their groups; "particle<j>" (j < ``n_particles``) of the k-th turn
    becomes "particle<k n_particles + j>" (the part's and its mirror's halves one particle), and
    so do "particle<j>_boundary"; the facet group "symmetry" (the part's cut faces, inside the
    whole) is dropped."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    P, C = np.asarray(part.points), np.asarray(part.cells)
    n, m = len(P), len(C)
    copies = []
    for k in range(turns):
        a = 2.0 * math.pi * k / turns
        rot = np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]])
        copies += [P @ rot.T, (P * np.array([1.0, -1.0, 1.0])) @ rot.T]
    points = np.vstack(copies)
    pairs = cKDTree(points).query_pairs(tol, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(points),) * 2)
    _, label = connected_components(graph, directed=False)
    _, first = np.unique(label, return_index=True)
    node = first[label]  # every node's representative: the first of its merged set
    cells = np.vstack([node[C + c * n] for c in range(2 * turns)])
    groups: dict[str, list] = {}
    for name, idx in part.cell_groups.items():
        for c in range(2 * turns):
            key = name
            if name.startswith("particle"):
                key = f"particle{(c // 2) * n_particles + int(name[len('particle'):])}"
            groups.setdefault(key, []).append(np.asarray(idx) + c * m)
    facets: dict[str, list] = {}
    for name, fac in part.facet_groups.items():
        if name == "symmetry":
            continue
        for c in range(2 * turns):
            key = name
            if name.startswith("particle"):
                j = int(name[len("particle"):-len("_boundary")])
                key = f"particle{(c // 2) * n_particles + j}_boundary"
            facets.setdefault(key, []).append(node[np.asarray(fac) + c * n])
    return Mesh.create(points, cells, part.cell_type, {k: np.concatenate(v) for k, v in groups.items()},
                       {k: np.vstack(v) for k, v in facets.items()}, prune=True)


def mesh_design(design: Design) -> Mesh:
    """The quadratic-triangle mesh of a 2D design (groups as in :func:`actuator_2d`); a 3D design:
    :func:`mesh_design_3d`."""
    if design.dimension == 3:
        if design.round_axis:
            return actuator_3d_round(design)
        return mesh_design_3d(design) if design.chambers is None else actuator_3d_chambers(design)
    if design.chambers is not None:
        return actuator_2d_chambers(design)
    return actuator_2d(
        design.resolved_cavity_width, design.resolved_cavity_length, design.side_wall_thickness,
        design.end_wall_thickness, design.strain_limit_thickness, particle_centres(design),
        design.particle_diameter / 2, design.mesh_size, order=2,
    )


def replica_offsets(design: Design) -> np.ndarray:
    """The rigid offset of every particle centre of the design's replica (n_particles, dimension) [mm].

    Replica index 0 (``design.replicas.index``): zeros, the design as drawn. Replica k > 0: each
    offset is uniform in a disk of radius ``replicas.jitter`` x clearance (2D, and the 3D half
    model, whose half spheres stay on the symmetry plane y = 0: the disk lies in x-z), or in a ball
    (the full 3D model), drawn particle by particle (the order of :func:`particle_centres`) from
    PCG64 seeded with the SeedSequence of (seed, k) and read as 53-bit uniform numbers, so a
    replica is the same on every machine and NumPy version. Neighbours then keep a gap of at least
    (1 - 2 jitter) c.
    """
    if design.chambers is None:
        n = len(particle_centres(design))
    else:
        n = len((round_axis_particles if design.round_axis else chamber_particles)(design)[0])
    dim = design.dimension
    spec = design.replicas
    if spec.index == 0:
        return np.zeros((n, dim))
    in_plane = dim == 2 or design.mesh.symmetry
    k = 2 if in_plane else 3
    stream = np.random.PCG64(np.random.SeedSequence([spec.seed, spec.index]))
    u = (stream.random_raw(n * k) >> np.uint64(11)).astype(np.float64).reshape(n, k) * 2.0**-53
    radius = spec.jitter * design.clearance
    if in_plane:
        phi, r = 2.0 * np.pi * u[:, 0], radius * np.sqrt(u[:, 1])
        a, b = r * np.cos(phi), r * np.sin(phi)
        return np.column_stack([a, b]) if dim == 2 else np.column_stack([a, np.zeros(n), b])
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


def actuator_3d(cavity_width: float, cavity_depth: float, cavity_length: float, side_wall: float,
                end_wall: float, strain_limit: float, centres, radius: float, size: float,
                symmetry: bool = True, order: int = 2, strain_limit_width: float | None = None,
                strain_limit_helix_deg: float = 0.0) -> Mesh:
    """The actuator in 3D (docs/actuator.md, "3D"), quadratic tetrahedra, lengths in mm.

    Cavity [-w/2, w/2] x [-D/2, D/2] x [-t1 - cavity_length, -t1] (w width, D depth); membrane:
    the box [-w/2 - t0, w/2 + t0] x [-D/2 - t0, D/2 + t0] x [-L, 0] (L = cavity_length + 2 t1)
    minus the cavity; strain-limit layer [-w/2 - t0 - h, -w/2 - t0] x [-D/2 - t0, D/2 + t0] x
    [-L, 0], bonded to the membrane (shared nodes) and split at its mid-plane x = -w/2 - t0 - h/2
    so that its mid-surface is a surface of nodes; with ``strain_limit_width`` b, a strip
    [-b/2, b/2] in y instead of the face's full width D + 2 t0; particles: separate spheres of ``radius``
    about ``centres`` ((n, 2) as (x, z), on y = 0; or (n, 3)).

    ``symmetry``: only the half y >= 0 (particles are half spheres, the cut faces lie on y = 0);
    otherwise the whole actuator, drawn as two halves glued on y = 0, so that the mid-plane
    y = 0 is a surface of nodes in every body (the centreline and the section figure).

    ``strain_limit_helix_deg`` a (nonzero; the whole actuator only, with ``strain_limit_width``
    b): the strip wound round the chamber, a helix (:func:`helix_twist_rad`). It is the part of
    the sleeve of thickness h round the membrane's outer faces swept by the half-plane band
    {x <= 0, |y| <= b / (2 cos a)} at z = 0, turned about the z axis by an angle proportional to
    -z, so that on the -x face's mid-surface (x = -w/2 - t0 - h/2) the strip's centre line runs
    at a to the axis and the strip is b wide across its own direction; a > 0 turns it toward +y
    from the clamp to the free end. The band is drawn as a loft through its sections at least
    every :data:`HELIX_SECTION_DEG` of turn. It is not split through its thickness.

    Cell groups "membrane", "strain_limit_layer", "particle0", ...; facet groups "clamp"
    (z = 0), "free_end" (z = -L), "cavity" (the cavity's wall, without cut faces),
    "particle<k>_boundary" (the sphere's surface, without cut faces) and "symmetry" (the cut
    faces on y = 0; half model) or "mid_plane" (the faces on y = 0 inside the bodies; full model).
    """
    w, D, lc = float(cavity_width), float(cavity_depth), float(cavity_length)
    t0, t1, h = float(side_wall), float(end_wall), float(strain_limit)
    length = lc + 2 * t1
    x_out, y_out = w / 2 + t0, D / 2 + t0
    y_strip = y_out if strain_limit_width is None else min(float(strain_limit_width) / 2, y_out)
    centres = np.atleast_2d(np.asarray(centres, dtype=float))
    if centres.shape[1] == 2:
        centres = np.column_stack([centres[:, 0], np.zeros(len(centres)), centres[:, 1]])
    # OCC pads bounding boxes by its tolerance, which grows to about 2e-3 mm on curved faces after
    # mirroring and gluing; distinct parallel faces lie at least min(t0, t1, h) apart
    tol = 0.05 * min(t0, t1, h)
    with gmsh_session():
        set_mesh_size(size)
        occ = gmsh.model.occ
        # the half y >= 0 of every body, then (full model) its mirror image
        outer = occ.addBox(-x_out, 0.0, -length, 2 * x_out, y_out, length)
        cavity = occ.addBox(-w / 2, 0.0, -t1 - lc, w, D / 2, lc)
        (membrane, _) = occ.cut([(3, outer)], [(3, cavity)])
        helix = float(strain_limit_helix_deg) != 0.0
        if helix and (symmetry or strain_limit_width is None):
            raise ValueError("a helical strip needs the whole actuator (symmetry False) and a strain_limit_width")
        if helix:
            walls = list(membrane)
        else:
            walls = membrane + [(3, occ.addBox(-x_out - h, 0.0, -length, h / 2, y_strip, length)),
                                (3, occ.addBox(-x_out - h / 2, 0.0, -length, h / 2, y_strip, length))]
        particles = []
        for c in centres:
            ball = occ.addSphere(c[0], c[1], c[2], radius)
            half = occ.addBox(c[0] - 2 * radius, 0.0, c[2] - 2 * radius, 4 * radius, 2 * radius, 4 * radius)
            (part, _) = occ.intersect([(3, ball)], [(3, half)])
            particles.append(part)
        if not symmetry:
            mirrored = occ.copy(walls)
            occ.mirror(mirrored, 0.0, 1.0, 0.0, 0.0)
            walls = walls + mirrored
            for k, part in enumerate(particles):
                other = occ.copy(part)
                occ.mirror(other, 0.0, 1.0, 0.0, 0.0)
                (glued, _) = occ.fragment(part, other)
                particles[k] = glued
        strip = []
        if helix:
            strip = _helical_strip(occ, x_out, y_out, h, length, float(strain_limit_width),
                                   float(strain_limit_helix_deg))
        (frag, pieces) = occ.fragment(walls + strip, [])  # bonded walls: conforming interfaces
        occ.synchronize()
        body = [t for d, t in frag if d == 3]
        if helix:
            sll = sorted({t for piece in pieces[len(walls):] for d, t in piece if d == 3})
        else:
            sll = [t for t in body if bounding_box(3, t)[1, 0] <= -x_out + tol]
        return _group_3d(body, sll, particles, [(-w / 2, w / 2)], D, lc, t1, length, tol, symmetry, order)


#: the helical strip's loft has a section at least every this many degrees of turn [deg]
HELIX_SECTION_DEG = 10.0


def helix_twist_rad(x_out: float, strain_limit: float, length: float, helix_deg: float) -> float:
    """The turn [rad] of the helical strip from the clamp to the free end, about +z: -L tan(a) / r,
    r = x_out + h/2 the -x face's mid-surface distance from the axis (lengths in mm, a in deg);
    negative for a > 0 (the strip runs toward +y on the -x face)."""
    return -float(length) * math.tan(math.radians(helix_deg)) / (float(x_out) + float(strain_limit) / 2)


def _helical_strip(occ, x_out: float, y_out: float, h: float, length: float, width: float, helix_deg: float):
    """The helical strip's volumes (dimTags) in the open OCC model: the sleeve of thickness ``h``
    round the box |x| <= x_out, |y| <= y_out (drawn as its halves y >= 0 and y <= 0, so that y = 0
    is a surface of nodes) cut by the twisted band of :func:`actuator_3d`."""
    span = width / math.cos(math.radians(helix_deg))
    turn = helix_twist_rad(x_out, h, length, helix_deg)
    reach = 2.0 * (x_out + y_out + 2.0 * h)  # beyond the sleeve's far corner
    n = max(2, math.ceil(abs(math.degrees(turn)) / HELIX_SECTION_DEG)) + 1
    wires = []
    for i in range(n):
        z, phi = -length * i / (n - 1), turn * i / (n - 1)
        c, s = math.cos(phi), math.sin(phi)
        corners = [(-reach, -span / 2), (0.0, -span / 2), (0.0, span / 2), (-reach, span / 2)]
        points = [occ.addPoint(c * x - s * y, s * x + c * y, z) for x, y in corners]
        wires.append(occ.addWire([occ.addLine(points[k], points[(k + 1) % 4]) for k in range(4)]))
    band = [v for v in occ.addThruSections(wires, makeSolid=True, makeRuled=False) if v[0] == 3]
    outer = occ.addBox(-x_out - h, 0.0, -length, 2 * (x_out + h), y_out + h, length)
    inner = occ.addBox(-x_out, 0.0, -length, 2 * x_out, y_out, length)
    (upper, _) = occ.cut([(3, outer)], [(3, inner)])
    lower = occ.copy(upper)
    occ.mirror(lower, 0.0, 1.0, 0.0, 0.0)
    (strip, _) = occ.intersect(upper + lower, band)
    return [v for v in strip if v[0] == 3]


def mesh_design_3d(design: Design) -> Mesh:
    """The quadratic-tetrahedron mesh of a 3D design (groups as in :func:`actuator_3d`); the half
    model y >= 0 unless ``mesh.symmetry`` is false. Particle centres from :func:`particle_centres`
    (x, z) on the plane y = 0."""
    return actuator_3d(
        design.resolved_cavity_width, design.resolved_cavity_depth, design.resolved_cavity_length,
        design.side_wall_thickness, design.end_wall_thickness, design.strain_limit_thickness,
        particle_centres(design), design.particle_diameter / 2, design.mesh_size,
        symmetry=design.mesh.symmetry, order=2, strain_limit_width=design.strain_limit_width,
        strain_limit_helix_deg=design.helix_angle_deg,
    )
