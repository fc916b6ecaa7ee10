"""The paper's statements checked by hydrojam.paper.claims on synthetic rows."""

from __future__ import annotations

import pytest
from paper_synthetic import FIELDS, layer_rows, row, temperature_rows, thickness_rows, with_values

from hydrojam.paper import claims as pclaims, study as pstudy


def test_claim_ids_unique_with_reasons():
    ids = [c.id for c in pclaims.PAPER_CLAIMS]
    assert len(ids) == len(set(ids)) == 12
    assert len(pclaims.paper_claims(2)) == 10  # the strip-width reading of h is 3D only
    assert [c.id for c in pclaims.paper_claims(3)] == ids
    assert set(pclaims.DISAGREEMENT_REASONS) == set(ids)
    assert all("likely" in text for text in pclaims.DISAGREEMENT_REASONS.values())
    assert {c.sweep for c in pclaims.PAPER_CLAIMS} == {s.name for s in pstudy.PAPER_SWEEPS}


@pytest.mark.parametrize("quick", [False, True])
def test_paper_like_rows_agree(quick):
    """Rows that follow every statement agree on the full and the quick grid: the quick h grid
    carries 10 mm, the break point of both h statements, so both halves are checked."""
    pts = pstudy.paper_points(quick)
    Ts, PLs, hs = (pts[s][f] for s, f in zip(("temperature", "particle_layers", "strain_limit_thickness"), FIELDS))
    assert 10.0 in hs
    rows = temperature_rows(Ts) + layer_rows(PLs) + thickness_rows(hs)
    for res in pclaims.check_claims(rows):
        assert res.verdict == "agree", (res.claim.id, res.summary)
        assert "nan" not in res.summary.lower()


def test_h_claims_without_the_break_point_are_undetermined():
    """h = 4, 8, 12 mm: "4 to 10 mm" is checked from 4 to 8 mm and "10 to 12 mm" cannot be."""
    results = {r.claim.id: r for r in pclaims.check_claims(thickness_rows([4.0, 8.0, 12.0]))}
    for cid in ("h-angle", "h-displacement"):
        assert results[cid].verdict == "undetermined", results[cid].summary
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


# -------------------------------------------------------------------- with replicas' spread

FALLS = pclaims.Claim(id="falls", sweep="temperature", figure="-", paper="-", rule="-", quantities=("bending_angle_deg",),
                      trends=(pclaims.Trend("falls", 275.0, 295.0),), tolerance=pclaims.ANGLE_TOL, reason="-")


def test_a_trend_decides_only_beyond_the_spread():
    """θ falls 75 -> 29° over 275-295 K: tol = 0.05 x 75 = 3.75°, margin 46 - 3.75 = 42.25° against
    u = sqrt(2) s (s the standard deviation at both ends): agree for s < 42.25/sqrt(2) = 29.875°,
    undetermined (spread) above. Rising instead (75 -> 121°, tol 0.05 x 121 = 6.05°): the margin
    -52.05° disagrees while u < 52.05°, i.e. s < 36.805°."""
    from paper_synthetic import with_spread

    rows = temperature_rows()
    for s, verdict in ((29.85, "agree"), (29.9, pclaims.SPREAD_VERDICT)):
        res = pclaims.check_claim(FALLS, with_spread(rows, {"bending_angle_deg": s}))
        assert res.verdict == verdict, (s, res.summary)
    res = pclaims.check_claim(FALLS, with_spread(rows, {"bending_angle_deg": 29.9}))
    assert "75.0 ± 29.9°" in res.summary and "-46.0° ± 42.3°" in res.summary
    assert "undetermined (spread): +42.2° from the threshold, within the spread ±42.3°" in res.summary
    rising = temperature_rows(sign=+1.0)
    for s, verdict in ((36.79, "disagree"), (36.82, pclaims.SPREAD_VERDICT)):
        assert pclaims.check_claim(FALLS, with_spread(rising, {"bending_angle_deg": s})).verdict == verdict, s


def test_spread_small_keeps_the_verdicts_large_leaves_them_open():
    """Paper-like rows with a small spread agree as without one; with a spread far above every
    trend, no claim agrees or disagrees: each is undetermined (spread), with the numbers."""
    from paper_synthetic import with_spread

    rows = temperature_rows() + layer_rows() + thickness_rows()
    keys = ("bending_angle_deg", "tip_dx_mm", "tip_dz_mm", "curling_index")
    small = pclaims.check_claims(with_spread(rows, dict.fromkeys(keys, 0.01)))
    assert [r.verdict for r in small] == ["agree"] * len(small)
    large = [dict(r, curling_index_min=0.0, curling_index_max=1.0)  # every replica's index in [0, 1]
             for r in with_spread(rows, dict.fromkeys(keys, 100.0))]
    large = pclaims.check_claims(large)
    for res in large:
        assert res.verdict == pclaims.SPREAD_VERDICT, (res.claim.id, res.summary)
        assert "±" in res.summary and pclaims.SPREAD_VERDICT in res.summary
    # a part that clearly disagrees still decides the claim, whatever another part's spread
    wrong = with_values(with_spread(temperature_rows(), {"bending_angle_deg": 100.0}),
                        bending_angle_deg={285.0: 500.0})
    wrong = [dict(r, bending_angle_deg_std=0.0) if r["stimulus.temperature"] in (280.0, 285.0) else r for r in wrong]
    res = {r.claim.id: r for r in pclaims.check_claims(wrong)}["T-angle"]
    assert res.verdict == "disagree", res.summary


