"""The paper's Section IV (hydrojam.paper): the study's point sets, claim checks, figures, report and
reproduce() end to end.

No simulation runs here: rows are synthetic, shaped like the paper's statements (or against
them), and point folders hold tiny hand-made final.vtu files (a few quadratic triangles with a
body id each) and a design.toml.
"""

from __future__ import annotations

import re
from pathlib import Path

import meshio
import numpy as np
import pytest

from hydrojam.paper import claims as pclaims, figures as pfigures, report as preport, study as pstudy
from hydrojam.paper.reproduce import reproduce
from hydrojam.actuator.design import apply_overrides, default_design, write_design

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
FIELDS = ("stimulus.temperature", "particle_layers", "strain_limit_thickness")
BASE = {"stimulus.temperature": 275.0, "particle_layers": 5, "strain_limit_thickness": 8.0}


# ------------------------------------------------------------------------------------------------
# synthetic rows


def row(sweep: str, field: str, value, theta, dx, dz, ci=0.5, status="ok", **extra) -> dict:
    point = dict(BASE)
    point[field] = value
    failed = status == "failed"
    r = {"sweep": sweep, "point": f"{field}={value}", "key": f"{field}={value}", **point,
         "bending_angle_deg": None if failed else theta, "tip_dx_mm": None if failed else dx,
         "tip_dz_mm": None if failed else dz, "curling_index": None if failed else ci,
         "converged": None if failed else status == "ok", "stabilization_released": status == "ok",
         "newton_iterations": None if failed else 900, "wall_time_s": None if failed else 120.0,
         "status": status, "error": "solver stopped: minimum increment" if failed else None,
         "point_dir": f"points/{sweep}-{value}"}
    r.update(extra)
    return r


def temperature_rows(Ts=pstudy.TEMPERATURES_K, sign=-1.0) -> list[dict]:
    """Paper-like (sign -1): angle and displacements fall linearly as T rises, δx falls most."""
    return [row("temperature", "stimulus.temperature", T, 75 + sign * 2.3 * (T - 275),
                -(50 + sign * 1.5 * (T - 275)), -(12 + sign * 0.3 * (T - 275))) for T in Ts]


def layer_rows(PLs=pstudy.PARTICLE_LAYERS) -> list[dict]:
    """Paper-like: θ peaks at 9, |δx| rises to 9 then flat, |δz| peaks at 7, curling from 10 on."""
    rows = []
    for n in PLs:
        theta = 60 + 5 * (n - 5) if n <= 9 else 80 - 1.5 * (n - 9)
        dx = 30 + 5 * (n - 5) if n <= 9 else 50.0
        dz = 10 + 3 * (n - 5) if n <= 7 else 16 - 0.6 * (n - 7)
        rows.append(row("particle_layers", "particle_layers", n, theta, -dx, -dz, ci=0.4 if n <= 9 else 0.7))
    return rows


def thickness_rows(hs=pstudy.STRAIN_LIMIT_THICKNESSES_MM) -> list[dict]:
    """Paper-like: θ rises to 10 mm then levels; displacements rise to 10 mm and drop at 12."""
    rows = []
    for h in hs:
        theta = 40 + 8 * (h - 4) if h <= 10 else 89.0
        dx = 20 + 5 * (h - 4) if h <= 10 else 44.0
        dz = 8 + 2 * (h - 4) if h <= 10 else 17.0
        rows.append(row("strain_limit_thickness", "strain_limit_thickness", h, theta, -dx, -dz))
    return rows


def paper_like(design) -> dict:
    """Metrics of a design, paper-like in each parameter: the three sweeps' shapes added round the
    base point (275 K, PL 5, h 8 mm), so the shared base point has one set of values."""
    t, = temperature_rows([design.stimulus.temperature])
    n, = layer_rows([design.particle_layers])
    h, = thickness_rows([design.strain_limit_thickness])
    t0, = temperature_rows([275.0])
    n0, = layer_rows([5])
    h0, = thickness_rows([8.0])
    out = {k: t[k] + (n[k] - n0[k]) + (h[k] - h0[k]) for k in ("bending_angle_deg", "tip_dx_mm", "tip_dz_mm")}
    out["curling_index"] = n["curling_index"]
    return out


