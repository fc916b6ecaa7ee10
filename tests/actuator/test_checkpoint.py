"""Checkpoints (hydrojam.actuator.checkpoint, docs/actuator.md "Checkpoints"): a run stopped after
an accepted state goes on from it as if it had not stopped.

The reference is the same design run in one go in the same process. A resumed run replays the
same floating-point operations (the same states, the same linear solver's union pattern, so the
same orderings), so it must reproduce the reference exactly: the same Newton iterations and the
same positions, bit for bit. A tolerance would be the wrong test here. Equilibria of a particle
column are path dependent, and a resumed run that lost part of the solver's state lands elsewhere:
measured on this design, a fresh solver pattern at s = 0.125 gave 43.82 deg against 44.00 deg,
and a particle 5 mm away.
"""

from __future__ import annotations

import csv
import dataclasses
import json

import numpy as np
import pytest

import hydrojam.actuator.simulate as simulate_module
from hydrojam.actuator.checkpoint import (CHECKPOINT, CheckpointError, ReleaseProgress, load_checkpoint,
                                         release_progress, save_checkpoint)
from hydrojam.actuator.design import apply_overrides, default_design, write_design
from hydrojam.actuator.model import build_model
from hydrojam.actuator.results import ResultWriter
from hydrojam.actuator.simulate import simulate
from hydrojam.cli import main
from hydrojam.fem.solver.release import ReleaseOptions

SMALL = ["particle_layers=1", "mesh.size=4"]

#: the path that releases its stabilisation once, at s = 1 (ReleaseOptions.each_step False): the
#: runs whose release at s = 1 is stopped and resumed
STABILISED = dataclasses.replace(simulate_module.ACTUATOR_PATH, damping_start=1.0, extrapolate=False,
                                 release=ReleaseOptions(each_step=False))


class _Stop(Exception):
    """Stands for a kill: raised from inside the run."""


@pytest.fixture(scope="module")
def design():
    return apply_overrides(default_design(), SMALL)


@pytest.fixture(scope="module")
def reference(design):
    return simulate(build_model(design))


@pytest.fixture(scope="module")
def stabilised(design):
    """The design run in one go on the path released at s = 1 only."""
    return simulate(build_model(design), options=STABILISED)


def _interrupted(folder, design, stop_at_state=None, stop_in_release=False, monkeypatch=None):
    """Run ``design`` into ``folder`` and stop it: after the state of index ``stop_at_state`` has
    been written (before its checkpoint), or after the release's first checkpoint."""
    model = build_model(design)
    writer = ResultWriter(folder, model)
    assert writer.start(resume=True) is None

    def on_step(state):
        writer.step(state)
        if state.index == stop_at_state:
            raise _Stop

    if stop_in_release:
        save = simulate_module.save_checkpoint

        def save_then_stop(path, ck):
            save(path, ck)
            if ck.release is not None:
                raise _Stop

        monkeypatch.setattr(simulate_module, "save_checkpoint", save_then_stop)
    with pytest.raises(_Stop):
        simulate(model, on_step=on_step, checkpoint=writer.checkpoint_path,
                 options=STABILISED if stop_in_release else None)
    if monkeypatch is not None:
        monkeypatch.undo()


def _resumed(folder, design, options=None):
    model = build_model(design)
    writer = ResultWriter(folder, model)
    ck = writer.start(resume=True)
    assert ck is not None, writer.discarded
    result = simulate(model, on_step=writer.step, checkpoint=writer.checkpoint_path, resume=ck, options=options)
    return ck, result, writer.finish(result, plot=False)


def _history(folder):
    with open(folder / "history.csv", newline="") as f:
        return list(csv.DictReader(f))


