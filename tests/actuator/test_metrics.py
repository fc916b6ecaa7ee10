"""Verification of the actuator metrics (docs/actuator.md, "Metrics") against closed-form motions.

Sign convention under test: in the (x right, z up) plane, with the clamp at z = 0 and the free end
at z = -L, bending toward the strain-limit side (-x) is a clockwise rotation and counts positive.

Pure bending, derived here once: bend the neutral axis x = 0 (inextensible) into an arc of signed
radius R centred at (-R, 0), so that the tip swings to -x when R > 0. The material line at axial
position z (arc length -z from the clamp) turns by p = -z / R, and stays straight and normal to
the arc (plane sections stay plane). A point at lateral offset x lies along the outward normal
(cos p, -sin p) (which is +x at the clamp), at distance R + x from the centre:

    x' = -R + (R + x) cos p,    z' = -(R + x) sin p,    p = -z / R.

For R < 0 (bending toward +x) the centre is at (|R|, 0), a point lies at distance |R| - x from
it, and p < 0. The face at z = -L maps to a radial line turned clockwise by L / R; the centreline
has the signed curvature 1 / R.
"""

from __future__ import annotations

import numpy as np
import pytest

from hydrojam.actuator.metrics import (
    CentrelineProfile,
    bending_angle_deg,
    centreline_points,
    centreline_profile,
    contacts_per_particle,
    curling_index,
    face_rotation_deg,
    packing_fraction,
    polygon_area,
    tip_displacement,
    unwrapped_angle_deg,
)

L = 60.0  # actuator length [mm]
W = 10.0  # actuator width [mm]


def clockwise(points, angle_deg, centre=(0.0, 0.0)):
    """Rotate points clockwise by angle_deg about centre, in the (x right, z up) plane."""
    a = np.radians(angle_deg)
    c, s = np.cos(a), np.sin(a)
    rot = np.array([[c, s], [-s, c]])  # maps (1, 0) to (cos a, -sin a): clockwise
    centre = np.asarray(centre)
    return (np.asarray(points) - centre) @ rot.T + centre


def pure_bending(points, R):
    """The exact pure-bending map of the module docstring, signed radius R [mm]."""
    x, z = points[:, 0], points[:, 1]
    p = -z / R
    return np.column_stack((-R + (R + x) * np.cos(p), -(R + x) * np.sin(p)))


def jittered(a, b, n, rng, jitter=0.4):
    """n increasing points from a to b, spacing uneven by +-jitter of the mean."""
    h = 1.0 + jitter * rng.uniform(-1.0, 1.0, n - 1)
    return a + (b - a) * np.concatenate(([0.0], np.cumsum(h))) / h.sum()


def straight_line(n, rng, length=L):
    z = -jittered(0.0, length, n, rng)
    return np.column_stack((np.zeros(n), z))


def end_face(n, rng, length=L, width=W):
    x = jittered(-width / 2, width / 2, n, rng)
    return np.column_stack((x, np.full(n, -length)))


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


# --- rigid motions -----------------------------------------------------------------------------


def test_clockwise_rotation_is_positive():
    """Sign convention: a face turned clockwise (its +x end going down) by 30 deg gives +30 deg;
    the tip tangent of an arc centred at (-R, 0) swept by p = 0.5 rad turns by +0.5 rad."""
    X = np.array([[-5.0, -L], [5.0, -L]])
    x = np.array([[-5.0 * np.cos(np.pi / 6), -L + 5.0 * np.sin(np.pi / 6)],
                  [5.0 * np.cos(np.pi / 6), -L - 5.0 * np.sin(np.pi / 6)]])
    assert bending_angle_deg(X, x) == pytest.approx(30.0, abs=1e-10)
    assert bending_angle_deg(X[::-1], x[::-1]) == pytest.approx(30.0, abs=1e-10)  # node order is irrelevant

    R, p_end = 40.0, 0.5
    p = np.linspace(0.0, p_end, 11)
    arc = np.column_stack((-R + R * np.cos(p), -R * np.sin(p)))
    ref = np.column_stack((np.zeros_like(p), -R * p))
    prof = centreline_profile(ref, arc)
    assert arc[-1, 0] < 0.0  # the tip swung to -x, the strain-limit side
    # an angle from 2 mm segments of coordinates up to 40 mm: eps x 40 / 2 = 4.4e-15 rad per segment
    assert prof.rotation[-1] == pytest.approx(p_end, abs=1e-11)
    assert prof.curvature == pytest.approx(np.full_like(p, 1.0 / R), rel=1e-6)