def with_values(rows, **by_param):
    """Copies of rows with some metrics replaced: by_param = {key: {param: value}}."""
    out = []
    for r in rows:
        r = dict(r)
        field = {"temperature": "stimulus.temperature"}.get(r["sweep"], r["sweep"])
        for key, values in by_param.items():
            if r[field] in values:
                r[key] = values[r[field]]
        out.append(r)
    return out


# ------------------------------------------------------------------------------------------------
# the study


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


# ------------------------------------------------------------------------------------------------
# claims


def test_claim_ids_unique_with_reasons():
    ids = [c.id for c in pclaims.PAPER_CLAIMS]
    assert len(ids) == len(set(ids)) == 10
    assert set(pclaims.DISAGREEMENT_REASONS) == set(ids)
    assert all("likely" in text for text in pclaims.DISAGREEMENT_REASONS.values())
    assert {c.sweep for c in pclaims.PAPER_CLAIMS} == {s.name for s in pstudy.PAPER_SWEEPS}


@pytest.mark.parametrize("quick", [False, True])
def test_paper_like_rows_agree(quick):
    pts = pstudy.paper_points(quick)
    Ts, PLs, hs = (pts[s][f] for s, f in zip(("temperature", "particle_layers", "strain_limit_thickness"), FIELDS))
    rows = temperature_rows(Ts) + layer_rows(PLs) + thickness_rows(hs)
    results = {r.claim.id: r for r in pclaims.check_claims(rows)}
    expected = {"h-angle": "undetermined", "h-displacement": "undetermined"} if quick else {}
    for cid, res in results.items():
        assert res.verdict == expected.get(cid, "agree"), (cid, res.summary)
        assert "nan" not in res.summary.lower()
    if quick:
        for cid in ("h-angle", "h-displacement"):  # 4, 8, 12 mm: nothing between 10 and 12 mm to compare
            assert "the paper's 4 mm to 10 mm checked on the points run, 4 mm to 8 mm" in results[cid].summary
            assert "cannot decide: fewer than 2 points run within 10 mm to 12 mm" in results[cid].summary


def test_temperature_claims_disagree_when_bending_rises_with_T():
    results = {r.claim.id: r for r in pclaims.check_claims(temperature_rows(sign=+1.0))}
    assert results["T-angle"].verdict == "disagree"
    assert results["T-displacement"].verdict == "disagree"
    assert "+46.0°" in results["T-angle"].summary  # 75 -> 121 deg over 20 K
    assert results["T-linear"].verdict == "agree"  # still linear


def test_temperature_non_monotone_and_dz_dominant_disagree():
    rows = with_values(temperature_rows(), bending_angle_deg={285.0: 90.0}, tip_dz_mm={275.0: -80.0})
    results = {r.claim.id: r for r in pclaims.check_claims(rows)}
    assert results["T-angle"].verdict == "disagree"
    assert "280 K -> 285 K" in results["T-angle"].summary
    assert results["T-dx-dominant"].verdict == "disagree"
    assert results["T-linear"].verdict == "disagree"  # |δz| 80, 13.5, 12, ...: not a line


def test_layer_claims_disagree():
    PLs = pstudy.PARTICLE_LAYERS
    rows = [row("particle_layers", "particle_layers", n, 50 + 2 * n, -(20 + 3 * n), -(5 + n), ci=0.5) for n in PLs]
    results = {r.claim.id: r for r in pclaims.check_claims(rows)}
    for cid in ("PL-angle", "PL-curling", "PL-dx", "PL-dz"):
        assert results[cid].verdict == "disagree", cid
    # the curling rise in the wrong place: at 15 -> 16 layers
    rows = with_values(layer_rows(), curling_index={n: (0.4 if n <= 15 else 0.9) for n in PLs})
    res = {r.claim.id: r for r in pclaims.check_claims(rows)}["PL-curling"]
    assert res.verdict == "disagree" and "from PL 15 to 16" in res.summary


