"""Actuator simulations end to end (hydrojam.actuator.simulate): the undeformed-state check, failure
handling, and (slow) the bending direction and its temperature trend."""

import json
import math

import numpy as np
import pytest

from hydrojam.actuator.design import apply_overrides, default_design
from hydrojam.actuator.model import build_model
from hydrojam.actuator.simulate import simulate
from hydrojam.fem.solver import NewtonOptions, PathOptions


def _model(*overrides):
    return build_model(apply_overrides(default_design(), list(overrides)))


def test_nothing_moves_when_the_stimulus_stays_at_the_as_prepared_state():
    """With the target stimulus equal to (mu0, T0) the as-prepared state is stress-free and
    contact-free: every node stays where it is (DESIGN.md section 3, reference configuration)."""
    d = default_design()
    mu0, T0 = d.hydrogel.mu0, d.hydrogel.T0
    model = _model("particle_layers=2", f"stimulus.mu={mu0!r}", f"stimulus.temperature={T0!r}")
    res = simulate(model)
    assert res.converged
    assert np.abs(res.final.x - model.mesh.points).max() < 1e-9
    m = res.metrics
    assert abs(m["bending_angle_deg"]) < 1e-8 and abs(m["tip_dx_mm"]) < 1e-9 and abs(m["tip_dz_mm"]) < 1e-9
    assert m["contacts_per_particle"] == 0


def test_a_solver_that_cannot_converge_says_so_and_keeps_the_last_converged_state():
    """Newton allowed one iteration and a large minimum increment: the path stops early, the
    result says where and why, and every number in it is finite (no NaN)."""
    model = _model("particle_layers=1")
    tight = PathOptions(ds0=0.5, ds_min=0.2, newton=NewtonOptions(max_iter=1))
    res = simulate(model, options=tight)
    assert not res.converged
    assert "last converged state kept" in res.message
    assert res.final.s < 1.0
    assert np.all(np.isfinite(res.final.x))
    text = json.dumps(res.metrics, allow_nan=False)  # raises on NaN / inf
    assert '"converged": false' in text


@pytest.mark.slow
def test_actuator_bends_toward_the_strain_limit_layer_and_less_when_warmer():
    """Paper Sec. IV-A (Figs. 6-7): cold water (275 K) swells the particles more than 295 K
    water, so the actuator bends toward the strain-limit layer (-x, positive angle), more at
    275 K; its tip moves to -x and down. One particle layer and a coarse mesh keep it fast;
    the default design's figures are in benchmarks/actuator.py."""
    out = {}
    for T in (275.0, 295.0):
        res = simulate(_model("particle_layers=1", "mesh.size=3.0", f"stimulus.temperature={T}"))
        assert res.converged, res.message
        out[T] = res.metrics
    cold, warm = out[275.0], out[295.0]
    assert cold["bending_angle_deg"] > warm["bending_angle_deg"] > 0.0
    assert cold["tip_dx_mm"] < warm["tip_dx_mm"] < 0.0
    assert cold["tip_dz_mm"] < 0.0 and warm["tip_dz_mm"] < 0.0
    assert cold["mean_swelling_ratio"] > warm["mean_swelling_ratio"] > 1.0
    assert math.isfinite(cold["packing_fraction"]) and cold["contacts_per_particle"] >= 1.0
