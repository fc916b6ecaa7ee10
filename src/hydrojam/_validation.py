"""One-line messages for invalid input: the field, the allowed range, the value given."""

from __future__ import annotations

import math
import re
import typing
from collections.abc import Sequence

import annotated_types as at
from pydantic import BaseModel, ValidationError


def _model_class(annotation) -> type[BaseModel] | None:
    """The pydantic model class inside an annotation (``Model``, ``Model | None``), else None."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in typing.get_args(annotation):
        found = _model_class(arg)
        if found is not None:
            return found
    return None


def _parts(loc: str | Sequence) -> list[str]:
    """The names along ``loc``, without list indices (``chambers.0.temperature`` walks the
    chamber table's ``temperature``)."""
    parts = loc.split(".") if isinstance(loc, str) else [str(p) for p in loc]
    return [p for p in parts if not p.isdigit()]


def owner_model(model: type[BaseModel], loc: str | Sequence) -> tuple[type[BaseModel], str] | None:
    """The (sub-)model class owning the field at ``loc`` ('stimulus.temperature' or a pydantic loc
    tuple) and that field's name; None where the path leaves the models."""
    parts = _parts(loc)
    if not parts:
        return None
    for name in parts[:-1]:
        info = model.model_fields.get(name)
        sub = _model_class(info.annotation) if info is not None else None
        if sub is None:
            return None
        model = sub
    return model, parts[-1]


def submodel(model: type[BaseModel], loc: str | Sequence) -> type[BaseModel] | None:
    """The model class reached by walking ``loc`` through nested model fields ('' = ``model``)."""
    for name in [p for p in _parts(loc) if p != ""]:
        info = model.model_fields.get(name)
        sub = _model_class(info.annotation) if info is not None else None
        if sub is None:
            return None
        model = sub
    return model


def field_range(model: type[BaseModel], name: str | Sequence) -> str | None:
    """The allowed interval of a numeric field, e.g. '(0, 1]', from its pydantic constraints.

    ``name`` is a field of ``model`` or a dotted path / loc tuple into nested models
    ('stimulus.temperature').
    """
    owner = owner_model(model, name)
    if owner is None:
        return None
    model, name = owner
    info = model.model_fields.get(name)
    if info is None:
        return None
    lo = hi = None
    lo_open = hi_open = False
    for m in info.metadata:
        if isinstance(m, at.Gt):
            lo, lo_open = m.gt, True
        elif isinstance(m, at.Ge):
            lo, lo_open = m.ge, False
        elif isinstance(m, at.Lt):
            hi, hi_open = m.lt, True
        elif isinstance(m, at.Le):
            hi, hi_open = m.le, False
    if lo is None and hi is None:
        return None
    left = "(" if lo is None or lo_open else "["
    right = ")" if hi is None or hi_open else "]"
    return f"{left}{'-inf' if lo is None else lo}, {'inf' if hi is None else hi}{right}"


def field_unit(model: type[BaseModel], name: str | Sequence) -> str:
    """The unit of a field, read from the '[unit]' that ends its description ('' if none or '-')."""
    owner = owner_model(model, name)
    info = owner[0].model_fields.get(owner[1]) if owner else None
    m = re.search(r"\[([^\]]+)\]\s*\.?\s*$", (info.description or "") if info else "")
    unit = m.group(1).strip() if m else ""
    return "" if unit == "-" else unit


def is_non_finite(value) -> bool:
    """True for a float that is nan or +-inf (the input every numeric field refuses alike)."""
    return isinstance(value, float) and not math.isfinite(value)


def non_finite_message(label: str, value, allowed: str | None = None, unit: str = "") -> str:
    """The one wording for a non-finite number, for design files and CLI options alike:
    '{label}: must be a finite number; allowed range {allowed} {unit} (got nan)'."""
    where = f"; allowed range {allowed}{' ' + unit if unit else ''}" if allowed else ""
    return f"{label}: must be a finite number{where} (got {short_repr(value)})"


# pydantic error kinds that judge a value's type or size: a non-finite input gets the finite wording
_NUMERIC_KINDS = frozenset({"finite_number", "greater_than", "greater_than_equal", "less_than", "less_than_equal",
                            "float_type", "float_parsing", "int_type", "int_parsing", "int_from_float",
                            "multiple_of"})


def describe_error(err: ValidationError, model: type[BaseModel], names: dict[str, str] | None = None) -> str:
    """The first problem of a pydantic ValidationError as one line naming the field (or its alias
    in ``names``, e.g. a CLI option) and its allowed range."""
    e = err.errors()[0]
    loc = ".".join(str(p) for p in e["loc"])
    field = e["loc"][0] if e["loc"] else ""
    label = (names or {}).get(str(field), loc)
    if e["type"] == "extra_forbidden":
        owner = submodel(model, e["loc"][:-1]) or model
        allowed = ", ".join(owner.model_fields)
        return f"{label}: unknown key (allowed: {allowed})"
    rng = field_range(model, e["loc"]) if e["loc"] else None
    got = e.get("input")
    if e["type"] in _NUMERIC_KINDS and is_non_finite(got):
        return non_finite_message(label, got, rng, field_unit(model, e["loc"]))
    msg = f"{label}: {e['msg'].lower()}"
    if rng:
        msg += f"; allowed range {rng}"
    return msg + f" (got {got!r})"


_EXPECTED = {
    "float_type": "a number",
    "float_parsing": "a number",
    "int_type": "an integer",
    "int_parsing": "an integer",
    "int_from_float": "an integer",
    "bool_type": "true or false",
    "bool_parsing": "true or false",
    "string_type": "a string",
    "tuple_type": "a list",
    "list_type": "a list",
    "model_type": "a table of keys",
    "model_attributes_type": "a table of keys",
    "dict_type": "a table of keys",
}
_BOUND = {"greater_than": ">", "greater_than_equal": ">=", "less_than": "<", "less_than_equal": "<="}


def short_repr(value, limit: int = 60) -> str:
    """``repr(value)``, cut to ``limit`` characters with "..." (for one-line messages)."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def explain_error(err: ValidationError, model: type[BaseModel], names: dict[str, str] | None = None) -> str:
    """The first problem of a ValidationError of (nested) ``model`` as one line: the dotted field
    path, what is wrong, the allowed range and unit of a numeric field, and the value given.

    Model validators are expected to raise ``ValueError("field: problem")``; the message is
    prefixed with the path of the model that raised it. A field validator's message follows the
    field's path and a colon. ``names`` maps a top-level field to the name the user gave it (a
    CLI option, e.g. ``{"max_force": "--max-force"}``), which then replaces the path.
    """
    e = err.errors()[0]
    parts = [str(p) for p in e["loc"]]
    path = ".".join(parts)
    if names and parts and parts[0] in names:
        path = ".".join([names[parts[0]], *parts[1:]])
    kind = e["type"]
    got = e.get("input")
    if kind == "extra_forbidden":
        owner = submodel(model, parts[:-1]) or model
        msg = f"{path}: unknown key (allowed: {', '.join(owner.model_fields)})"
    elif kind in ("value_error", "assertion_error"):
        text = re.sub(r"^(Value|Assertion) error, ", "", e["msg"])
        if not path:
            msg = text
        elif submodel(model, parts) is None:  # a field validator: the message is about the field itself
            msg = f"{path}: {text}"
        else:
            msg = f"{path}.{text}"
    else:
        rng = field_range(model, parts) if parts else None
        unit = field_unit(model, parts) if parts else ""
        where = f"; allowed range {rng}{' ' + unit if unit else ''}" if rng else ""
        if kind in _NUMERIC_KINDS and is_non_finite(got):
            msg = non_finite_message(path, got, rng, unit)
        elif kind in _BOUND:
            bound = next(iter((e.get("ctx") or {}).values()), "?")
            bound = f"{bound:g}" if isinstance(bound, float) else bound
            msg = f"{path}: must be {_BOUND[kind]} {bound}{where} (got {short_repr(got)})"
        elif kind in _EXPECTED:
            msg = f"{path}: expected {_EXPECTED[kind]}, got {short_repr(got)} ({type(got).__name__}){where}"
        elif kind == "literal_error":
            msg = f"{path}: expected {e['ctx']['expected']}, got {short_repr(got)}"
        elif kind == "finite_number":
            msg = non_finite_message(path, got, rng, unit)
        elif kind == "missing":
            msg = f"{path}: required key missing"
        else:
            msg = f"{path}: {e['msg'][:1].lower()}{e['msg'][1:]}{where} (got {short_repr(got)})"
    return " ".join(msg.split("\n"))
