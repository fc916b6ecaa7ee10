"""Studies: the TOML format, the grid of points, up-front validation, and the design key."""

import tomllib

import pytest
from pydantic import ValidationError

import hydrojam
from hydrojam.study import spec as study_mod
from hydrojam.actuator.design import Design, DesignError, write_design
from hydrojam.study.spec import (
    Study,
    StudyError,
    SweepSpec,
    design_key,
    load_study,
    study_from_dict,
    study_to_toml,
    write_study,
)

STUDY_TOML = """\
name = "my-study"
base = "designs/base.toml"
[design]
particle_layers = 3
stimulus.mu = -0.01

[[sweep]]
name = "temperature"
[sweep.vary]
"stimulus.temperature" = [275, 285, 295]

[[sweep]]
name = "layers_x_thickness"
[sweep.vary]
particle_layers = [1, 3]
strain_limit_thickness = [4.0, 8.0]
"""


@pytest.fixture
def study_file(tmp_path):
    write_design(tmp_path / "sub" / "designs" / "base.toml", Design(clearance=0.2, mesh={"size": 3.0}))
    path = tmp_path / "sub" / "study.toml"
    path.write_text(STUDY_TOML)
    return path


def test_load_study_base_relative_to_the_study_file(study_file, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # not the study's folder: base is found relative to the file
    study = load_study(study_file)
    assert study.name == "my-study"
    assert study.base.clearance == 0.2 and study.base.mesh.size == 3.0  # from the base file
    assert study.base.particle_layers == 3 and study.base.stimulus.mu == -0.01  # [design] on top
    assert [s.name for s in study.sweeps] == ["temperature", "layers_x_thickness"]
    assert hydrojam.Study is Study and hydrojam.load_study is load_study


def test_grid_is_the_product_in_key_then_value_order(study_file):
    points = load_study(study_file).points()
    assert [(p.sweep, p.index) for p in points] == [("temperature", i) for i in range(3)] + [
        ("layers_x_thickness", i) for i in range(4)]
    grid = [(p.values["particle_layers"], p.values["strain_limit_thickness"]) for p in points[3:]]
    assert grid == [(1, 4.0), (1, 8.0), (3, 4.0), (3, 8.0)]  # the last key varies fastest
    for p in points[3:]:
        assert p.design.particle_layers == p.values["particle_layers"]
        assert p.design.strain_limit_thickness == p.values["strain_limit_thickness"]
        assert p.design.stimulus.temperature == 275.0 and p.design.clearance == 0.2
        # derived cavity follows the varied particle count
        pl = p.design.particle_layers
        assert p.design.resolved_cavity_length == pytest.approx(pl * 16.0 + (pl + 1) * 0.2)
    assert [p.design.stimulus.temperature for p in points[:3]] == [275.0, 285.0, 295.0]
    assert all(p.design.particle_layers == 3 for p in points[:3])


def test_toml_round_trip(study_file, tmp_path):
    study = load_study(study_file)
    text = study_to_toml(study)
    again = study_from_dict(tomllib.loads(text))
    assert again == study
    assert [p.key for p in again.points()] == [p.key for p in study.points()]
    out = tmp_path / "copy" / "study.toml"
    write_study(out, study)
    assert load_study(out) == study
    assert sorted(p.name for p in out.parent.iterdir()) == ["study.toml"]  # no temporary left


def test_study_from_python_and_default_base():
    study = Study(sweeps=[SweepSpec(name="t", vary={"stimulus.temperature": [280.0, 290.0]})])
    assert study.name == "study" and study.base == Design()
    assert [p.design.stimulus.temperature for p in study.points()] == [280.0, 290.0]
    with pytest.raises(ValidationError, match="particle_layers"):
        Study(sweeps=[SweepSpec(name="t", vary={"particle_layers": [0]})])


def _sweep(vary, name="s", **extra):
    return {"sweep": [{"name": name, "vary": vary, **extra}]}


@pytest.mark.parametrize(
    "data, needles",
    [
        ({"colour": "red", **_sweep({"particle_layers": [1]})},
         ["colour", "unknown key", "allowed: name, base, design, sweep"]),
        (_sweep({"particle_layers": [1]}, extra=1), ["sweep 's'", "extra", "unknown key", "allowed: name, vary"]),
        (_sweep({"stimulus.colour": [1]}), ["sweep 's'", "stimulus.colour", "unknown design field", "temperature"]),
        (_sweep({"nonsense": [1]}), ["sweep 's'", "nonsense", "unknown design field"]),
        (_sweep({"stimulus": [1]}), ["sweep 's'", "stimulus", "is a table"]),
        (_sweep({"particle_layers": [1, 0]}, name="layers"),
         ["sweep 'layers' point 1", "particle_layers", "allowed range [1, 100]", "got 0"]),
        (_sweep({"stimulus.temperature": [275, 400]}, name="temps"),
         ["sweep 'temps' point 1", "stimulus.temperature", "[273.15, 373.15] K", "got 400"]),
        (_sweep({"particle_layers": [2.5]}), ["sweep 's'", "particle_layers", "expected an integer"]),
        (_sweep({"particle_layers": []}), ["sweep 's'", "particle_layers", "at least one value"]),
        (_sweep({}), ["sweep 's'", "vary", "at least one"]),
        (_sweep({"particle_layers": 3}), ["sweep 's'", "vary.particle_layers", "expected a list"]),
        ({"sweep": [{"name": "a", "vary": {"particle_layers": [1]}},
                    {"name": "a", "vary": {"particle_layers": [2]}}]}, ["sweep 'a'", "duplicate"]),
        (_sweep({"particle_layers": [1]}, name="bad name"), ["name", "letters, digits"]),
        ({"name": "x"}, ["sweep", "at least one"]),
        ({"design": {"particle_layers": 0}, **_sweep({"mesh.size": [2.0]})}, ["design.particle_layers", "[1, 100]"]),
        ({"design": {"colour": 1}, **_sweep({"mesh.size": [2.0]})}, ["design.colour", "unknown key"]),
        # mesh.size 3 is fine for the base (d = 16) but too coarse once a sweep shrinks the particles
        ({"design": {"mesh": {"size": 3.0}}, **_sweep({"particle_diameter": [16.0, 8.0]}, name="d")},
         ["sweep 'd' point 1", "mesh.size", "particle_diameter/4"]),
    ],
)
def test_bad_studies_are_refused_in_one_line(data, needles):
    with pytest.raises(StudyError) as info:
        study_from_dict(data)
    msg = str(info.value)
    assert "\n" not in msg
    for needle in needles:
        assert needle in msg, msg
    assert isinstance(info.value, DesignError)  # the CLI maps it to exit status 2


def test_missing_base_file_and_bad_toml(tmp_path):
    path = tmp_path / "study.toml"
    path.write_text('base = "nowhere.toml"\n[[sweep]]\nname = "a"\n[sweep.vary]\nparticle_layers = [1]\n')
    with pytest.raises(StudyError, match="base: .*nowhere.toml: design file not found"):
        load_study(path)
    path.write_text("[[sweep]\n")
    with pytest.raises(StudyError, match="invalid TOML"):
        load_study(path)
    with pytest.raises(StudyError, match="study file not found"):
        load_study(tmp_path / "missing.toml")


def test_design_key_equal_for_equal_resolved_designs():
    d = Design()
    assert len(design_key(d)) == 16 and int(design_key(d), 16) >= 0
    assert design_key(d) == design_key(d.resolved())  # derived cavity left out or written out
    assert design_key(Design(stimulus={"temperature": 295})) == design_key(Design(stimulus={"temperature": 295.0}))
    keys = {design_key(d)}
    for change in [{"particle_layers": 4}, {"stimulus": {"temperature": 276.0}}, {"mesh": {"size": 1.9}},
                   {"membrane": {"shear_modulus": 0.024}}, {"hydrogel": {"n": 0.011}}, {"friction": 0.1},
                   {"cavity_width": 17.0}, {"stimulus": {"path": "linear"}}]:
        keys.add(design_key(Design(**change)))
    assert len(keys) == 9


def test_design_key_includes_the_cache_format(monkeypatch):
    before = design_key(Design())
    monkeypatch.setattr(study_mod, "CACHE_FORMAT", study_mod.CACHE_FORMAT + 1)
    assert design_key(Design()) != before


def test_points_shared_between_sweeps_have_one_key():
    study = study_from_dict({
        "design": {"particle_layers": 5, "stimulus": {"temperature": 275.0}},
        "sweep": [{"name": "temperature", "vary": {"stimulus.temperature": [275, 295]}},
                  {"name": "layers", "vary": {"particle_layers": [3, 5]}}],
    })
    keys = [p.key for p in study.points()]
    assert keys[0] == keys[3] == design_key(study.base)  # the base point is in both sweeps
    assert len(set(keys)) == 3
    assert study.varied_fields() == ["stimulus.temperature", "particle_layers"]


def test_2d_cache_keys_survive_the_3d_mesh_fields():
    """A 2D design's key ignores mesh.symmetry (3D only), so caches written before it existed
    resume: these are the keys the default and one-layer designs had then (frictionless, the
    default then; the default friction 0.01 is another design, with another key)."""
    assert design_key(hydrojam.default_design().model_copy(update={"friction": 0.0})) == "04eb2f4c262fe1b7"
    assert design_key(Design(particle_layers=1, friction=0.0)) == "1635fb00d9c54ea9"
    assert design_key(Design(particle_layers=1)) != "1635fb00d9c54ea9"
    assert design_key(Design(dimension=3)) != design_key(Design(dimension=3, mesh={"size": 2, "symmetry": False}))
