"""The 2D-against-3D table of hydrojam.paper.compare, from small synthetic results tables, and the
reading of a 2D study's folder. No simulation runs."""

from __future__ import annotations

import pytest
from paper_synthetic import Table, row

from hydrojam.materials.swelling import free_swelling
from hydrojam.paper import compare as pcompare, study as pstudy

BASE_3D = pstudy.paper_base(True, dimension=3)


def _tables():
    """2D and 3D rows of a few quick points: at 275 K 3D bends less, at 285 K about as much, at
    295 K both straight; PL 7 shortens in 2D (tip up) but bends down in 3D; h 12 mm failed in 3D;
    PL 9 only in 3D."""
    two = [row("temperature", "stimulus.temperature", 275.0, 70.0, -45.0, -10.0),
           row("temperature", "stimulus.temperature", 285.0, 40.0, -25.0, -5.0),
           row("temperature", "stimulus.temperature", 295.0, 1.0, -0.5, -0.2),
           row("particle_layers", "particle_layers", 5, 70.0, -45.0, -10.0),
           row("particle_layers", "particle_layers", 7, 20.0, 2.0, 3.0),
           row("strain_limit_thickness", "strain_limit_thickness", 12.0, 80.0, -50.0, -12.0)]
    three = [row("temperature", "stimulus.temperature", 275.0, 50.0, -30.0, -8.0),
             row("temperature", "stimulus.temperature", 285.0, 41.0, -24.0, -5.0),
             row("temperature", "stimulus.temperature", 295.0, 0.5, -0.1, -0.1),
             row("particle_layers", "particle_layers", 5, 50.0, -30.0, -8.0),
             row("particle_layers", "particle_layers", 7, 35.0, -20.0, -6.0),
             row("particle_layers", "particle_layers", 9, 30.0, -15.0, -6.0),
             row("strain_limit_thickness", "strain_limit_thickness", 12.0, 0, 0, 0, status="failed")]
    return Table(three), Table(two)


def test_compare_points_pairs_the_same_designs_and_says_what_changes():
    three, two = _tables()
    points = pcompare.compare_points(three, two, BASE_3D)
    labels = [p.label for p in points]
    # the base point (in the temperature and the particle-layer sweeps) once, in the sweeps' order
    assert labels == ["base: T 275 K, PL 5, h 8 mm", "T = 285 K", "T = 295 K", "PL = 7", "PL = 9", "h = 12 mm"]
    by = dict(zip(labels, points))
    base = by["base: T 275 K, PL 5, h 8 mm"]
    assert base.row_2d["bending_angle_deg"] == 70.0 and base.row_3d["bending_angle_deg"] == 50.0
    assert base.change.startswith("bends less in 3D (θ -20.0°, -29 %)") and "hoop stretch" in base.change
    cyl, sph = base.stretches
    assert "2.16x" in base.change and "2.59x" in base.change
    assert sph == pytest.approx(free_swelling(BASE_3D.hydrogel.params(), 0.0, 275.0).stretch_rel)
    assert sph == pytest.approx(2.1602, abs=1e-3) and cyl == pytest.approx(2.5858, abs=1e-3)
    assert by["T = 285 K"].change.startswith("bends about as much in 3D (θ +1.0°)")
    assert by["T = 295 K"].change.startswith("both nearly straight")
    pl7 = by["PL = 7"].change
    assert pl7.startswith("bends more in 3D") and "the 2D chamber shortens (tip up) where the 3D one bends down" in pl7
    assert by["PL = 9"].change == "not run in 2D" and by["PL = 9"].row_2d is None
    assert by["h = 12 mm"].change.startswith("no comparison: the 3D point failed")


