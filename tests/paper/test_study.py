"""The paper's Section IV study (hydrojam.paper.study): point sets, base design, the Study."""

from __future__ import annotations

import json
import sys

import pytest

from hydrojam.actuator.design import DEFAULT_MESH_SIZE_MM, apply_overrides, default_design
from hydrojam.paper import study as pstudy


def test_point_sets_full_and_quick():
    full, quick = pstudy.paper_points(False), pstudy.paper_points(True)
    assert full == {"temperature": {"stimulus.temperature": [275.0, 280.0, 285.0, 290.0, 295.0]},
                    "particle_layers": {"particle_layers": list(range(5, 20))},
                    "strain_limit_thickness": {"strain_limit_thickness": [4.0, 6.0, 8.0, 10.0, 12.0]}}
    assert quick == {"temperature": {"stimulus.temperature": [275.0, 285.0, 295.0]},
                     "particle_layers": {"particle_layers": [5, 7, 9, 11, 15, 19]},
                     "strain_limit_thickness": {"strain_limit_thickness": [4.0, 8.0, 10.0, 12.0]}}
    assert sum(len(v) for s in full.values() for v in s.values()) == 25
    assert pstudy.paper_base(False) == default_design()
    assert pstudy.paper_base(True).mesh.size == pstudy.QUICK_MESH_SIZE == 4.0
    assert pstudy.paper_base(True) == apply_overrides(default_design(), ["mesh.size=4.0"])


@pytest.mark.parametrize("quick", [False, True])
def test_base_point_is_the_same_design_in_every_sweep(quick):
    """Each sweep's value at the base equals the base design exactly (types included), so the
    sweep machinery runs it once (one key)."""
    base = pstudy.paper_base(quick)
    for sweep in pstudy.paper_points(quick).values():
        ((field, values),) = sweep.items()
        at_base = [v for v in values if v == {"stimulus.temperature": 275.0, "particle_layers": 5,
                                               "strain_limit_thickness": 8.0}[field]]
        assert len(at_base) == 1
        assert apply_overrides(base, [f"{field}={at_base[0]!r}"]) == base


@pytest.mark.parametrize("quick, distinct", [(False, 23), (True, 11)])
def test_paper_study(quick, distinct):
    """25 (13) points, 23 (11) distinct designs: the base point is one key in all three sweeps."""
    study_mod = pytest.importorskip("hydrojam.study.spec")
    study = pstudy.paper_study(quick)
    assert isinstance(study, study_mod.Study)
    assert study.base == pstudy.paper_base(quick)
    assert {s.name: s.vary for s in study.sweeps} == pstudy.paper_points(quick)
    points = study.points()
    assert len(points) == distinct + 2 and len({p.key for p in points}) == distinct
    base_key = study_mod.design_key(study.base)
    assert {p.sweep for p in points if p.key == base_key} == {s.name for s in pstudy.paper_sweeps(2)}
    assert all(p.design.mesh_size == (pstudy.QUICK_MESH_SIZE if quick else 2.0) for p in points)


def _old_way(quick):
    """The Section IV study built as paper_study built it before it took a dimension."""
    from hydrojam.study.spec import Study, SweepSpec

    base = default_design()
    if quick:
        base = apply_overrides(base, ["mesh.size=4.0"])
    vary = {"temperature": {"stimulus.temperature": [275.0, 285.0, 295.0] if quick else [275.0, 280.0, 285.0, 290.0, 295.0]},
            "particle_layers": {"particle_layers": [5, 7, 9, 11, 15, 19] if quick else list(range(5, 20))},
            "strain_limit_thickness": {"strain_limit_thickness": [4.0, 8.0, 10.0, 12.0] if quick else [4.0, 6.0, 8.0, 10.0, 12.0]}}
    return Study(name="paper-quick" if quick else "paper", base=base,
                 sweeps=[SweepSpec(name=n, vary=v) for n, v in vary.items()])


