"""Replicas' perturbations of the as-prepared state (actuator.geometry): reproducible from their
seed, inside the jitter disk, and never starting in contact, on the real meshed design.

A replica moves every particle rigidly by at most r = jitter x c (c the clearance). Two neighbours
moving toward each other close their gap by at most 2 r, so every gap between particle circles
stays >= (1 - 2 jitter) c, and to a straight wall >= (1 - jitter) c; a meshed particle's boundary
(nodes on the circle, straight between them in the contact's collision mesh) lies inside its
circle, so the meshed gaps are at least as wide. At the largest jitter, 0.1, that is 0.8 c: the
contact barrier's activation distance, so the barrier starts inactive (the as-prepared state is
stress-free).
"""

from __future__ import annotations

import numpy as np
import pytest

from hydrojam.actuator.design import MAX_JITTER, Design
from hydrojam.actuator.geometry import jitter_particles, particle_centres, replica_offsets
from hydrojam.actuator.model import DHAT_PER_CLEARANCE, build_model
from hydrojam.fem.contact import Contact, default_settings

C = 0.1  # clearance [mm]
D = 16.0  # particle diameter [mm]


def replica(index: int, seed: int = 0, jitter: float = MAX_JITTER, **fields) -> Design:
    """Replica ``index`` of a 3-layer, 2-per-layer design on the quick mesh (gaps along x and z)."""
    return Design(particle_layers=3, particles_per_layer=2, mesh={"size": 4.0},
                  replicas={"count": 1, "index": index, "seed": seed, "jitter": jitter}, **fields)


def test_the_jitter_bound_keeps_the_barrier_inactive():
    """The largest jitter closes a gap to exactly the barrier's activation distance at most."""
    assert 1.0 - 2.0 * MAX_JITTER >= DHAT_PER_CLEARANCE


def test_replicas_are_reproducible_from_their_seed():
    """Same (seed, index): identical offsets, also in a fresh model's mesh; another seed or index:
    different offsets; replica 0: none; every offset within jitter x c."""
    a, b = replica_offsets(replica(3, seed=11)), replica_offsets(replica(3, seed=11))
    assert a.shape == (6, 2) and np.array_equal(a, b)
    assert not np.allclose(a, replica_offsets(replica(3, seed=12)))
    assert not np.allclose(a, replica_offsets(replica(4, seed=11)))
    assert not replica_offsets(replica(0, seed=11)).any()
    for k in range(1, 40):
        r = np.linalg.norm(replica_offsets(replica(k, jitter=0.05)), axis=1)
        assert r.max() <= 0.05 * C * (1 + 1e-12)
    m1, m2 = build_model(replica(3, seed=11)), build_model(replica(3, seed=11))
    assert np.array_equal(m1.mesh.points, m2.mesh.points)
    m0 = build_model(replica(0))
    moved = m1.mesh.points - m0.mesh.points
    for k, cells in enumerate(m0.particle_cells):  # each particle moved rigidly by its offset
        nodes = np.unique(m0.mesh.cells[cells])
        assert np.allclose(moved[nodes], a[k], rtol=0, atol=1e-12 * D)
    walls = np.unique(m0.mesh.cells[np.concatenate([m0.mesh.cell_groups["membrane"],
                                                    m0.mesh.cell_groups["strain_limit_layer"]])])
    assert not moved[walls].any()


def test_the_offsets_fill_the_disk_uniformly():
    """Uniform in the disk of radius R: P(|offset| <= R/sqrt(2)) = 1/2 and the mean offset is 0
    (600 draws: 4 binomial standard deviations, 0.08, and 4 standard errors of the mean)."""
    R = MAX_JITTER * C
    offs = np.vstack([replica_offsets(replica(k)) for k in range(1, 101)])
    inside = np.mean(np.linalg.norm(offs, axis=1) <= R / np.sqrt(2))
    assert abs(inside - 0.5) < 4 * np.sqrt(0.25 / len(offs))
    assert np.all(np.abs(offs.mean(axis=0)) < 4 * (R / 2) / np.sqrt(len(offs)))


def test_a_replica_never_starts_in_contact():
    """On the real meshed design at the largest jitter: no intersection, the barrier inactive
    (energy 0), and the smallest distance between boundaries, measured by a contact term that
    reaches 2 c, at least 0.8 c (the bound in the module docstring), for 60 replicas."""
    model = build_model(replica(0))
    mesh = model.mesh
    facets = mesh.boundary_facets()
    reach = Contact(mesh.points, facets, model.components,
                    default_settings(mesh.points, facets, model.membrane.shear_modulus_ref, dhat=2.0 * C, kappa=1.0))
    bound = (1.0 - 2.0 * MAX_JITTER) * C
    closest = np.inf
    for k in range(1, 61):
        X = jitter_particles(mesh, replica(k, seed=5)).points
        assert not model.contact.has_intersections(X)
        assert model.contact.energy(X) == 0.0
        d = reach.minimum_distance(X)
        assert d >= bound * (1.0 - 1e-9)
        closest = min(closest, d)
    assert closest < C  # the replicas did close some gaps
    built = build_model(replica(7, seed=5))  # and through build_model, the model's own contact
    assert not built.contact.has_intersections(built.mesh.points)
    assert built.contact.energy(built.mesh.points) == 0.0


def test_circle_gaps_stay_above_the_bound_analytically():
    """Centres + offsets: every pair of circles and every circle-to-wall gap >= the bound."""
    d = replica(1)
    r0 = D / 2
    half_w, top, bottom = d.resolved_cavity_width / 2, -d.end_wall_thickness, -d.end_wall_thickness - d.resolved_cavity_length
    for k in range(1, 201):
        x = particle_centres(d) + replica_offsets(replica(k, seed=3))
        gaps = [np.linalg.norm(x[i] - x[j]) - 2 * r0 for i in range(len(x)) for j in range(i)]
        assert min(gaps) >= (1 - 2 * MAX_JITTER) * C * (1 - 1e-9)
        walls = np.concatenate([half_w - np.abs(x[:, 0]), top - x[:, 1], x[:, 1] - bottom]) - r0
        assert walls.min() >= (1 - MAX_JITTER) * C * (1 - 1e-9)


@pytest.mark.parametrize("symmetry", [True, False])
def test_3d_offsets_keep_half_spheres_on_the_symmetry_plane(symmetry):
    """The 3D half model's particles are half spheres cut by y = 0: their offsets lie in x-z; the
    full model's fill a ball. Both within jitter x clearance."""
    base = Design(dimension=3, particle_layers=3, mesh={"size": 4, "symmetry": symmetry}, replicas={"count": 4})
    off = replica_offsets(base.replica(3))
    radius = base.replicas.jitter * base.clearance
    assert off.shape == (3, 3)
    assert np.all(np.linalg.norm(off, axis=1) <= radius * (1 + 1e-12))
    assert np.all(off[:, 1] == 0.0) == symmetry
