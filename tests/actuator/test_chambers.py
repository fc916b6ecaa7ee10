"""Multi-chamber designs (docs/chambers.md): the design's chambers list and its checks, the
two-chamber geometry, and the free end's rotation metrics (bending plane, twist).

The swing-twist split is checked against rotations composed here in closed form; the geometry
against the layout the design describes."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

from hydrojam.actuator.design import DesignError, default_design, design_from_dict, design_to_toml
from hydrojam.actuator.metrics import face_rotation_matrix, swing_twist_deg
from hydrojam.study.spec import design_key
from undeformed import assert_nothing_moved

#: a second gel: PNIPAM with every temperature 10 K lower (chi(T) = chi_PNIPAM(T + 10 K): A0 + 10 B0,
#: A1 + 10 B1; prepared at T0 = 290 K), an illustrative gel whose transition is 10 K below
#: PNIPAM's (docs/chambers.md)
SHIFTED = {"A0": -12.947 + 0.04496 * 10.0, "A1": 17.92 - 0.0569 * 10.0, "T0": 290.0}

TWO = {"particle_layers": 2, "strain_limit_position": "none", "mesh": {"size": 4.0},
       "chambers": [{}, {"hydrogel": SHIFTED}]}


def _rot(axis, angle):
    """The rotation by ``angle`` [rad] about the unit vector ``axis`` (Rodrigues)."""
    k = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


# ------------------------------------------------------------------------------------------------ design


def test_a_design_without_chambers_keeps_its_key_and_its_toml():
    """The multi-chamber fields left out change neither the cache key nor the plain TOML: the
    keys below are those of the default 2D and 3D designs before the fields existed."""
    d = default_design()
    assert design_key(d) == "894a189094082666"
    assert design_key(d.model_copy(update={"dimension": 3})) == "294500bf73f76013"
    plain = design_to_toml(d, comments=False)
    assert "chamber" not in plain and "strain_limit_position" not in plain


def test_chambers_resolve_from_the_design_and_round_trip():
    d = design_from_dict(TWO)
    r = d.resolved()
    a, b = r.chambers
    assert (a.particle_layers, a.particles_per_layer, a.particle_diameter) == (2, 1, 16.0)
    assert a.cavity_width == pytest.approx(16.0 + 2 * 0.1) and a.temperature == 275.0
    assert b.hydrogel.A0 == pytest.approx(SHIFTED["A0"]) and a.hydrogel.A0 == d.hydrogel.A0
    # width: two cavities, the shared wall (side_wall_thickness), two side walls, no outer layer
    assert d.width == pytest.approx(2 * 16.2 + 2.0 + 2 * 2.0)
    for design in (d, r):
        for comments in (True, False):
            assert design_from_dict(tomllib.loads(design_to_toml(design, comments))) == design
    assert design_key(d) == design_key(r) != design_key(default_design())


@pytest.mark.parametrize(
    "change, expected",
    [
        ({"chambers": [{}, {}, {}]}, ["chambers: 2D takes 2 chambers", "dimension = 3", "got 3"]),
        ({"chambers": [{}]}, ["chambers: 2D takes 2 chambers", "got 1"]),
        ({"chambers": [{}, {"temperature": 400.0}]}, ["chambers.1.temperature", "[273.15, 373.15]", "400"]),
        ({"chambers": [{"temperature": 250.0}, {}]}, ["chambers.0.temperature", "[273.15, 373.15]"]),
        ({"chambers": [{}, {"cavity_width": 10.0}]}, ["chambers.1.cavity_width", "do not fit", ">= 16.2 mm"]),
        ({"cavity_length": 20.0}, ["cavity_length", "chamber 0's particles do not fit", ">= 32.3 mm"]),
        ({"cavity_width": 40.0}, ["cavity_width: not with chambers"]),
        ({"chambers": [{}, {"particle_diameter": 0.3}]}, ["chambers.1.particle_diameter", "> 4 clearance"]),
        ({"chamber_wall_thickness": 0.5}, ["chamber_wall_thickness: too thin for mesh.size 4 mm", ">= 2 mm"]),
        ({"chambers": [{}, {"hydrogel": {"A0": float("nan")}}]}, ["chambers.1.hydrogel.A0", "finite"]),
        ({"chambers": [{}, {"colour": 1}]}, ["chambers.1.colour: unknown key"]),
        ({"strain_limit_position": "top"}, ["strain_limit_position", "'-x'", "'middle'"]),
        ({"dimension": 3, "chambers": [{}, {}, {}, {}]}, ["chambers: 3D takes 2 chambers", "or 3 round the axis"]),
        ({"dimension": 3, "chambers": [{}, {"particle_diameter": 20.0}], "cavity_depth": 17.0},
         ["cavity_depth: chamber 1's particles do not fit", ">= 20.2 mm"]),
        ({"dimension": 3, "strain_limit_width": 8.0}, ["strain_limit_width: not with chambers"]),
        ({"stimulus": {"schedule": [[0, 300], [60, 275]]}}, ["stimulus.schedule: not with chambers"]),
    ],
)
def test_bad_chambers_are_refused_naming_the_field(change, expected):
    data = {**TWO, **change}
    with pytest.raises(DesignError) as info:
        design_from_dict(data)
    msg = str(info.value)
    assert "\n" not in msg
    for part in expected:
        assert part in msg, msg


@pytest.mark.parametrize("field, value", [("strain_limit_position", "middle"), ("chamber_wall_thickness", 3.0)])
def test_multi_chamber_fields_need_chambers(field, value):
    with pytest.raises(DesignError, match=f"{field}: only with chambers"):
        design_from_dict({field: value})


@pytest.mark.parametrize("where, groups", [("none", 0), ("-x", 1), ("+x", 1), ("middle", 1)])
def test_two_chamber_geometry(where, groups):
    """The meshed walls and cavities have the areas the layout gives, the strain-limit layer
    sits where asked, and the shared wall's mid-line x = 0 is a line of nodes end to end."""
    from hydrojam.actuator.geometry import actuator_2d_chambers, chamber_layout
    from hydrojam.actuator.model import _centreline
    from hydrojam.fem.elements import element_for_meshio_type
    from hydrojam.fem.assembly import Block, Solid
    from hydrojam.materials.energies import NeoHookean

    d = design_from_dict({**TWO, "strain_limit_position": where}).resolved()
    mesh = actuator_2d_chambers(d)
    assert ("strain_limit_layer" in mesh.cell_groups) == bool(groups)
    el = element_for_meshio_type(mesh.cell_type)
    mat = NeoHookean(shear_modulus=1.0, poisson_ratio=0.3)

    def area(name):
        return float(Solid(mesh.points, [Block(mesh.cells[mesh.cell_groups[name]], el, mat, name)])
                     .current_volumes(mesh.points)[name].sum())

    L, h, wall = d.length, d.strain_limit_thickness, d.resolved_chamber_wall
    cavities = sum(x1 - x0 for x0, x1 in chamber_layout(d)) * d.resolved_cavity_length
    outer = (d.width - (h if where in ("-x", "+x") else 0.0)) * L
    sll = {"none": 0.0, "-x": h * L, "+x": h * L, "middle": wall * L}[where]
    # straight-sided cells: the areas are exact up to round-off of the coordinates
    tol = 1e-9 * d.width * L
    assert area("membrane") == pytest.approx(outer - cavities - (sll if where == "middle" else 0.0), abs=tol)
    if groups:
        assert area("strain_limit_layer") == pytest.approx(sll, abs=tol)
        xs = mesh.points[np.unique(mesh.cells[mesh.cell_groups["strain_limit_layer"]])][:, 0]
        if where == "middle":
            assert xs.min() == pytest.approx(-wall / 2) and xs.max() == pytest.approx(wall / 2)
        elif where == "-x":
            assert xs.max() < chamber_layout(d)[0][0]
        else:
            assert xs.min() > chamber_layout(d)[1][1]
    line = mesh.points[_centreline(mesh, d)]
    assert np.all(np.abs(line[:, 0]) < 1e-9 * L)
    assert line[0, 1] == pytest.approx(0.0, abs=1e-9 * L) and line[-1, 1] == pytest.approx(-L)
    assert np.all(np.diff(line[:, 1]) < 0)


