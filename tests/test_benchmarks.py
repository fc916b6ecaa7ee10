"""The benchmarks' instruments, run on a small problem: they observe the solver through its
events (hydrojam.fem.solver.events), and the recorders of the linear systems wrap PARDISO's
handle, so a change of either breaks them without any benchmark being run."""

import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from hydrojam.fem import LinearSolver
from hydrojam.fem.solver.newton import minimize
from hydrojam.fem.terms import EnergyTerm

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from _trace import FIELDS, IterationTrace  # noqa: E402


class _Quartic(EnergyTerm):
    """sum (x - 1)^4 / 4 + (x - 1)^2 / 2 [mJ]: one minimum at x = 1, a few Newton iterations."""

    name = "quartic"

    def energy(self, x):
        u = x.ravel() - 1.0
        return float(np.sum(u**4 / 4 + u**2 / 2))

    def gradient(self, x):
        u = x.ravel() - 1.0
        return u**3 + u

    def hessian(self, x, project=False):
        u = x.ravel() - 1.0
        return sp.diags(3 * u**2 + 1.0, format="csr")


def _minimised_with(*observers):
    """The quartic minimised from x = 3 with ``observers`` attached (as ``path.py`` attaches them)."""
    return minimize([_Quartic()], np.full((4, 1), 3.0), np.ones(4, dtype=bool), 1.0, observers=observers)


def test_the_iteration_trace_records_every_newton_iteration():
    """Attached, the trace sees every iteration of a minimisation, with the factorisations its
    direction took, and writes its columns."""
    trace = IterationTrace()
    res = _minimised_with(trace)
    assert res.converged and res.iterations == len(trace.rows) > 0
    assert all(set(row) == set(FIELDS) for row in trace.rows)
    assert all(row["solves"] == 1 and row["substitutions"] == 0 and row["projected"] == 0 for row in trace.rows)
    # the quartic's one pattern: analysed once
    assert [row["analysis"] for row in trace.rows] == [1] + [0] * (len(trace.rows) - 1)
    assert "iterations over 1 steps" in trace.summary("quartic")


def test_the_piece_timer_counts_the_pieces_of_a_minimisation():
    """Attached, the timer counts every direction and PARDISO call of a minimisation, PARDISO's
    calls also phase by phase (their counts and seconds add up to the calls'), and prints them
    costliest first."""
    from _pieces import PieceTimer

    from hydrojam.fem.solver.linsolve import _pardiso_available

    timer = PieceTimer()
    res = _minimised_with(timer)
    assert res.converged
    assert timer.calls["Newton direction"] == res.iterations > 0
    assert timer.calls["linear solver (solve)"] == res.iterations
    if _pardiso_available():
        phases = [name for name in timer.calls if name.startswith("PARDISO ") and name != "PARDISO calls"]
        # the quartic's one pattern: analysed once (phase 13), then refactorised (phase 23)
        assert timer.calls["PARDISO analysis + factorisation + substitution (LDL^T)"] == 1
        assert timer.calls["PARDISO factorisation + substitution (LDL^T)"] == res.iterations - 1
        assert sum(timer.calls[p] for p in phases) == timer.calls["PARDISO calls"]
        assert sum(timer.seconds[p] for p in phases) == pytest.approx(timer.seconds["PARDISO calls"], rel=1e-9)
    text = timer.summary("quartic", wall=1.0)
    assert "Newton direction" in text and "ms a call" in text


def test_the_piece_timer_names_a_pardiso_call_by_phase_and_keeps_refused_ones_apart():
    """A call that failed (PARDISO refusing a Cholesky) is counted under its phase with " refused"."""
    from types import SimpleNamespace

    from _pieces import PieceTimer

    timer = PieceTimer()
    timer.on_linear_solve(SimpleNamespace(call="solve", seconds=0.3, pattern_seconds=0.0, refine_seconds=0.0,
                                          pardiso=((23, "Cholesky", 0.1, True), (11, "Cholesky", 0.2, False))))
    assert timer.calls == {"linear solver (solve)": 1, "PARDISO calls": 2,
                           "PARDISO factorisation + substitution (Cholesky) refused": 1,
                           "PARDISO analysis (Cholesky)": 1}


