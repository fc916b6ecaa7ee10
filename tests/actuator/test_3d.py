"""The 3D actuator (docs/actuator.md, "3D"; issue 13): the gmsh tet10 mesh and its groups by hand,
the half model's symmetry set-up, the 3D metrics on closed-form states, the undeformed check,
no interpenetration at accepted states, half against full model, VTU mirroring and refusals.

Designs are small: one particle layer, the quick mesh (4 mm). By hand (d = 16 mm, c = 0.1 mm,
t0 = 2, t1 = 4, h = 8 mm): cavity 16.2 x 16.2 x 16.2 mm (width x depth x length), L = 24.2 mm,
outer membrane 20.2 x 20.2 x 24.2 mm, strain-limit layer 8 x 20.2 x 24.2 mm on
x in [-18.1, -10.1] (its mid-plane x = -14.1); the particle's centre (0, 0, -12.1). The half model
holds y >= 0 of all this.
"""

from __future__ import annotations

import math

import meshio
import numpy as np
import pytest

from hydrojam.actuator.design import DesignError, apply_overrides, default_design
from hydrojam.actuator.metrics import bending_angle_3d_deg, enclosed_volume
from hydrojam.actuator.model import build_model, measure
from hydrojam.actuator.results import write_vtu
from hydrojam.actuator.simulate import StepState, simulate
from hydrojam.cli import main
from hydrojam.fem.mesh import signed_measures
from undeformed import assert_nothing_moved

D, C, T0, T1, H = 16.0, 0.1, 2.0, 4.0, 8.0
W = D + 2 * C  # cavity width = depth = length with one layer [mm]
L = W + 2 * T1
Y_OUT = W / 2 + T0  # outer membrane face in y [mm]
X_MID = -W / 2 - T0 - H / 2
SMALL = ["dimension=3", "particle_layers=1", "mesh.size=4"]
# a partial hydration at T0: the free particle would grow 7 % in diameter (to 17.2 mm in a 16.2 mm
# cavity), so it presses the walls and the actuator bends a little: a cheap loaded path
MILD = ["stimulus.temperature=300", "stimulus.mu=-0.025"]


def _design(*extra):
    return apply_overrides(default_design(), SMALL + list(extra))


@pytest.fixture(scope="module")
def half():
    return build_model(_design())


@pytest.fixture(scope="module")
def full():
    return build_model(_design("mesh.symmetry=false"))


def _volumes(model, group):
    return model.mesh.cell_volumes(curved=True)[model.mesh.cell_groups[group]].sum()


# ------------------------------------------------------------------------------------------------
# Mesh and groups


def test_the_half_model_mesh_has_the_bodies_and_faces_by_hand(half):
    """Quadratic tetrahedra; the membrane, the strain-limit layer and the half particle have the
    volumes of the drawing (boxes exactly, the sphere within 0.5 % at 4 mm elements); clamp,
    free end and cut faces lie on their planes with the areas by hand."""
    m = half.mesh
    assert m.cell_type == "tetra10" and m.dim == 3 and half.half
    assert set(m.cell_groups) == {"membrane", "strain_limit_layer", "particle0"}
    assert {"clamp", "free_end", "cavity", "symmetry", "particle0_boundary"} <= set(m.facet_groups)
    assert np.all(m.cell_volumes(curved=True) > 0)
    assert _volumes(half, "membrane") == pytest.approx((W + 2 * T0) * Y_OUT * L - W * W / 2 * W, rel=1e-9)
    assert _volumes(half, "strain_limit_layer") == pytest.approx(H * Y_OUT * L, rel=1e-9)
    assert _volumes(half, "particle0") == pytest.approx(2 / 3 * math.pi * (D / 2) ** 3, rel=5e-3)
    P = m.points
    assert np.abs(P[m.group_nodes("clamp"), 2]).max() < 1e-9
    assert np.abs(P[m.group_nodes("free_end"), 2] + L).max() < 1e-9
    assert np.abs(P[m.group_nodes("symmetry"), 1]).max() < 1e-9
    assert P[:, 1].min() > -1e-9 and P[:, 1].max() == pytest.approx(Y_OUT)
    face = (W + 2 * T0 + H) * Y_OUT
    assert m.facet_measures(m.facet_groups["clamp"]).sum() == pytest.approx(face, rel=1e-9)
    assert m.facet_measures(m.facet_groups["free_end"]).sum() == pytest.approx(face, rel=1e-9)
    # the cut: the membrane's ring and the layer exactly; the particle's disk (its corner facets
    # are a polygon of 4 mm chords, a few % short of the circle) and nothing else
    cut = m.facet_groups["symmetry"]
    in_particle = np.isin(cut, m.group_nodes("particle0")).all(axis=1)
    walls = (W + 2 * T0) * L - W * W + H * L
    assert m.facet_measures(cut[~in_particle]).sum() == pytest.approx(walls, rel=1e-9)
    assert m.facet_measures(cut[in_particle]).sum() == pytest.approx(math.pi * (D / 2) ** 2, rel=0.05)