def test_a_tip_that_rises_within_its_bends_lift_is_not_called_a_shortening():
    """Bending alone lifts the free end of an actuator of length L by L (1 - sin θ/θ) (a circular
    arc): the default design, L = 5 x 16 + 6 x 0.1 + 2 x 4 = 88.6 mm, bent 120.5° lifts it by
    88.6 (1 - sin(2.103)/2.103) = 52.3 mm and 69.1° by 20.0 mm, more than the measured 3D rises
    (+31.1, +5.7 mm): the bend outruns the lengthening. A rise beyond the lift (PL 7, 20°: lift
    2.4 mm, rise 3 mm, in the other test) is a chamber that shortens."""
    two = Table([row("temperature", "stimulus.temperature", 275.0, 63.5, -48.4, -6.0),
                 row("temperature", "stimulus.temperature", 295.0, 26.6, -14.6, -9.4)])
    three = Table([row("temperature", "stimulus.temperature", 275.0, 120.5, -72.5, 31.1),
                   row("temperature", "stimulus.temperature", 295.0, 69.1, -52.8, 5.7)])
    by = {p.label: p.change for p in pcompare.compare_points(three, two, BASE_3D)}
    curled = by["base: T 275 K, PL 5, h 8 mm"]
    assert "the 3D tip rises (δz > 0): bent by 120°, an arc of the actuator's length lifts its end by 52 mm" in curled
    assert "shortens" not in curled
    assert "bent by 69°, an arc of the actuator's length lifts its end by 20 mm" in by["T = 295 K"]
    lines = pcompare.comparison_lines(three, two, BASE_3D, quick=True, out="o", source="s")
    rows = [line for line in lines if line.startswith("| base") or line.startswith("| T = 295")]
    assert all("[a]; the 3D tip rises (δz > 0) within its bend's lift" in r and r.endswith("[b] |") for r in rows)
    assert "(52 mm at 120°)" in rows[0] and "(20 mm at 69°)" in rows[1]
    assert f"- [b] {pcompare.REASONS['lift 3D']}." in lines


def test_comparison_lines_table_and_without_2d():
    three, two = _tables()
    lines = pcompare.comparison_lines(three, two, BASE_3D, quick=True, out="out3d", source="out2d")
    text = "\n".join(lines)
    assert lines[0] == "## 2D against 3D (the same designs)" and "`out2d`" in text
    table = [line for line in lines if line.startswith("| ") and not line.startswith("| point")]
    assert len(table) == 6
    cells = table[0].split(" | ")
    assert cells[1:7] == ["70.0", "50.0", "-45.0", "-30.0", "-10.0", "-8.0"]
    assert table[-1].split(" | ")[1:7] == ["80.0", "—", "-50.0", "—", "-12.0", "—"]
    assert "Over the 4 points run in both, θ changes by -20.0° to +15.0° from 2D to 3D (mean -1.1°)." in text
    # each hypothesis is said once, below the table, and the rows point to it by its letter
    assert table[0].split(" | ")[7].startswith("bends less in 3D (θ -20.0°, -29 %; a free sphere swells 2.16x")
    assert table[0].endswith("[a] |") and "bends more in 3D (θ +15.0°) [b]" in table[3]
    why = lines[lines.index("Why (hypotheses):") + 1:]
    assert why[0] == f"- [a] {pcompare.REASONS['less']}." and why[1] == f"- [b] {pcompare.REASONS['more']}."
    assert all(text.count(reason) == 1 for reason in (pcompare.REASONS["less"], pcompare.REASONS["more"]))
    # replicated rows give mean ± standard deviation
    three.rows[0]["bending_angle_deg_std"] = 2.5
    assert "50.0 ± 2.5" in "\n".join(pcompare.comparison_lines(three, two, BASE_3D, quick=True, out="o", source="s"))
    # without 2D results: how to get them
    text = "\n".join(pcompare.comparison_lines(three, None, BASE_3D, quick=True, out="out3d"))
    assert "*No 2D results given.*" in text and "hydrojam reproduce --quick -o OUT2D" in text
    assert "hydrojam reproduce --dimension 3 --quick -o out3d --compare-2d OUT2D" in text


def test_read_2d_results_refuses_what_is_not_the_2d_study_of_the_same_kind(tmp_path):
    from hydrojam.study.spec import write_study
    from hydrojam.study.table import SweepTable

    with pytest.raises(pcompare.CompareError, match="no such folder"):
        pcompare.read_2d_results(tmp_path / "none", True)
    with pytest.raises(pcompare.CompareError, match="no study.toml"):
        pcompare.read_2d_results(tmp_path, True)
    write_study(tmp_path / "study.toml", pstudy.paper_study(True, ["temperature"], dimension=3))
    with pytest.raises(pcompare.CompareError, match="holds the study 'paper-3d-quick', not 'paper-quick'"):
        pcompare.read_2d_results(tmp_path, True)
    write_study(tmp_path / "study.toml", pstudy.paper_study(True, ["temperature"]))
    with pytest.raises(pcompare.CompareError, match="not 'paper' .*full"):
        pcompare.read_2d_results(tmp_path, False)
    with pytest.raises(pcompare.CompareError, match="no results.csv yet"):
        pcompare.read_2d_results(tmp_path, True)
    rows = [dict(r, point=0) for r in _tables()[1].rows[:2]]
    SweepTable(rows, list(rows[0])).write(tmp_path)
    table = pcompare.read_2d_results(tmp_path, True)
    assert [r["bending_angle_deg"] for r in table.rows] == [70.0, 40.0]


