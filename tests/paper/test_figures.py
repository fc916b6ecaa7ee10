"""The shapes and trend figures of hydrojam.paper.figures, from synthetic rows and point folders."""

from __future__ import annotations

import meshio
import numpy as np
import pytest
from paper_synthetic import CORNERS, PNG_MAGIC, tri6

from hydrojam.paper import figures as pfigures


def test_plot_shapes_and_trends(study_dir, tmp_path):
    out, table = study_dir
    rows = table.select("temperature")
    pfigures.plot_shapes(out, rows, "stimulus.temperature", tmp_path / "shapes.png")
    pfigures.plot_trends(rows, "stimulus.temperature", tmp_path / "trends.png", "temperature T", "K")
    pfigures.plot_trends(table.select("particle_layers"), "particle_layers", tmp_path / "pl.png", "particle layers PL",
                         "layers")
    for name in ("shapes.png", "trends.png", "pl.png"):
        assert (tmp_path / name).read_bytes()[:8] == PNG_MAGIC
    # a point whose final.vtu is missing gets a panel too
    broken = [dict(rows[0], point_dir="points/nowhere")]
    pfigures.plot_shapes(out, broken, "stimulus.temperature", tmp_path / "broken.png")
    assert (tmp_path / "broken.png").read_bytes()[:8] == PNG_MAGIC


def test_the_trends_draw_each_state_where_the_runs_reach_several(study_dir, tmp_path):
    """state_series gives each state's θ (mean, std) at the points with a run in it, and nothing
    for a sweep whose runs reach one state; plot_trends draws them."""
    from hydrojam.paper._rows import without_result

    _, table = study_dir
    rows = [r for r in table.select("temperature") if not without_result(r)]
    assert len(rows) >= 2
    arc = [dict(r, bending_angle_deg=100.0 + k, bending_angle_deg_std=0.5) for k, r in enumerate(rows)]
    folded = [dict(rows[0], bending_angle_deg=60.0, bending_angle_deg_std=None)]
    series = pfigures.state_series({"arc": arc, "folded": folded}, "stimulus.temperature")
    temps = sorted(r["stimulus.temperature"] for r in rows)
    assert series["arc"] == (temps, [100.0 + k for k in range(len(rows))], [0.5] * len(rows))
    assert series["folded"] == ([rows[0]["stimulus.temperature"]], [60.0], [0.0])
    assert pfigures.state_series({"arc": arc}, "stimulus.temperature") == {}
    assert pfigures.state_series({"arc": arc, "folded": []}, "stimulus.temperature") == {}
    pfigures.plot_trends(rows, "stimulus.temperature", tmp_path / "trends.png", "temperature T", "K",
                         states={"arc": arc, "folded": folded})
    assert (tmp_path / "trends.png").read_bytes()[:8] == PNG_MAGIC


def test_read_shape_moves_reference_points_by_displacement(tmp_path):
    """A VTU in results.write_vtu's layout (reference points + displacement) is read as deformed,
    with the reference points' bounding box as the undeformed outline."""
    corners = np.array([[-14.1, 0.0], [10.1, 0.0], [10.1, -88.5], [-14.1, -88.5]])
    p, c = tri6(corners, CORNERS)
    disp = np.tile([1.5, -2.0], (len(p), 1))
    xyz = lambda a: np.column_stack([a[:, 0], np.zeros(len(a)), a[:, 1]])  # noqa: E731
    meshio.write(tmp_path / "final.vtu", meshio.Mesh(xyz(p), [("triangle6", c)], point_data={"displacement": xyz(disp)},
                                                     cell_data={"body_id": [np.array([0, 1], dtype=np.int32)]}))
    pts, tris, body, outline = pfigures._read_drawing(tmp_path)[:4]
    np.testing.assert_allclose(pts, p + disp)
    assert tris.shape == (8, 3) and list(body) == [0] * 4 + [1] * 4
    np.testing.assert_allclose(outline.min(axis=0), [-14.1, -88.5])
    np.testing.assert_allclose(outline.max(axis=0), [10.1, 0.0])
    # without a displacement field the points are taken as deformed, and there is no outline
    meshio.write(tmp_path / "final.vtu", meshio.Mesh(xyz(p + disp), [("triangle6", c)],
                                                     cell_data={"body_id": [np.array([0, 1], dtype=np.int32)]}))
    pts, _, _, outline = pfigures._read_drawing(tmp_path)[:4]
    np.testing.assert_allclose(pts, p + disp)
    assert outline is None


