"""The design refusal check shared by the design tests: one line, raised before any work."""

import pytest

from hydrojam.actuator.design import DesignError, design_from_dict


def refusal(data: dict) -> str:
    """The DesignError message of the design ``data``; asserts it is one line."""
    with pytest.raises(DesignError) as exc:
        design_from_dict(data)
    msg = str(exc.value)
    assert "\n" not in msg, msg
    return msg