def test_the_half_model_holds_the_cut_and_leaves_it_out_of_contact(half):
    """u_y = 0 on every node of y = 0 (and the clamp in full); no collision triangle lies on the cut."""
    problem = half.problem()
    free = problem.free_mask().reshape(-1, 3)
    sym = half.mesh.group_nodes("symmetry")
    assert not free[sym, 1].any()
    assert free[np.setdiff1d(sym, half.clamp_nodes)][:, [0, 2]].all()
    assert not free[half.clamp_nodes].any()
    faces = np.asarray(half.contact._cm.faces)
    on_cut = np.abs(half.contact.X[half.contact.vertex_ids][faces, 1]).max(axis=1) < 1e-9
    assert faces.size and not on_cut.any()
    # the particle's curved surface and the cavity's five walls are in it
    assert len(half.centreline_nodes) >= 3
    assert np.allclose(half.mesh.points[half.centreline_nodes][:, :2], [X_MID, 0.0], atol=1e-9)


def test_the_walls_outer_faces_are_in_the_collision_mesh_and_may_meet_themselves(half):
    """A chamber long enough curls past a full turn onto itself: the walls (membrane and
    strain-limit layer, one component) are self-contacting, and their collision triangles are
    the cavity's five walls (3 W^2) and the outer faces by hand (the two side faces, the far face
    y = Y_OUT and the free end; not the clamp, not the cut), to the round-off of flat faces."""
    from hydrojam.actuator.model import WALL_COMPONENT

    C = half.contact
    assert C.self_contact and C.self_contacts(C.X) == 0
    faces = np.asarray(C._cm.faces)
    V = C.X[C.vertex_ids]
    on_wall = (C.components[faces] == WALL_COMPONENT).all(axis=1)
    tri = V[faces[on_wall]]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    outer = 2 * Y_OUT * L + (W + 2 * T0 + H) * L + (W + 2 * T0 + H) * Y_OUT
    assert area == pytest.approx(3 * W * W + outer, rel=1e-9)


def test_the_full_model_is_two_glued_halves(full, half):
    """The whole actuator: twice the half's volumes, a mid-plane of nodes on y = 0 and no
    symmetry condition."""
    assert not full.half and full.symmetry_nodes is None
    for group in ("membrane", "strain_limit_layer", "particle0"):
        assert _volumes(full, group) == pytest.approx(2 * _volumes(half, group), rel=1e-3)
    assert np.abs(full.mesh.points[full.mesh.group_nodes("mid_plane"), 1]).max() < 1e-9
    assert len(full.problem().dirichlet) == 1
    assert np.allclose(full.mesh.points[full.centreline_nodes][:, :2], [X_MID, 0.0], atol=1e-9)
    assert np.all(np.diff(full.mesh.points[full.centreline_nodes][:, 2]) < 0)  # from the clamp down
    assert full.mesh.points[full.centreline_nodes][[0, -1], 2] == pytest.approx([0.0, -L])


# ------------------------------------------------------------------------------------------------
# Metrics on closed-form states