def test_a_run_stopped_on_its_path_goes_on_as_if_it_had_not_stopped(tmp_path, design, reference):
    _interrupted(tmp_path, design, stop_at_state=3)
    # state 3 was written but not checkpointed: the run goes on from state 2
    ck, result, metrics = _resumed(tmp_path, design)
    assert [st["index"] for st in ck.states] == [0, 1, 2] and ck.release is None
    assert result.newton_iterations == reference.newton_iterations
    np.testing.assert_array_equal(result.final.x, reference.final.x)
    assert metrics["bending_angle_deg"] == reference.metrics["bending_angle_deg"]
    assert [st.s for st in result.states] == [st.s for st in reference.states]
    rows = _history(tmp_path)
    assert [int(r["step"]) for r in rows] == list(range(len(reference.states)))
    assert len(list((tmp_path / "steps").glob("step_*.vtu"))) == len(reference.states)
    assert result.timings["newton_iterations"] == reference.timings["newton_iterations"]
    assert metrics["provenance"]["resumed"][0]["state"] == 2
    assert metrics["provenance"]["resumed"][0]["s"] == pytest.approx(reference.states[2].s)
    assert not (tmp_path / CHECKPOINT).exists()  # removed with the results written
    # the whole run's time, the stopped part included
    assert metrics["wall_time_s"] >= ck.elapsed_s


def test_a_run_stopped_in_the_release_goes_on_in_the_release(tmp_path, design, stabilised, monkeypatch):
    _interrupted(tmp_path, design, stop_in_release=True, monkeypatch=monkeypatch)
    ck, result, metrics = _resumed(tmp_path, design, STABILISED)
    assert ck.release is not None and len(ck.release.rounds) == 1
    assert ck.states[-1]["s"] == 1.0
    assert result.newton_iterations == stabilised.newton_iterations
    np.testing.assert_array_equal(result.final.x, stabilised.final.x)
    assert result.stabilisation["release_rounds"] == stabilised.stabilisation["release_rounds"]
    assert metrics["stabilisation_released"] is True
    assert len(_history(tmp_path)) == len(stabilised.states)  # the released state replaced the stabilised one
    # the work of the whole run, rejected attempts and the stopped part's rounds included
    assert result.timings["newton_iterations"] == stabilised.timings["newton_iterations"]
    assert ck.release.timings.iterations == ck.release.iterations


def test_a_checkpoint_of_another_design_or_an_unreadable_one_is_not_resumed(tmp_path, design):
    _interrupted(tmp_path, design, stop_at_state=2)
    other = apply_overrides(design, ["stimulus.temperature=285"])
    model = build_model(other)
    with pytest.raises(CheckpointError, match="another design"):
        load_checkpoint(tmp_path / CHECKPOINT, other, model.mesh.points.shape)
    writer = ResultWriter(tmp_path, model)
    assert writer.start(resume=True) is None
    assert "another design" in writer.discarded
    assert not (tmp_path / CHECKPOINT).exists() and not (tmp_path / "history.csv").exists()

    (tmp_path / CHECKPOINT).write_bytes(b"not a checkpoint")
    writer = ResultWriter(tmp_path, build_model(design))
    assert writer.start(resume=True) is None and "unreadable" in writer.discarded
    with pytest.raises(FileNotFoundError):
        load_checkpoint(tmp_path / CHECKPOINT, design, (3, 2))


def test_hydrojam_run_goes_on_from_a_checkpoint_and_fresh_starts_over(tmp_path, design, reference, capsys):
    design_file = tmp_path / "design.toml"
    write_design(design_file, design)
    out = tmp_path / "out"
    _interrupted(out, design, stop_at_state=2)
    assert main(["run", str(design_file), "-o", str(out), "--no-vtu"]) == 0
    err = " ".join(capsys.readouterr().err.split())  # rich wraps at the console's width, round the path
    assert "going on from the checkpoint" in err and "at s = 0.05 (state 1)" in err
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["newton_iterations"] == reference.newton_iterations
    assert metrics["provenance"]["resumed"][0]["state"] == 1
    assert not (out / CHECKPOINT).exists()

    _interrupted(out, design, stop_at_state=2)
    assert main(["run", str(design_file), "-o", str(out), "--no-vtu", "--fresh"]) == 0
    assert "going on" not in capsys.readouterr().err
    assert "resumed" not in json.loads((out / "metrics.json").read_text())["provenance"]


