"""One-line messages for invalid input: the field, the allowed range, the value given."""

from __future__ import annotations

import annotated_types as at
from pydantic import BaseModel, ValidationError


def field_range(model: type[BaseModel], name: str) -> str | None:
    """The allowed interval of a numeric field, e.g. '(0, 1]', from its pydantic constraints."""
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


def describe_error(err: ValidationError, model: type[BaseModel], names: dict[str, str] | None = None) -> str:
    """The first problem of a pydantic ValidationError as one line naming the field (or its alias
    in ``names``, e.g. a CLI option) and its allowed range."""
    e = err.errors()[0]
    loc = ".".join(str(p) for p in e["loc"])
    field = e["loc"][0] if e["loc"] else ""
    label = (names or {}).get(str(field), loc)
    if e["type"] == "extra_forbidden":
        allowed = ", ".join(model.model_fields)
        return f"{label}: unknown key (allowed: {allowed})"
    rng = field_range(model, str(field)) if len(e["loc"]) == 1 else None
    got = e.get("input")
    msg = f"{label}: {e['msg'].lower()}"
    if rng:
        msg += f"; allowed range {rng}"
    return msg + f" (got {got!r})"
