"""A table of a pydantic model's fields under its class docstring in the API reference: each
field's name, default, allowed range and meaning with its unit, read from the model itself (its
``Field`` descriptions and constraints), so the reference cannot drift from what a design file
accepts. Runs after numpydoc (priority 600), which leaves the appended reST table as it is."""

from __future__ import annotations

import inspect
import typing
from typing import Literal


def _cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|").replace("*", "\\*")


def _allowed(model, path: str, info) -> str:
    """The allowed range of a numeric field, or the choices of a Literal one ('2 or 3')."""
    from hydrojam._validation import field_range

    choices = list(typing.get_args(info.annotation)) if typing.get_origin(info.annotation) is Literal else []
    if choices:
        return " or ".join(repr(c) for c in choices)
    return field_range(model, path) or ""


def _rows(model, root, prefix: str = "") -> list[tuple[str, str, str, str]]:
    """(key, default, allowed, meaning) of every field, a nested model's fields under its dotted
    key (``mesh.size``: the keys of a design file's tables)."""
    from hydrojam._validation import _model_class

    rows = []
    for name, info in model.model_fields.items():
        key = f"{prefix}{name}"
        sub = _model_class(info.annotation)
        if sub is not None:
            rows.append((f"``{key}``", "a table", "", _cell(info.description or "")))
            rows.extend(_rows(sub, root, f"{key}."))
            continue
        default = "required" if info.is_required() else repr(info.get_default(call_default_factory=True))
        rows.append((f"``{key}``", _cell(default), _cell(_allowed(root, key, info)), _cell(info.description or "")))
    return rows


def _fields_table(model) -> list[str]:
    rows = _rows(model, model)
    if not rows:
        return []
    out = ["", ".. list-table:: Fields (the keys of a file of this kind; a table's keys under its name)",
           "   :header-rows: 1", "   :widths: 28 12 16 44", "",
           "   * - field", "     - default", "     - allowed", "     - meaning [unit]"]
    for row in rows:
        out.append(f"   * - {row[0]}")
        out.extend(f"     - {cell}" if cell else "     -" for cell in row[1:])
    return out + [""]


def _append_fields(app, what, name, obj, options, lines):
    from pydantic import BaseModel

    if what == "class" and inspect.isclass(obj) and issubclass(obj, BaseModel) and obj is not BaseModel:
        lines.extend(_fields_table(obj))


def setup(app):
    app.connect("autodoc-process-docstring", _append_fields, priority=600)
    return {"parallel_read_safe": True}
