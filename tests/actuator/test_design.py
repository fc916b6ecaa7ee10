"""The actuator design schema: defaults, TOML round trip, one-line refusals, overrides."""

from __future__ import annotations

import tomllib

import pytest

from hydrojam._validation import describe_error, field_range
from hydrojam.actuator.design import (
    DEFAULT_MESH_SIZE_MM,
    GelSpec,
    Design,
    DesignError,
    ElastomerSpec,
    StimulusSpec,
    apply_overrides,
    default_design,
    design_from_dict,
    design_to_toml,
    load_design,
    write_design,
)
from hydrojam.materials.energies import HydrogelParams, NeoHookean, Yeoh
from hydrojam.materials.kinetics import DEFAULT_DIFFUSIVITY

from refusals import refusal


def test_defaults_match_design_md():
    """docs/actuator.md, "Design": d 16, PL 5, clearance 0.1, t0 2, t1 4, h 8; cavity 16.2 x 80.6, L 88.6."""
    d = default_design()
    assert d == Design()
    assert (d.dimension, d.particle_diameter, d.particle_layers, d.particles_per_layer) == (2, 16.0, 5, 1)
    assert (d.clearance, d.side_wall_thickness, d.end_wall_thickness, d.strain_limit_thickness) == (0.1, 2.0, 4.0, 8.0)
    assert d.cavity_width is None and d.cavity_length is None
    assert d.resolved_cavity_width == pytest.approx(16.2)
    assert d.resolved_cavity_length == pytest.approx(80.6)
    assert d.resolved_cavity_depth == pytest.approx(16.2)
    assert d.length == pytest.approx(88.6)
    assert d.width == pytest.approx(8 + 4 + 16.2)
    assert (d.stimulus.temperature, d.stimulus.mu, d.stimulus.path) == (275.0, 0.0, "swelling")
    assert d.hydrogel.params() == HydrogelParams()  # the gel constants; the diffusivity is new (issue 16)
    assert d.hydrogel == GelSpec() and d.hydrogel.diffusivity == DEFAULT_DIFFUSIVITY
    mat = d.membrane.material()
    assert isinstance(mat, NeoHookean) and mat.shear_modulus == 0.023 and mat.poisson_ratio == 0.45


def test_resolved_fills_in_the_cavity():
    r = default_design().resolved()
    assert r.cavity_width == pytest.approx(16.2) and r.cavity_length == pytest.approx(80.6)
    assert r.cavity_depth is None
    r3 = Design(dimension=3).resolved()
    assert r3.cavity_depth == pytest.approx(16.2)
    assert design_from_dict(r3.model_dump()) == r3


def test_yeoh_material():
    spec = ElastomerSpec(model="yeoh", shear_modulus=0.03, c20=1e-4, c30=-1e-7)
    mat = spec.material()
    assert isinstance(mat, Yeoh)
    assert (mat.c10, mat.c20, mat.c30, mat.poisson_ratio) == (0.015, 1e-4, -1e-7, 0.45)


def _modified() -> Design:
    return design_from_dict(
        {
            "particle_layers": 7,
            "cavity_width": 17.0,
            "friction": 0.3,
            "membrane": {"model": "yeoh", "shear_modulus": 0.03, "c20": 2e-4, "c30": 1e-6},
            "hydrogel": {"n": 0.02, "T0": 298.0},
            "stimulus": {"temperature": 295.0, "mu": -0.01, "path": "linear"},
            "mesh": {"size": 1.5},
        }
    )


@pytest.mark.parametrize("design", [default_design(), _modified(), Design(dimension=3).resolved()])
@pytest.mark.parametrize("comments", [True, False])
def test_toml_round_trip(design, comments):
    text = design_to_toml(design, comments=comments)
    assert design_from_dict(tomllib.loads(text)) == design
    assert "mu0" not in tomllib.loads(text)["hydrogel"]


def test_commented_toml_documents_every_field():
    text = design_to_toml(default_design())
    assert text.startswith("#") and "hydrojam run design.toml -o out" in text
    assert "# cavity_width = 16.2" in text and "# cavity_length = 80.6" in text
    for table in ("[membrane]", "[strain_limit_layer]", "[hydrogel]", "[stimulus]", "[mesh]"):
        assert table in text
    lines = text.splitlines()
    i = lines.index("strain_limit_thickness = 8.0")
    assert "[mm]" in " ".join(lines[i - 2 : i]) and "(0, 1000.0]" in " ".join(lines[i - 2 : i])
    assert all(len(line) <= 100 for line in lines)
    assert "#" not in design_to_toml(default_design(), comments=False)