def test_curling_index_outside_unit_interval_is_not_used():
    """A curling index outside [0, 1] (the rotation reverses along the actuator, e.g. -1.05 or
    2.94 where the total rotation is near zero) says neither bending nor curling: such points are
    skipped and named, and with too few left the transition is undetermined, not agreed."""
    PLs = pstudy.PARTICLE_LAYERS
    ci = {n: (0.4 if n <= 9 else 0.8) for n in PLs}
    ci.update({n: (-1.05 if n % 2 else 2.94) for n in PLs if n >= 11})
    res = {r.claim.id: r for r in pclaims.check_claims(with_values(layer_rows(), curling_index=ci))}["PL-curling"]
    assert res.verdict == "undetermined"
    assert "skipped" in res.summary and res.summary.count("outside [0, 1]") == 9  # PL 11..19


def test_thickness_claims_disagree():
    rows = [row("strain_limit_thickness", "strain_limit_thickness", h, 100 - 5 * h, -(60 - 3 * h), -(20 - h))
            for h in pstudy.STRAIN_LIMIT_THICKNESSES_MM]
    results = {r.claim.id: r for r in pclaims.check_claims(rows)}
    assert results["h-angle"].verdict == "disagree"
    assert results["h-displacement"].verdict == "disagree"


def test_undetermined_with_missing_failed_or_unconverged_points():
    rows = temperature_rows()
    rows[-1] = row("temperature", "stimulus.temperature", 295.0, 0, 0, 0, status="failed")
    results = {r.claim.id: r for r in pclaims.check_claims(rows + layer_rows() + thickness_rows())}
    for cid in ("T-angle", "T-displacement", "T-dx-dominant"):
        assert results[cid].verdict == "undetermined", cid
        assert "at 295 K: failed" in results[cid].summary
    assert results["T-linear"].verdict == "agree"  # 4 usable points, the failed one named
    assert "skipped 295 K (failed)" in results["T-linear"].summary
    # not converged at the peak, and no points at all
    rows = layer_rows()
    rows[4] = row("particle_layers", "particle_layers", 9, 80.0, -50.0, -14.8, ci=0.4, status="not_converged")
    results = {r.claim.id: r for r in pclaims.check_claims(rows)}
    assert results["PL-angle"].verdict == "undetermined"
    assert "θ at 9: not converged" in results["PL-angle"].summary
    assert results["PL-dz"].verdict == "agree"  # does not need PL 9; skips it
    results = {r.claim.id: r for r in pclaims.check_claims([])}
    assert {r.verdict for r in results.values()} == {"undetermined"}
    # a straight actuator: curling index None
    rows = with_values(layer_rows(), curling_index={n: None for n in range(10, 20)})
    assert {r.claim.id: r for r in pclaims.check_claims(rows)}["PL-curling"].verdict == "undetermined"


def test_interior_failure_is_skipped_and_named():
    rows = layer_rows()
    rows[8] = row("particle_layers", "particle_layers", 13, 0, 0, 0, status="failed")
    res = {r.claim.id: r for r in pclaims.check_claims(rows)}
    assert res["PL-dx"].verdict == "agree"
    assert "skipped 13 (failed)" in res["PL-dx"].summary


# ------------------------------------------------------------------------------------------------
# figures and report

CORNERS = np.array([[0, 1, 2], [0, 2, 3]])