@pytest.mark.parametrize("angle", [30.0, -45.0, 120.0])
def test_rigid_rotation_gives_the_angle(angle, rng):
    """Rigid rotation by `angle` about an arbitrary point: the face rotation, the bending angle of
    a whole straight actuator and every centreline rotation equal `angle` exactly (1e-10); the
    centroid moves by the rotation of its arm about the pivot; no curvature."""
    pivot = (3.7, -12.1)
    face = end_face(7, rng)
    assert face_rotation_deg(face, clockwise(face, angle, pivot)) == pytest.approx(angle, abs=1e-10)
    reversed_face = face[::-1]
    theta = bending_angle_deg(reversed_face, clockwise(reversed_face, angle, pivot))
    assert theta == pytest.approx(angle, abs=1e-10)

    centroid = face.mean(axis=0)
    expected = clockwise(centroid[None], angle, pivot)[0] - centroid
    assert tip_displacement(face, clockwise(face, angle, pivot)) == pytest.approx(tuple(expected), abs=1e-10)

    # the whole actuator: a 2D block of nodes and its straight centreline
    xs, zs = np.meshgrid(np.linspace(-W / 2, W / 2, 5), -jittered(0.0, L, 13, rng))
    block = np.column_stack((xs.ravel(), zs.ravel()))
    assert face_rotation_deg(block, clockwise(block, angle, pivot)) == pytest.approx(angle, abs=1e-10)
    line = straight_line(21, rng)
    prof = centreline_profile(line, clockwise(line, angle, pivot))
    # angles from 3 mm segments of coordinates up to 60 mm: eps x 60 / 3 = 4.4e-15 rad per segment
    assert np.allclose(prof.rotation, np.radians(angle), atol=1e-11, rtol=0)
    assert np.allclose(prof.curvature, 0.0, atol=1e-12)
    assert prof.total_rotation_deg == pytest.approx(0.0, abs=1e-10)
    assert np.allclose(prof.arc_length, prof.reference_arc_length, atol=1e-12)
    assert curling_index(prof) is None


def test_translation_gives_no_rotation_and_the_exact_displacement(rng):
    """Rigid translation by (d_x, d_z): bending angle 0, tip displacement (d_x, d_z)."""
    d = np.array([-2.5, 1.25])
    face = end_face(6, rng)
    assert bending_angle_deg(face, face + d) == pytest.approx(0.0, abs=1e-12)
    assert tip_displacement(face, face + d) == pytest.approx((-2.5, 1.25), abs=1e-12)
    line = straight_line(9, rng)
    prof = centreline_profile(line, line + d)
    assert isinstance(prof, CentrelineProfile)
    assert np.allclose(prof.rotation, 0.0, atol=1e-14) and np.allclose(prof.curvature, 0.0, atol=1e-14)


def test_half_turn_is_180_and_flip_keeps_order():
    """A 180 deg rotation reports +180 (range (-180, 180]); the current axis is oriented by the
    nodes' order, so a face rotated by 170 deg is not mistaken for -10 deg."""
    face = np.array([[-5.0, -L], [0.0, -L], [5.0, -L]])
    assert face_rotation_deg(face, clockwise(face, 180.0, (1.0, 2.0))) == pytest.approx(180.0, abs=1e-10)
    assert face_rotation_deg(face, clockwise(face, -180.0, (1.0, 2.0))) == pytest.approx(180.0, abs=1e-10)
    assert face_rotation_deg(face, clockwise(face, 170.0)) == pytest.approx(170.0, abs=1e-10)
    assert face_rotation_deg(face, clockwise(face, -170.0)) == pytest.approx(-170.0, abs=1e-10)