def test_a_release_checkpoint_without_its_timings_still_counts_its_iterations(tmp_path, design, stabilised,
                                                                             monkeypatch):
    """A checkpoint written before the release's timings were kept (release.timings None) is
    resumed, and the run's timings count the stopped rounds' iterations from its round list."""
    _interrupted(tmp_path, design, stop_in_release=True, monkeypatch=monkeypatch)
    model = build_model(design)
    path = tmp_path / CHECKPOINT
    ck = load_checkpoint(path, model.design, model.mesh.points.shape)
    save_checkpoint(path, dataclasses.replace(ck, release=dataclasses.replace(ck.release, timings=None)))
    ck, result, _ = _resumed(tmp_path, design, STABILISED)
    assert ck.release.timings is None
    assert result.timings["newton_iterations"] == stabilised.timings["newton_iterations"]
    np.testing.assert_array_equal(result.final.x, stabilised.final.x)


def test_a_release_reports_its_progress_after_every_round(tmp_path, design, stabilised, monkeypatch):
    """on_release sees every round the release goes on from (their count, the iterations so far,
    the next round's damping); the checkpoint says the same to a reader in another process
    (release_progress, the sweep's running points), where the wall time counts the rounds so far
    too."""
    from hydrojam.study.cache import running_point

    seen = []
    result = simulate(build_model(design), on_release=seen.append, options=STABILISED)
    rounds = result.stabilisation["release_rounds"]
    assert result.stabilisation["released"] and len(rounds) >= 2
    assert [p.rounds for p in seen] == list(range(1, len(rounds)))  # the last round ends it
    assert [p.iterations for p in seen] == list(np.cumsum([r["iterations"] for r in rounds[:-1]]))
    assert [p.damping for p in seen] == [r["scale"] for r in rounds[1:]]  # the next round's
    assert all(b.seconds >= a.seconds >= 0 for a, b in zip(seen, seen[1:]))

    _interrupted(tmp_path, design, stop_in_release=True, monkeypatch=monkeypatch)
    got = release_progress(tmp_path / CHECKPOINT)
    assert isinstance(got, ReleaseProgress)
    assert (got.rounds, got.iterations, got.damping) == (1, rounds[0]["iterations"], rounds[1]["scale"])
    point = running_point((), tmp_path)
    assert point.s == 1.0 and point.release == got
    assert point.wall_time_s == float(_history(tmp_path)[-1]["wall_time_s"]) + got.seconds
    assert release_progress(tmp_path / "none.npz") is None
    (tmp_path / "bad.npz").write_bytes(b"not a checkpoint")
    assert release_progress(tmp_path / "bad.npz") is None


def test_a_release_under_way_is_measured_from_its_folder(tmp_path, design, reference, monkeypatch, capsys):
    """`hydrojam status --measure` measures the release's current centre: the checkpoint's
    release positions on the model of the folder's design.toml, the same metrics as measuring
    them on the run's own model; nothing for a run on its path."""
    from hydrojam.actuator.model import measure
    from hydrojam.study.status import folder_status, release_metrics

    _interrupted(tmp_path / "path", design, stop_at_state=3)
    assert release_metrics(tmp_path / "path") is None
    assert folder_status(tmp_path / "path", measure=True).runs[0].release_metrics is None

    _interrupted(tmp_path / "rel", design, stop_in_release=True, monkeypatch=monkeypatch)
    model = build_model(design)
    ck = load_checkpoint(tmp_path / "rel" / CHECKPOINT, model.design, model.mesh.points.shape)
    expected = measure(model, ck.release.x)
    got = release_metrics(tmp_path / "rel")
    assert got == expected
    assert got["bending_angle_deg"] != ck.states[-1]["metrics"]["bending_angle_deg"]  # it moved in round 1
    (run,) = folder_status(tmp_path / "rel", measure=True).runs
    assert run.state == "unfinished" and run.release_metrics == expected
    monkeypatch.setenv("COLUMNS", "250")
    assert main(["status", str(tmp_path / "rel"), "--measure"]) == 0
    assert f"now {expected['bending_angle_deg']:.2f} deg" in capsys.readouterr().out