def tri6(points: np.ndarray, tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quadratic triangles from corner triangles: mid-side nodes appended (0-1, 1-2, 2-0)."""
    pts = [p for p in points]
    cells = []
    for a, b, c in tris:
        mids = []
        for i, j in ((a, b), (b, c), (c, a)):
            pts.append(0.5 * (points[i] + points[j]))
            mids.append(len(pts) - 1)
        cells.append([a, b, c, *mids])
    return np.array(pts), np.array(cells)


def write_point(out: Path, r: dict, bend: float, design=None) -> None:
    """A point folder: design.toml and a final.vtu of membrane, layer and one particle, sheared by ``bend``."""
    pdir = out / r["point_dir"]
    pdir.mkdir(parents=True)
    if design is None:
        design = apply_overrides(default_design(), [f"{f}={r[f]!r}" for f in FIELDS])
    write_design(pdir / "design.toml", design)
    L, w, h = design.length_mm, design.cavity_width_mm / 2 + 2.0, design.strain_limit_thickness
    quads = [np.array([[-w, -L], [w, -L], [w, 0], [-w, 0]]),  # membrane
             np.array([[-w - h, -L], [-w, -L], [-w, 0], [-w - h, 0]]),  # strain-limit layer
             np.array([[-6, -20], [6, -20], [6, -8], [-6, -8]])]  # a particle
    pts, cells, body = [], [], []
    for k, q in enumerate(quads):
        p, c = tri6(q, CORNERS)
        cells.append(c + sum(len(x) for x in pts))
        pts.append(p)
        body += [k, k]
    p2 = np.vstack(pts)
    p2 = p2 + np.column_stack([bend * p2[:, 1] ** 2 / L, np.zeros(len(p2))])  # a parabolic bend to -x
    mesh = meshio.Mesh(np.column_stack([p2[:, 0], np.zeros(len(p2)), p2[:, 1]]), [("triangle6", np.vstack(cells))],
                       cell_data={"body_id": [np.array(body, dtype=np.int32)]})
    meshio.write(pdir / "final.vtu", mesh)


class Table:
    """The part of hydrojam.sweep.SweepTable the report reads."""

    def __init__(self, rows):
        self.rows = rows

    def select(self, sweep):
        return [r for r in self.rows if r["sweep"] == sweep]


@pytest.fixture(scope="module")
def study_dir(tmp_path_factory):
    """A quick study's rows and point folders; T = 295 K failed, PL 11 not converged, θ falling
    with h (h-angle disagrees) and a flat curling index (PL-curling disagrees)."""
    out = tmp_path_factory.mktemp("reproduce")
    pts = pstudy.paper_points(True)
    rows = (temperature_rows(pts["temperature"]["stimulus.temperature"])
            + layer_rows(pts["particle_layers"]["particle_layers"])
            + thickness_rows(pts["strain_limit_thickness"]["strain_limit_thickness"]))
    rows[2] = row("temperature", "stimulus.temperature", 295.0, 0, 0, 0, status="failed")
    rows[6]["status"], rows[6]["converged"] = "not_converged", False
    for r in rows:
        if r["sweep"] == "strain_limit_thickness":
            r["bending_angle_deg"] = 100.0 - 5.0 * r["strain_limit_thickness"]
        if r["sweep"] == "particle_layers":
            r["curling_index"] = 0.5
    for r in rows:
        if r["status"] != "failed":
            write_point(out, r, bend=-0.5 * r["bending_angle_deg"] / 90.0)
    return out, Table(rows)


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


def test_read_shape_moves_reference_points_by_displacement(tmp_path):
    """A VTU in results.write_vtu's layout (reference points + displacement) is read as deformed,
    with the reference points' bounding box as the undeformed outline."""
    corners = np.array([[-14.1, 0.0], [10.1, 0.0], [10.1, -88.5], [-14.1, -88.5]])
    p, c = tri6(corners, CORNERS)
    disp = np.tile([1.5, -2.0], (len(p), 1))
    xyz = lambda a: np.column_stack([a[:, 0], np.zeros(len(a)), a[:, 1]])  # noqa: E731
    meshio.write(tmp_path / "final.vtu", meshio.Mesh(xyz(p), [("triangle6", c)], point_data={"displacement": xyz(disp)},
                                                     cell_data={"body_id": [np.array([0, 1], dtype=np.int32)]}))
    pts, tris, body, outline = pfigures._read_shape(tmp_path)
    np.testing.assert_allclose(pts, p + disp)
    assert tris.shape == (8, 3) and list(body) == [0] * 4 + [1] * 4
    np.testing.assert_allclose(outline.min(axis=0), [-14.1, -88.5])
    np.testing.assert_allclose(outline.max(axis=0), [10.1, 0.0])
    # without a displacement field the points are taken as deformed, and there is no outline
    meshio.write(tmp_path / "final.vtu", meshio.Mesh(xyz(p + disp), [("triangle6", c)],
                                                     cell_data={"body_id": [np.array([0, 1], dtype=np.int32)]}))
    pts, _, _, outline = pfigures._read_shape(tmp_path)
    np.testing.assert_allclose(pts, p + disp)
    assert outline is None


def test_report(study_dir):
    out, table = study_dir
    written = pfigures.write_figures(out, table)
    assert sorted(p.name for p in written) == sorted(f"{s.name}_{k}.png" for s in pstudy.PAPER_SWEEPS
                                                     for k in ("shapes", "trends"))
    path = preport.write_report(out, table, quick=True, wall_time_s=3725.0, workers=2,
                           explanations={"h-angle": "EXPLAINED BY THE CALLER"})
    assert path == out / "report.md"
    text = path.read_text(encoding="utf-8")
    for s in pstudy.PAPER_SWEEPS:
        for k in ("shapes", "trends"):
            assert f"](figures/{s.name}_{k}.png)" in text
            assert (out / "figures" / f"{s.name}_{k}.png").read_bytes()[:8] == PNG_MAGIC
    claims = [line for line in text.splitlines() if line.startswith("| ") and " | **" in line]
    assert [line.split(" | ")[0][2:] for line in claims] == [c.id for c in pclaims.PAPER_CLAIMS]
    assert not re.search(r"\bnan\b|\binf\b", text, re.IGNORECASE)
    assert "**quick**" in text and "mesh size 4 mm" in text and "62.1 min" in text and "Workers: 2 local" in text
    assert "failed: solver stopped: minimum increment" in text
    assert "not_converged" in text
    assert "EXPLAINED BY THE CALLER" in text  # h-angle disagrees: the caller's reason
    assert pclaims.DISAGREEMENT_REASONS["PL-curling"] in text  # the default reason
    assert pclaims.DISAGREEMENT_REASONS["h-angle"] not in text
    assert "## Model differences" in text and "plane strain" in text
    assert f"{pclaims.ANGLE_TOL:g} ×" in text
    from hydrojam import __version__

    assert f"hydrojam {__version__}" in text
    verdicts = [line.split(" | ")[3] for line in claims]
    assert all(v in ("**agree**", "**disagree**", "**undetermined**") for v in verdicts)
    # the four temperature claims (295 K failed, 2 points left) and h-displacement (nothing in 10-12 mm)
    assert verdicts.count("**undetermined**") == 5
    assert verdicts.count("**disagree**") == 2


def test_reproduce_end_to_end_from_cached_points(tmp_path):
    """reproduce() with hydrojam.sweep.run_sweep: every point of the quick study is already in
    OUT/points/<key>/ (point.json ok, paper-like metrics, a tiny final.vtu), so nothing is
    simulated; the table, the six figures and the report come out."""
    pytest.importorskip("hydrojam.study.sweep")
    import json

    study = pstudy.paper_study(quick=True)
    done = set()
    for p in study.points():
        if p.key in done:
            continue
        done.add(p.key)
        metrics = paper_like(p.design)
        metrics.update(converged=True, stabilization_released=True, newton_iterations=900)
        write_point(tmp_path, {"point_dir": f"points/{p.key}"}, bend=-0.5, design=p.design)
        record = {"key": p.key, "status": "ok", "error": None, "metrics": metrics, "wall_time_s": 60.0}
        (tmp_path / "points" / p.key / "point.json").write_text(json.dumps(record))
    seen = []
    table, report = reproduce(tmp_path, quick=True, on_point=lambda o, d, t: seen.append((d, t)))
    assert seen[-1] == (10, 10) and len(table.rows) == 12
    text = report.read_text(encoding="utf-8")
    assert report == tmp_path / "report.md"
    assert len(list((tmp_path / "figures").glob("*.png"))) == 6
    verdicts = {c.claim.id: c.verdict for c in pclaims.check_claims(table)}
    assert verdicts == {c.id: ("undetermined" if c.sweep == "strain_limit_thickness" else "agree")
                        for c in pclaims.PAPER_CLAIMS}
    assert "10 distinct points" in text and "compute time summed over points 10.0 min" in text
    # the command line over the same cache: nothing to simulate, exit status 0, report rewritten
    from hydrojam.cli import main

    report.unlink()
    assert main(["reproduce", "--quick", "-o", str(tmp_path), "--quiet"]) == 0
    assert report.is_file()


@pytest.mark.parametrize("args", [["--workers", "0"], ["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"]])
def test_reproduce_command_refuses_bad_options_before_any_work(tmp_path, capsys, args):
    from hydrojam.cli import main

    out = tmp_path / "out"
    assert main(["reproduce", "--quick", "-o", str(out), *args]) == 2
    assert "--workers" in capsys.readouterr().err and not out.exists()
