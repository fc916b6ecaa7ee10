"""Results on disk (docs/actuator.md, "Outputs"; layout in hydrojam.actuator.results): cell fields verified against
closed-form stresses, the VTU and PVD files, and the ResultWriter end to end.

No test here runs the solver: states are built by hand (StepState, SimulationResult) from the
reference positions X moved by closed-form maps (rigid rotations, homogeneous deformations).
Coordinates are (x, z) in hydrojam; results are written in ParaView's (x, y, z) with y = 0.
"""

from __future__ import annotations

import csv
import json
import math
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pytest

from hydrojam.actuator.design import apply_overrides, default_design, load_design
from hydrojam.actuator.model import MEMBRANE_BODY, PARTICLE_BODY, STRAIN_LIMIT_BODY, build_model, measure
from hydrojam.actuator.fields import cell_fields
from hydrojam.actuator.results import HISTORY_COLUMNS, ResultWriter, history_row, pvd_text, write_vtu
from hydrojam.actuator.simulate import SimulationResult, StepState

G, NU = 0.023, 0.45  # Ecoflex 00-30 (membrane and strain-limit layer defaults) [MPa], [-]
F2 = np.array([[1.1, 0.05], [0.0, 0.95]])  # homogeneous deformation gradient in (x, z)
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def model():
    return build_model(apply_overrides(default_design(), ["particle_layers=2"]))


@pytest.fixture(scope="module")
def X(model):
    return model.mesh.points


def clockwise(points: np.ndarray, angle_deg: float) -> np.ndarray:
    """Points rotated clockwise by angle_deg about the origin (the clamp centre) in (x, z)."""
    a = np.radians(angle_deg)
    return points @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]]).T


def make_state(model, index: int, s: float, x: np.ndarray, iterations: int = 0, wall: float = 0.0,
               metrics: dict | None = None) -> StepState:
    mu, T = model.stimulus(s)
    return StepState(index, s, float(mu), float(T), x, measure(model, x) if metrics is None else metrics,
                     iterations, wall)


def plane_strain_F3(F: np.ndarray) -> np.ndarray:
    """(x, z) deformation gradient as a 3D one in (x, y, z), out-of-plane stretch 1."""
    return np.array([[F[0, 0], 0.0, F[0, 1]], [0.0, 1.0, 0.0], [F[1, 0], 0.0, F[1, 1]]])


def von_mises(sigma: np.ndarray) -> float:
    s = sigma - np.trace(sigma) / 3 * np.eye(3)
    return math.sqrt(1.5 * np.sum(s * s))


# ------------------------------------------------------------------------------------------------
# Cell fields


def test_cell_fields_as_prepared_state_is_stress_free(model, X):
    """As prepared (s = 0): the gel is stress-free by the choice of mu0 (and the elastomers are
    undeformed), so every stress vanishes; the gel holds lambda0^3 = 1.5^3 = 3.375 times its dry
    volume, the elastomers report 1."""
    f = cell_fields(model, X, 0.0)
    n = model.mesh.n_cells
    assert f["cauchy_stress"].shape == (n, 3, 3)
    assert np.abs(f["cauchy_stress"]).max() < 1e-9
    assert np.abs(f["von_mises_stress"]).max() < 1e-9
    gel = f["body_id"] >= PARTICLE_BODY
    assert gel.any() and (~gel).any()
    assert np.allclose(f["swelling_ratio"][gel], 1.5**3, rtol=1e-12)
    assert np.all(f["swelling_ratio"][~gel] == 1.0)


def test_cell_fields_body_ids(model):
    """body_id: 0 membrane, 1 strain-limit layer, 2 + k particle k (module docstring)."""
    ids = cell_fields(model, model.mesh.points, 0.0)["body_id"]
    assert ids.dtype == np.int32
    groups = model.mesh.cell_groups
    assert (MEMBRANE_BODY, STRAIN_LIMIT_BODY, PARTICLE_BODY) == (0, 1, 2)
    assert np.all(ids[groups["membrane"]] == 0)
    assert np.all(ids[groups["strain_limit_layer"]] == 1)
    for k in range(model.n_particles):
        assert np.all(ids[groups[f"particle{k}"]] == 2 + k)
    assert sorted(np.unique(ids)) == [0, 1, 2, 3]