def _rotate_about_y(points, angle_deg, pivot):
    """Clockwise in the (x right, z up) plane, i.e. toward -x for a point below the pivot."""
    a = math.radians(angle_deg)
    R = np.array([[math.cos(a), 0.0, math.sin(a)], [0.0, 1.0, 0.0], [-math.sin(a), 0.0, math.cos(a)]])
    return (points - pivot) @ R.T + pivot


@pytest.mark.parametrize("angle", [-30.0, 12.5, 100.0, 179.0])
def test_a_rigid_rotation_about_y_is_its_bending_angle(half, angle):
    """Rotating the whole actuator by theta about a line along y: the best-fit plane angle is theta,
    the centroid moves as the rotation moves it, the volumes and the curvature do not change."""
    X = half.mesh.points
    pivot = np.array([3.0, 0.0, -5.0])
    x = _rotate_about_y(X, angle, pivot)
    m = measure(half, x)
    assert m["bending_angle_deg"] == pytest.approx(angle, abs=1e-9)
    fe = half.free_end_nodes
    expected = (x[fe] - X[fe]).mean(axis=0)
    assert m["tip_dx_mm"] == pytest.approx(expected[0], abs=1e-9)
    assert m["tip_dz_mm"] == pytest.approx(expected[2], abs=1e-9)
    assert m["max_curvature_per_mm"] < 1e-9
    assert m["mean_swelling_ratio"] == pytest.approx(1.0, rel=1e-12)
    ref = measure(half, X)
    assert m["packing_fraction"] == pytest.approx(ref["packing_fraction"], rel=1e-12)


@pytest.mark.parametrize("angle", [-30.0, 12.5, 100.0])
def test_the_half_model_bends_in_the_x_z_plane_without_twist(half, angle):
    """The half model's free end (its face and the mirror image) turned about y: the bending
    plane is 180 deg (toward -x) or 0 (toward +x), and twist and tip_dy are 0; positions
    are exact to round-off, so the tolerance is 1e-9 deg (mm) against angles (lengths) of order 10-100."""
    x = _rotate_about_y(half.mesh.points, angle, np.array([3.0, 0.0, -5.0]))
    m = measure(half, x)
    assert m["bending_plane_deg"] == pytest.approx(180.0 if angle > 0 else 0.0, abs=1e-9)
    assert m["twist_deg"] == pytest.approx(0.0, abs=1e-9) and m["tip_dy_mm"] == pytest.approx(0.0, abs=1e-9)


def test_the_full_model_reads_a_twisted_and_swung_free_end(full):
    """The whole actuator turned rigidly: twisted by 15 deg about z, then swung by 20 deg toward
    +y (plane 90 deg): the free end reads those back, and tip_dy the centroid's move along y."""
    def rot(axis, a):
        k = np.asarray(axis, dtype=float)
        K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        return np.eye(3) + math.sin(a) * K + (1 - math.cos(a)) * K @ K

    R = rot([1.0, 0.0, 0.0], math.radians(20.0)) @ rot([0.0, 0.0, 1.0], math.radians(15.0))
    X = full.mesh.points
    x = X @ R.T
    m = measure(full, x)
    assert m["bending_plane_deg"] == pytest.approx(90.0, abs=1e-9)
    assert m["twist_deg"] == pytest.approx(15.0, abs=1e-9)
    fe = full.free_end_nodes
    assert m["tip_dy_mm"] == pytest.approx((x[fe] - X[fe])[:, 1].mean(), abs=1e-9)


def test_a_free_end_face_tilted_about_x_has_no_bending_angle():
    """A tilt about the x axis (out of the bending plane) is not a bending: theta stays 0."""
    rng = np.random.default_rng(1)
    X = np.column_stack([rng.uniform(-10, 10, 40), rng.uniform(0, 10, 40), np.full(40, -24.2)])
    a = math.radians(20.0)
    R = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    assert bending_angle_3d_deg(X, X @ R.T) == pytest.approx(0.0, abs=1e-9)