def test_the_base_point_pairs_across_sweeps_and_missing_columns():
    """The base point run in 3D's particle-layer sweep pairs with 2D's from the temperature sweep,
    and a row without a column for a field its study did not vary takes the base design's value."""
    two = Table([{k: v for k, v in r.items() if k not in ("particle_layers", "strain_limit_thickness")}
                 for r in _tables()[1].rows[:2]])
    three = Table([r for r in _tables()[0].rows if r["sweep"] == "particle_layers"])
    by = {p.label: p for p in pcompare.compare_points(three, two, BASE_3D)}
    assert list(by) == ["base: T 275 K, PL 5, h 8 mm", "T = 285 K", "PL = 7", "PL = 9"]
    base = by["base: T 275 K, PL 5, h 8 mm"]
    assert base.row_2d["bending_angle_deg"] == 70.0 and base.row_3d["bending_angle_deg"] == 50.0
    assert by["T = 285 K"].change == "not run in 3D"


def test_points_not_finished_are_named_and_a_failed_one_first():
    """Rows of a table written without running (status unfinished): no comparison yet, saying
    where the point stands; a failed point on the other side is named before it."""
    unfinished = row("temperature", "stimulus.temperature", 285.0, None, None, None, status="unfinished",
                     error="replica 1: not started")
    two = Table([unfinished, row("temperature", "stimulus.temperature", 295.0, 26.6, -14.6, -9.4),
                 row("particle_layers", "particle_layers", 7, None, None, None, status="unfinished",
                     error="not finished: s = 0.500 reached")])
    three = Table([row("temperature", "stimulus.temperature", 285.0, 0, 0, 0, status="failed"),
                   row("temperature", "stimulus.temperature", 295.0, None, None, None, status="unfinished",
                       error="not started"),
                   row("particle_layers", "particle_layers", 7, 35.0, -20.0, -6.0)])
    by = {p.label: p.change for p in pcompare.compare_points(three, two, BASE_3D)}
    assert by["T = 285 K"].startswith("no comparison: the 3D point failed")
    assert by["T = 295 K"] == "no comparison yet: the 3D point is not started"
    assert by["PL = 7"] == "no comparison yet: the 2D point is not finished: s = 0.500 reached"
    lines = "\n".join(pcompare.comparison_lines(three, two, BASE_3D, quick=True, out="out3d"))
    assert "nan" not in lines.lower()
    unfinished["error"] = "replica 1: not started"
    two2 = Table([unfinished])
    three2 = Table([row("temperature", "stimulus.temperature", 285.0, 41.0, -24.0, -5.0)])
    change, = [p.change for p in pcompare.compare_points(three2, two2, BASE_3D)]
    assert change == "no comparison yet: the 2D point is not finished (replica 1: not started)"


def test_a_point_with_some_replicas_finished_is_compared_with_those_runs():
    """A 3D point with 1 of 3 replicas finished has that run's result: it is compared, its cells
    filled, and the change says how many runs it stands on; it counts one run in the pictures."""
    from hydrojam.paper._rows import partial_runs, runs_of, without_result

    partial = row("particle_layers", "particle_layers", 7, 190.0, -90.0, 140.0, status="unfinished",
                  replicas=3, replicas_used=1, replica_dirs="points/a;points/b;points/c",
                  error="replica 1: not started; replica 2: not started")
    assert partial_runs(partial) == "1 of 3 runs" and not without_result(partial) and runs_of(partial) == 1
    none_yet = dict(partial, replicas_used=0, bending_angle_deg=None)
    assert partial_runs(none_yet) is None and without_result(none_yet)
    two = Table([row("particle_layers", "particle_layers", 7, 28.0, -29.0, 3.0)])
    point, = pcompare.compare_points(Table([partial]), two, BASE_3D)
    assert point.change.startswith("bends more in 3D (θ +162.0°)"), point.change
    assert point.change.endswith("3D: 1 of 3 runs so far"), point.change
    lines = "\n".join(pcompare.comparison_lines(Table([partial]), two, BASE_3D, quick=True, out="out3d"))
    assert "| 190.0 |" in lines and "nan" not in lines.lower()