def test_the_instruments_observe_one_minimisation_together_and_leave_it_as_it_was():
    """``path.py`` attaches the trace, the model check and the piece timer together: each sees
    the whole minimisation, and the minimisation is the one without them, to the bit."""
    from _model_check import ModelCheck
    from _pieces import PieceTimer

    alone = _minimised_with()
    trace, checker, timer = IterationTrace(), ModelCheck(1), PieceTimer()
    res = _minimised_with(trace, checker, timer)
    assert np.array_equal(res.x, alone.x) and res.iterations == alone.iterations
    assert len(trace.rows) == res.iterations and timer.calls["Newton direction"] == res.iterations
    assert len(checker.samples) == timer.calls["line search"]


def test_the_replica_tables_are_written_as_markdown_with_their_conditions(tmp_path):
    """``path.py --markdown``: a line of conditions naming the command and the commit, then per
    design a table whose mean, spread, extremes and per-run values are the rows' own."""
    import path as path_benchmark

    rows = [["default", "main", f"r{k}", "100", "0", "0", str(100 + 10 * k), "1.0", "True", f"{74.0 + k:.2f}",
             f"(-6{k}.0, -2.0)"] for k in range(3)]
    out = tmp_path / "replicas.md"
    path_benchmark._write_markdown(str(out), rows, 2, ["friction=0.01"])
    text = out.read_text(encoding="utf-8")
    assert text.startswith("Measured by `benchmarks/path.py") and "code of `" in text
    assert "**default** (friction=0.01), 3 run(s), variant main:" in text
    assert "| θ [deg] | 75.00 ± 1.00 | 74.00 (r0) | 76.00 (r2) | 74.00, 75.00, 76.00 |" in text
    assert "| Newton iterations (all) | 110 ± 10 | 100 (r0) | 120 (r2) | 100, 110, 120 |" in text


def test_a_marked_section_of_a_page_is_replaced_and_nothing_else():
    import path as path_benchmark

    page = "intro\n<!-- path.py: t -->\nold table\n<!-- /path.py: t -->\noutro\n"
    out = path_benchmark.replace_section(page, "t", "new table\n")
    assert out == "intro\n<!-- path.py: t -->\nnew table\n<!-- /path.py: t -->\noutro\n"
    assert path_benchmark.replace_section(out, "t", "new table") == out
    with pytest.raises(ValueError, match="no section"):
        path_benchmark.replace_section(page, "other", "x")


def test_the_design_map_table_reads_its_csv_in_kilopascals_and_marks_a_failed_point(tmp_path):
    """``design_map.py``: one row per point of OUT/design_map.csv, pressures MPa -> kPa, a negative
    angle with a minus sign, and "n/a" where a point failed (its empty cells)."""
    import design_map as map_benchmark

    (tmp_path / "design_map.csv").write_text(
        "side_wall_thickness,membrane.shear_modulus,bending_angle_deg,stiffness_ratio,contact_pressure_mean,"
        "contact_pressure_max,swelling_pressure,confinement_share,converged\n"
        "1.0,0.023,56.83,4.31,0.0046,0.0198,7.35,0.00063,True\n"
        "4.0,0.2,-2.1,12.6,0.0422,0.16,7.35,0.0057,True\n"
        "2.0,0.07,,,,,,,\n", encoding="utf-8")
    lines = map_benchmark.table(tmp_path)
    assert lines[2] == "| 1 | 0.023 | 56.8 | 4.3 | 4.6 / 19.8 | 0.00063 |"
    assert lines[3] == "| 4 | 0.2 | \u22122.1 | 12.6 | 42.2 / 160 | 0.0057 |"
    assert lines[4] == "| 2 | 0.07 | n/a | n/a | n/a / n/a | n/a |"