def test_a_3d_point_is_drawn_as_its_section_y0(tmp_path):
    """A 3D final.vtu (tetra10, mirrored about y = 0) is drawn as its section y = 0: the faces on that
    plane of the cells above it, which tile each body's x-z rectangle (areas summed independently),
    moved by the displacement; the shapes figure of 3D rows is written."""
    from paper_synthetic import BOXES_3D, row, write_point_3d

    r = row("temperature", "stimulus.temperature", 275.0, 30.0, -5.0, -2.0, point_dir="points/a")
    write_point_3d(tmp_path, r, bend=-0.3)
    mesh = meshio.read(tmp_path / "points/a/final.vtu")
    X = np.asarray(mesh.points)
    pts, tris, body, outline, section = pfigures._read_drawing(tmp_path / "points/a")
    assert section
    np.testing.assert_allclose(X[tris.ravel(), 1], 0.0, atol=1e-12)  # every corner on y = 0
    ref = X[:, [0, 2]]
    e1, e2 = ref[tris[:, 1]] - ref[tris[:, 0]], ref[tris[:, 2]] - ref[tris[:, 0]]
    area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    for b, (x0, x1, _, _, z0, z1) in enumerate(BOXES_3D):
        assert np.isclose(area[body == b].sum(), (x1 - x0) * (z1 - z0), rtol=1e-12)
    np.testing.assert_allclose(pts, ref + np.asarray(mesh.point_data["displacement"])[:, [0, 2]])
    np.testing.assert_allclose(outline.min(axis=0), [-18.0, -40.0])
    pfigures.plot_shapes(tmp_path, [r], "stimulus.temperature", tmp_path / "shapes.png")
    assert (tmp_path / "shapes.png").read_bytes()[:8] == PNG_MAGIC


def test_a_3d_sweep_is_drawn_as_renders_at_one_scale(tmp_path, monkeypatch):
    """With PyVista, a 3D sweep whose points with a result all hold a final.vtu is drawn as
    renders: one per such point, all framed by the box of every state and on one colour range,
    without a colour bar each (the figure draws one), a failed point's panel saying why; without
    PyVista, as sections."""
    import hydrojam.actuator as actuator
    from hydrojam.actuator import render
    from paper_synthetic import row, write_point_3d

    if not render.renders_available(say=False):
        pytest.skip("no PyVista renders here")
    rows = [row("temperature", "stimulus.temperature", t, 30.0, -5.0, -2.0, point_dir=f"points/{k}")
            for k, t in enumerate((275.0, 300.0))]
    for r, bend in zip(rows, (-0.3, -0.6)):
        write_point_3d(tmp_path, r, bend=bend)
    rows.append(row("temperature", "stimulus.temperature", 285.0, None, None, None, status="failed",
                    error="no replica in state arc"))
    drawn = []
    draw = render.Renderer.draw

    def spy(self, surf, title="", scale_bar=True):
        assert not scale_bar
        drawn.append((self.bounds.copy(), self.clim, surf.points.min(axis=0), surf.points.max(axis=0)))
        return draw(self, surf, title, scale_bar)

    monkeypatch.setattr(render.Renderer, "draw", spy)
    pfigures.plot_shapes(tmp_path, rows, "stimulus.temperature", tmp_path / "shapes.png")
    assert (tmp_path / "shapes.png").read_bytes()[:8] == PNG_MAGIC
    assert len(drawn) == 2
    (b0, c0, *_), (b1, c1, *_) = drawn
    np.testing.assert_array_equal(b0, b1)
    assert c0 == c1
    for bounds, _, lo, hi in drawn:  # the box frames every state
        assert np.all(bounds[0] <= lo) and np.all(hi <= bounds[1])
    monkeypatch.setattr(actuator, "renders_available", lambda say=True: False)
    pfigures.plot_shapes(tmp_path, rows, "stimulus.temperature", tmp_path / "sections.png")
    assert len(drawn) == 2 and (tmp_path / "sections.png").read_bytes()[:8] == PNG_MAGIC


