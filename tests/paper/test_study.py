"""The paper's Section IV study (hydrojam.paper.study): point sets, base design, the Study."""

from __future__ import annotations

import pytest

from hydrojam.actuator.design import apply_overrides, default_design
from hydrojam.paper import study as pstudy


def test_point_sets_full_and_quick():
    full, quick = pstudy.paper_points(False), pstudy.paper_points(True)
    assert full == {"temperature": {"stimulus.temperature": [275.0, 280.0, 285.0, 290.0, 295.0]},
                    "particle_layers": {"particle_layers": list(range(5, 20))},
                    "strain_limit_thickness": {"strain_limit_thickness": [4.0, 6.0, 8.0, 10.0, 12.0]}}
    assert quick == {"temperature": {"stimulus.temperature": [275.0, 285.0, 295.0]},
                     "particle_layers": {"particle_layers": [5, 7, 9, 11, 15, 19]},
                     "strain_limit_thickness": {"strain_limit_thickness": [4.0, 8.0, 12.0]}}
    assert sum(len(v) for s in full.values() for v in s.values()) == 25
    assert pstudy.paper_base(False) == default_design()
    assert pstudy.paper_base(True).mesh.size == pstudy.QUICK_MESH_SIZE == 4.0
    assert pstudy.paper_base(True) == apply_overrides(default_design(), ["mesh.size=4.0"])


@pytest.mark.parametrize("quick", [False, True])
def test_base_point_is_the_same_design_in_every_sweep(quick):
    """Each sweep's value at the base equals the base design exactly (types included), so the
    sweep machinery runs it once (one key)."""
    base = pstudy.paper_base(quick)
    for sweep in pstudy.paper_points(quick).values():
        ((field, values),) = sweep.items()
        at_base = [v for v in values if v == {"stimulus.temperature": 275.0, "particle_layers": 5,
                                               "strain_limit_thickness": 8.0}[field]]
        assert len(at_base) == 1
        assert apply_overrides(base, [f"{field}={at_base[0]!r}"]) == base


@pytest.mark.parametrize("quick, distinct", [(False, 23), (True, 10)])
def test_paper_study(quick, distinct):
    """25 (12) points, 23 (10) distinct designs: the base point is one key in all three sweeps."""
    study_mod = pytest.importorskip("hydrojam.study.spec")
    study = pstudy.paper_study(quick)
    assert isinstance(study, study_mod.Study)
    assert study.base == pstudy.paper_base(quick)
    assert {s.name: s.vary for s in study.sweeps} == pstudy.paper_points(quick)
    points = study.points()
    assert len(points) == distinct + 2 and len({p.key for p in points}) == distinct
    base_key = study_mod.design_key(study.base)
    assert {p.sweep for p in points if p.key == base_key} == {s.name for s in pstudy.PAPER_SWEEPS}
    assert all(p.design.mesh.size == (pstudy.QUICK_MESH_SIZE if quick else 2.0) for p in points)
