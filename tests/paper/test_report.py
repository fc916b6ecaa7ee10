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
    assert f"{pclaims.ANGLE_TOL:g} ×" in text
    from hydrojam import __version__

    assert f"hydrojam {__version__}" in text
    verdicts = [line.split(" | ")[3] for line in claims]
    assert all(v in ("**agree**", "**disagree**", "**undetermined**") for v in verdicts)
    # the four temperature claims (295 K failed, 2 points left) and h-displacement (nothing in 10-12 mm)
    assert verdicts.count("**undetermined**") == 5
    assert verdicts.count("**disagree**") == 2
