"""The actuator model (docs/actuator.md, "Model"): mesh groups, particle placement, contact set-up and
the measurements of section 7 on synthetic states (rigid rotations, uniform dilations).

No test here runs the solver: the states are the reference positions X moved by closed-form maps.
Coordinates are (x, z): x the bending direction (strain-limit layer on -x), z the axis (clamp at
z = 0, free end at z = -L). A clockwise rotation (toward -x at the free end) is a positive angle.

The model under test has two layers of two particles (d = 16 mm, clearance c = 0.1 mm), so that
the particle numbering (layer by layer from the clamp, -x first in a layer) is exercised along
both axes. By hand: cavity width = cavity length = 2 x 16 + 3 x 0.1 = 32.3 mm; cavity
[-16.15, 16.15] x [-36.3, -4] (t1 = 4 mm); L = 32.3 + 2 x 4 = 40.3 mm; strain-limit layer
[-16.15 - 2 - 8, -16.15 - 2] = [-26.15, -18.15], mid-line x = -22.15 mm.
"""

from __future__ import annotations

import numpy as np
import pytest

from hydrojam.actuator.design import DesignError, apply_overrides, default_design
from hydrojam.actuator.model import (
    MEMBRANE_BODY,
    PARTICLE_BODY,
    STRAIN_LIMIT_BODY,
    build_model,
    centreline_x,
    check_supported,
    measure,
    particle_areas,
)
from hydrojam.actuator.geometry import particle_centres

D = 16.0  # particle diameter [mm]
C = 0.1  # clearance [mm]
W_CAV = 32.3  # cavity width [mm], 2 d + 3 c
L_CAV = 32.3  # cavity length [mm], 2 d + 3 c
T0, T1, H = 2.0, 4.0, 8.0  # side wall, end wall, strain-limit layer thickness [mm]
LENGTH = L_CAV + 2 * T1  # actuator length L [mm]
X_MID = -W_CAV / 2 - T0 - H / 2  # strain-limit layer mid-line [mm]
# particle centres by hand: x = -w/2 + c + d/2 and its mirror; z = -t1 - c - d/2, then one d + c lower
CENTRES = np.array([[-8.05, -12.1], [8.05, -12.1], [-8.05, -28.2], [8.05, -28.2]])


def clockwise(points: np.ndarray, angle_deg: float) -> np.ndarray:
    """Points rotated clockwise by angle_deg about the origin in the (x right, z up) plane."""
    a = np.radians(angle_deg)
    R = np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
    return points @ R.T


@pytest.fixture(scope="module")
def model():
    return build_model(apply_overrides(default_design(), ["particle_layers=2", "particles_per_layer=2"]))


@pytest.fixture(scope="module")
def X(model):
    return model.mesh.points


@pytest.fixture(scope="module")
def reference(model, X):
    return measure(model, X)


# ------------------------------------------------------------------------------------------------
# Mesh, groups and particle placement


def test_design_is_resolved_to_the_hand_computed_sizes(model):
    d = model.design
    assert d.cavity_width == pytest.approx(W_CAV, rel=1e-12)
    assert d.cavity_length == pytest.approx(L_CAV, rel=1e-12)
    assert d.length == pytest.approx(LENGTH, rel=1e-12)


def test_particle_count_is_layers_times_particles_per_layer(model):
    d = model.design
    assert model.n_particles == d.particle_layers * d.particles_per_layer == 4
    assert len(particle_centres(d)) == 4
    assert set(model.mesh.cell_groups) == {"membrane", "strain_limit_layer", "particle0", "particle1",
                                           "particle2", "particle3"}


def test_clamp_nodes_are_the_whole_top_face(model, X):
    top = X[model.clamp_nodes]
    assert np.all(top[:, 1] == 0.0)
    # the clamp holds membrane and strain-limit layer: the full width of the actuator
    # mm coordinates up to 40 mm through gmsh and a few operations: round-off ~eps x 40 x a few = 3e-14 mm
    assert top[:, 0].min() == pytest.approx(-W_CAV / 2 - T0 - H, abs=1e-11)
    assert top[:, 0].max() == pytest.approx(W_CAV / 2 + T0, abs=1e-11)
    assert np.array_equal(np.flatnonzero(np.abs(X[:, 1]) < 1e-9), np.sort(model.clamp_nodes))