def test_cell_fields_neo_hookean_cauchy_stress(model, X):
    """Homogeneous x = F X, plane strain: the elastomer cells' Cauchy stress equals the
    compressible neo-Hookean (Abaqus form, W = G/2 (I1bar - 3) + K/2 (J - 1)^2) in closed form,
    sigma = G / J^(5/3) (b - I1/3 I) + K (J - 1) I, b = F3 F3^T, K = 2G(1 + nu) / (3(1 - 2nu)),
    with F3 the 3D gradient (out-of-plane stretch 1) in ParaView's (x, y, z); von Mises
    sqrt(3/2 s:s) of that sigma."""
    F3 = plane_strain_F3(F2)
    J = np.linalg.det(F3)
    b = F3 @ F3.T
    K = 2 * G * (1 + NU) / (3 * (1 - 2 * NU))
    sigma = G / J ** (5 / 3) * (b - np.trace(b) / 3 * np.eye(3)) + K * (J - 1) * np.eye(3)
    f = cell_fields(model, X @ F2.T, 0.0)
    elastomer = np.concatenate([model.mesh.cell_groups["membrane"], model.mesh.cell_groups["strain_limit_layer"]])
    got = f["cauchy_stress"][elastomer]
    assert np.allclose(got, sigma, rtol=1e-10, atol=1e-12 * np.abs(sigma).max())
    # symmetric: P F^T / J is symmetric only up to round-off of the stress, eps x |sigma| x a few
    assert np.allclose(got, np.swapaxes(got, 1, 2), rtol=0, atol=1e-12 * np.abs(sigma).max())
    assert sigma[1, 1] != 0.0  # plane strain carries an out-of-plane stress
    assert np.allclose(f["von_mises_stress"][elastomer], von_mises(sigma), rtol=1e-10)
    assert np.all(f["swelling_ratio"][elastomer] == 1.0)


def test_cell_fields_gel_cauchy_stress(model, X):
    """Homogeneous x = F X in the gel at the as-prepared stimulus (mu0, T0): the Cauchy stress of
    the Flory-Rehner gel (Hong et al. 2008; Cai & Suo 2011) in terms of the dry-state gradient
    Fd = lambda0 F3, Jd = det Fd,
    sigma = (kT/nu) [ n/Jd (bd - I) + (ln(1 - 1/Jd) + 1/Jd + (chi0 - chi1)/Jd^2 + 2 chi1/Jd^3 - mu) I ],
    chi = chi0 + chi1/Jd, chi0 = A0 + B0 T, chi1 = A1 + B1 T; swelling ratio Jd = lambda0^3 det F."""
    p = model.gel.params
    mu, T = model.stimulus(0.0)
    Fd = p.lambda0 * plane_strain_F3(F2)
    Jd = np.linalg.det(Fd)
    chi0, chi1 = p.A0 + p.B0 * T, p.A1 + p.B1 * T
    mix = math.log(1 - 1 / Jd) + 1 / Jd + (chi0 - chi1) / Jd**2 + 2 * chi1 / Jd**3 - mu
    sigma = p.kT_over_nu * (p.n / Jd * (Fd @ Fd.T - np.eye(3)) + mix * np.eye(3))
    f = cell_fields(model, X @ F2.T, 0.0)
    gel = np.concatenate(model.particle_cells)
    assert np.allclose(f["cauchy_stress"][gel], sigma, rtol=1e-8, atol=1e-10 * np.abs(sigma).max())
    assert np.allclose(f["von_mises_stress"][gel], von_mises(sigma), rtol=1e-8)
    assert np.allclose(f["swelling_ratio"][gel], p.lambda0**3 * np.linalg.det(F2), rtol=1e-12)


def test_cell_fields_rigid_rotation_is_stress_free(model, X):
    """Objectivity: a rigid rotation of the as-prepared state leaves every stress zero."""
    f = cell_fields(model, clockwise(X, 40.0), 0.0)
    assert np.abs(f["cauchy_stress"]).max() < 1e-9


# ------------------------------------------------------------------------------------------------
# VTU and PVD