@pytest.mark.parametrize("where", ["-x", "middle"])
def test_two_chamber_geometry_in_3d(where):
    """The 3D half model: walls and strain-limit layer of the volumes the layout gives (the half
    y >= 0), the cut faces on y = 0, and the shared wall's mid-line on y = 0 a line of nodes."""
    from hydrojam.actuator.geometry import actuator_3d_chambers, chamber_layout
    from hydrojam.actuator.model import _centreline
    from hydrojam.fem.assembly import Block, Solid
    from hydrojam.fem.elements import element_for_meshio_type
    from hydrojam.materials.energies import NeoHookean

    d = design_from_dict({**TWO, "dimension": 3, "particle_layers": 1, "strain_limit_position": where}).resolved()
    mesh = actuator_3d_chambers(d)
    el = element_for_meshio_type(mesh.cell_type)
    mat = NeoHookean(shear_modulus=1.0, poisson_ratio=0.3)

    def volume(name):
        return float(Solid(mesh.points, [Block(mesh.cells[mesh.cell_groups[name]], el, mat, name)])
                     .current_volumes(mesh.points)[name].sum())

    L, h, wall = d.length, d.strain_limit_thickness, d.resolved_chamber_wall
    depth = d.resolved_cavity_depth / 2 + d.side_wall_thickness  # the half y >= 0
    cavities = sum(x1 - x0 for x0, x1 in chamber_layout(d)) * d.resolved_cavity_length * d.resolved_cavity_depth / 2
    outer = (d.width - (h if where == "-x" else 0.0)) * L * depth
    sll = (h if where == "-x" else wall) * L * depth
    tol = 1e-9 * d.width * L * depth  # flat-faced cells: exact to round-off
    assert volume("membrane") == pytest.approx(outer - cavities - (sll if where == "middle" else 0.0), abs=tol)
    assert volume("strain_limit_layer") == pytest.approx(sll, abs=tol)
    assert np.all(np.abs(mesh.points[mesh.group_nodes("symmetry"), 1]) < 1e-9 * L)
    line = mesh.points[_centreline(mesh, d)]
    assert np.all(np.abs(line[:, :2]) < 1e-9 * L)
    assert line[-1, 2] == pytest.approx(-L)


