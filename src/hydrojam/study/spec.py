"""A study: a base design and named parameter sweeps over it, read from and written to TOML.

Each sweep varies one or more dotted design fields; its points are the cartesian product of the
value lists, in key order then value order (the last key varies fastest). Every point's design
is validated when the study is made, so a bad value is refused before any work with one line
naming the sweep, the field and its allowed range (:class:`StudyError`, a
:class:`~hydrojam.design.DesignError`).

The study file (every key optional except ``[[sweep]]``)::

    name = "my-study"
    base = "design.toml"          # a design file, relative to the study file (default: the default design)
    [design]                      # overrides of the base design: the keys of design.toml, nested tables
    particle_layers = 5
    [[sweep]]
    name = "temperature"          # letters, digits, '_' and '-'
    [sweep.vary]
    "stimulus.temperature" = [275, 285, 295]

Points with equal resolved designs have equal :func:`design_key`, the name of their folder in a
sweep's cache (:mod:`hydrojam.study.cache`): the base point shared by two sweeps is computed once.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import tomli_w
from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationError, field_validator, model_validator

from hydrojam._io import read_toml, write_text_atomic
from hydrojam._validation import short_repr, explain_error, submodel
from hydrojam.actuator.design import (
    Design,
    DesignError,
    merge_value,
    toml_value,
    default_design,
    design_from_dict,
    load_design,
    with_replicas,
)

#: bump when what a cached point holds changes: every key changes, so nothing old is reused
CACHE_FORMAT = 2

_NAME_CHARS = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-")
_TOP_KEYS = ("name", "base", "design", "sweep")

__all__ = [
    "CACHE_FORMAT",
    "Point",
    "Study",
    "StudyError",
    "SweepSpec",
    "design_key",
    "load_study",
    "study_from_dict",
    "study_to_toml",
    "write_study",
]


class StudyError(DesignError):
    """Invalid study: one line naming the sweep, the dotted design field and its allowed range."""


def design_key(design: Design) -> str:
    """The cache key of a design: 16 hex digits of SHA-256 over the resolved design (canonical JSON)
    and :data:`CACHE_FORMAT`.

    Equal designs written differently (a derived cavity size left out or written out) share a key.
    Of the ``replicas`` table only what changes the run counts: nothing for replica 0 (the design
    as drawn, the key it had before replicas existed), seed, jitter and index for another; of
    ``mesh.symmetry`` nothing in 2D; of ``friction_slip``, ``strain_limit_width`` and the multi-chamber
    fields (``chambers``, ``chamber_wall_thickness``, ``strain_limit_position``) nothing when omitted;
    of ``strain_limit_helix_deg`` nothing when omitted or 0 (the straight strip).

    Parameters
    ----------
    design : Design
        The design.

    Returns
    -------
    str
        The key, 16 hexadecimal digits.
    """
    dumped = design.resolved().model_dump(mode="json")
    replicas = dumped.pop("replicas")
    if design.dimension == 2:  # no symmetry plane in 2D: the key it had before 3D existed
        dumped["mesh"].pop("symmetry", None)
    for optional in ("friction_slip", "strain_limit_width", "chamber_wall_thickness", "strain_limit_position",
                     "chambers"):  # omitted: the key it had before the field
        if dumped.get(optional) is None:
            dumped.pop(optional, None)
    if not dumped.get("strain_limit_helix_deg"):  # omitted or 0: the straight strip, its key unchanged
        dumped.pop("strain_limit_helix_deg", None)
    if replicas["index"] > 0:
        dumped["replica"] = {k: replicas[k] for k in ("seed", "jitter", "index")}
    data = {"cache_format": CACHE_FORMAT, "design": dumped}
    text = json.dumps(data, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def _check_name(value: str, what: str) -> str:
    if not value or not set(value) <= _NAME_CHARS:
        raise ValueError(f"{what}: must be a non-empty name of letters, digits, '_' and '-' (got {value!r})")
    return value


def _leaf_field(path: str) -> str | None:
    """Why ``path`` is not a dotted leaf field of Design, or None if it is one."""
    parts = path.split(".")
    if not path or any(not p for p in parts):
        return "expected a dotted design field, e.g. stimulus.temperature"
    for i, name in enumerate(parts):
        model = submodel(Design, parts[:i])
        if model is None:
            return f"{'.'.join(parts[:i])} is not a table"
        if name not in model.model_fields:
            return f"unknown design field (allowed here: {', '.join(model.model_fields)})"
    table = submodel(Design, parts)
    if table is not None:
        return f"is a table; vary one of its fields, e.g. {path}.{next(iter(table.model_fields))}"
    return None


class SweepSpec(BaseModel):
    """One sweep: ``vary`` maps dotted design fields to value lists; the points are their product."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    name: str = Field(description="sweep name: letters, digits, '_' and '-'")
    vary: dict[str, list[bool | int | float | str]] = Field(
        description="dotted design field -> non-empty list of values, e.g. {'stimulus.temperature': [275, 295]}"
    )

    @field_validator("name")
    @classmethod
    def _name(cls, v: str) -> str:
        return _check_name(v, "name")

    @field_validator("vary")
    @classmethod
    def _vary(cls, v: dict) -> dict:
        if not v:
            raise ValueError("vary: give at least one dotted design field and its values")
        for key, values in v.items():
            why = _leaf_field(key)
            if why is not None:
                raise ValueError(f"vary.{key}: {why}")
            if not values:
                raise ValueError(f"vary.{key}: give at least one value (got an empty list)")
        return v

    def grid(self) -> list[dict[str, Any]]:
        """The points' varied values, the product over the keys in order (the last varies fastest)."""
        keys = list(self.vary)
        return [dict(zip(keys, combo)) for combo in itertools.product(*(self.vary[k] for k in keys))]