def test_the_cudss_recorder_stores_pardisos_calls_as_solvable_upper_triangles(tmp_path):
    """``cudss.py record``: each PARDISO call is kept with the pattern in force (1-based upper
    CSR), the values it factorised and its right-hand side, from which the replay rebuilds K;
    uninstalled, PARDISO's call is back."""
    import cudss

    from hydrojam.fem.solver import linsolve

    if not linsolve._pardiso_available():
        pytest.skip("PARDISO is not available")
    saved = linsolve._Pardiso.solve
    n = 30
    K = sp.diags([-np.ones(n - 1), 4.0 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1], format="csr")
    b = np.arange(1.0, n + 1)
    recorder = cudss.Recorder(pick={1})
    recorder.install()
    try:
        solver = LinearSolver("pardiso")
        x0 = solver.solve(K, b)
        x1 = solver.solve(2.0 * K, b)
        cholesky = linsolve._Pardiso(1, 2)  # refuses -K, which is negative definite
        upper = sp.triu(-K, format="csr")
        with pytest.raises(cholesky.error):
            cholesky.solve(upper.data, (upper.indptr + 1).astype(np.int32), (upper.indices + 1).astype(np.int32),
                           b, reuse_analysis=False)
    finally:
        recorder.uninstall()
    assert linsolve._Pardiso.solve is saved
    assert [m["new"] for m in recorder.meta] == [True, False, True]
    assert [m["ok"] for m in recorder.meta] == [True, True, False]
    kept = recorder.save(str(tmp_path / "calls.npz.xz"))
    meta, z = cudss._load(str(tmp_path / "calls.npz.xz"))
    assert meta == kept and [m["i"] for m in meta] == [1] and meta[0]["pattern"] == 0
    # a double LDL^T of a matrix of condition number below 3: errors of a few 1e-16, bounds 1e-12
    K1 = cudss._full(z["ia0"], z["ja0"], z["val1"])
    scale = np.abs(K1).max() * np.linalg.norm(x1)
    assert np.linalg.norm(K1 @ x1 - z["rhs1"]) <= 1e-12 * scale
    assert np.allclose(x0, 2.0 * x1, rtol=1e-12, atol=0.0)


def test_the_cholmod_replay_solves_every_recorded_cholesky_and_keeps_the_refusals(tmp_path, capsys):
    """``cholmod.py``: a record's Cholesky calls replayed through PARDISO in single (refined) and
    double precision, and CHOLMOD where scikit-sparse is installed: the same refusals as recorded,
    and solutions to the precision each promises."""
    import cholmod
    import cudss

    from hydrojam.fem.solver import linsolve

    if not linsolve._pardiso_available():
        pytest.skip("PARDISO is not available")
    n = 30
    K = sp.diags([-np.ones(n - 1), 4.0 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1], format="csr")
    b = np.arange(1.0, n + 1)
    recorder = cudss.Recorder()
    recorder.install()
    try:
        for matrix in (K, 2.0 * K, -K):  # the last is negative definite: refused
            upper = sp.triu(matrix, format="csr")
            handle = linsolve._Pardiso(1, 2)
            try:
                handle.solve(upper.data, (upper.indptr + 1).astype(np.int32), (upper.indices + 1).astype(np.int32),
                             b, reuse_analysis=False)
            except handle.error:
                pass
    finally:
        recorder.uninstall()
    recorder.save(str(tmp_path / "calls.npz.xz"))
    rows = cholmod.replay(str(tmp_path / "calls.npz.xz"))
    assert "PARDISO single" in rows and "PARDISO double" in rows
    # K's condition number is below 3: a double solve's relative residual is a few 1e-16 (bound
    # 1e-12), a single one is refined to 1e-8 (cudss.REFINE_TO)
    bounds = {name: cudss.REFINE_TO if name == "PARDISO single" else 1e-12 for name in rows}
    for name, r in rows.items():
        assert [x["refused"] for x in r] == [False, False, True], name
        assert all(x["residual"] <= bounds[name] for x in r[:2]), name
    assert "max residual" in capsys.readouterr().out


def test_the_model_check_measures_each_terms_deviation_from_its_quadratic_model():
    """Along a step d of length h at u0 = x - 1, the quartic's deviation from its quadratic model is
    its Taylor remainder, sum of u0 (h d)^3 + (h d)^4 / 4, at every fraction of the cap."""
    from _model_check import ModelCheck, term_deviations

    x, step, cap = np.full(4, 3.0), np.full(4, -1.5), 0.5
    dev, models, pairs = term_deviations([_Quartic()], x, step, (4, 1), cap)
    for a in (0.25, 0.5, 1.0):
        hd = a * cap * -1.5
        model = 4 * (hd * (2.0**3 + 2.0) + 0.5 * hd**2 * (3 * 2.0**2 + 1))
        assert models[a] == pytest.approx(model, rel=1e-12)
        # the energies are O(10) mJ: their difference is exact to about 1e-14 mJ
        assert dev[("quartic", a)] == pytest.approx(4 * (2.0 * hd**3 + hd**4 / 4), rel=1e-9, abs=1e-12)
    assert pairs.shape == (0, 3)

    check = ModelCheck(1)
    res = _minimised_with(check)
    assert res.converged and len(check.samples) == res.iterations
    assert "the quadratic model along" in check.summary("quartic")


