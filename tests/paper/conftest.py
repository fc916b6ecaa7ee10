"""Fixtures of the hydrojam.paper tests."""

from __future__ import annotations

import pytest
from paper_synthetic import Table, layer_rows, row, temperature_rows, thickness_rows, write_point

from hydrojam.paper import study as pstudy


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