@dataclass(frozen=True)
class Point:
    """One run of a study.

    Parameters
    ----------
    sweep : str
        The sweep's name.
    index : int
        Index of the point within the sweep.
    values : dict
        Dotted design field -> the value varied at this point.
    design : Design
        The design of this run (this replica's, a single run).
    key : str
        The cache key (:func:`design_key`).
    replica : int, optional
        Which of the point's replicas this run is.
    replicas : int, optional
        How many replicas the point has.
    """

    sweep: str
    index: int
    values: dict[str, Any]
    design: Design
    key: str
    replica: int = 0
    replicas: int = 1


def _point_design(base: Design, values: dict[str, Any]) -> Design:
    """The base design with the dotted values applied (derived cavity sizes follow), validated."""
    data = base.model_dump(exclude_none=True)
    for key, value in values.items():
        merge_value(data, key.split("."), value)
    return design_from_dict(data)


class Study(BaseModel):
    """A base design and named sweeps over it; :meth:`points` lists every (sweep, point).

    Every point's design is validated when the study is made; the first invalid one is refused
    with a message naming its sweep and field.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str = Field("study", description="study name: letters, digits, '_' and '-'")
    base: Design = Field(default_factory=default_design, description="the design every sweep starts from")
    sweeps: list[SweepSpec] = Field(description="the sweeps, at least one, unique names")

    _points: list[Point] = PrivateAttr(default_factory=list)

    @field_validator("name")
    @classmethod
    def _name(cls, v: str) -> str:
        return _check_name(v, "name")

    @model_validator(mode="after")
    def _check(self) -> Study:
        if not self.sweeps:
            raise ValueError("sweep: give at least one [[sweep]]")
        seen: set[str] = set()
        for sweep in self.sweeps:
            if sweep.name in seen:
                raise ValueError(f"sweep '{sweep.name}': duplicate sweep name; each sweep needs its own")
            seen.add(sweep.name)
        points: list[Point] = []
        for sweep in self.sweeps:
            for index, values in enumerate(sweep.grid()):
                try:
                    design = _point_design(self.base, values)
                except DesignError as err:
                    given = ", ".join(f"{k} = {v!r}" for k, v in values.items())
                    raise ValueError(f"sweep '{sweep.name}' point {index} ({given}): {err}") from None
                n = design.replicas.count
                for k in range(n):
                    one = design.replica(k)
                    points.append(Point(sweep.name, index, values, one, design_key(one), k, n))
        self._points = points
        return self

    def points(self) -> list[Point]:
        """Every run of every sweep, in study order (sweep order, then grid order, then replica):
        a point of a design with ``replicas.count`` N is N runs (:meth:`Design.replica`)."""
        return list(self._points)

    @property
    def replicas(self) -> int:
        """The most replicas of any point (1: every point is a single run)."""
        return max((p.replicas for p in self._points), default=1)

    def with_replicas(self, count: int) -> Study:
        """The study with ``count`` replicas of every point (the base design's ``replicas.count``;
        a sweep varying it still wins); DesignError naming the field for a bad count."""
        try:
            return Study(name=self.name, base=with_replicas(self.base, count), sweeps=self.sweeps)
        except ValidationError as err:
            raise StudyError(validation_message(err, Study, "")) from None

    def varied_fields(self) -> list[str]:
        """The dotted fields varied anywhere in the study, in order of first appearance."""
        return list(dict.fromkeys(k for s in self.sweeps for k in s.vary))


# -------------------------------------------------------------------- reading


def validation_message(err: ValidationError, model: type[BaseModel], prefix: str) -> str:
    """``prefix`` and the one-line message for err's first error (pydantic): the field and its
    allowed range, as every refusal of a study or sweep file reads."""
    e = err.errors()[0]
    loc = e["loc"]
    if e["type"] in ("value_error", "assertion_error") and (not loc or loc[0] in ("name", "vary")):
        # our validators' messages already start with the field they are about
        msg = e["msg"].removeprefix("Value error, ").removeprefix("Assertion error, ")
    elif loc and loc[0] == "vary" and len(loc) > 1:
        msg = f"vary.{loc[1]}: expected a list of numbers, strings or booleans (got {short_repr(e.get('input'))})"
    else:
        msg = explain_error(err, model)
    return f"{prefix}{msg}"


def _sweep_from_dict(raw: Any, i: int) -> SweepSpec:
    if not isinstance(raw, dict):
        raise StudyError(f"sweep[{i}]: expected a [[sweep]] table, got {type(raw).__name__}")
    label = f"sweep '{raw['name']}'" if isinstance(raw.get("name"), str) and raw["name"] else f"sweep[{i}]"
    for key in raw:
        if key not in SweepSpec.model_fields:
            raise StudyError(f"{label}: {key}: unknown key (allowed: {', '.join(SweepSpec.model_fields)})")
    if not isinstance(raw.get("vary", {}), dict):
        raise StudyError(f"{label}: vary: expected a [sweep.vary] table of dotted field = [values]")
    if "vary" not in raw:
        raise StudyError(f'{label}: vary: required table missing, e.g. [sweep.vary] "stimulus.temperature" = [275, 295]')
    try:
        return SweepSpec.model_validate(raw, strict=True)
    except ValidationError as err:
        raise StudyError(validation_message(err, SweepSpec, f"{label}: ")) from None


def study_from_dict(data: dict, root: str | os.PathLike | None = None) -> Study:
    """A validated Study from parsed TOML (see the module docstring).

    Parameters
    ----------
    data : dict
        The parsed study file.
    root : str or os.PathLike, optional
        The folder ``base`` is read relative to (default: the current folder).

    Returns
    -------
    Study

    Raises
    ------
    StudyError
        For an invalid study (one line naming the key).
    """
    if not isinstance(data, dict):
        raise StudyError(f"study: expected a table of keys, got {type(data).__name__}")
    for key in data:
        if key not in _TOP_KEYS:
            raise StudyError(f"{key}: unknown key (allowed: {', '.join(_TOP_KEYS)})")
    name = data.get("name", "study")
    if not isinstance(name, str):
        raise StudyError(f"name: expected a string, got {name!r}")
    base = default_design()
    if "base" in data:
        if not isinstance(data["base"], str):
            raise StudyError(f"base: expected the path of a design file, got {data['base']!r}")
        path = Path(data["base"])
        if not path.is_absolute():
            path = Path(root or ".") / path
        try:
            base = load_design(path)
        except DesignError as err:
            raise StudyError(f"base: {err}") from None
    if "design" in data:
        overrides = data["design"]
        if not isinstance(overrides, dict):
            raise StudyError(f"design: expected a table of design keys, got {type(overrides).__name__}")
        merged = base.model_dump(exclude_none=True)
        for key, value in overrides.items():
            merge_value(merged, [key], value)
        try:
            base = design_from_dict(merged)
        except DesignError as err:
            raise StudyError(f"design.{err}") from None
    raw_sweeps = data.get("sweep", [])
    if not isinstance(raw_sweeps, list) or not raw_sweeps:
        raise StudyError('sweep: give at least one [[sweep]] table with a name and a [sweep.vary] table')
    sweeps = [_sweep_from_dict(raw, i) for i, raw in enumerate(raw_sweeps)]
    try:
        return Study(name=name, base=base, sweeps=sweeps)
    except ValidationError as err:
        raise StudyError(validation_message(err, Study, "")) from None


def load_study(path: str | os.PathLike) -> Study:
    """Read a study TOML file.

    Parameters
    ----------
    path : str or os.PathLike
        The study file; its ``base`` is read relative to its folder.

    Returns
    -------
    Study

    Raises
    ------
    StudyError
        Naming the file, for a missing or invalid one.
    """
    path = Path(path)
    data = read_toml(path, "study", StudyError)
    try:
        return study_from_dict(data, root=path.parent)
    except DesignError as err:
        raise StudyError(f"{path}: {err}") from None


# -------------------------------------------------------------------- writing

_HEADER = """\
# hydrojam study: a base design ([design], every field written out) and named sweeps over it.
# Each sweep's points are the product of its value lists. Run it with:
#   hydrojam sweep study.toml -o out
"""


def study_to_toml(study: Study) -> str:
    """The study as a self-contained TOML document: the full base design inline (derived cavity
    sizes left out, so they follow a varied particle count) and the sweeps.

    Round-trips: ``study_from_dict(tomllib.loads(study_to_toml(s))) == s``.

    Parameters
    ----------
    study : Study

    Returns
    -------
    str
        The TOML text.
    """
    text = tomli_w.dumps({"name": study.name, "design": study.base.model_dump(exclude_none=True)})
    for sweep in study.sweeps:
        lines = ["", "[[sweep]]", f"name = {toml_value(sweep.name)}", "", "[sweep.vary]"]
        for key, values in sweep.vary.items():
            lines.append(f"{toml_value(key) if '.' in key else key} = [{', '.join(toml_value(v) for v in values)}]")
        text += "\n".join(lines) + "\n"
    return _HEADER + "\n" + text


def write_study(path: str | os.PathLike, study: Study) -> None:
    """Write the study as TOML (:func:`study_to_toml`) atomically.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write.
    study : Study
    """
    write_text_atomic(path, study_to_toml(study))
