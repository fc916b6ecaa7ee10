"""report.md of hydrojam.paper.report, from a synthetic quick study with failed and unconverged points."""

from __future__ import annotations

import re

from paper_synthetic import PNG_MAGIC

from hydrojam.paper import claims as pclaims, figures as pfigures, report as preport, study as pstudy


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
    # the title question is answered by `assess`, and the report says how to run it (issue 15)
    assert "## The title question" in text and "hydrojam assess design.toml" in text
    assert f"{pclaims.ANGLE_TOL:g} ×" in text
    from hydrojam import __version__

    assert f"hydrojam {__version__}" in text
    verdicts = [line.split(" | ")[3] for line in claims]
    assert all(v in ("**agree**", "**disagree**", "**undetermined**") for v in verdicts)
    # the four temperature claims (295 K failed, 2 points left) and h-displacement (nothing in 10-12 mm)
    assert verdicts.count("**undetermined**") == 5
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
    for s in pstudy.PAPER_SWEEPS:
        pfigures.plot_trends(replicated.select(s.name), s.field, tmp_path / f"{s.name}.png", s.label, s.unit)
        assert (tmp_path / f"{s.name}.png").read_bytes()[:8] == PNG_MAGIC
    text = preport.write_report(out, replicated, quick=True, wall_time_s=60.0,
                                base=with_replicas(pstudy.paper_base(True), 4)).read_text(encoding="utf-8")
    assert "Replicas: 4 per point (`--replicas 4`)" in text and "`hydrojam reproduce --quick --replicas 4`" in text
    assert "| 275 | 75.0 ± 40.0 | -50.0 ± 0.5 | -12.0 ± 0.5 | 0.50 ± 0.01 | 4/4 |" in text
    results = pclaims.check_claims(replicated)
    n_spread = sum(r.verdict == pclaims.SPREAD_VERDICT for r in results)
    assert n_spread >= 1 and f"{n_spread} {pclaims.SPREAD_VERDICT}." in text
    assert f"**{pclaims.SPREAD_VERDICT}**" in text and "u = √(s_a² + s_b²)" in text