def test_a_replica_reversing_its_rotation_makes_the_curling_index_unusable():
    """The mean curling index of a point is not used when a replica's index lies outside [0, 1]."""
    from paper_synthetic import with_spread

    rows = with_spread(layer_rows(), {"curling_index": 0.01})
    rows = [dict(r, curling_index_min=-0.4) if r["particle_layers"] == 12 else r for r in rows]
    res = {r.claim.id: r for r in pclaims.check_claims(rows)}["PL-curling"]
    assert "12 (curling index of a replica outside [0, 1] (-0.40 to 0.72" in res.summary
    assert res.verdict == "agree"  # the other points still show the transition


def test_a_point_not_finished_leaves_the_claim_open_and_says_what_the_others_read():
    """A table written while the study runs (`reproduce --report-only`): a claim whose sweep has
    a point not finished is undetermined whatever the finished points read, and says what they
    read; an unfinished end point leaves the claim undetermined as a failed one does."""
    rows = with_values(layer_rows(), bending_angle_deg={15: 120.0})  # PL 15 far above PL 9's 80°
    assert {r.claim.id: r for r in pclaims.check_claims(rows)}["PL-angle"].verdict == "disagree"
    rows[6] = row("particle_layers", "particle_layers", 11, None, None, None, status="unfinished",
                  error="not finished: s = 0.500 reached")
    res = {r.claim.id: r for r in pclaims.check_claims(rows)}
    assert res["PL-angle"].verdict == "undetermined"
    assert res["PL-angle"].summary.startswith("not final, PL 11 not finished; the finished points alone read disagree: ")
    assert res["PL-dx"].verdict == "undetermined"
    assert res["PL-dx"].summary.startswith("not final, PL 11 not finished; the finished points alone read agree: ")
    assert "skipped 11 (not finished)" in res["PL-dx"].summary
    rows[-1] = row("particle_layers", "particle_layers", 19, None, None, None, status="unfinished")
    res = {r.claim.id: r for r in pclaims.check_claims(rows)}
    assert res["PL-dx"].verdict == "undetermined" and "|δx| at 19: not finished" in res["PL-dx"].summary


def test_a_point_with_one_run_takes_its_sweeps_largest_spread():
    """One run measures no spread: with 29.9° at 275 K (4 runs) and one run at 295 K, the
    comparison's spread is sqrt(2) x 29.9° = 42.3° (not 29.9°), and the margin of 42.2° lies
    within it, as when both points spread by 29.9°; the one run is named."""
    from paper_synthetic import with_spread

    rows = with_spread(temperature_rows(), {"bending_angle_deg": 29.9})
    rows = [dict(r, replicas_used=1, bending_angle_deg_std=None) if r["stimulus.temperature"] == 295.0 else r
            for r in rows]
    res = pclaims.check_claim(FALLS, rows)
    assert res.verdict == pclaims.SPREAD_VERDICT, res.summary
    assert "-46.0° ± 42.3°" in res.summary and "29.0° (one run)" in res.summary


def test_a_point_with_some_replicas_finished_is_used_with_them_and_keeps_the_claim_open():
    """A study in progress: PL 11 with 1 of 3 replicas finished is read with that run (not
    skipped), and the claim is not final until the point finishes."""
    from paper_synthetic import with_spread

    rows = with_spread(layer_rows(), {"bending_angle_deg": 0.5, "tip_dx_mm": 0.5}, replicas=3)
    rows = [dict(r, status="unfinished", replicas_used=1, bending_angle_deg_std=None, tip_dx_mm_std=None)
            if r["particle_layers"] == 11 else r for r in rows]
    res = {r.claim.id: r for r in pclaims.check_claims(rows)}
    assert res["PL-dx"].verdict == "undetermined"
    assert res["PL-dx"].summary.startswith(
        "not final, PL 11 (1 of 3 runs) not finished; the finished points alone read agree: "), res["PL-dx"].summary
    assert "skipped" not in res["PL-dx"].summary
    finished = {r.claim.id: r for r in pclaims.check_claims(
        [dict(r, status="ok", replicas_used=3) for r in rows])}
    assert finished["PL-dx"].verdict == "agree", finished["PL-dx"].summary


def test_a_state_is_checked_over_the_points_where_it_occurs():
    """A state's table (one row a point, a point without a run in that state marked "no replica in
    state"): the claims are checked over the points the state reached, the summary naming that
    part of the paper's range; counted as failed, the same point would leave them undetermined."""
    from hydrojam.study.table import NOT_IN_STATE

    rows = temperature_rows()
    rows[0] = dict(rows[0], status="failed", error=f"{NOT_IN_STATE} arc", bending_angle_deg=None,
                   tip_dx_mm=None, tip_dz_mm=None)
    results = {r.claim.id: r for r in pclaims.check_state_claims(rows)}
    assert results["T-angle"].verdict == "agree"
    assert "the paper's 275 K to 295 K checked on the points run, 280 K to 295 K" in results["T-angle"].summary
    assert {r.claim.id: r.verdict for r in pclaims.check_claims(rows)}["T-angle"] == "undetermined"
