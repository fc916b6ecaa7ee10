"""hydrojam._validation on its own, on a small nested model: every refusal is one line naming the
field's path (or the user's name for it), what is wrong, the allowed range with its unit, and
the value given."""

from typing import Literal

import pytest
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from hydrojam import _validation as v


class Inner(BaseModel):
    model_config = ConfigDict(extra="forbid")
    temperature: float = Field(300.0, gt=273.15, le=373.15, description="water temperature [K]")
    ratio: float = Field(0.5, ge=0, lt=1, description="a share [-]")


class Outer(BaseModel):
    model_config = ConfigDict(extra="forbid")
    size: float = Field(2.0, gt=0, description="mesh size [mm]")
    count: int = Field(1, ge=1, le=10, description="how many")
    kind: Literal["a", "b"] = "a"
    inner: Inner = Inner()
    maybe: Inner | None = None

    @model_validator(mode="after")
    def _check(self):
        if self.size > 100:
            raise ValueError("size: must be at most 100 here")
        return self


def _explain(**data) -> str:
    with pytest.raises(ValidationError) as info:
        Outer(**data)
    return v.explain_error(info.value, Outer)


def test_ranges_units_and_owners_are_read_from_the_constraints():
    assert v.field_range(Outer, "size") == "(0, inf)"
    assert v.field_range(Outer, "count") == "[1, 10]"
    assert v.field_range(Outer, "inner.temperature") == "(273.15, 373.15]"
    assert v.field_range(Outer, ("maybe", "ratio")) == "[0, 1)"
    assert v.field_range(Outer, "kind") is None and v.field_range(Outer, "nowhere.x") is None
    assert v.field_unit(Outer, "size") == "mm" and v.field_unit(Outer, "inner.ratio") == ""
    assert v.field_unit(Outer, "count") == ""
    assert v.owner_model(Outer, "maybe.temperature") == (Inner, "temperature")
    assert v.submodel(Outer, "inner") is Inner and v.submodel(Outer, "") is Outer


@pytest.mark.parametrize("data, line", [
    ({"size": -1.0}, "size: must be > 0; allowed range (0, inf) mm (got -1.0)"),
    ({"inner": {"temperature": 400.0}},
     "inner.temperature: must be <= 373.15; allowed range (273.15, 373.15] K (got 400.0)"),
    ({"size": float("nan")}, "size: must be a finite number; allowed range (0, inf) mm (got nan)"),
    ({"count": "many"}, "count: expected an integer, got 'many' (str); allowed range [1, 10]"),
    ({"kind": "c"}, "kind: expected 'a' or 'b', got 'c'"),
    ({"inner": {"colour": 1}}, "inner.colour: unknown key (allowed: temperature, ratio)"),
    ({"size": 200.0}, "size: must be at most 100 here"),
])
def test_every_refusal_is_one_line_naming_the_field_its_range_and_the_value(data, line):
    msg = _explain(**data)
    assert msg == line
    assert "\n" not in msg


def test_a_users_name_for_a_field_replaces_its_path():
    with pytest.raises(ValidationError) as info:
        Outer(count=0)
    assert v.explain_error(info.value, Outer, {"count": "--count"}).startswith("--count: must be >= 1")
    assert v.describe_error(info.value, Outer, {"count": "--count"}).startswith("--count: ")


def test_non_finite_values_get_one_wording():
    assert v.is_non_finite(float("inf")) and not v.is_non_finite(1.0) and not v.is_non_finite("nan")
    assert v.non_finite_message("x", float("inf"), "(0, 1]", "mm") == \
        "x: must be a finite number; allowed range (0, 1] mm (got inf)"
    assert v.non_finite_message("x", float("nan")) == "x: must be a finite number (got nan)"