# --- pure bending ------------------------------------------------------------------------------


@pytest.mark.parametrize("R", [45.0, -45.0])
def test_uniform_arc_centreline(R, rng):
    """Pure bending of a straight centreline into an arc of signed radius R (41 unevenly spaced
    nodes): curvature 1/R everywhere (1e-3 rel), total rotation L/R, curling index 0.5, arc length
    L (inextensible neutral axis; 1e-6), bending angle of the end face L/R."""
    line = straight_line(41, rng)
    prof = centreline_profile(line, pure_bending(line, R))
    assert np.allclose(prof.curvature, 1.0 / R, rtol=1e-3, atol=0)
    assert np.radians(prof.total_rotation_deg) == pytest.approx(L / R, rel=1e-6)
    assert np.allclose(prof.rotation, -line[:, 1] / R, rtol=0, atol=1e-8)
    assert curling_index(prof) == pytest.approx(0.5, abs=1e-3)
    assert prof.reference_arc_length[-1] == pytest.approx(L, rel=1e-12)
    assert prof.arc_length[-1] == pytest.approx(L, rel=1e-6)

    face = end_face(5, rng)
    assert bending_angle_deg(face, pure_bending(face, R)) == pytest.approx(np.degrees(L / R), abs=1e-10)


@pytest.mark.parametrize("R", [25.0, -25.0])
def test_whole_cross_section_pure_bending(R, rng):
    """The exact pure-bending map applied to the whole 2D section (a point at offset x goes to
    the circle of radius R + x about (-R, 0)): the free-end face turns by L/R [deg], its centroid
    (offsets symmetric about the axis) moves by (-R (1 - cos(L/R)), L - R sin(L/R)); the
    centreline has curvature 1/R; bending toward +x (R < 0) gives negative angle and curvature."""
    xs = np.linspace(-W / 2, W / 2, 7)
    zs = -jittered(0.0, L, 31, rng)
    gx, gz = np.meshgrid(xs, zs)
    section = np.column_stack((gx.ravel(), gz.ravel()))
    bent = pure_bending(section, R)

    on_face = np.isclose(section[:, 1], -L)
    assert on_face.sum() == xs.size
    theta = bending_angle_deg(section[on_face], bent[on_face])
    assert theta == pytest.approx(np.degrees(L / R), abs=1e-10)
    assert np.sign(theta) == np.sign(R)

    p = L / R
    dx, dz = tip_displacement(section[on_face], bent[on_face])
    assert dx == pytest.approx(-R * (1.0 - np.cos(p)), abs=1e-10)
    assert dz == pytest.approx(L - R * np.sin(p), abs=1e-10)
    assert dx < 0.0 if R > 0 else dx > 0.0

    on_axis = np.isclose(section[:, 0], 0.0)
    prof = centreline_profile(section[on_axis], bent[on_axis])
    assert np.allclose(prof.curvature, 1.0 / R, rtol=1e-3, atol=0)
    assert np.all(np.sign(prof.curvature) == np.sign(R))
    # every material line z = const turns like the centreline tangent there
    inner = np.isclose(section[:, 1], zs[10])
    assert face_rotation_deg(section[inner], bent[inner]) == pytest.approx(np.degrees(-zs[10] / R), abs=1e-10)


