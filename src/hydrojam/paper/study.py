"""The paper's Section IV study (Chen, Schott & Jovanova, Figs. 6-11): three one-parameter sweeps
round the default design (PL 5, h 8 mm, 275 K), in 2D plane strain (cylinders; the default) or
in 3D (spheres, the half model: ``dimension=3``, a study of its own name).

Temperature (Figs. 6-7), particle layers (Figs. 8-9) and strain-limit layer thickness
(Figs. 10-11), each a :class:`PaperSweep`; :func:`paper_study` makes them one
:class:`hydrojam.study.spec.Study`. The quick study runs a subset of the points on a coarser mesh
(QUICK_MESH_SIZE, in 2D and 3D alike); the full study runs all of them at the default design's 2 mm.
Units: mm, K.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from hydrojam.actuator.design import Design, apply_overrides, default_design, with_replicas
from hydrojam.study.spec import Study, SweepSpec

__all__ = [
    "DIMENSIONS",
    "PARTICLE_LAYERS",
    "PAPER_SWEEPS",
    "PaperSweep",
    "QUICK_MESH_SIZE",
    "QUICK_PARTICLE_LAYERS",
    "QUICK_STRAIN_LIMIT_THICKNESSES_MM",
    "QUICK_TEMPERATURES_K",
    "STRAIN_LIMIT_THICKNESSES_MM",
    "TEMPERATURES_K",
    "paper_base",
    "paper_points",
    "paper_study",
    "paper_sweep",
    "paper_sweeps",
    "reproduce_command",
    "study_kind",
    "variant_name",
    "study_name",
    "sweep_of_field",
]

#: mesh size of the quick study [mm]; the design allows at most d/4 = 4 mm
QUICK_MESH_SIZE = 4.0
#: the dimensions a study runs in: 2 (plane strain, cylinders) or 3 (spheres, half model)
DIMENSIONS = (2, 3)

TEMPERATURES_K = [275.0, 280.0, 285.0, 290.0, 295.0]
PARTICLE_LAYERS = list(range(5, 20))
STRAIN_LIMIT_THICKNESSES_MM = [4.0, 6.0, 8.0, 10.0, 12.0]

QUICK_TEMPERATURES_K = [275.0, 285.0, 295.0]
QUICK_PARTICLE_LAYERS = [5, 7, 9, 11, 15, 19]
#: 10 mm is the paper's break point of both h statements (rises from 4 to 10 mm, then levels or falls
#: to 12 mm): without it the quick study cannot check the second half of either
QUICK_STRAIN_LIMIT_THICKNESSES_MM = [4.0, 8.0, 10.0, 12.0]


@dataclass(frozen=True)
class PaperSweep:
    """One sweep of the paper's Section IV: the varied design field and how to label it.

    Parameters
    ----------
    name : str
        Sweep name, also the figures' file stem.
    field : str
        Dotted design field varied.
    symbol : str
        The paper's symbol.
    label : str
        Axis label without unit.
    unit : str
        The field's unit (K, layers, mm).
    figures : str
        The paper's figures.
    values, quick_values : tuple
        The paper's values and the quick subset [``unit``].
    points_noun : str
        The swept values in words, plural ("temperatures").
    dimensions : tuple of int
        The study dimensions the sweep runs in (the strip's width: 3D only).
    reading : str
        For the paper's h, which reading of it the sweep varies ("" for the other sweeps).
    """

    name: str  # sweep name, also the figures' file stem
    field: str  # dotted design field varied
    symbol: str  # the paper's symbol
    label: str  # axis label without unit
    unit: str
    figures: str  # the paper's figures
    values: tuple
    quick_values: tuple
    points_noun: str  # the swept values in words, plural ("temperatures")
    dimensions: tuple[int, ...] = (2, 3)
    reading: str = ""


PAPER_SWEEPS: tuple[PaperSweep, ...] = (
    PaperSweep("temperature", "stimulus.temperature", "T", "temperature T", "K", "Figs. 6-7",
               tuple(TEMPERATURES_K), tuple(QUICK_TEMPERATURES_K), "temperatures"),
    PaperSweep("particle_layers", "particle_layers", "PL", "particle layers PL", "layers", "Figs. 8-9",
               tuple(PARTICLE_LAYERS), tuple(QUICK_PARTICLE_LAYERS), "layer counts"),
    PaperSweep("strain_limit_thickness", "strain_limit_thickness", "h", "strain-limit layer thickness h", "mm",
               "Figs. 10-11", tuple(STRAIN_LIMIT_THICKNESSES_MM), tuple(QUICK_STRAIN_LIMIT_THICKNESSES_MM),
               "thicknesses", reading="thickness"),
    PaperSweep("strain_limit_width", "strain_limit_width", "h", "strain-limit strip width h", "mm",
               "Figs. 10-11", tuple(STRAIN_LIMIT_THICKNESSES_MM), tuple(QUICK_STRAIN_LIMIT_THICKNESSES_MM),
               "widths", dimensions=(3,), reading="width"),
)
_BY_NAME = {s.name: s for s in PAPER_SWEEPS}
_BY_FIELD = {s.field: s for s in PAPER_SWEEPS}


def paper_sweeps(dimension: int = 2) -> tuple[PaperSweep, ...]:
    """The sweeps of PAPER_SWEEPS that run in a study of ``dimension`` (2 or 3), in order."""
    dimension = _check_dimension(dimension)
    return tuple(s for s in PAPER_SWEEPS if dimension in s.dimensions)


def paper_sweep(name: str) -> PaperSweep:
    """The sweep of PAPER_SWEEPS called ``name`` (KeyError if none)."""
    return _BY_NAME[name]


def sweep_of_field(field: str) -> PaperSweep | None:
    """The sweep of PAPER_SWEEPS that varies the dotted design field ``field``, or None."""
    return _BY_FIELD.get(field)


def _check_dimension(dimension) -> int:
    """``dimension`` if it is one of DIMENSIONS, else ValueError naming the allowed values."""
    if isinstance(dimension, bool) or dimension not in DIMENSIONS:
        raise ValueError(f"dimension: allowed {' or '.join(map(str, DIMENSIONS))} (got {dimension!r})")
    return int(dimension)


#: what separates a study's kind from its model choices in its name ("paper-3d-quick--friction_0_1")
VARIANT_SEPARATOR = "--"


def variant_name(overrides: Sequence[str] = ()) -> str:
    """The model choices ``overrides`` ("friction=0.1") as a name ("friction_0_1"; "" for none):
    every character other than a letter, digit, "_" or "-" becomes "_"."""
    return "--".join("".join(c if c.isascii() and (c.isalnum() or c in "_-") else "_" for c in o.strip())
                     for o in overrides)


def study_name(quick: bool = False, dimension: int = 2, overrides: Sequence[str] = ()) -> str:
    """The paper study's name, also the one ``OUT/study.toml`` records.

    Two kinds never share an output folder (the sweep refuses an OUT holding another name), nor
    does a study run under other model choices (``overrides``) share one with the default's.

    Parameters
    ----------
    quick : bool, optional
        The quick subset.
    dimension : {2, 3}, optional
        The study's dimension.
    overrides : sequence of str, optional
        Model choices changed for every point ("friction=0.1", as ``--set`` takes them).

    Returns
    -------
    str
        "paper", "paper-quick" (2D), "paper-3d" or "paper-3d-quick" (3D), followed with
        overrides by "--" and :func:`variant_name` ("paper-3d-quick--friction_0_1").

    Raises
    ------
    ValueError
        For another dimension.
    """
    name = "paper" + ("-3d" if _check_dimension(dimension) == 3 else "") + ("-quick" if quick else "")
    return name + (VARIANT_SEPARATOR + variant_name(overrides) if overrides else "")


def reproduce_command(quick: bool = False, dimension: int = 2, replicas: int = 1,
                      overrides: Sequence[str] = ()) -> str:
    """The command line of the study of that kind ("hydrojam reproduce --dimension 3 --quick
    --replicas 4 --set friction=0.1"), without its output folder: what the reports and
    `hydrojam status` print."""
    return (f"hydrojam reproduce{' --dimension 3' if _check_dimension(dimension) == 3 else ''}"
            f"{' --quick' if quick else ''}{f' --replicas {replicas}' if replicas > 1 else ''}"
            + "".join(f" --set {o}" for o in overrides))


def study_kind(name: str) -> tuple[bool, int] | None:
    """(quick, dimension) of a paper study's name (:func:`study_name`, with or without model
    choices), or None for another study."""
    kind = name.split(VARIANT_SEPARATOR, 1)[0]
    for quick in (False, True):
        for dimension in DIMENSIONS:
            if study_name(quick, dimension) == kind:
                return quick, dimension
    return None


def paper_base(quick: bool = False, replicas: int = 1, dimension: int = 2, overrides: Sequence[str] = ()) -> Design:
    """The base design of every sweep: the default (PL 5, h 8 mm, 275 K, 2D), with the model
    choices ``overrides`` changed.

    Parameters
    ----------
    quick : bool, optional
        Mesh size QUICK_MESH_SIZE [mm].
    replicas : int, optional
        Replicas per point (``replicas.count``).
    dimension : {2, 3}, optional
        3: the same design with spheres (the half model, the design's default).
    overrides : sequence of str, optional
        Design fields changed ("friction=0.1", "membrane.shear_modulus=0.046"), as ``--set``.

    Returns
    -------
    Design

    Raises
    ------
    ValueError
        For another dimension; DesignError (a ValueError) for a bad override.
    """
    base = default_design()
    if _check_dimension(dimension) == 3:
        base = apply_overrides(base, ["dimension=3"])
    if quick:
        base = apply_overrides(base, [f"mesh.size={QUICK_MESH_SIZE!r}"])
    if overrides:
        base = apply_overrides(base, list(overrides))
    return with_replicas(base, replicas) if replicas != 1 else base


def paper_points(quick: bool = False, dimension: int = 2) -> dict[str, dict[str, list]]:
    """Sweep name -> {dotted design field: values}, the paper's points (quick: a subset) in a
    study of ``dimension``; values in the field's unit (K, layers, mm)."""
    return {s.name: {s.field: list(s.quick_values if quick else s.values)} for s in paper_sweeps(dimension)}


def paper_study(quick: bool = False, sweeps: Sequence[str] | None = None, replicas: int = 1,
                dimension: int = 2, overrides: Sequence[str] = ()) -> Study:
    """The Section IV study as a :class:`hydrojam.study.spec.Study` named :func:`study_name`.

    Sweeps "temperature", "particle_layers", "strain_limit_thickness" and, in 3D,
    "strain_limit_width" (the paper's h read as the strip's width along y, at the base design's
    thickness) round :func:`paper_base`.
    Replica 0 of each point is the single run's point, so a study with more replicas reuses a
    finished single-run study in the same folder. The base point (275 K, PL 5, h 8 mm) lies in all
    three. The 3D study has the 2D one's points.

    Parameters
    ----------
    quick : bool, optional
        A subset of the points on the quick mesh.
    sweeps : sequence of str, optional
        Only the sweeps named, in the paper's order (default: all three).
    replicas : int, optional
        Runs per point.
    dimension : {2, 3}, optional
        The study's dimension.
    overrides : sequence of str, optional
        Model choices changed for every point (``--set``): the study is then one of its own,
        named by them (:func:`study_name`), to be run into its own folder.

    Returns
    -------
    Study

    Raises
    ------
    ValueError
        Naming the allowed ones, for an unknown sweep name or dimension.
    """
    name = study_name(quick, dimension, overrides)
    points = paper_points(quick, dimension)
    unknown = [s for s in (sweeps or ()) if s not in points]
    if unknown:
        raise ValueError(f"unknown sweep {', '.join(map(repr, unknown))}; allowed: {', '.join(points)}")
    sweeps = [SweepSpec(name=sweep, vary=vary) for sweep, vary in points.items() if sweeps is None or sweep in sweeps]
    return Study(name=name, base=paper_base(quick, replicas, dimension, overrides), sweeps=sweeps)