# ------------------------------------------------------------------------------------------------ metrics


def _face(n=5):
    """A square free-end face in the plane z = -L: its nodes (n*n, 3) [mm]."""
    g = np.linspace(-5.0, 5.0, n)
    return np.array([(x, y, -40.0) for x in g for y in g])


@pytest.mark.parametrize("bend, direction, twist", [(30.0, 180.0, 0.0), (30.0, 0.0, 12.0), (60.0, 90.0, -25.0),
                                                   (10.0, -135.0, 40.0), (150.0, 45.0, 5.0)])
def test_swing_twist_of_a_rigid_rotation(bend, direction, twist):
    """A face twisted by psi about z, then swung by theta toward the direction phi in x-y, reads
    back (phi, psi) from its nodes: the rotation is found by least squares from positions, so
    the tolerance is the round-off of the positions (1e-12 of the face's size) over its size."""
    phi, th, ps = np.radians([direction, bend, twist])
    # the free end's outward axis -e_z swings toward (cos phi, sin phi, 0): about (sin phi, -cos phi, 0)
    R = _rot([math.sin(phi), -math.cos(phi), 0.0], th) @ _rot([0, 0, 1], ps)
    X = _face()
    x = (X - X.mean(axis=0)) @ R.T + X.mean(axis=0) + np.array([1.0, -2.0, 3.0])
    got_plane, got_twist = swing_twist_deg(face_rotation_matrix(X, x))
    tol = math.degrees(1e-10)
    assert got_plane == pytest.approx(direction, abs=tol) and got_twist == pytest.approx(twist, abs=tol)


def test_a_straight_face_has_no_plane_and_a_half_turn_no_twist():
    X = _face()
    assert swing_twist_deg(face_rotation_matrix(X, X)) == (None, 0.0)
    plane, twist = swing_twist_deg(_rot([0, 1, 0], math.pi))
    assert twist is None and plane == pytest.approx(180.0, abs=1e-6)


def test_a_mirror_symmetric_bend_has_no_twist():
    """A face bent toward -x and deformed symmetrically about y = 0 (each node's y scaled, x
    sheared by y^2) has no twist and bends in the plane 180 deg: the rotation of a face mirror-
    symmetric about y = 0 has no component about x or z, so both hold to round-off; tolerance
    1e-9 deg."""
    X = _face()
    R = _rot([0, 1, 0], math.radians(40.0))
    x = (X - X.mean(axis=0)) @ R.T
    x[:, 1] *= 1.3
    x[:, 0] += 0.01 * X[:, 1] ** 2
    plane, twist = swing_twist_deg(face_rotation_matrix(X, x))
    assert plane == pytest.approx(180.0, abs=1e-9) and twist == pytest.approx(0.0, abs=1e-9)


# ------------------------------------------------------------------------------------------------ symmetry