def test_the_model_check_splits_the_contact_and_measures_each_pair():
    """Two parallel segments at gap g, one moved towards the other by delta: the same pairs at
    every fraction, no friction, every gap closing by delta / g, and the barrier's deviation that
    of ipctk's clamped log barrier on squared distances, B(s) = -(s - S)^2 ln(s / S), scaled by
    the energy at x."""
    from _model_check import ModelCheck, term_deviations

    from hydrojam.fem.contact import Contact, ContactSettings

    g, dhat, delta = 0.05, 0.1, 0.02
    X = np.array([[0, 0], [10, 0], [10, g], [0, g]], float)
    contact = Contact(X, np.array([[0, 1], [2, 3]]), np.array([0, 0, 1, 1]), ContactSettings(dhat=dhat, kappa=1.0))
    step = np.zeros(8)
    step[[5, 7]] = -delta
    dev, models, pairs = term_deviations([contact], X.ravel(), step, X.shape, 1.0)
    S = dhat**2

    def B(d):
        return -((d * d - S) ** 2) * np.log(d * d / S)

    def dB(d):  # dB/dd
        s = d * d
        return 2 * d * (-2 * (s - S) * np.log(s / S) - (s - S) ** 2 / s)

    def d2B(d):
        s = d * d
        Bs = -2 * (s - S) * np.log(s / S) - (s - S) ** 2 / s
        Bss = -2 * np.log(s / S) - 4 * (s - S) / s + (s - S) ** 2 / s**2
        return 4 * s * Bss + 2 * Bs

    scale = contact.energy(X) / B(g)
    for a in (0.25, 0.5, 1.0):
        h = a * delta
        expected = scale * (B(g - h) - B(g) + dB(g) * h - 0.5 * d2B(g) * h * h)
        assert dev[("contact", a)] == pytest.approx(expected, rel=1e-8)
        assert dev[("barrier, pairs at x", a)] == pytest.approx(expected, rel=1e-8)
        assert dev[("barrier, new pairs", a)] == 0.0 and abs(dev[("friction", a)]) <= 1e-12 * abs(models[a])
    # each pair's own deviation: together the pairs' barrier's, every gap from g to g - delta
    assert pairs[:, 0].sum() == pytest.approx(dev[("barrier, pairs at x", 1.0)], rel=1e-8)
    gaps = np.tile([g / dhat, (g - delta) / dhat], (len(pairs), 1))
    np.testing.assert_allclose(pairs[:, 1:], gaps, rtol=1e-12)

    check = ModelCheck(1)  # and its summary names the pieces
    check.samples, check.pairs = [(dev, models)], [pairs]
    text = check.summary("two segments")
    assert "barrier, pairs at x" in text and "closing by more than 30 %: 100.00% of 4 pair samples" in text
    # closed to a tenth of the gap, the model is off by 0.49 of its decrease, a quarter of that on
    # each of the four equal pairs: two of them account for the excess over a quarter
    step[[5, 7]] = -0.045
    dev, models, pairs = term_deviations([contact], X.ravel(), step, X.shape, 1.0)
    assert dev[("contact", 1.0)] / models[1.0] == pytest.approx(0.49, abs=0.01)
    check.samples, check.pairs = [(dev, models)], [pairs]
    assert "account for the excess: 2 in 1; the largest pair closes in 1" in check.summary("two segments")


def test_the_model_check_counts_the_pairs_behind_a_deviation():
    """The pairs taken out largest first until the rest is within the bound, and a pair's move."""
    from _model_check import MOST_PAIRS, pair_move, pairs_accounting

    devs = np.array([6.0, -1.0, 3.0, 0.5])  # largest first: 6, 3, -1, 0.5; rests 10, 4, 1, 2, 1.5
    assert pairs_accounting(10.0, devs, 2.0) == 2
    assert pairs_accounting(10.0, devs, 0.5) is None and MOST_PAIRS == 3
    assert pairs_accounting(1.0, devs, 2.0) == 0
    assert [pair_move(0.5, d1) for d1 in (1.2, 0.3, 0.7)] == ["leaves dhat", "closes", "opens within dhat"]


