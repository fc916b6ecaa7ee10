"""The study's results written into a page's marked sections (hydrojam.paper.sections)."""

from __future__ import annotations

import pytest
from paper_synthetic import Table, with_spread

from hydrojam.paper import claims as pclaims, sections as psections, study as pstudy

PAGE = """# A page

Text before.

<!-- reproduce: paper-quick -->
old table
<!-- /reproduce: paper-quick -->

Between.

<!-- reproduce: paper-quick verdicts -->
old verdicts
<!-- /reproduce: paper-quick verdicts -->

Text after.
"""


def _states(rows):
    """Two states: every point's replicas split 3 arc, 1 folded (the folded ones 30 deg lower)."""
    arc = [dict(r, replicas_used=3) for r in rows]
    folded = [dict(r, replicas_used=1, bending_angle_deg=(r.get("bending_angle_deg") or 0.0) - 30.0,
                   bending_angle_deg_std=None) for r in rows]
    return {"arc": Table(arc), "folded": Table(folded)}


def test_sections_are_replaced_and_the_rest_kept(study_dir, tmp_path):
    _, table = study_dir
    rows = with_spread(table.rows, {"bending_angle_deg": 1.5, "tip_dx_mm": 0.5, "tip_dz_mm": 0.5, "curling_index": 0.01})
    replicated = Table(rows)
    results = pclaims.check_claims(replicated)
    base = pstudy.paper_base(True)
    lines = psections.results_lines(replicated, base, True, 4, 2, _states(rows), results)
    page = tmp_path / "page.md"
    page.write_text(PAGE, encoding="utf-8")
    written = psections.write_sections(page, "paper-quick", lines, psections.verdict_lines(results, "paper-quick"))
    assert written == ["paper-quick", "paper-quick verdicts"]
    text = page.read_text(encoding="utf-8")
    assert "old table" not in text and "old verdicts" not in text
    for kept in ("# A page", "Text before.", "Between.", "Text after."):
        assert text.count(kept) == 1
    table_part = text.split("<!-- reproduce: paper-quick -->")[1].split("<!-- /reproduce: paper-quick -->")[0]
    assert table_part.lstrip().startswith("Conditions: `hydrojam reproduce --quick --replicas 4`, runs computed by the code of `")
    assert "mesh 4 mm, 4 runs a point, friction 0.01, 2 workers" in table_part
    assert "| temperature | 275 K | " in table_part and "± 1.5" in table_part
    assert "arc 3: " in table_part and "folded 1: " in table_part  # each state's runs and θ
    counts = {v: sum(r.verdict == v for r in results) for v in pclaims.Verdict}
    verdict_part = text.split("<!-- reproduce: paper-quick verdicts -->")[1]
    for v, n in counts.items():
        assert (f"| {v} | {n}: " in verdict_part) == (n > 0)
    # again: the same page, the sections replaced once more, nothing duplicated
    psections.write_sections(page, "paper-quick", ["new"], ["newer"])
    text = page.read_text(encoding="utf-8")
    assert text.count("<!-- reproduce: paper-quick -->") == 1 and "\nnew\n" in text and "\nnewer\n" in text


def test_a_page_without_the_study_section_is_refused(tmp_path):
    page = tmp_path / "page.md"
    page.write_text(PAGE, encoding="utf-8")
    with pytest.raises(psections.SectionError, match=r"no section <!-- reproduce: paper-3d-quick -->"):
        psections.check_page(page, "paper-3d-quick")
    with pytest.raises(psections.SectionError, match=r"cannot be read"):
        psections.check_page(tmp_path / "missing.md", "paper-quick")
    psections.check_page(page, "paper-quick")