def test_free_end_nodes_are_the_whole_bottom_face(model, X):
    end = X[model.free_end_nodes]
    # mm coordinates up to 40 mm through gmsh and a few operations: round-off ~eps x 40 x a few = 3e-14 mm
    assert np.allclose(end[:, 1], -LENGTH, rtol=0, atol=1e-11)
    assert end[:, 0].min() == pytest.approx(-W_CAV / 2 - T0 - H, abs=1e-11)
    assert end[:, 0].max() == pytest.approx(W_CAV / 2 + T0, abs=1e-11)
    assert np.array_equal(np.flatnonzero(np.abs(X[:, 1] + LENGTH) < 1e-9), np.sort(model.free_end_nodes))


def test_centreline_is_the_strain_limit_mid_line_ordered_from_the_clamp(model, X):
    line = X[model.centreline_nodes]
    assert np.allclose(line[:, 0], X_MID, rtol=0, atol=1e-9)
    assert centreline_x(model.design) == pytest.approx(X_MID, abs=1e-9)  # what a kept record's figure starts at
    assert np.all(np.diff(line[:, 1]) < 0.0)  # ordered from the clamp: z decreasing
    # mm coordinates up to 40 mm through gmsh and a few operations: round-off ~eps x 40 x a few = 3e-14 mm
    assert line[0, 1] == pytest.approx(0.0, abs=1e-11)
    assert line[-1, 1] == pytest.approx(-LENGTH, abs=1e-11)
    # every node of the mesh on the mid-line is on the centreline (none skipped)
    on = np.flatnonzero(np.abs(X[:, 0] - X_MID) < 1e-9)
    assert np.array_equal(np.sort(on), np.sort(model.centreline_nodes))


def test_particle_centres_are_the_hand_computed_ones(model):
    assert np.allclose(particle_centres(model.design), CENTRES, rtol=0, atol=1e-11)  # mm, up to 40 mm: eps x 40 = 9e-15


def test_particle_centres_leave_the_clearance_to_walls_and_neighbours(model):
    """Derived cavity: every gap (wall-particle and particle-particle) equals the clearance."""
    p, r = particle_centres(model.design), D / 2
    x_lo, x_hi, z_hi, z_lo = -W_CAV / 2, W_CAV / 2, -T1, -T1 - L_CAV
    assert np.all((p[:, 0] - r > x_lo) & (p[:, 0] + r < x_hi) & (p[:, 1] + r < z_hi) & (p[:, 1] - r > z_lo))
    wall_gap = np.min(np.stack([p[:, 0] - r - x_lo, x_hi - p[:, 0] - r, z_hi - p[:, 1] - r, p[:, 1] - r - z_lo]))
    # differences of mm positions up to 40 mm: round-off ~eps x 40 x a few = 3e-14 mm
    assert wall_gap == pytest.approx(C, abs=1e-11)
    dist = np.linalg.norm(p[:, None] - p[None], axis=-1)[np.triu_indices(len(p), 1)]
    assert dist.min() - D == pytest.approx(C, abs=1e-11)


def test_particle_centres_in_a_given_cavity_are_evenly_spaced():
    """An explicit cavity larger than needed: the free room is shared into m + 1 equal gaps."""
    design = apply_overrides(default_design(), ["particle_layers=2", "particles_per_layer=2",
                                                 "cavity_width=40.0", "cavity_length=35.0"])
    gx, gz = (40.0 - 2 * D) / 3, (35.0 - 2 * D) / 3  # 8/3 and 1 mm
    xs = [-20.0 + gx + D / 2, 20.0 - gx - D / 2]
    zs = [-T1 - gz - D / 2, -T1 - 2 * gz - 3 * D / 2]
    expected = np.array([(x, z) for z in zs for x in xs])
    assert np.allclose(particle_centres(design), expected, rtol=0, atol=1e-11)  # mm, up to 40 mm: eps x 40 = 9e-15


def test_meshed_particles_are_circles_about_their_centres(model, X):
    """Particle k's boundary nodes lie on the circle of radius d/2 about particle_centres[k]."""
    centres = particle_centres(model.design)
    for k in range(model.n_particles):
        nodes = model.mesh.group_nodes(f"particle{k}_boundary")
        radius = np.linalg.norm(X[nodes] - centres[k], axis=1)
        assert np.allclose(radius, D / 2, rtol=1e-9)


