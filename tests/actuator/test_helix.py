"""The helical strain-limit strip (``strain_limit_helix_deg``): its refusals, its geometry against
its sections' areas, and its elastic twist against a beam model (docs/chambers.md, "A helical
strip")."""

from __future__ import annotations

import numpy as np
import pytest

from hydrojam.actuator.design import design_from_dict
from hydrojam.actuator.geometry import actuator_3d
from hydrojam.study.spec import design_key

from eigenstrain import cell_volume, isotropic_stiffness, rigid_rotation, solve_eigenstrain
from helix_beam import free_end_rotation, strip_volume
from refusals import refusal

#: a small tube with a strip 6 mm wide, 2 mm walls and strip [mm]; the design's -x face is 14 mm wide
GEOMETRY = dict(cavity_width=10.0, cavity_depth=10.0, cavity_length=40.0, side_wall=2.0, end_wall=2.0,
                strain_limit=2.0, strip_width=6.0)
SIZE = 2.5  # mesh size [mm]
HELIX = 15.0  # [deg]

_WOUND = {"dimension": 3, "mesh": {"symmetry": False, "size": 4.0}, "strain_limit_width": 8.0}


@pytest.mark.parametrize(
    ("data", "expected"),
    [
        ({"strain_limit_helix_deg": 30.0}, ["strain_limit_helix_deg", "dimension = 3"]),
        ({**_WOUND, "mesh": {"symmetry": True}, "strain_limit_helix_deg": 30.0},
         ["strain_limit_helix_deg", "mesh.symmetry = false"]),
        ({**_WOUND, "strain_limit_width": None, "strain_limit_helix_deg": 30.0},
         ["strain_limit_helix_deg", "strain_limit_width"]),
        # a strip 8 mm wide on the default's 20.2 mm face winds at most acos(8/20.2) = 66.67 deg
        ({**_WOUND, "strain_limit_helix_deg": 70.0}, ["strain_limit_helix_deg", "[-66.6692, 66.6692]", "at 70 deg"]),
        ({**_WOUND, "strain_limit_helix_deg": -70.0}, ["strain_limit_helix_deg", "66.6692]", "at -70 deg"]),
        ({**_WOUND, "strain_limit_helix_deg": 90.0}, ["strain_limit_helix_deg", "< 90"]),
        ({**_WOUND, "strain_limit_width": None, "strain_limit_helix_deg": 30.0, "chambers": [{}, {}]},
         ["strain_limit_helix_deg", "not with chambers"]),
    ],
)
def test_a_helix_that_cannot_be_wound_is_refused(data, expected):
    data = {k: v for k, v in data.items() if v is not None}
    msg = refusal(data)
    for part in expected:
        assert part in msg, msg


def test_the_straight_strip_keeps_its_key():
    plain = design_from_dict({"dimension": 3, "mesh": {"symmetry": False}, "strain_limit_width": 8.0})
    zero = design_from_dict({"dimension": 3, "mesh": {"symmetry": False}, "strain_limit_width": 8.0,
                             "strain_limit_helix_deg": 0.0})
    wound = design_from_dict({**_WOUND, "strain_limit_helix_deg": 30.0})
    assert design_key(zero) == design_key(plain)
    assert design_key(wound) != design_key(plain)
    assert design_from_dict(_WOUND).max_helix_angle_deg() == pytest.approx(np.degrees(np.arccos(8.0 / 20.2)))


def _mesh(helix_deg: float):
    g = GEOMETRY
    return actuator_3d(g["cavity_width"], g["cavity_depth"], g["cavity_length"], g["side_wall"], g["end_wall"],
                       g["strain_limit"], np.zeros((0, 3)), 1.0, SIZE, symmetry=False,
                       strain_limit_width=g["strip_width"], strain_limit_helix_deg=helix_deg)


def _free_end_rotation(helix_deg: float):
    """The free end's rotation [rad] of the meshed walls, the membrane under the axial eigenstrain
    1e-2, both elastomers G = 1 MPa, nu = 0.3; and the strip's meshed volume [mm^3]."""
    mesh = _mesh(helix_deg)
    eps0 = np.array([0.0, 0.0, 1e-2, 0.0, 0.0, 0.0])
    C = isotropic_stiffness(1.0, 0.3)
    u = solve_eigenstrain(mesh, {"membrane": (C, eps0), "strain_limit_layer": (C, np.zeros(6))},
                          np.unique(mesh.facet_groups["clamp"]))
    end = np.unique(mesh.facet_groups["free_end"])
    return rigid_rotation(mesh.points[end], u[end]), cell_volume(mesh, "strain_limit_layer")


@pytest.mark.slow
def test_a_helical_strip_twists_as_the_beam_model_bounds():
    """+a and -a twist the tube by opposite angles and bend it as mirror images; the twist has
    the beam model's sign and at most its size, the bending its size (module helix_beam)."""
    plus, volume = _free_end_rotation(HELIX)
    minus, _ = _free_end_rotation(-HELIX)
    # the strip where the turning band cuts the sleeve: the grid's error is below 1e-4 (measured
    # 3e-5 against a grid of half the cell); the loft through sections every 10 deg and the
    # quadratic tetrahedra's faces on it add their own, as small
    assert volume == pytest.approx(strip_volume(GEOMETRY, HELIX, dx=0.05, nz=100), rel=1e-3)
    # the two meshes are not mirror images: their discretisation errors, O((h / cavity width)^2)
    # of the largest rotation, differ
    tol = np.abs(plus).max() * (SIZE / GEOMETRY["cavity_width"]) ** 2
    np.testing.assert_allclose(minus, plus * np.array([-1.0, 1.0, -1.0]), atol=tol)
    beam = free_end_rotation(GEOMETRY, HELIX, 1.0, 0.3, 1.0, 1e-2)
    # bending: the plane sections of the beam fail within about the section's half-width
    # (9 mm) of each end, 18 mm of the 44 mm; its error is that fraction of the rotation, 0.2
    np.testing.assert_allclose(plus[:2], beam[:2], rtol=0.2)
    # twist: the beam's narrow strip carries stress only along itself, an upper bound on the
    # coupling; the strip bonded across its 6 mm width carries some across it as well
    assert np.sign(plus[2]) == np.sign(beam[2]) == 1.0
    assert 0.0 < plus[2] / beam[2] <= 1.0 + (SIZE / GEOMETRY["cavity_width"]) ** 2


def test_the_helix_example_study_winds_one_strip_at_four_angles():
    """examples/helix_study.toml (docs/chambers.md, "Twist against the angle"): every point the
    whole actuator in 3D with an 8 mm strip, at 0, 15, 30 and 45 deg."""
    from pathlib import Path

    from hydrojam.study.spec import load_study

    study = load_study(Path(__file__).parents[2] / "examples" / "helix_study.toml")
    points = list(study.points())
    assert [p.design.helix_angle_deg for p in points] == [0.0, 15.0, 30.0, 45.0]
    for p in points:
        assert p.design.dimension == 3 and not p.design.mesh.symmetry and p.design.strain_limit_width == 8.0