def test_mesh_size_left_out_takes_the_dimensions_default():
    """mesh.size omitted is derived from the dimension (written out by resolved(), so a run's
    design.toml and its cache key name the size it ran with); --set dimension=3 follows it, and an
    explicit size keeps its key."""
    from hydrojam.study.spec import design_key

    for dim in (2, 3):
        d = Design(dimension=dim)
        assert d.mesh.size is None and d.mesh_size == DEFAULT_MESH_SIZE_MM[dim]
        assert d.resolved().mesh.size == DEFAULT_MESH_SIZE_MM[dim]
        explicit = Design(dimension=dim, mesh={"size": DEFAULT_MESH_SIZE_MM[dim]})
        assert design_key(d) == design_key(explicit)
    assert apply_overrides(default_design(), ["dimension=3"]).mesh_size == DEFAULT_MESH_SIZE_MM[3]
    assert apply_overrides(default_design(), ["dimension=3", "mesh.size=3"]).mesh_size == 3.0
    text = design_to_toml(Design(dimension=3))
    assert f"# size = {DEFAULT_MESH_SIZE_MM[3]!r}" in text.splitlines()
    assert "size" not in tomllib.loads(text)["mesh"]


def test_write_and_load(tmp_path):
    path = tmp_path / "sub" / "design.toml"
    write_design(path, _modified())
    assert load_design(path) == _modified()
    assert list(path.parent.iterdir()) == [path]  # no temporary file left behind


@pytest.mark.parametrize(
    ("data", "expected"),
    [
        ({"cavity_width": 15.0}, ["cavity_width", "do not fit", "16.2 mm > cavity_width 15 mm"]),
        ({"cavity_length": 80.0}, ["cavity_length", "need cavity_length >= 80.6"]),
        ({"dimension": 3, "cavity_depth": 16.0}, ["cavity_depth", "16.2"]),
        ({"cavity_depth": 20.0}, ["cavity_depth", "dimension = 3"]),
        ({"strain_limit_thickness": -1}, ["strain_limit_thickness", "(0, 1000.0]", "mm", "-1"]),
        ({"particle_layers": 0}, ["particle_layers", "[1, 100]", "got 0"]),
        ({"particle_layers": 5.5}, ["particle_layers", "expected an integer", "5.5"]),
        ({"particle_diameter": "big"}, ["particle_diameter", "expected a number", "'big'"]),
        ({"dimension": 4}, ["dimension", "2 or 3"]),
        ({"colour": "red"}, ["colour: unknown key", "particle_diameter", "stimulus"]),
        ({"stimulus": {"temprature": 280}}, ["stimulus.temprature: unknown key (allowed: temperature, mu, path, schedule)"]),
        ({"stimulus": {"temperature": 400}}, ["stimulus.temperature", "[273.15, 373.15]", "K", "400"]),
        ({"stimulus": {"mu": 0.1}}, ["stimulus.mu", "(-inf, 0.0]", "0.1"]),
        ({"stimulus": {"path": "spiral"}}, ["stimulus.path", "'swelling' or 'linear'"]),
        ({"stimulus": 3}, ["stimulus", "expected a table"]),
        ({"hydrogel": {"n": 0}}, ["hydrogel.n", "(0, 1.0]", "got 0"]),
        ({"hydrogel": {"A0": float("inf")}}, ["hydrogel.A0", "finite"]),
        ({"hydrogel": {"mu0": -0.03}}, ["hydrogel.mu0: unknown key"]),
        ({"membrane": {"c20": 0.001}}, ["membrane.c20", "yeoh", "0.001"]),
        ({"strain_limit_layer": {"model": "yeoh", "c20": -0.01}}, ["strain_limit_layer.c20", "> 0"]),
        ({"membrane": {"model": "yeoh", "c30": -1e-3}}, ["membrane.c30", "> 0"]),
        ({"membrane": {"poisson_ratio": 0.5}}, ["membrane.poisson_ratio", "[0, 0.5)"]),
        ({"mesh": {"size": 5.0}}, ["mesh.size", "particle_diameter/4 = 4 mm", "5"]),
        ({"mesh": {"size": float("nan")}}, ["mesh.size", "finite"]),
        ({"clearance": 4.0}, ["clearance", "< particle_diameter/4"]),
        ({"friction": 3}, ["friction", "[0, 2]"]),
        ({"friction_slip": 0.0}, ["friction_slip", "(0, 1]", "got 0"]),
        ({"replicas": {"count": 0}}, ["replicas.count", "[1, 1000]", "got 0"]),
        ({"replicas": {"count": 1001}}, ["replicas.count", "[1, 1000]"]),
        ({"replicas": {"jitter": 0.0}}, ["replicas.jitter", "(0, 0.1]"]),
        ({"replicas": {"jitter": 0.5}}, ["replicas.jitter", "(0, 0.1]", "0.5"]),
        ({"replicas": {"seed": -1}}, ["replicas.seed", "[0, "]),
        ({"replicas": {"count": 2, "index": 1}}, ["replicas.index", "only with count = 1"]),
        ({"replicas": {"colour": 1}}, ["replicas.colour: unknown key (allowed: count, seed, jitter, index)"]),
    ],
)
def test_refusals_name_the_field(data, expected):
    msg = refusal(data)
    for part in expected:
        assert part in msg, msg