def test_meshed_particles_keep_the_clearance_from_the_cavity_wall(model, X):
    """Nodes on a circle inscribed with gap c to a wall are at least c from it (equal where a
    node sits at the nearest point)."""
    nodes = np.unique(np.concatenate([model.mesh.group_nodes(f"particle{k}_boundary")
                                      for k in range(model.n_particles)]))
    p = X[nodes]
    gaps = np.stack([p[:, 0] + W_CAV / 2, W_CAV / 2 - p[:, 0], -T1 - p[:, 1], p[:, 1] + T1 + L_CAV])
    assert gaps.min() >= C * (1 - 1e-9)


def test_body_ids(model, X):
    """0 membrane, 1 strain-limit layer, 2 + k particle k (cells located geometrically)."""
    centroid = X[model.mesh.cells[:, :3]].mean(axis=1)
    ids = model.body_id
    assert np.all(ids[model.mesh.cell_groups["membrane"]] == MEMBRANE_BODY)
    sll = ids == STRAIN_LIMIT_BODY
    assert np.array_equal(np.flatnonzero(sll), np.sort(model.mesh.cell_groups["strain_limit_layer"]))
    assert np.all(centroid[sll, 0] < -W_CAV / 2 - T0)
    for k, c in enumerate(CENTRES):
        cells = np.flatnonzero(ids == PARTICLE_BODY + k)
        assert np.array_equal(cells, np.sort(model.particle_cells[k]))
        assert np.all(np.linalg.norm(centroid[cells] - c, axis=1) < D / 2)


# ------------------------------------------------------------------------------------------------
# Contact set-up


def test_contact_starts_intersection_free_and_inactive(model, X):
    assert model.contact.has_intersections(X) is False
    # the barrier must start inactive (stress-free as-prepared state): dhat below the gap
    assert model.contact.settings.dhat < model.design.clearance
    assert model.contact.minimum_distance(X) == np.inf
    assert model.contact.active(X) == 0


def test_the_designs_friction_reaches_the_contact_term():
    """friction and friction_slip [mm] are the contact's Coulomb coefficient and static slip;
    friction_slip omitted leaves the contact's own default (1% of dhat)."""
    drawn = build_model(apply_overrides(default_design(), ["particle_layers=1", "mesh.size=4", "friction=0.05"]))
    assert drawn.contact.settings.friction == 0.05
    assert drawn.contact.settings.friction_eps is None
    set_ = build_model(apply_overrides(default_design(), ["particle_layers=1", "mesh.size=4", "friction_slip=0.002"]))
    assert set_.contact.settings.friction_eps == 0.002


def test_contact_components_are_one_per_particle_and_one_wall(model):
    comps = model.components
    for k, cells in enumerate(model.particle_cells):
        assert np.all(comps[np.unique(model.mesh.cells[cells])] == k)
    assert len(np.unique(comps)) == model.n_particles + 1


# ------------------------------------------------------------------------------------------------
# Measurements (docs/actuator.md, "Metrics")


def test_check_supported_accepts_3d():
    """3D designs are simulated (tests/actuator/test_3d.py); a bad one is refused by the design."""
    check_supported(apply_overrides(default_design(), ["dimension=3"]))
    with pytest.raises(DesignError, match="cavity_depth"):
        apply_overrides(default_design(), ["dimension=3", "cavity_depth=15"])
    check_supported(default_design())  # 2D passes


def test_measure_reference_state(reference):
    """As prepared: straight, nothing moved, no contact; packing fraction n pi d^2 / 4 over the
    cavity area (w x l_c) and swelling ratio 1.

    Tolerance 1e-3 on both: the meshed particles are quadratic (isoparametric) polygons whose
    area falls short of the circle's by O(h^4) (7e-6 relative at the default mesh size).
    """
    assert reference["bending_angle_deg"] == 0.0
    assert reference["tip_dx_mm"] == 0.0
    assert reference["tip_dz_mm"] == 0.0
    assert reference["contacts_per_particle"] == 0.0
    assert reference["curling_index"] is None
    assert reference["max_curvature_per_mm"] == 0.0
    expected = 4 * np.pi * D**2 / 4 / (W_CAV * L_CAV)
    assert reference["packing_fraction"] == pytest.approx(expected, rel=1e-3)
    assert reference["mean_swelling_ratio"] == pytest.approx(1.0, rel=1e-3)
    assert reference["bending_plane_deg"] is None  # straight: no plane
    assert reference["twist_deg"] == 0.0 and reference["tip_dy_mm"] == 0.0
    assert reference["column_folds"] == 0
    assert set(reference) == {"bending_angle_deg", "bending_plane_deg", "twist_deg", "tip_dx_mm", "tip_dy_mm",
                              "tip_dz_mm", "curling_index", "max_curvature_per_mm", "packing_fraction",
                              "contacts_per_particle", "mean_swelling_ratio", "column_folds"}