def test_curled_arc_unwraps_beyond_half_turn(rng):
    """Arc with L/R = 5 rad > pi (a curled actuator): the profile's rotation grows monotonically to
    5 rad (286.5 deg, unwrapped), curvature 1/R; the end face's angle is L/R wrapped to
    (-180, 180], i.e. 286.48 - 360 deg."""
    length, R = 100.0, 20.0
    line = straight_line(161, rng, length=length)
    prof = centreline_profile(line, pure_bending(line, R))
    assert np.all(np.diff(prof.rotation) > 0.0)
    assert prof.total_rotation_deg == pytest.approx(np.degrees(length / R), rel=1e-6)
    assert prof.rotation.max() > np.pi
    assert np.allclose(prof.curvature, 1.0 / R, rtol=1e-3, atol=0)
    assert curling_index(prof) == pytest.approx(0.5, abs=1e-3)
    face = end_face(5, rng, length=length)
    wrapped = np.degrees(length / R) - 360.0
    angle = bending_angle_deg(face, pure_bending(face, R))
    assert angle == pytest.approx(wrapped, abs=1e-10)
    # the state metric: the turn picked by the centreline's unwrapped rotation at the free end
    end = np.degrees(prof.rotation[-1])
    assert unwrapped_angle_deg(angle, end) == pytest.approx(np.degrees(length / R), abs=1e-10)


@pytest.mark.parametrize("angle, near, expected", [(-170.4, 180.0, 189.6), (10.0, 5.0, 10.0), (170.0, -175.0, -190.0),
                                                   (179.0, 900.0, 899.0)])
def test_an_angle_is_unwrapped_to_the_turn_nearest_an_estimate(angle, near, expected):
    """The face's rotation modulo 360 deg, moved by whole turns to the one nearest the estimate."""
    assert unwrapped_angle_deg(angle, near) == pytest.approx(expected, abs=1e-9)


@pytest.mark.parametrize("grid", ["graded", "alternating"])
def test_tangent_and_curvature_second_order(grid):
    """Elliptic arc x = -A (1 - cos t), z = -B sin t (tangent down at the clamp): the tangent turns
    clockwise by atan2(A sin t, B cos t), the curvature is A B / (A^2 sin^2 t + B^2 cos^2 t)^(3/2).
    Halving the spacing cuts the rotation and curvature errors about 4 times: at every node on a
    smoothly graded grid; on a grid whose spacing alternates 1.3 h / 0.7 h, everywhere for the
    rotation and away from the two nodes at each end for the curvature (first order there)."""
    A, B, t_end = 30.0, 50.0, 1.2

    def errors(n):
        u = np.linspace(0.0, 1.0, n)
        if grid == "alternating":
            h = np.where(np.arange(n - 1) % 2 == 0, 1.3, 0.7)
            u = np.concatenate(([0.0], np.cumsum(h))) / h.sum()
        t = t_end * (u + 0.4 * u * (1.0 - u))  # spacing graded by a factor of ~2
        x = np.column_stack((-A * (1.0 - np.cos(t)), -B * np.sin(t)))
        X = np.column_stack((np.zeros(n), -B * t))  # straight reference, pointing down
        prof = centreline_profile(X, x)
        rot = np.arctan2(A * np.sin(t), B * np.cos(t))
        kappa = A * B / (A**2 * np.sin(t) ** 2 + B**2 * np.cos(t) ** 2) ** 1.5
        kappa_err = np.abs(prof.curvature - kappa) / kappa.max()
        if grid == "alternating":
            kappa_err = kappa_err[2:-2]
        return np.abs(prof.rotation - rot).max(), kappa_err.max()

    (r1, k1), (r2, k2) = errors(41), errors(81)
    assert r1 < 1e-4 and k1 < 1e-3
    assert r1 / r2 > 3.5
    assert k1 / k2 > 3.5


# --- curling index -----------------------------------------------------------------------------


def bent_in_part(s, start, stop, R):
    """Centreline (clamp at the origin, pointing down) straight except for an arc of radius R on
    arc lengths start..stop; s: node arc lengths. Exact positions, piece by piece."""
    s = np.asarray(s)
    out = np.empty((s.size, 2))
    before = s <= start
    out[before] = np.column_stack((np.zeros(before.sum()), -s[before]))
    p = (np.clip(s, start, stop) - start) / R
    on_arc = (s > start) & (s <= stop)
    arc = np.column_stack((-R + R * np.cos(p), -start - R * np.sin(p)))
    out[on_arc] = arc[on_arc]
    after = s > stop
    p_end = (stop - start) / R
    tangent = np.array([-np.sin(p_end), -np.cos(p_end)])
    out[after] = arc[after] + (s[after] - stop)[:, None] * tangent
    return out


