"""report.md of hydrojam.paper.report, from a synthetic quick study with failed and unconverged points."""

from __future__ import annotations

import re

from paper_synthetic import PNG_MAGIC

from hydrojam.paper import claims as pclaims, figures as pfigures, report as preport, study as pstudy


def test_report(study_dir):
    out, table = study_dir
    written = pfigures.write_figures(out, table)
    assert sorted(p.name for p in written) == sorted(f"{s.name}_{k}.png" for s in pstudy.paper_sweeps(2)
                                                     for k in ("shapes", "trends"))
    path = preport.write_report(out, table, quick=True, wall_time_s=3725.0, workers=2,
                                explanations={"h-angle": "EXPLAINED BY THE CALLER"})
    assert path == out / "report.md"
    text = path.read_text(encoding="utf-8")
    for s in pstudy.paper_sweeps(2):
        for k in ("shapes", "trends"):
            assert f"](figures/{s.name}_{k}.png)" in text
            assert (out / "figures" / f"{s.name}_{k}.png").read_bytes()[:8] == PNG_MAGIC
    claims = [line for line in text.splitlines() if line.startswith("| ") and " | **" in line]
    assert [line.split(" | ")[0][2:] for line in claims] == [c.id for c in pclaims.paper_claims(2)]
    assert not re.search(r"\bnan\b|\binf\b", text, re.IGNORECASE)
    assert "**quick**" in text and "mesh size 4 mm" in text and "62.1 min" in text and "Workers: 2 local" in text
    # single runs: the report opens by saying each point is one sample, with the command that measures the spread
    opening = text.split("## What was run", 1)[0]
    assert "one sample of a spread" in opening and "`hydrojam reproduce --quick --replicas 4 -o " in opening
    assert "failed: solver stopped: minimum increment" in text
    assert "this run:" not in text  # no count given, none claimed
    again = preport.write_report(out, table, quick=True, wall_time_s=1.0, computed=3).read_text(encoding="utf-8")
    assert "wall time 1 s (this run: 3 of the " in again and "points computed, the others reused" in again
    assert "not_converged" in text
    assert "EXPLAINED BY THE CALLER" in text  # h-angle disagrees: the caller's reason
    assert pclaims.DISAGREEMENT_REASONS["PL-curling"] in text  # the default reason
    assert pclaims.DISAGREEMENT_REASONS["h-angle"] not in text
    assert "## Model differences" in text and "plane strain" in text
    # the title question is answered by `assess`, and the report says how to run it (issue 15)
    assert "## The title question" in text and "hydrojam assess design.toml" in text
    assert f"{pclaims.ANGLE_TOL:g} ×" in text
    from hydrojam import __version__

    assert f"hydrojam {__version__}" in text
    verdicts = [line.split(" | ")[3] for line in claims]
    assert all(v in ("**agree**", "**disagree**", "**undetermined**") for v in verdicts)
    # the four temperature claims (295 K failed, 2 points left); the quick h grid carries the
    # 10 mm break point, so h-displacement is decided
    assert verdicts.count("**undetermined**") == 4
    assert verdicts.count("**disagree**") == 2