def test_the_cli_refuses_a_page_without_a_section_before_any_work(tmp_path, capsys):
    from hydrojam.cli import main

    page = tmp_path / "page.md"
    page.write_text("# nothing marked\n", encoding="utf-8")
    out = tmp_path / "out"
    assert main(["reproduce", "--quick", "-o", str(out), "--write-results", str(page)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--write-results" in err and "no section" in err
    assert not out.exists() and page.read_text(encoding="utf-8") == "# nothing marked\n"


SENSITIVITY_PAGE = """# Sensitivity

<!-- reproduce: paper-quick sensitivity -->
<!-- /reproduce: paper-quick sensitivity -->

After.
"""


def test_the_table_of_verdict_against_choice_keeps_a_row_per_study(study_dir, tmp_path):
    """The default's row and each --set study's row, each replaced by its own rerun, the default's
    first; a point's states and each state's verdict beside the verdict on all runs; a page with only
    this section takes a variant's results (check_page) and its own sections are not required."""
    _, table = study_dir
    rows = with_spread(table.rows, {"bending_angle_deg": 1.5, "tip_dx_mm": 0.5, "tip_dz_mm": 0.5, "curling_index": 0.01})
    for r in rows:
        r["states"] = "arc 3; folded 1"
    replicated = Table(rows)
    results = pclaims.check_claims(replicated)
    page = tmp_path / "page.md"
    page.write_text(SENSITIVITY_PAGE, encoding="utf-8")
    variant = pstudy.study_name(True, 2, ["friction=0.3"])
    psections.check_page(page, variant)
    assert psections.write_sections(page, variant, ["t"], ["v"]) == []  # no section of its own: nothing, no error

    def row(overrides, states):
        return psections.sensitivity_row(replicated, 2, 4, overrides, states, results, ("abcdef0123",))

    for overrides in (["friction=0.3"], [], ["friction=0.3"], ["clearance=0.2"]):
        assert psections.write_sensitivity_row(page, pstudy.study_name(True, 2, overrides), 2,
                                               row(overrides, _states(rows)))
    part = page.read_text(encoding="utf-8").split("sensitivity -->")[1]
    lines = [line for line in part.splitlines() if line.startswith("| ")]
    ids = [c.id for c in pclaims.PAPER_CLAIMS if c.sweep != "strain_limit_width"]
    assert lines[0] == "| model choice | runs | states | " + " | ".join(ids) + " | code |"
    assert [line.split(" | ")[0] for line in lines[1:]] == ["| default", "| `clearance=0.2`", "| `friction=0.3`"]
    default = lines[1].split(" | ")
    assert len(default) == len(ids) + 4 and default[-1] == "`abcdef0` |"
    assert "T 275 K: arc 3, folded 1; T 285 K: " in default[2] and "; h 12 mm: arc 3, folded 1" in default[2]
    by_id = {r.claim.id: r for r in results}
    per_state = {n: {r.claim.id: r for r in pclaims.check_state_claims(t)} for n, t in _states(rows).items()}
    for cid, text in zip(ids, default[3:-1]):  # each state's verdict where its runs decide one
        decided = [f"{n}: {v[cid].verdict}" + (" (part of the range)" if "checked on the points run" in v[cid].summary else "")
                   for n, v in per_state.items() if not str(v[cid].verdict).startswith("undetermined")]
        assert text == str(by_id[cid].verdict) + ("; " + ", ".join(decided) if decided else "")
    assert any("; arc: " in text for text in default[3:-1])
    assert page.read_text(encoding="utf-8").endswith("\nAfter.\n")
    # one state: the verdict alone
    single = row([], {"arc": replicated}).split(" | ")
    assert single[3] == str(by_id[ids[0]].verdict)


def test_the_figure_section_shows_the_study_figures_beside_the_page(tmp_path):
    """write_figure_section copies each figure into _static/NAME/ beside the page, links it with its
    caption, removes a copy no longer the study's; a page without the section gets nothing."""
    figures = []
    for k, stem in enumerate(("temperature_trends", "particle_layers_trends")):
        source = tmp_path / "out" / "figures" / f"{stem}.png"
        source.parent.mkdir(parents=True, exist_ok=True)
        source.write_bytes(bytes([137, 80, 78, 71, k]))
        figures.append((f"caption {k}", source))
    docs = tmp_path / "docs"
    docs.mkdir()
    page = docs / "page.md"
    page.write_text("# p\n\nBefore.\n<!-- reproduce: s figures -->\nold\n<!-- /reproduce: s figures -->\nAfter.\n",
                    encoding="utf-8")
    stale = docs / "_static" / "s" / "strain_limit_thickness_trends.png"
    stale.parent.mkdir(parents=True)
    stale.write_bytes(b"old")
    written = psections.write_figure_section(page, "s", figures)
    assert [p.name for p in written] == ["temperature_trends.png", "particle_layers_trends.png"]
    assert all(copy.read_bytes() == source.read_bytes() for copy, (_, source) in zip(written, figures))
    assert not stale.exists()
    assert page.read_text(encoding="utf-8") == (
        "# p\n\nBefore.\n<!-- reproduce: s figures -->\n![caption 0](_static/s/temperature_trends.png)\n\n"
        "![caption 1](_static/s/particle_layers_trends.png)\n<!-- /reproduce: s figures -->\nAfter.\n")
    other = tmp_path / "other.md"
    other.write_text(PAGE, encoding="utf-8")
    assert psections.write_figure_section(other, "s", figures) == []
    assert other.read_text(encoding="utf-8") == PAGE and not (tmp_path / "_static").exists()