def test_uniform_dilation_scales_the_packing_fraction_by_the_volume_ratios(half):
    """Every node moved by the map y -> lambda y (a stretch across the depth, which keeps the cut
    on y = 0): volumes scale by lambda, the packing fraction does not change and the swelling
    ratio is lambda. The half model's cavity volume closes off at the cut: it is W^3 / 2."""
    X = half.mesh.points
    cavity = enclosed_volume(X, half.cavity_segments)
    assert cavity == pytest.approx(W ** 3 / 2, rel=1e-9)
    x = X * np.array([1.0, 1.3, 1.0])
    m, ref = measure(half, x), measure(half, X)
    assert m["mean_swelling_ratio"] == pytest.approx(1.3, rel=1e-9)
    assert m["packing_fraction"] == pytest.approx(ref["packing_fraction"], rel=1e-9)
    # the particle volume by the elements' quadrature (not exact on curved tet10): 1e-6
    assert ref["packing_fraction"] == pytest.approx(_volumes(half, "particle0") / cavity, rel=1e-6)


# ------------------------------------------------------------------------------------------------
# Refusals


@pytest.mark.parametrize("overrides, field", [
    (["cavity_depth=15"], "cavity_depth"),
    (["dimension=2", "mesh.symmetry=false"], "mesh.symmetry"),
    (["cavity_width=16.1"], "cavity_width"),
])
def test_bad_3d_designs_are_refused_naming_the_field(overrides, field):
    with pytest.raises(DesignError, match=field.replace(".", r"\.")):
        apply_overrides(default_design(), ["dimension=3"] + overrides)