def test_report_and_trends_with_replicas(study_dir, tmp_path):
    """Replicated points: the trend figures draw their spread, the tables give mean ± standard
    deviation and replicas used, the verdicts count 'undetermined (spread)', the rule is stated."""
    from paper_synthetic import Table, with_spread, write_point

    from hydrojam.actuator.design import with_replicas

    _, table = study_dir
    rows = with_spread(table.rows, {"bending_angle_deg": 40.0, "tip_dx_mm": 0.5, "tip_dz_mm": 0.5,
                                    "curling_index": 0.01})
    out = tmp_path / "out"
    for r in rows:
        if r["status"] != "failed":
            write_point(out, r, bend=-0.3)
    replicated = Table(rows)
    for s in pstudy.paper_sweeps(2):
        pfigures.plot_trends(replicated.select(s.name), s.field, tmp_path / f"{s.name}.png", s.label, s.unit)
        assert (tmp_path / f"{s.name}.png").read_bytes()[:8] == PNG_MAGIC
    text = preport.write_report(out, replicated, quick=True, wall_time_s=60.0,
                                base=with_replicas(pstudy.paper_base(True), 4)).read_text(encoding="utf-8")
    assert "one sample of a spread" not in text  # with replicas the spread is measured
    assert "Replicas: 4 per point (`--replicas 4`)" in text and "`hydrojam reproduce --quick --replicas 4`" in text
    assert "| 275 | 75.0 ± 40.0 | -50.0 ± 0.5 | -12.0 ± 0.5 | 0.50 ± 0.01 | 4/4 |" in text
    results = pclaims.check_claims(replicated)
    n_spread = sum(r.verdict == pclaims.SPREAD_VERDICT for r in results)
    assert n_spread >= 1 and f"{n_spread} {pclaims.SPREAD_VERDICT}." in text
    assert f"**{pclaims.SPREAD_VERDICT}**" in text and "u = √(s_a² + s_b²)" in text
    # a run's count is of replica runs, not of points: each point is 4 of them
    again = preport.write_report(out, replicated, quick=True, wall_time_s=60.0, computed=12,
                                 base=with_replicas(pstudy.paper_base(True), 4)).read_text(encoding="utf-8")
    n_points = len({r["key"] for r in rows})
    assert f"(this run: 12 of the {4 * n_points} runs ({n_points} points x 4 replicas) computed" in again


def _section(text: str, head: str) -> str:
    """The text of the Markdown section that starts with ``head`` (up to the next "## ")."""
    start = text.index(head)
    end = text.find("\n## ", start + len(head))
    return text[start:] if end < 0 else text[start:end]


def test_report_in_3d(study_dir, tmp_path):
    """A 3D study's report: its title, command and model say 3D (spheres, half model, tetrahedra),
    never 2D plane strain or cylinders outside the 2D-against-3D section; the reasons for a
    disagreement are the 3D ones; the 2D-against-3D section has the table with 2D results and
    says how to get them without."""
    from paper_synthetic import Table

    _, table = study_dir
    out = tmp_path / "out"
    out.mkdir()
    base = pstudy.paper_base(True, dimension=3)
    text = preport.write_report(out, table, True, 60.0, base=base).read_text(encoding="utf-8")
    assert text.startswith("# hydrojam reproduction of Chen, Schott & Jovanova, Section IV (Figs. 6-11), in 3D")
    run = _section(text, "## What was run")
    assert "**quick, 3D** (`hydrojam reproduce --dimension 3 --quick`)" in run
    assert "3D (particles are spheres; the half model" in run and "quadratic tetrahedra" in run
    assert "`hydrojam reproduce --dimension 3 --quick -o " in text
    claims = _section(text, "## The paper's statements")
    differences = _section(text, "## Model differences")
    for part in (run, claims, differences):
        assert "plane strain" not in part and "cylinder" not in part and "2D" not in part
    assert differences.count("\n- ") == len(preport.MODEL_DIFFERENCES_3D)
    assert preport.model_differences(2) == preport.MODEL_DIFFERENCES and preport.model_differences(3)[0].startswith(
        "hydrojam's 3D model has spheres")
    assert pclaims.DISAGREEMENT_REASONS_3D["h-angle"] in claims  # h-angle disagrees in study_dir
    assert "*No 2D results given.*" in _section(text, "## 2D against 3D")
    two = Table([dict(r, bending_angle_deg=(r["bending_angle_deg"] or 0) + 10.0) for r in table.rows])
    text = preport.write_report(out, table, True, 60.0, base=base, compare_2d=two,
                                compare_source="out2d").read_text(encoding="utf-8")
    compare = _section(text, "## 2D against 3D")
    assert "| point | θ 2D [deg] | θ 3D [deg] |" in compare and "`out2d`" in compare
    assert compare.count("\n| ") == 1 + 11  # the header and the 11 distinct designs of the quick study
    # a 2D report has no such section
    text2 = preport.write_report(out, table, True, 60.0).read_text(encoding="utf-8")
    assert "## 2D against 3D" not in text2 and "plane strain" in _section(text2, "## What was run")