def test_a_kept_record_without_final_vtu_is_drawn_as_its_mid_line(tmp_path):
    """A finished point put back from its kept record (design.toml, centreline.csv, no final.vtu):
    its panel is the strain-limit layer's mid-line rebuilt from centreline.csv, starting at the
    clamp on the design's mid-line. The csv is written here the way results.py writes it, from the
    profile of an arc of radius 50 mm turned by 1.2 rad; the rebuilt nodes are the arc's to 1e-9 of
    its length (the rebuilding is exact on arcs; the csv's repr of floats keeps every bit)."""
    import csv

    from paper_synthetic import row

    from hydrojam.actuator.design import default_design, write_design
    from hydrojam.actuator.metrics import centreline_profile
    from hydrojam.actuator.model import centreline_x

    r = row("temperature", "stimulus.temperature", 275.0, 68.8, -40.0, -10.0, point_dir="points/kept")
    pdir = tmp_path / "points/kept"
    pdir.mkdir(parents=True)
    design = default_design()
    write_design(pdir / "design.toml", design)
    x0, R = centreline_x(design), 50.0
    S = np.linspace(0.0, 60.0, 31)
    arc = np.column_stack((x0 - R + R * np.cos(S / R), -R * np.sin(S / R)))
    prof = centreline_profile(np.column_stack((np.full_like(S, x0), -S)), arc)
    with open(pdir / "centreline.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["reference_arc_length_mm", "arc_length_mm", "rotation_deg", "curvature_per_mm"])
        w.writerows(zip(prof.reference_arc_length, prof.arc_length, np.degrees(prof.rotation), prof.curvature))
    line, made = pfigures._centreline_drawing(pdir)
    assert np.abs(line - arc).max() <= 1e-9 * 60.0
    np.testing.assert_allclose(made, [[x0, 0.0], [x0, -60.0]], rtol=0, atol=1e-9 * 60.0)
    pfigures.plot_shapes(tmp_path, [r], "stimulus.temperature", tmp_path / "shapes.png")
    assert (tmp_path / "shapes.png").read_bytes()[:8] == PNG_MAGIC
    (pdir / "centreline.csv").unlink()  # neither file: the panel says why, and the figure is still written
    pfigures.plot_shapes(tmp_path, [r], "stimulus.temperature", tmp_path / "shapes.png")
    with pytest.raises(OSError):
        pfigures._centreline_drawing(pdir)


def test_a_title_gives_the_mean_angle_and_the_angle_of_the_run_drawn(tmp_path):
    """A row of several runs is titled with their mean angle and, where the run drawn (its
    point_dir) ended elsewhere, that run's angle; a row of one run with its angle alone."""
    (tmp_path / "points/a").mkdir(parents=True)
    (tmp_path / "points/a/metrics.json").write_text('{"bending_angle_deg": 100.84}')
    r = {"bending_angle_deg": 146.0, "point_dir": "points/a", "replica_dirs": "points/a;points/b;points/c"}
    assert pfigures._angle_lines(r, tmp_path) == "\nθ = 146.0° (mean of 3 runs)\ndrawn: run with θ = 100.8°"
    assert pfigures._angle_lines({**r, "bending_angle_deg": 100.82}, tmp_path) == "\nθ = 100.8° (mean of 3 runs)"
    assert pfigures._angle_lines({"bending_angle_deg": 30.0, "point_dir": "points/a"}, tmp_path) == "\nθ = 30.0°"
    assert pfigures._angle_lines({"bending_angle_deg": None}, tmp_path) == "\nθ: —"


def test_a_state_no_run_of_a_sweep_reached_gets_no_figure(tmp_path):
    """Of a sweep's state figures, those of states none of its runs reached are not written (an
    earlier one is removed): a figure of empty panels only says what the table already does; a
    sweep whose runs reached one state gets none (its shapes figure shows that state)."""
    from paper_synthetic import row

    from hydrojam.paper.study import PAPER_SWEEPS

    sw = next(s for s in PAPER_SWEEPS if s.name == "temperature")
    main = [row("temperature", "stimulus.temperature", t, 30.0, -5.0, -2.0, point_dir=None) for t in (275.0, 285.0)]
    none = [{**r, "status": "failed", "bending_angle_deg": None, "error": "no replica in state multi-folded"}
            for r in main]
    (tmp_path / "figures").mkdir()
    stale = tmp_path / pfigures.state_figure_name(sw, "multi-folded")
    stale.write_bytes(b"old")
    written = pfigures.write_figures(tmp_path, main, {"arc": main[:1] + none[1:], "folded": none[:1] + main[1:],
                                                     "multi-folded": none})
    names = {p.name for p in written}
    assert {n for n in names if "_shapes_" in n} == {"temperature_shapes_arc.png", "temperature_shapes_folded.png"}
    assert not stale.exists()
    written = pfigures.write_figures(tmp_path, main, {"arc": main, "multi-folded": none})
    assert not any("_shapes_" in p.name for p in written) and not (tmp_path / "figures/temperature_shapes_arc.png").exists()


def test_a_replicated_point_is_drawn_in_the_state_most_of_its_runs_reached(tmp_path):
    """Replica 0 folded, replicas 1 and 2 arcs: the picture draws replica 1 (the first arc); a tie
    keeps replica 0, and so does a row whose runs' states cannot be read."""
    import json

    from hydrojam.paper._rows import drawn_row

    for k, folds in enumerate((1, 0, 0, 1)):
        (tmp_path / f"points/r{k}").mkdir(parents=True)
        (tmp_path / f"points/r{k}/metrics.json").write_text(json.dumps({"column_folds": folds}))
    row = {"point_dir": "points/r0", "replica_dirs": "points/r0;points/r1;points/r2"}
    assert drawn_row(tmp_path, row)["point_dir"] == "points/r1"
    tie = {"point_dir": "points/r0", "replica_dirs": "points/r0;points/r1;points/r2;points/r3"}
    assert drawn_row(tmp_path, tie)["point_dir"] == "points/r0"
    unread = {"point_dir": "points/x0", "replica_dirs": "points/x0;points/x1"}
    assert drawn_row(tmp_path, unread) is unread
    single = {"point_dir": "points/r2"}
    assert drawn_row(tmp_path, single) is single