@pytest.mark.slow
def test_two_chambers_bend_by_symmetry():
    """Two chambers without a strain-limit layer, PNIPAM on one side and the shifted gel on the
    other, at 300 K (PNIPAM swollen, the other collapsed): the actuator bends away from the
    swollen side, and swapping the gels mirrors the angle; two identical chambers stay straight.

    The mesh is not mirror-symmetric, so both hold within its discretisation error: quadratic
    elements' strains err by O((h/d)^2), and so does the bending they drive, hence the tolerance
    |theta| (h/d)^2 of the one-sided design's angle (h = mesh.size, d = particle diameter).
    """
    from hydrojam.actuator.model import build_model
    from hydrojam.actuator.simulate import simulate

    base = {"particle_layers": 1, "strain_limit_position": "none", "mesh": {"size": 4.0},
            "stimulus": {"temperature": 300.0}}
    angle = {}
    for name, chambers in (("AB", [{}, {"hydrogel": SHIFTED}]), ("BA", [{"hydrogel": SHIFTED}, {}]),
                           ("AA", [{}, {}])):
        result = simulate(build_model(design_from_dict({**base, "chambers": chambers})))
        assert result.metrics["converged"], name
        angle[name] = result.metrics["bending_angle_deg"]
    tol = abs(angle["AB"]) * (4.0 / 16.0) ** 2
    assert angle["AB"] < -5.0  # toward +x, away from the swollen PNIPAM chamber on -x
    assert abs(angle["AB"] + angle["BA"]) <= tol, angle
    assert abs(angle["AA"]) <= tol, angle


@pytest.mark.parametrize("dimension", [2, 3])
def test_nothing_moves_at_the_as_prepared_stimulus(dimension):
    """Two chambers of PNIPAM at their as-prepared stimulus (mu0, T0): stress-free and contact-free,
    so no node moves (the bound of tests/actuator/undeformed.py) and the free end neither swings
    nor twists."""
    from hydrojam.actuator.model import build_model
    from hydrojam.actuator.simulate import simulate

    gel = default_design().hydrogel
    model = build_model(design_from_dict({**TWO, "dimension": dimension, "particle_layers": 1,
                                          "chambers": [{}, {}], "stimulus": {"mu": gel.mu0, "temperature": gel.T0}}))
    res = simulate(model)
    drift = assert_nothing_moved(model, res)
    m = res.metrics
    assert m["bending_plane_deg"] is None and abs(m["twist_deg"]) < math.degrees(2 * drift / model.design.width)
    assert abs(m["tip_dy_mm"]) < drift


def test_an_assessment_refuses_chambers():
    from hydrojam.assess.assessment import check_assessable

    with pytest.raises(DesignError, match="chambers: an assessment takes one chamber"):
        check_assessable(design_from_dict(TWO))


def test_each_chamber_follows_its_own_path_to_its_own_temperature():
    """Each chamber's gel starts at its own as-prepared stimulus (mu0 of its gel, T0) and ends at
    (mu, its temperature): the first at stimulus.temperature, the second at its own."""
    from hydrojam.actuator.model import PARTICLES, build_model, particle_block

    model = build_model(design_from_dict({**TWO, "particle_layers": 1,
                                          "chambers": [{}, {"hydrogel": SHIFTED, "temperature": 290.0}]}))
    start, end = model.materials_at(0.0), model.materials_at(1.0)
    first, second = PARTICLES, particle_block(1)
    gels = model.design.resolved_chambers
    for name, chamber, T in ((first, gels[0], 275.0), (second, gels[1], 290.0)):
        assert start[name].T == pytest.approx(chamber.hydrogel.T0) and start[name].mu == pytest.approx(
            start[name].params.mu0)
        assert end[name].T == pytest.approx(T) and end[name].mu == 0.0
    assert start[second].T == 290.0 != start[first].T  # two gels, each prepared at its own T0
    assert "strain_limit_layer" not in start


def test_the_bilateral_example_study_is_two_chambers_of_two_gels():
    """examples/bilateral_study.toml (docs/chambers.md): every point two chambers, PNIPAM on -x and
    the second gel (10 K colder, half the crosslinks) on +x, from 275 to 310 K."""
    from pathlib import Path

    from hydrojam.study.spec import load_study

    study = load_study(Path(__file__).parents[2] / "examples" / "bilateral_study.toml")
    points = study.points()
    assert [p.design.stimulus.temperature for p in points] == [275, 280, 285, 290, 295, 300, 305, 310]
    for p in points:
        a, b = p.design.resolved_chambers
        assert a.hydrogel == default_design().hydrogel
        assert (b.hydrogel.T0, b.hydrogel.n) == (290.0, 0.005) and b.hydrogel.A0 == pytest.approx(SHIFTED["A0"])