def _replicas_csv(out: Path, angles: list[float], state: str = "folded") -> None:
    """A replica study's replicas.csv: one finished run per angle, the tip and curling index from it."""
    out.mkdir(parents=True)
    lines = ["replica,bending_angle_deg,tip_dx_mm,tip_dz_mm,curling_index,newton_iterations,wall_time_s,states,status"]
    lines += [f"{k},{a},{-a / 1.5},{a / 3.0},{a / 200.0},900,600,{state},ok" for k, a in enumerate(angles)]
    (out / "replicas.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")


def test_the_mesh_table_reads_the_runs_a_stopped_replica_study_finished(tmp_path):
    """Without replicas.csv (a replica study stopped before its last run), the finished runs are
    read from their records in points/; the finest size's single run is said to be provisional."""
    import json

    import mesh as mesh_benchmark

    from hydrojam.actuator.design import apply_overrides, default_design
    from hydrojam.study.replicas import replica_study

    base = default_design()
    keys = [p.key for p in replica_study(apply_overrides(base, ["mesh.size=4.0"]), 2).points()]
    metrics = {"bending_angle_deg": 74.0, "tip_dx_mm": -64.0, "tip_dz_mm": -2.5, "curling_index": 0.74,
               "column_folds": 1, "newton_iterations": 1200, "wall_time_s": 70.0, "converged": True}
    (tmp_path / "mesh-4" / "points" / keys[0]).mkdir(parents=True)
    (tmp_path / "mesh-4" / "points" / keys[0] / "point.json").write_text(
        json.dumps({"key": keys[0], "status": "ok", "error": None, "metrics": metrics}), encoding="utf-8")
    runs = mesh_benchmark.read_runs(tmp_path / "mesh-4", 4.0, base, 2)
    assert (len(runs.runs), runs.total) == (1, 2) and runs.values("bending_angle_deg") == [74.0]
    text, chosen = mesh_benchmark.convergence_table([runs])
    assert chosen == 4.0 and "has one finished run" in text and "| 1 of 2 |" in text


def test_the_mesh_convergence_table_chooses_the_coarsest_size_within_the_finest_spread(tmp_path):
    """``mesh.py``: a size qualifies where every metric's mean lies within the finest's mean ± 2 s,
    s the larger standard deviation of the two; the coarsest such size is chosen, a coarser one
    beyond it is not."""
    import mesh as mesh_benchmark

    _replicas_csv(tmp_path / "mesh-6", [130.0, 130.2])  # 10° off: beyond
    _replicas_csv(tmp_path / "mesh-4", [121.0, 122.0, 123.0])  # mean 122, std 1: within 2 x 1 of 121
    _replicas_csv(tmp_path / "mesh-2", [120.9, 121.1])
    sizes = [mesh_benchmark.read_runs(tmp_path / f"mesh-{s}", float(s)) for s in (6, 4, 2)]
    text, chosen = mesh_benchmark.convergence_table(sizes)
    assert chosen == 4.0
    rows = [line for line in text.splitlines() if line.startswith("| ") and not line.startswith("| mesh")]
    assert [r.split(" | ")[0] for r in rows] == ["| 6", "| 4", "| 2"]
    assert "**beyond**: θ [deg] +9.00 (within" not in rows[0] and "**beyond**" in rows[0]
    assert "| 122.00 ± 1.00 |" in rows[1] and "**within**: θ [deg] +1.00 (within 2.00)" in rows[1]
    assert rows[2].endswith("| the finest |")
    # a state other than the finest's most common one is left out of the comparison
    _replicas_csv(tmp_path / "mesh-3", [160.0], state="arc")
    ok, notes = mesh_benchmark.qualifies(mesh_benchmark.read_runs(tmp_path / "mesh-3", 3.0), sizes[2])
    assert not ok and notes == ["no run in the state folded"]
    # the section of a page, written by the command over the folders (nothing run)
    page = tmp_path / "page.md"
    page.write_text("a\n<!-- mesh.py: m -->\n<!-- /mesh.py: m -->\nb\n", encoding="utf-8")
    assert mesh_benchmark.main(["--sizes", "6", "4", "2", "--replicas", "2", "3", "2", "--root", str(tmp_path),
                                "--report-only", "--markdown", str(page), "--section", "m"]) == 0
    written = page.read_text(encoding="utf-8")
    assert written.startswith("a\n<!-- mesh.py: m -->\nMeasured by `benchmarks/mesh.py --sizes 6 4 2 --replicas 2 3 2`")
    assert "The coarsest mesh within the finest's spread: **4 mm**." in written and written.endswith("b\n")
