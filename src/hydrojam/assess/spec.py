"""The loads of an assessment (``hydrojam assess --loads LOADS.toml``): validated before any work,
one line naming the field and its allowed range (docs/assess.md). Units: forces N/mm (2D, per
unit depth) or N (3D, the whole actuator), kPa, K, deg."""

from __future__ import annotations

import os

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from hydrojam._io import read_toml
from hydrojam._validation import explain_error
from hydrojam.actuator.design import WATER_RANGE_K, DesignError, ElastomerSpec

#: a vacuum cannot pull harder than the atmosphere it works against [kPa]
ATMOSPHERE_KPA = 101.325
#: largest tip force [N/mm per unit depth in 2D, N in 3D]: 10 is over 1000x the bending
#: stiffness of an Ecoflex actuator times its length; anything larger is a unit mistake
MAX_TIP_FORCE = 10.0
#: largest inner pressure of the pneumatic baseline [kPa]: 1 MPa is 40x the shear modulus of
#: Ecoflex 00-30, far past any soft pneumatic actuator's working range
MAX_PNEUMATIC_KPA = 1000.0


class AssessError(DesignError):
    """Invalid assessment loads: one line naming the field and its allowed range."""


class Loads(BaseModel):
    """What an assessment applies to the design (docs/assess.md).

    Parameters
    ----------
    max_force : float, optional
        Largest tip force of the load-deflection curves, in +x and -x [N/mm per mm of depth in
        2D, N of the whole actuator in 3D]; omitted: the force that deflects the unactuated
        actuator by 5% of its length at its tangent stiffness.
    temperatures : tuple of float, optional
        Temperatures of the blocked force [K], in liquid water's range.
    vacuum_pressure : float, optional
        Pressure difference of the vacuum-jamming baseline on the chamber's outer surface, at most
        one atmosphere [kPa].
    baseline_particles : ElastomerSpec, optional
        Particles of the vacuum baseline; omitted: the gel as prepared (mu0, T0).
    blocking : bool, optional
        Compute the blocked force at each temperature.
    vacuum : bool, optional
        Compute the vacuum-jamming baseline.
    pneumatic : bool, optional
        Compute the pneumatic baseline.
    pneumatic_max_pressure : float, optional
        Largest inner pressure of the pneumatic baseline's ramp [kPa].
    pneumatic_angle : float, optional
        Bending angle the pneumatic chamber is pressurised to [deg]; omitted: the actuator's own.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    max_force: float | None = Field(
        None, gt=0, le=MAX_TIP_FORCE,
        description="largest tip force of the load-deflection curves, in +x and -x; omitted: the force "
        "that deflects the unactuated actuator by 5% of its length at its tangent stiffness [N/mm per mm of depth in 2D; N in 3D]",
    )
    temperatures: tuple[float, ...] = Field(
        (275.0, 285.0, 295.0), min_length=1, max_length=20,
        description="temperatures of the blocked force [K]",
    )
    vacuum_pressure: float = Field(
        80.0, gt=0, le=ATMOSPHERE_KPA,
        description="pressure difference of the vacuum-jamming baseline on the chamber's outer surface, "
        "at most one atmosphere [kPa]",
    )
    baseline_particles: ElastomerSpec | None = Field(
        None, description="particles of the vacuum baseline; omitted: the gel as prepared (mu0, T0)",
    )
    blocking: bool = Field(True, description="compute the blocked force at each temperature [-]")
    vacuum: bool = Field(True, description="compute the vacuum-jamming baseline [-]")
    pneumatic: bool = Field(True, description="compute the pneumatic baseline [-]")
    pneumatic_max_pressure: float = Field(
        100.0, gt=0, le=MAX_PNEUMATIC_KPA,
        description="largest inner pressure of the pneumatic baseline's ramp [kPa]",
    )
    pneumatic_angle: float | None = Field(
        None, gt=0, le=360,
        description="bending angle the pneumatic chamber is pressurised to; omitted: the actuator's own [deg]",
    )

    @field_validator("temperatures", mode="before")
    @classmethod
    def _as_tuple(cls, value):
        # a TOML array arrives as a list; strict validation takes a tuple only
        return tuple(value) if isinstance(value, list) else value

    @field_validator("temperatures")
    @classmethod
    def _in_water(cls, value):
        lo, hi = WATER_RANGE_K
        for T in value:
            if not lo <= T <= hi:
                raise ValueError(f"each temperature must be in liquid water's range [{lo}, {hi}] K (got {T:g} K)")
        return value


def loads_from_dict(data: dict, names: dict[str, str] | None = None) -> Loads:
    """Validated :class:`Loads` from plain data.

    As strict as a design file (:func:`hydrojam.actuator.design.design_from_dict`): TOML values
    are typed, so a string or a boolean where a number is meant, a number where a boolean is
    meant, and unknown keys are refused; an integer is accepted for a number.

    Parameters
    ----------
    data : dict
        The loads' keys, e.g. a parsed TOML file.
    names : dict of str to str, optional
        Field -> the name to report it by in errors (e.g. a CLI option).

    Returns
    -------
    Loads

    Raises
    ------
    AssessError
        One line naming the field (or its alias in ``names``).
    """
    if not isinstance(data, dict):
        raise AssessError(f"loads: expected a table of keys, got {type(data).__name__}")
    lo, hi = WATER_RANGE_K
    temps = data.get("temperatures")
    if isinstance(temps, (list, tuple)):
        for T in temps:
            if isinstance(T, (int, float)) and not isinstance(T, bool) and not lo <= T <= hi:
                label = (names or {}).get("temperatures", "temperatures")
                raise AssessError(f"{label}: each temperature must be in liquid water's range [{lo}, {hi}] K (got {T:g} K)")
    try:
        return Loads.model_validate(data, strict=True)
    except ValidationError as err:
        raise AssessError(explain_error(err, Loads, names)) from None


def load_loads(path: str | os.PathLike) -> Loads:
    """Read a loads TOML file.

    Parameters
    ----------
    path : str or os.PathLike
        The file.

    Returns
    -------
    Loads

    Raises
    ------
    AssessError
        Naming the file, for a missing or invalid one.
    """
    data = read_toml(path, "loads", AssessError)
    try:
        return loads_from_dict(data)
    except AssessError as err:
        raise AssessError(f"{path}: {err}") from None