def test_write_vtu_round_trip(model, X, tmp_path):
    """Points (x, 0, z), displacement (u_x, 0, u_z), the four cell fields (stress as 9 components)."""
    x = X @ F2.T + np.array([0.3, -0.2])
    state = make_state(model, 3, 0.0, x)
    path = tmp_path / "steps" / "step_0003.vtu"
    write_vtu(path, model, state)
    m = meshio.read(path)
    n = len(X)
    assert m.points.shape == (n, 3)
    assert np.allclose(m.points, np.column_stack([X[:, 0], np.zeros(n), X[:, 1]]), rtol=0, atol=1e-12)
    u = m.point_data["displacement"]
    assert u.shape == (n, 3)
    assert np.allclose(u, np.column_stack([x[:, 0] - X[:, 0], np.zeros(n), x[:, 1] - X[:, 1]]), rtol=0, atol=1e-12)
    assert [c.type for c in m.cells] == ["triangle6"]
    assert np.array_equal(m.cells[0].data, model.mesh.cells)
    f = cell_fields(model, x, 0.0)
    cd = {k: v[0] for k, v in m.cell_data.items()}
    assert set(cd) == {"body_id", "swelling_ratio", "cauchy_stress", "von_mises_stress"}
    assert np.array_equal(cd["body_id"].ravel(), f["body_id"])
    assert np.allclose(cd["swelling_ratio"].ravel(), f["swelling_ratio"], rtol=1e-15)
    assert cd["cauchy_stress"].shape == (model.mesh.n_cells, 9)
    assert np.allclose(cd["cauchy_stress"].reshape(-1, 3, 3), f["cauchy_stress"], rtol=1e-15)
    assert np.allclose(cd["von_mises_stress"].ravel(), f["von_mises_stress"], rtol=1e-15)
    assert [p.name for p in path.parent.iterdir()] == ["step_0003.vtu"]  # no temporary left


def test_pvd_text_parses_in_order():
    entries = [(0.0, "steps/step_0000.vtu"), (0.125, "steps/step_0001.vtu"), (1.0, "steps/a&b \"c\".vtu")]
    root = ET.fromstring(pvd_text(entries))
    assert root.tag == "VTKFile" and root.get("type") == "Collection"
    data = root.findall("./Collection/DataSet")
    assert [float(d.get("timestep")) for d in data] == [0.0, 0.125, 1.0]
    assert [d.get("file") for d in data] == [f for _, f in entries]
    assert ET.fromstring(pvd_text([])).findall("./Collection/DataSet") == []


def test_history_row_columns_and_no_nan(model, X):
    """The documented columns in order; curling_index None gives an empty cell and a NaN metric
    no NaN (the written file is checked in test_no_nan_is_ever_written)."""
    metrics = dict(measure(model, X), max_curvature_per_mm=float("nan"))
    row = history_row(make_state(model, 0, 0.0, X, metrics=metrics))
    assert list(row) == HISTORY_COLUMNS
    assert row["curling_index"] == ""
    assert not any(isinstance(v, float) and not math.isfinite(v) for v in row.values())
    assert row["step"] == 0 and row["s"] == 0.0 and row["bending_angle_deg"] == 0.0


# ------------------------------------------------------------------------------------------------
# ResultWriter end to end


def read_csv(path):
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        return reader.fieldnames, list(reader)


def pvd_files(path):
    return [(float(d.get("timestep")), d.get("file")) for d in ET.parse(path).getroot().iter("DataSet")]


def result_of(model, states, converged=True):
    return SimulationResult(model, states, converged, "converged" if converged else "step too small",
                            12.5, 40, 1, {"total": 12.5, "elastic": 3.0, "contact": 2.0, "linear_solve": 4.0},
                            {"damping_N_per_mm3": 0.0, "max_energy_ratio": 0.0, "released": True})