def test_the_cli_refuses_a_sphere_deeper_than_the_cavity_before_meshing(tmp_path, capsys):
    """Exit status 2, one line naming cavity_depth, nothing written."""
    design = tmp_path / "bad.toml"
    design.write_text("dimension = 3\ncavity_depth = 15.0\n")
    out = tmp_path / "out"
    rc = main(["run", str(design), "-o", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and "cavity_depth" in err and len(err.splitlines()) == 1 and "Traceback" not in err
    assert not out.exists()


# ------------------------------------------------------------------------------------------------
# Simulations


def test_nothing_moves_at_the_as_prepared_stimulus_in_3d():
    """Target stimulus (mu0, T0): the as-prepared state is stress-free and contact-free, so no node
    moves (docs/model.md, "Reference state") and every metric stays at its reference."""
    d = default_design()
    model = build_model(_design(f"stimulus.mu={d.hydrogel.mu0!r}", f"stimulus.temperature={d.hydrogel.T0!r}"))
    res = simulate(model)
    drift = assert_nothing_moved(model, res)
    assert res.metrics["mean_swelling_ratio"] == pytest.approx(1.0, abs=6 * drift / model.design.particle_diameter)


def _run(model):
    """Simulate, checking at every accepted state that no two bodies interpenetrate."""
    gaps = []

    def check(state):
        assert not model.contact.has_intersections(state.x), f"intersection at s = {state.s}"
        gaps.append(model.contact.minimum_distance(state.x))

    res = simulate(model, on_step=check)
    assert res.converged, res.message
    assert min(gaps) > 0.0
    return res


@pytest.mark.slow
def test_half_and_full_models_agree_and_never_interpenetrate(half, full, tmp_path):
    """One particle, partly hydrated at T0 (the free particle would grow to 17.2 mm in the 16.2 mm
    cavity): it presses the walls, which bulge, and the actuator bends toward the strain-limit
    layer. The half model (u_y = 0 on the cut) and the whole actuator give the same metrics:
    within 2 % of the bending angle (plus 0.05 deg), the tip within what that angle moves it at
    the actuator's length L (its displacement's 2 % or L times the angle's tolerance), the volume
    ratios within 1 % (the two meshes differ only in the mirrored half, and the solver's
    tolerance is 1e-6 of the forces); the half model's VTU file holds the whole actuator,
    mirrored, with the full model's volume, and no accepted state interpenetrates."""
    mh = build_model(_design(*MILD))
    mf = build_model(_design("mesh.symmetry=false", *MILD))
    rh, rf = _run(mh), _run(mf)
    a, b = rh.metrics, rf.metrics
    assert a["bending_angle_deg"] > 0.1  # it bends toward the strain-limit layer
    angle_tol = max(0.02 * abs(b["bending_angle_deg"]), 0.05)  # [deg]
    assert a["bending_angle_deg"] == pytest.approx(b["bending_angle_deg"], abs=angle_tol)
    tip = np.hypot(b["tip_dx_mm"], b["tip_dz_mm"])
    tip_tol = max(0.02 * tip, L * np.radians(angle_tol))  # [mm]
    for key in ("tip_dx_mm", "tip_dz_mm"):
        assert a[key] == pytest.approx(b[key], abs=tip_tol)
    for key in ("packing_fraction", "mean_swelling_ratio"):
        assert a[key] == pytest.approx(b[key], rel=0.01)
    assert a["contacts_per_particle"] == b["contacts_per_particle"]
    # the full model stays close to symmetric: its mid-plane nodes leave y = 0 by less than 10 % of
    # a particle diameter. The symmetric state is a saddle of the whole actuator (the full model's
    # path without the inertia correction met negative eigenvalues that the half model, which has
    # no antisymmetric modes, never had), so the full model leaves it along the particle's
    # sideways mode, held only by the soft membrane (about 1 mm here); the metrics above are what
    # must agree
    mid = mf.mesh.group_nodes("mid_plane")
    assert np.abs(rf.final.x[mid, 1]).max() < 0.1 * D
    # VTU of the half model: both halves, positively oriented, the whole actuator's volume
    path = tmp_path / "half.vtu"
    write_vtu(path, mh, rh.final)
    vtu = meshio.read(path)
    cells = vtu.cells[0].data
    x = vtu.points + vtu.point_data["displacement"]
    assert len(cells) == 2 * mh.mesh.n_cells
    corner = [0, 1, 2, 3]
    assert signed_measures(vtu.points, cells[:, corner]).min() > 0
    half_volume = signed_measures(mh.mesh.points, mh.mesh.cells[:, corner]).sum()
    assert signed_measures(vtu.points, cells[:, corner]).sum() == pytest.approx(2 * half_volume, rel=1e-12)
    now = signed_measures(x, cells[:, corner]).sum()
    assert now == pytest.approx(2 * signed_measures(rh.final.x, mh.mesh.cells[:, corner]).sum(), rel=1e-12)
    assert now == pytest.approx(signed_measures(rf.final.x, mf.mesh.cells[:, corner]).sum(), rel=1e-2)
    assert np.abs(x[:, 1]).max() == pytest.approx(np.abs(rf.final.x[:, 1]).max(), rel=1e-2)


def test_hydrojam_run_in_3d_writes_every_file(tmp_path, capsys):
    """`hydrojam run --dimension 3` at the as-prepared stimulus (nothing moves, seconds): exit 0,
    every result file, the VTU files hold the whole actuator (the half mirrored) and metrics.json
    its metrics; --dimension 4 is refused with one line."""
    d = default_design()
    design = tmp_path / "d.toml"
    design.write_text(f"particle_layers = 1\n[mesh]\nsize = 4.0\n[stimulus]\nmu = {d.hydrogel.mu0!r}\n"
                      f"temperature = {d.hydrogel.T0!r}\n")
    out = tmp_path / "out"
    rc = main(["run", str(design), "-o", str(out), "--dimension", "3", "-q"])
    assert rc == 0, capsys.readouterr().err
    for name in ("design.toml", "metrics.json", "history.csv", "centreline.csv", "final.png", "results.pvd"):
        assert (out / name).is_file(), name
    assert "dimension = 3" in (out / "design.toml").read_text()
    vtu = meshio.read(sorted((out / "steps").glob("*.vtu"))[-1])
    assert vtu.points[:, 1].min() == pytest.approx(-vtu.points[:, 1].max()) and vtu.points[:, 1].max() > 10
    assert set(vtu.cell_data["mirror_image"][0]) == {0, 1}
    rc = main(["run", str(design), "-o", str(tmp_path / "o2"), "--dimension", "4"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and err.startswith("hydrojam: error: --dimension") and len(err.splitlines()) == 1