def test_refusal_is_never_a_pydantic_error():
    with pytest.raises(DesignError):
        design_from_dict([1, 2])
    assert issubclass(DesignError, ValueError)


def test_a_derived_cavity_fits_exactly():
    """Sizes that round (d = 0.3, c = 0.07) still fit the cavity derived from them."""
    d = design_from_dict({"particle_diameter": 0.3, "clearance": 0.07, "particle_layers": 17, "mesh": {"size": 0.07}})
    assert design_from_dict(tomllib.loads(design_to_toml(d.resolved()))) == d.resolved()


def test_overrides():
    d = apply_overrides(default_design(), ["particle_layers=7", "stimulus.path=linear", "stimulus.temperature=295"])
    assert d.particle_layers == 7 and d.cavity_length is None
    assert d.resolved_cavity_length == pytest.approx(7 * 16 + 8 * 0.1)
    assert d.stimulus.path == "linear" and d.stimulus.temperature == 295.0
    # a derived cavity follows a new diameter
    d = apply_overrides(default_design(), ["particle_diameter=12", "mesh.size=1"])
    assert d.resolved_cavity_width == pytest.approx(12.2) and d.length == pytest.approx(5 * 12 + 0.6 + 8)
    # a table override merges into the table
    d = apply_overrides(default_design(), ['membrane={model="yeoh", c20=1e-4}'])
    assert d.membrane == ElastomerSpec(model="yeoh", c20=1e-4)
    assert apply_overrides(default_design(), []) == default_design()


@pytest.mark.parametrize(
    ("override", "expected"),
    [
        ("particle_layers", "--set particle_layers: expected key=value"),
        ("foo=1", "--set foo=1: unknown key foo (allowed: dimension,"),
        (
            "stimulus.temprature=280",
            "--set stimulus.temprature=280: unknown key stimulus.temprature (allowed: temperature, mu, path, schedule)",
        ),
        ("friction.x=1", "--set friction.x=1: friction is not a table"),
        ("stimulus.temperature=400", "--set stimulus.temperature=400: stimulus.temperature: must be <= 373.15"),
        ("particle_layers=many", "--set particle_layers=many: particle_layers: expected an integer, got 'many'"),
        ("=3", "--set =3: expected key=value"),
    ],
)
def test_bad_override_refused(override, expected):
    with pytest.raises(DesignError) as exc:
        apply_overrides(default_design(), [override])
    assert str(exc.value).startswith(expected), str(exc.value)
    assert "\n" not in str(exc.value)


def test_override_conflicting_with_an_explicit_cavity():
    d = default_design().resolved()
    with pytest.raises(DesignError, match=r"--set particle_diameter=20: cavity_width: the particles do not fit"):
        apply_overrides(d, ["particle_diameter=20"])


def test_load_design_errors_name_the_file(tmp_path):
    broken = tmp_path / "broken.toml"
    broken.write_text("particle_layers = 5\nclearance 0.1\n", encoding="utf-8")
    with pytest.raises(DesignError) as exc:
        load_design(broken)
    msg = str(exc.value)
    assert str(broken) in msg and "invalid TOML" in msg and "line 2" in msg and "\n" not in msg

    with pytest.raises(DesignError, match="not found"):
        load_design(tmp_path / "missing.toml")

    bad = tmp_path / "bad.toml"
    bad.write_text("[stimulus]\ntemperature = 400\n", encoding="utf-8")
    with pytest.raises(DesignError, match=r"bad\.toml: stimulus\.temperature"):
        load_design(bad)


def test_partial_file_takes_defaults(tmp_path):
    path = tmp_path / "design.toml"
    path.write_text("particle_layers = 9\n[stimulus]\ntemperature = 290\n", encoding="utf-8")
    d = load_design(path)
    assert d == Design(particle_layers=9, stimulus=StimulusSpec(temperature=290.0))


def test_field_range_walks_nested_models():
    assert field_range(Design, "stimulus.temperature") == "[273.15, 373.15]"
    assert field_range(Design, ("hydrogel", "n")) == "(0, 1.0]"
    assert field_range(Design, "strain_limit_thickness") == "(0, 1000.0]"
    assert field_range(Design, "clearance") == "(0, inf)"
    assert field_range(Design, "stimulus.nope") is None
    assert field_range(HydrogelParams, "n") == "(0, 1.0]"  # the old one-level use