def test_result_writer_end_to_end(model, X, tmp_path):
    out = tmp_path / "out"
    w = ResultWriter(out, model)
    w.start()
    assert load_design(out / "design.toml") == model.design
    s0 = make_state(model, 0, 0.0, X, 0, 0.1)
    s1 = make_state(model, 1, 0.5, clockwise(X, 10.0), 6, 1.0)
    s1_again = make_state(model, 1, 1.0, clockwise(X, 25.0), 9, 2.0)  # same index: replaces s1
    for st in (s0, s1, s1_again):
        w.step(st)

    columns, rows = read_csv(out / "history.csv")
    assert columns == HISTORY_COLUMNS
    assert [int(r["step"]) for r in rows] == [0, 1]
    assert float(rows[1]["s"]) == 1.0 and int(rows[1]["newton_iterations"]) == 9
    assert float(rows[1]["bending_angle_deg"]) == pytest.approx(25.0, abs=1e-9)
    assert float(rows[0]["temperature_K"]) == pytest.approx(s0.T)
    assert float(rows[1]["mu_kT"]) == pytest.approx(s1_again.mu)
    assert rows[0]["curling_index"] == ""  # straight: undefined, left empty

    entries = pvd_files(out / "results.pvd")
    assert entries == [(0.0, "steps/step_0000.vtu"), (1.0, "steps/step_0001.vtu")]
    assert all((out / f).is_file() for _, f in entries)
    assert sorted(p.name for p in (out / "steps").iterdir()) == ["step_0000.vtu", "step_0001.vtu"]
    u = meshio.read(out / "steps" / "step_0001.vtu").point_data["displacement"]  # the replacement's
    d = clockwise(X, 25.0) - X
    assert np.allclose(u[:, [0, 2]], d, rtol=0, atol=1e-12)

    result = result_of(model, [s0, s1_again])
    written = w.finish(result)
    text = (out / "metrics.json").read_text()
    assert "NaN" not in text and "Infinity" not in text
    metrics = json.loads(text)
    assert metrics == written
    for key in ("bending_angle_deg", "tip_dx_mm", "tip_dz_mm", "curling_index", "converged",
                "wall_time_s", "newton_iterations"):
        assert key in metrics
    assert metrics["bending_angle_deg"] == pytest.approx(25.0, abs=1e-9)
    assert metrics["curling_index"] is None
    assert metrics["converged"] is True and metrics["newton_iterations"] == 40 and metrics["wall_time_s"] == 12.5
    assert metrics["timings_s"]["total"] == 12.5

    columns, cl = read_csv(out / "centreline.csv")
    assert columns == ["reference_arc_length_mm", "arc_length_mm", "rotation_deg", "curvature_per_mm"]
    assert len(cl) == len(model.centreline_nodes)
    # a rigid rotation by 25 deg: every tangent turned by 25 deg, no curvature, lengths kept
    assert np.allclose([float(r["rotation_deg"]) for r in cl], 25.0, atol=1e-9)
    assert np.allclose([float(r["curvature_per_mm"]) for r in cl], 0.0, atol=1e-9)
    assert float(cl[-1]["reference_arc_length_mm"]) == pytest.approx(model.design.length, rel=1e-9)
    assert float(cl[-1]["arc_length_mm"]) == pytest.approx(model.design.length, rel=1e-9)

    png = (out / "final.png").read_bytes()
    assert len(png) > 1000 and png.startswith(PNG_MAGIC)
    assert not any(p.name.startswith(".") for p in out.rglob("*"))  # no temporary left


def test_result_writer_restart_clears_earlier_run(model, X, tmp_path):
    """A second run in the same folder (a new writer, start()) removes the old step files and the
    old final results, so the pvd can only list files of the new run."""
    out = tmp_path / "out"
    first = ResultWriter(out, model)
    first.start()
    for i, a in enumerate((0.0, 5.0, 10.0)):
        first.step(make_state(model, i, i / 2, clockwise(X, a)))
    first.finish(result_of(model, [make_state(model, 2, 1.0, clockwise(X, 10.0))]), plot=False)
    assert len(list((out / "steps").glob("step_*.vtu"))) == 3

    second = ResultWriter(out, model)
    second.start()
    assert list((out / "steps").glob("step_*.vtu")) == []
    for name in ("metrics.json", "centreline.csv", "results.pvd", "history.csv"):
        assert not (out / name).exists()
    assert (out / "design.toml").is_file()
    second.step(make_state(model, 0, 0.0, X))
    assert [f for _, f in pvd_files(out / "results.pvd")] == ["steps/step_0000.vtu"]
    assert [p.name for p in (out / "steps").iterdir()] == ["step_0000.vtu"]
    assert len(read_csv(out / "history.csv")[1]) == 1


def test_result_writer_without_vtu(model, X, tmp_path):
    w = ResultWriter(tmp_path, model, vtu=False)
    w.start()
    w.step(make_state(model, 0, 0.0, X))
    w.step(make_state(model, 0, 0.0, X))  # replaced, not appended
    assert len(read_csv(tmp_path / "history.csv")[1]) == 1
    assert not (tmp_path / "results.pvd").exists() and not (tmp_path / "steps").exists()