@pytest.mark.parametrize("quick", [False, True])
def test_the_2d_study_is_unchanged_by_the_dimension(quick):
    """2D (the default and dimension=2) keeps its name, base and cache keys: the study equals one
    built the old way, point by point, so a finished 2D folder is resumed, not rerun."""
    old = _old_way(quick)
    for study in (pstudy.paper_study(quick), pstudy.paper_study(quick, dimension=2)):
        assert study.name == old.name and study.base == old.base
        assert [(p.sweep, p.index, p.key) for p in study.points()] == [(p.sweep, p.index, p.key) for p in old.points()]
    assert pstudy.paper_base(quick, dimension=2) == pstudy.paper_base(quick)


@pytest.mark.parametrize("quick, name, mesh, distinct", [(True, "paper-3d-quick", 4.0, 15),
                                                     (False, "paper-3d", DEFAULT_MESH_SIZE_MM[3], 28)])
def test_the_3d_study(quick, name, mesh, distinct):
    """The 3D study: its own name, the 2D study's points on the same meshes (quick 4 mm, full
    the 3D default), spheres in the half model, and cache keys that no 2D point shares; and the strip-width
    sweep, the paper's h read as a width (3D only), at the base design's thickness."""
    study = pstudy.paper_study(quick, dimension=3)
    assert study.name == name == pstudy.study_name(quick, 3)
    assert pstudy.study_kind(name) == (quick, 3) and pstudy.study_kind(pstudy.study_name(quick)) == (quick, 2)
    assert pstudy.study_kind("my-study") is None
    assert {s.name: s.vary for s in study.sweeps} == pstudy.paper_points(quick, dimension=3)
    assert list(pstudy.paper_points(quick, dimension=3)) == [*pstudy.paper_points(quick), "strain_limit_width"]
    assert study.base == apply_overrides(pstudy.paper_base(quick), ["dimension=3"])
    assert study.base.dimension == 3 and study.base.mesh.symmetry and study.base.mesh_size == mesh
    points = study.points()
    assert len({p.key for p in points}) == distinct
    assert all(p.design.dimension == 3 and p.design.mesh_size == mesh for p in points)
    assert not {p.key for p in points} & {p.key for p in pstudy.paper_study(quick).points()}
    two = {(p.sweep, p.index): p.design for p in pstudy.paper_study(quick).points()}
    for p in points:  # the same designs but for the dimension
        if p.sweep == "strain_limit_width":
            assert p.design == apply_overrides(study.base, [f"strain_limit_width={p.values['strain_limit_width']!r}"])
            assert p.design.strain_limit_thickness == study.base.strain_limit_thickness
            continue
        assert p.design == apply_overrides(two[(p.sweep, p.index)], ["dimension=3"])
    assert pstudy.paper_study(quick, ["temperature"], 2, dimension=3).base.replicas.count == 2


@pytest.mark.parametrize("dimension", [1, 4, True, "3"])
def test_other_dimensions_are_refused(dimension):
    with pytest.raises(ValueError, match=r"dimension: allowed 2 or 3"):
        pstudy.paper_study(True, dimension=dimension)


def _kept_3d_study():
    """docs/data/paper-3d-quick/: its folder, the study its study.toml holds, and that study as the
    code builds it (the quick 3D study with the kept sweeps and replicas)."""
    from pathlib import Path

    from hydrojam.study.spec import load_study

    data = Path(__file__).resolve().parents[2] / "docs" / "data" / "paper-3d-quick"
    kept = load_study(data / "study.toml")
    code = pstudy.paper_study(quick=True, sweeps=[s.name for s in kept.sweeps], replicas=kept.replicas, dimension=3)
    return data, kept, code


