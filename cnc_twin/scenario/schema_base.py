"""Pieces shared by the scenario schema's modules: the strict base model, keyed validator errors,
and the path limits every tool-path program takes."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False)


class KeyedValueError(ValueError):
    """Raised inside validators to report a key path below the validated model."""

    def __init__(self, loc: tuple, message: str):
        self.loc = loc
        super().__init__(message)


class PathLimitsSpec(Strict):
    """Path limits of a curve program (axis limits come from the machine parameters)."""

    path_acceleration: float = Field(2000.0, gt=0, description="tangential acceleration [mm/s^2]")
    path_jerk: float = Field(50000.0, gt=0, description="tangential jerk [mm/s^3]")
    normal_acceleration: float = Field(2000.0, gt=0, description="centripetal acceleration [mm/s^2]")
    normal_jerk: float = Field(50000.0, gt=0, description="normal jerk [mm/s^3]")