@pytest.mark.parametrize("fraction", [0.2, 0.4, 0.7, 0.8, 1.0])
def test_curling_index_of_partly_bent_lines(fraction, rng):
    """Uniform arc over the clamp-side share f of the length, straight beyond: index
    min(1, 1/(2f)) (-> 1, curling); arc over the tip-side share f: index max(0, 1 - 1/(2f))
    (-> 0). Both are 0.5 for f = 1 (uniform bending)."""
    R = 30.0
    s = jittered(0.0, L, 81, rng, jitter=0.3)
    ref = np.column_stack((np.zeros_like(s), -s))
    clamp_side = centreline_profile(ref, bent_in_part(s, 0.0, fraction * L, R))
    tip_side = centreline_profile(ref, bent_in_part(s, (1.0 - fraction) * L, L, R))
    assert clamp_side.total_rotation_deg == pytest.approx(np.degrees(fraction * L / R), rel=1e-4)
    assert tip_side.total_rotation_deg == pytest.approx(np.degrees(fraction * L / R), rel=1e-4)
    assert curling_index(clamp_side) == pytest.approx(min(1.0, 0.5 / fraction), abs=2e-3)
    assert curling_index(tip_side) == pytest.approx(max(0.0, 1.0 - 0.5 / fraction), abs=2e-3)


def test_curling_index_limits_and_straight_line(rng):
    """Bent only near the clamp: exactly 1; only near the tip: exactly 0; a straight (or barely
    bent, total rotation < 1e-3 rad) line: None (undefined)."""
    s = jittered(0.0, L, 61, rng)
    ref = np.column_stack((np.zeros_like(s), -s))
    near_clamp = centreline_profile(ref, bent_in_part(s, 0.0, 0.25 * L, 10.0))
    near_tip = centreline_profile(ref, bent_in_part(s, 0.75 * L, L, 10.0))
    assert curling_index(near_clamp) == pytest.approx(1.0, abs=1e-9)
    assert curling_index(near_tip) == pytest.approx(0.0, abs=1e-9)
    assert curling_index(centreline_profile(ref, ref.copy())) is None
    slight = centreline_profile(ref, pure_bending(ref, L / 5e-4))
    assert curling_index(slight) is None


# --- areas and contacts ------------------------------------------------------------------------


def regular_polygon(n, r, centre=(0.0, 0.0)):
    a = 2.0 * np.pi * np.arange(n) / n
    return np.column_stack((centre[0] + r * np.cos(a), centre[1] + r * np.sin(a)))


def test_polygon_area():
    """Square of side 3: 9 in either sense; regular n-gon of circumradius r: (n/2) r^2 sin(2 pi/n)."""
    square = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 3.0], [0.0, 3.0]]) + [10.0, -7.0]
    assert polygon_area(square) == pytest.approx(9.0, rel=1e-14)
    assert polygon_area(square[::-1]) == pytest.approx(9.0, rel=1e-14)
    for n in (3, 6, 17):
        expected = 0.5 * n * 2.0**2 * np.sin(2.0 * np.pi / n)
        # shoelace off-centre: dot products of ~200 mm^2 cancel to 2 x area ~25 mm^2: n x eps x 8 = 3e-14 relative
        assert polygon_area(regular_polygon(n, 2.0, (4.0, -3.0))) == pytest.approx(expected, rel=1e-11)


def test_packing_fraction_of_a_disk_in_its_square():
    """A disk of radius r (as a 720-gon) in the square of side 2r: pi/4, up to the polygon's area
    error 1 - sin(2 pi/n) / (2 pi/n) ~ 1.3e-5."""
    r, n = 1.7, 720
    cavity = np.array([[-r, -r], [r, -r], [r, r], [-r, r]])
    phi = packing_fraction(polygon_area(regular_polygon(n, r)), polygon_area(cavity))
    assert phi == pytest.approx(np.pi / 4, rel=2e-5)
    with pytest.raises(ValueError):
        packing_fraction(1.0, 0.0)