def test_describe_error_unchanged_for_flat_models():
    from pydantic import ValidationError

    with pytest.raises(ValidationError) as exc:
        HydrogelParams(n=0)
    assert describe_error(exc.value, HydrogelParams, {"n": "--nnu"}) == (
        "--nnu: input should be greater than 0; allowed range (0, 1.0] (got 0)"
    )


def test_replicas_of_a_design():
    """Replica k is the design as a single run (count 1, index k), seed and jitter kept; a single
    run is its own replica 0; with_replicas sets the count and refuses what the file would."""
    from hydrojam.actuator.design import with_replicas

    d = with_replicas(default_design(), 4)
    assert d.replicas.count == 4 and d.replicas.index == 0
    r = d.replica(3)
    assert (r.replicas.count, r.replicas.index, r.replicas.seed, r.replicas.jitter) == (1, 3, 0, d.replicas.jitter)
    assert r.model_copy(update={"replicas": d.replicas}) == d
    assert default_design().replica(0) is not None and default_design().replica(0) == default_design()
    for bad in (-1, 4, True, 1.0):
        with pytest.raises(ValueError, match=r"replica: must be an integer in \[0, 3\]"):
            d.replica(bad)
    for bad in (0, 1001, 2.0):
        with pytest.raises(DesignError, match=r"^replicas.count: must be an integer in \[1, 1000\]"):
            with_replicas(default_design(), bad)
    with pytest.raises(DesignError, match=r"^replicas.index"):
        with_replicas(r, 2)


def test_every_length_field_has_an_upper_bound_or_a_relative_one():
    """Each length of the design is bounded above: by its own range, or (clearance, mesh.size,
    friction_slip) relative to another field, so no length reaches the geometry unchecked."""
    from hydrojam.actuator.design import MAX_CAVITY_MM, MAX_WALL_MM

    for name in ("side_wall_thickness", "end_wall_thickness", "strain_limit_thickness"):
        assert field_range(Design, name) == f"(0, {MAX_WALL_MM}]"
    for name in ("cavity_width", "cavity_length", "cavity_depth"):
        assert field_range(Design, name) == f"(0, {MAX_CAVITY_MM}]"
    assert field_range(Design, "particle_diameter") == "(0, 1000]"
    # the largest cavity derived from the particles stays inside the cavity's own range
    big = Design(particle_diameter=1000.0, particle_layers=100, clearance=249.0, mesh={"size": 250.0},
                 side_wall_thickness=100.0, end_wall_thickness=100.0, strain_limit_thickness=200.0)
    assert big.resolved().cavity_length <= MAX_CAVITY_MM


@pytest.mark.parametrize("data, words", [
    ({"side_wall_thickness": 0.4}, "side_wall_thickness: too thin for mesh.size 2 mm: must be >= 0.5 mm"),
    ({"end_wall_thickness": 0.1, "mesh": {"size": 1.0}}, "end_wall_thickness: too thin for mesh.size 1 mm: must be >= 0.25 mm"),
    ({"strain_limit_thickness": 0.9}, "strain_limit_thickness: too thin for mesh.size 2 mm: must be >= 1 mm"),
    ({"cavity_width": 3e4}, "mesh.size: the mesh would have about"),
    ({"dimension": 3, "mesh": {"size": 0.3}}, "mesh.size: the mesh would have about"),
    ({"clearance": 1e-5}, "clearance: must be >= 1e-6 x the actuator's larger size 88.0001 mm"),
])
def test_designs_the_geometry_cannot_build_are_refused(data, words):
    with pytest.raises(DesignError) as err:
        design_from_dict(data)
    assert words in str(err.value) and "\n" not in str(err.value)


def test_the_buildability_limits_leave_room_for_the_paper_and_the_examples():
    """The thinnest walls in use (the quick study: t0 = 2 mm at mesh.size 4 mm; the bead-size
    study: t0 = d/8 at d/4) pass, and the paper's largest mesh (the full 3D study) has a tenth of
    MAX_ELEMENTS or fewer."""
    from hydrojam.actuator.design import MAX_ELEMENTS
    from hydrojam.paper.study import paper_study

    Design(mesh={"size": 4.0}, side_wall_thickness=1.0, strain_limit_thickness=2.0)  # walls at mesh/4
    largest = max(p.design.estimated_elements() for p in paper_study(False, None, dimension=3).points())
    assert largest < 0.2 * MAX_ELEMENTS


def test_estimated_elements_is_within_a_factor_two_of_gmsh():
    """The estimate (outer area over an equilateral triangle of edge mesh.size) against the mesh
    gmsh makes: gmsh refines round the particles, so it makes more, up to about twice."""
    from hydrojam.actuator.geometry import mesh_design

    for d in (Design(), Design(particle_layers=2, mesh={"size": 1.0})):
        n = len(mesh_design(d).cells)
        assert 0.5 * n <= d.estimated_elements() <= 2.0 * n