def test_no_nan_is_ever_written(model, X, tmp_path):
    """curling_index None (straight) and non-finite values: an empty CSV cell and JSON null."""
    metrics = dict(measure(model, X), max_curvature_per_mm=float("nan"), packing_fraction=np.float64("inf"))
    assert metrics["curling_index"] is None
    state = make_state(model, 0, 0.0, X, metrics=metrics)
    w = ResultWriter(tmp_path, model, vtu=False)
    w.start()
    w.step(state)
    text = (tmp_path / "history.csv").read_text()
    assert "nan" not in text.lower() and "inf" not in text.lower() and "None" not in text
    _, rows = read_csv(tmp_path / "history.csv")
    assert rows[0]["curling_index"] == rows[0]["max_curvature_per_mm"] == rows[0]["packing_fraction"] == ""
    result = SimulationResult(model, [state], False, "step too small", float("nan"), 3, 0,
                              {"total": float("inf")}, {})
    w.finish(result, plot=False)
    text = (tmp_path / "metrics.json").read_text()
    assert "NaN" not in text and "Infinity" not in text
    metrics = json.loads(text)
    assert metrics["curling_index"] is None and metrics["max_curvature_per_mm"] is None
    assert metrics["packing_fraction"] is None and metrics["wall_time_s"] is None
    assert metrics["timings_s"]["total"] is None and metrics["converged"] is False


def test_result_files_get_the_users_permissions(model, X, tmp_path):
    """Every file of a run is created 0666 less the umask, as any program's (not 0600)."""
    import os
    import stat

    old = os.umask(0o027)
    try:
        w = ResultWriter(tmp_path, model)
        w.start()
        w.step(make_state(model, 0, 0.0, X))
        w.finish(result_of(model, [make_state(model, 0, 0.0, X)]))
    finally:
        os.umask(old)
    files = [p for p in tmp_path.rglob("*") if p.is_file()]
    assert {p.name for p in files} >= {"design.toml", "history.csv", "step_0000.vtu", "results.pvd",
                                       "centreline.csv", "metrics.json", "final.png"}
    for p in files:
        assert stat.S_IMODE(p.stat().st_mode) == 0o640, p


def test_metrics_json_keys_follow_the_registry(model, X, tmp_path):
    """metrics.json: the state metrics, then the run fields, in the registry's order, then timings_s
    and provenance."""
    from hydrojam.actuator.metrics import RUN_FIELDS, STATE_METRICS

    w = ResultWriter(tmp_path, model, vtu=False)
    w.start()
    written = w.finish(result_of(model, [make_state(model, 0, 0.0, X)]), plot=False)
    keys = list(json.loads((tmp_path / "metrics.json").read_text()))
    assert keys == list(written) == [m.name for m in (*STATE_METRICS, *RUN_FIELDS)] + ["timings_s", "provenance"]
    assert HISTORY_COLUMNS[:5] == ["step", "s", "mu_kT", "temperature_K", "time_s"]
    assert HISTORY_COLUMNS[5:-5] == [m.name for m in STATE_METRICS]
    assert HISTORY_COLUMNS[-5:] == ["newton_iterations", "wall_time_s", "negative_eigenvalues", "residual_N",
                                    "tolerance_N"]


def test_metrics_json_records_provenance(monkeypatch):
    """What defines a result besides the design: the versions of hydrojam and the libraries that
    set its last bits, the thread settings as set, and the seeds."""
    from hydrojam.actuator.provenance import run_provenance

    monkeypatch.setenv("HYDROJAM_SOLVER_THREADS", "2")
    monkeypatch.delenv("HYDROJAM_IPC_THREADS", raising=False)
    p = run_provenance()
    from hydrojam import __version__

    assert p["versions"]["hydrojam"] == __version__
    assert all(p["versions"][name] for name in ("numpy", "scipy", "ipctk", "gmsh", "pypardiso"))
    assert p["environment"]["HYDROJAM_SOLVER_THREADS"] == "2" and p["environment"]["HYDROJAM_IPC_THREADS"] is None
    assert p["mesh_seed"] == 1234 and p["seed"] is None
    json.dumps(p, allow_nan=False)