def test_a_snapshot_draws_where_an_unfinished_run_is(tmp_path, design, monkeypatch, capsys):
    """`hydrojam snapshot`: a run stopped on its path is drawn at its last accepted state (the
    checkpoint's positions), one stopped in its release at the release's current centre, as a
    VTU whose points plus displacement are those positions and a picture; a finished folder
    draws nothing; a folder that is not hydrojam's is refused (2)."""
    import meshio

    from hydrojam.study.status import current_state

    _interrupted(tmp_path / "path", design, stop_at_state=3)
    _interrupted(tmp_path / "rel", design, stop_in_release=True, monkeypatch=monkeypatch)
    model = build_model(design)
    for name, releasing in (("path", False), ("rel", True)):
        ck = load_checkpoint(tmp_path / name / CHECKPOINT, model.design, model.mesh.points.shape)
        x = ck.release.x if releasing else ck.xs[-1]
        _, state, got_releasing = current_state(tmp_path / name)
        assert got_releasing is releasing and np.array_equal(state.x, x)
        assert state.s == (1.0 if releasing else ck.states[-1]["s"])
        assert main(["snapshot", str(tmp_path / name), "-o", str(tmp_path / "shots")]) == 0
        vtu = meshio.read(tmp_path / "shots" / f"{name}.vtu")
        # the VTU's (x, 0, z) points plus displacement give the positions back, to the round-off of
        # one subtraction and one addition (the states of neighbouring steps differ by 1e-3 mm or more)
        deformed = (vtu.points + vtu.point_data["displacement"])[:, [0, 2]]
        assert np.abs(deformed - x).max() <= 1e-12 * np.abs(x).max()
        assert (tmp_path / "shots" / f"{name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        text = capsys.readouterr().err
        assert ("its release under way" if releasing else f"s = {state.s:.3f}") in text
        assert f"{state.metrics['bending_angle_deg']:.2f} deg" in text
    (tmp_path / "path" / CHECKPOINT).unlink()
    assert main(["snapshot", str(tmp_path / "path"), "-o", str(tmp_path / "none")]) == 0
    assert "nothing drawn" in capsys.readouterr().err and not (tmp_path / "none").exists()
    assert main(["snapshot", str(tmp_path / "shots"), "-o", str(tmp_path / "none")]) == 2
    assert "not an output folder" in capsys.readouterr().err and not (tmp_path / "none").exists()


def test_hydrojam_run_into_a_folder_another_run_holds_is_refused(tmp_path, design, capsys):
    """Two `hydrojam run` into one folder would write the same checkpoint and history: the second,
    while the first holds the folder's lock, is refused before it writes (exit 2, one line naming
    the process); the lock is gone after the run."""
    import os

    from hydrojam._io import FOLDER_LOCK, hold_lock

    design_file = tmp_path / "design.toml"
    write_design(design_file, design)
    out = tmp_path / "out"
    out.mkdir()
    with hold_lock(out / FOLDER_LOCK):
        assert main(["run", str(design_file), "-o", str(out), "--no-vtu"]) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and f"in use by process {os.getpid()}" in err
        assert sorted(p.name for p in out.iterdir()) == [FOLDER_LOCK]
    assert main(["run", str(design_file), "-o", str(out), "--no-vtu"]) == 0
    assert not (out / FOLDER_LOCK).exists() and (out / "metrics.json").is_file()


def test_an_interim_shapes_figure_draws_an_unfinished_point_as_it_stands(tmp_path, design, monkeypatch):
    """The shapes figure of a table written without running: an unfinished point with a
    checkpoint is drawn from it (the snapshot's drawing, its title saying "not finished"), one
    without a checkpoint keeps the text panel."""
    from hydrojam.paper import figures

    _interrupted(tmp_path / "path", design, stop_at_state=3)
    (tmp_path / "none").mkdir()
    drawn, titles = [], []
    real = figures._current_drawing

    def spy(point_dir):
        got = real(point_dir)
        drawn.append((point_dir.name, got is not None))
        if got is not None:
            titles.append(got[1])
        return got

    monkeypatch.setattr(figures, "_current_drawing", spy)
    rows = [{"particle_layers": n, "status": "unfinished", "error": "not finished", "point_dir": d}
            for n, d in ((1, "path"), (2, "none"))]
    figures.plot_shapes(tmp_path, rows, "particle_layers", tmp_path / "shapes.png")
    assert drawn == [("path", True), ("none", False)]
    model = build_model(design)
    ck = load_checkpoint(tmp_path / "path" / CHECKPOINT, model.design, model.mesh.points.shape)
    assert titles == [f"not finished: s = {ck.states[-1]['s']:.2f}, θ now "
                      f"{ck.states[-1]['metrics']['bending_angle_deg']:.1f}°"]
    assert (tmp_path / "shapes.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