def test_contacts_per_particle_hand_count():
    """Particles 1, 2, 3 (walls 'left', 'floor'): contacts 1-2, 2-3 (particle pairs, twice each),
    1-left, 3-floor, 3-left (once each), left-floor (no particle): Z = (2*2 + 3)/3 = 7/3."""
    pairs = [(1, 2), (2, 3), (1, "left"), ("floor", 3), (3, "left"), ("left", "floor")]
    assert contacts_per_particle(pairs, [1, 2, 3]) == pytest.approx(7.0 / 3.0, rel=1e-15)
    assert contacts_per_particle(iter(pairs), {1, 2, 3, 4}) == pytest.approx(7.0 / 4.0, rel=1e-15)
    assert contacts_per_particle(pairs, []) == 0.0
    assert contacts_per_particle([], [1, 2]) == 0.0


def test_shape_errors():
    """Mismatched or malformed arrays are refused."""
    with pytest.raises(ValueError):
        face_rotation_deg(np.zeros((3, 2)), np.zeros((4, 2)))
    with pytest.raises(ValueError):
        centreline_profile(np.zeros((3, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError):
        centreline_profile(np.zeros((1, 2)), np.zeros((1, 2)))


# ---------------------------------------------------------------------------------------------
# the registry of metric names: the single definition every output derives from


def test_registry_names_are_unique_and_typed():
    from hydrojam.actuator.metrics import HISTORY_FIELDS, RUN_FIELDS, STATE_METRICS, metric, metric_names

    names = [m.name for m in (*STATE_METRICS, *RUN_FIELDS)]
    assert len(names) == len(set(names)) and metric_names() == names
    history = [m.name for m in HISTORY_FIELDS]
    assert len(history) == len(set(history))
    for m in (*STATE_METRICS, *RUN_FIELDS, *HISTORY_FIELDS):
        assert m.type in (bool, int, float, str) and m.description and m.kind in ("state", "run", "step")
    assert all(m.kind == "state" for m in STATE_METRICS) and all(m.kind == "run" for m in RUN_FIELDS)
    assert metric("bending_angle_deg").unit == "deg" and metric("tip_dx_mm").label == "tip_dx_mm [mm]"
    with pytest.raises(KeyError, match="no such metric"):
        metric("bending_angle")


def test_measure_and_run_metrics_have_exactly_the_registry_keys():
    """model.measure returns the state metrics and SimulationResult.metrics the state metrics
    then the run fields, each in the registry's order: nothing restates a name the registry lacks."""
    from hydrojam.actuator.design import apply_overrides, default_design
    from hydrojam.actuator.metrics import RUN_FIELDS, STATE_METRICS
    from hydrojam.actuator.model import build_model, measure
    from hydrojam.actuator.simulate import SimulationResult, StepState

    model = build_model(apply_overrides(default_design(), ["particle_layers=1", "mesh.size=4"]))
    X = model.mesh.points
    measured = measure(model, X)
    assert list(measured) == [m.name for m in STATE_METRICS]
    mu, T = model.stimulus(0.0)
    state = StepState(0, 0.0, mu, T, X.copy(), measured, 0, 0.0)
    result = SimulationResult(model, [state], True, "converged", 0.0, 0, 0, {"total": 0.0}, {})
    assert list(result.metrics) == [m.name for m in (*STATE_METRICS, *RUN_FIELDS)]
    for m in (*STATE_METRICS, *RUN_FIELDS):
        value = result.metrics[m.name]
        assert value is None or isinstance(value, m.type) or (m.type is float and type(value) is int), m.name


@pytest.mark.parametrize("R, p_end", [(40.0, 0.5), (-25.0, 1.2), (12.0, 4.0)])
def test_centreline_points_rebuild_a_circular_arc_exactly(R, p_end):
    """An arc of signed radius R from the clamp at (x0, 0), curled past 180 degrees in one case,
    on even nodes (on uneven ones the profile's own arc length is exact only to second order, its
    first pass spacing the nodes by chords): its profile's arc length and rotation give its nodes
    back. Each segment is
    taken as an arc, so only round-off remains: some 100 operations on coordinates up to 50 mm,
    about 1e-12 mm; the bound 1e-9 of the arc's length is far above that and far below a real
    error (the chord without its sin(d/2)/(d/2) factor is off by about a length x d^2 / 24, 1e-3 of
    it here)."""
    x0 = -12.0
    S = np.linspace(0.0, abs(R) * p_end, 23)  # reference arc length
    p = S / R
    arc = np.column_stack((x0 - R + R * np.cos(p), -R * np.sin(p)))
    ref = np.column_stack((np.full_like(p, x0), -S))
    prof = centreline_profile(ref, arc)
    got = centreline_points(prof.arc_length, prof.rotation, start=(x0, 0.0))
    assert np.abs(got - arc).max() <= 1e-9 * abs(R * p_end)
    assert got[0] == pytest.approx((x0, 0.0), abs=0.0)


def test_centreline_points_converge_at_second_order_on_a_varying_curvature():
    """A line whose rotation is a s + b s^2 / 2 + c sin(s / 15) (curvature varying and changing
    sign), its nodes integrated to 1e-13 by quadrature: the round trip through centreline_profile
    and centreline_points is second order, the error falling about 4x (measured 4.2, 4.0) each time
    the spacing halves, and under 0.1 % of the length at 4 mm spacing (measured 0.055 mm of 100)."""
    from scipy.integrate import quad

    length = 100.0

    def rotation(s):
        return 0.01 * s + 1e-4 * s * s + 0.3 * np.sin(s / 15.0)

    def node(s):
        return [quad(lambda t: f(rotation(t)), 0.0, s, epsabs=1e-13, epsrel=1e-13)[0]
                for f in (lambda r: -np.sin(r), lambda r: -np.cos(r))]

    errors = []
    for m in (26, 51, 101):
        S = np.linspace(0.0, length, m)
        x = np.array([node(s) for s in S])
        prof = centreline_profile(np.column_stack((np.zeros(m), -S)), x)
        errors.append(np.abs(centreline_points(prof.arc_length, prof.rotation) - x).max())
    assert errors[0] < 1e-3 * length
    assert errors[0] / errors[1] > 3.0 and errors[1] / errors[2] > 3.0


def test_centreline_points_refuse_mismatched_columns():
    with pytest.raises(ValueError, match="one length"):
        centreline_points([0.0, 1.0], [0.0])


def test_column_folds_reads_a_column_out_of_its_line():
    """column_folds on an arc of radius 40 mm (the strain-limit layer's mid-line) with layer centres
    20 mm outside it, 24 deg apart (about a 16 mm particle's pitch): 0 for the arc; 1 with one layer
    pushed 20 mm further out (more than d/2 = 8 mm beyond the median distance), as in the folded 3D
    column; 1 with one layer set beside the one before (no advance along the line)."""
    from hydrojam.actuator.metrics import column_folds

    s = np.linspace(0.0, np.radians(150.0), 200)
    line = np.column_stack([40.0 * (1.0 - np.cos(s)), -40.0 * np.sin(s)])
    phi = np.radians(np.array([12.0, 36.0, 60.0, 84.0, 108.0]))
    centre = lambda r, p: np.column_stack([40.0 - r * np.cos(p), -r * np.sin(p)])  # noqa: E731
    arc = centre(60.0, phi)
    assert column_folds(arc, line, 16.0) == 0
    out = arc.copy()
    out[3] = centre(80.0, phi[3:4])[0]
    assert column_folds(out, line, 16.0) == 1
    beside = arc.copy()
    beside[4] = centre(60.0, phi[3:4] + np.radians(2.0))[0]  # 1.3 mm along the line beyond layer 3
    assert column_folds(beside, line, 16.0) == 1
    assert column_folds(arc[:1], line, 16.0) == 0