def test_measure_no_negative_zero(reference):
    for key in ("bending_angle_deg", "tip_dx_mm", "tip_dz_mm"):
        assert np.copysign(1.0, reference[key]) == 1.0


@pytest.mark.parametrize("angle", [25.0, -25.0])
def test_measure_rigid_rotation(model, X, reference, angle):
    """Rigid rotation about the clamp centre (0, 0), clockwise by +25 deg (toward the strain-limit
    side) and counter-clockwise: the bending angle is the rotation angle, the tip moves by
    R c - c (c the free-end centroid), areas and contacts are unchanged."""
    x = clockwise(X, angle)
    m = measure(model, x)
    assert m["bending_angle_deg"] == pytest.approx(angle, abs=1e-9)
    c = X[model.free_end_nodes].mean(axis=0)
    a = np.radians(angle)
    moved = np.array([c[0] * np.cos(a) + c[1] * np.sin(a), -c[0] * np.sin(a) + c[1] * np.cos(a)])
    assert m["tip_dx_mm"] == pytest.approx(moved[0] - c[0], abs=1e-9)
    assert m["tip_dz_mm"] == pytest.approx(moved[1] - c[1], abs=1e-9)
    if angle > 0:
        assert m["tip_dx_mm"] < 0.0  # the tip swings toward the strain-limit side
    assert m["packing_fraction"] == pytest.approx(reference["packing_fraction"], rel=1e-12)
    assert m["mean_swelling_ratio"] == pytest.approx(reference["mean_swelling_ratio"], rel=1e-12)
    assert m["contacts_per_particle"] == 0.0
    assert m["curling_index"] is None  # a rigid motion does not bend the centreline
    assert m["max_curvature_per_mm"] == pytest.approx(0.0, abs=1e-9)


def test_measure_uniform_dilation(model, X, reference):
    """x = lambda X (lambda = 1.3): no rotation, areas scale by lambda^2 (swelling ratio and
    cavity alike, so the packing fraction is unchanged), the tip moves by (lambda - 1) c."""
    lam = 1.3
    m = measure(model, lam * X)
    assert m["bending_angle_deg"] == pytest.approx(0.0, abs=1e-9)
    c = X[model.free_end_nodes].mean(axis=0)
    assert m["tip_dx_mm"] == pytest.approx((lam - 1) * c[0], abs=1e-9)
    assert m["tip_dz_mm"] == pytest.approx((lam - 1) * c[1], abs=1e-9)
    assert m["tip_dz_mm"] == pytest.approx(-(lam - 1) * LENGTH, rel=1e-12)
    assert m["mean_swelling_ratio"] == pytest.approx(lam**2, rel=1e-3)
    assert m["mean_swelling_ratio"] == pytest.approx(lam**2 * reference["mean_swelling_ratio"], rel=1e-12)
    assert m["packing_fraction"] == pytest.approx(reference["packing_fraction"], rel=1e-12)
    assert m["contacts_per_particle"] == 0.0
    assert m["curling_index"] is None


def test_particle_areas_reference_and_dilation(model, X):
    """Reference area: the circle pi d^2 / 4 (to 1e-4: the quadratic particles' boundary falls
    inside the circle by O(h^4)) and exactly the mesh's isoparametric cell areas; under
    x = lambda X every area is lambda^2 times the reference one (det F = lambda^2)."""
    a0 = particle_areas(model, X)
    assert a0.shape == (4,)
    assert np.allclose(a0, np.pi * D**2 / 4, rtol=1e-4)
    cell_area = model.mesh.cell_volumes(curved=True)
    assert np.allclose(a0, [cell_area[c].sum() for c in model.particle_cells], rtol=1e-12)
    lam = 1.3
    assert np.allclose(particle_areas(model, lam * X), lam**2 * a0, rtol=1e-12)


def test_particle_areas_are_per_particle(model, X):
    """Dilating one particle about its own centre changes only its own area (ordering check)."""
    centres = particle_centres(model.design)
    x = X.copy()
    nodes = np.unique(model.mesh.cells[model.particle_cells[2]])
    x[nodes] = centres[2] + 1.1 * (X[nodes] - centres[2])
    a0, a = particle_areas(model, X), particle_areas(model, x)
    assert np.allclose(a / a0, [1.0, 1.0, 1.1**2, 1.0], rtol=1e-12)