def test_the_kept_3d_records_restore_into_the_quick_3d_study():
    """docs/data/paper-3d-quick/ keeps the finished quick 3D points' records (docs/data/keep.py) so
    that, copied into OUT/points/<key>/, `reproduce` loads them: each folder's label (T285, H4,
    W12, PL07, with r<k> past replica 0) and key must be those of a point of the kept study, its
    design.toml that point's design, and its point.json a finished record (what the sweep's cache
    reads)."""
    import importlib.util

    from hydrojam.actuator.design import load_design
    from hydrojam.study.cache import read_record
    from hydrojam.study.spec import design_key

    data, kept, code = _kept_3d_study()
    spec = importlib.util.spec_from_file_location("keep", data.parent / "keep.py")
    keep = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(keep)
    labels = {}
    for p in kept.points():
        labels.setdefault(p.key, keep.label(p))
    for folder in sorted(f for f in data.iterdir() if f.is_dir()):
        name, key = folder.name.split("-")
        assert labels.get(key) == name, folder.name
        assert design_key(load_design(folder / "design.toml")) == key, folder.name
        record = read_record(folder)
        assert record["status"] in ("ok", "not_converged") and record["key"] == key, folder.name


def test_the_kept_3d_records_give_the_report_again(tmp_path):
    """docs/data/paper-3d-quick/restore.sh puts the kept study.toml (the code's quick 3D study, not
    a stale copy) and every kept record back into a folder, and `reproduce --report-only` writes
    the table, figures and report from them: every kept run finished, the others not started.
    A second restore into the same folder keeps its study.toml; another study's folder is refused."""
    import subprocess

    from hydrojam.paper.reproduce import reproduce

    data, kept, code = _kept_3d_study()
    assert kept == code
    sys.path.insert(0, str(data.parent))
    import keep

    assert (data / "restore.sh").read_text() == keep.RESTORE  # keep.py's, calling docs/data/restore.sh
    n_kept = len([f for f in data.iterdir() if f.is_dir()])
    out = tmp_path / "out"
    for _ in range(2):
        done = subprocess.run(["sh", str(data / "restore.sh"), str(out)], capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
    table, report = reproduce(out, quick=True, dimension=3, report_only=True, replicas=kept.replicas,
                              sweeps=[s.name for s in kept.sweeps])
    assert report.is_file() and (out / "figures" / "temperature_shapes.png").is_file()
    finished = [p for p in {p.key: p for p in code.points()}.values()
                if (out / "points" / p.key / "point.json").is_file()]
    assert len(finished) == n_kept
    from hydrojam.study.cache import damaged_files

    for p in finished:  # loaded by a sweep, not computed again: no listed file is missing
        folder = out / "points" / p.key
        assert damaged_files(folder, json.loads((folder / "point.json").read_text())) == [], p.key
    other = tmp_path / "other"
    other.mkdir()
    (other / "study.toml").write_text('name = "my-study"\n')
    done = subprocess.run(["sh", str(data / "restore.sh"), str(other)], capture_output=True, text=True)
    assert done.returncode == 2 and "another study" in done.stderr and not (other / "points").exists()


def test_a_study_under_other_model_choices_is_one_of_its_own():
    """--set friction=0.1: the base design changes for every point, the study gets a name of its
    own (so it never shares a folder with the default's), its kind is still the quick 3D study's,
    and no point shares a cache key with the default study's."""
    default = pstudy.paper_study(True, ["temperature"], dimension=3)
    other = pstudy.paper_study(True, ["temperature"], dimension=3, overrides=["friction=0.1"])
    assert other.name == "paper-3d-quick--friction_0_1" == pstudy.study_name(True, 3, ["friction=0.1"])
    assert pstudy.study_kind(other.name) == (True, 3)
    assert other.base == apply_overrides(default.base, ["friction=0.1"])
    assert not {p.key for p in other.points()} & {p.key for p in default.points()}
    assert pstudy.reproduce_command(True, 3, 3, ["friction=0.1"]).endswith("--replicas 3 --set friction=0.1")
    two = pstudy.study_name(True, 3, ["membrane.shear_modulus=0.046", "friction=0"])
    assert two == "paper-3d-quick--membrane_shear_modulus_0_046--friction_0"
    with pytest.raises(ValueError, match="friction"):
        pstudy.paper_study(True, dimension=3, overrides=["friction=5"])
