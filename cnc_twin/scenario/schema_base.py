"""Pieces shared by the scenario schema's modules: the strict base model, keyed validator errors,
and the path limits every tool-path program takes."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, model_validator


LARGEST_VALUE = 1e9
"""magnitude no scenario number may exceed (in the file's own units: mm, ms, deg, V...): beyond
every quantity the machine or the card represents, and far inside what a period count, a 32-bit
record field or a float's precision can hold after conversion. Fields with a tighter range of
their own say so."""


DAY = 86400.0
"""[s] the longest time a scenario may name (a dwell, a settle, a fault's moment, a run's cap)"""
FEED_MIN = 1e-3
"""[mm/min] the slowest feed a scenario may program, 1 um/min: a positive feed below it (say
5e-324) would vanish in the conversion to m/s and reach the planner as zero"""


class Strict(BaseModel):
    """A scenario section: unknown keys refused, no type coercion, no inf or nan, and every
    number within +-:data:`LARGEST_VALUE` (a huge finite number would overflow a period count or
    a record field later, in the middle of a run)."""

    model_config = ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False)

    @model_validator(mode="after")
    def _numbers_in_range(self):
        for name, value in self:
            for index, number in _numbers(value):
                if abs(number) > LARGEST_VALUE:
                    raise KeyedValueError((name, *index), f"{number:g} is beyond +-{LARGEST_VALUE:g}, "
                                                           "larger than any quantity the machine or the card represents")
        return self


def _numbers(value, index: tuple = ()):
    """``(index, float)`` of every float in ``value``, a field's value: a number, or lists of
    them (the nested models check their own fields)."""
    if isinstance(value, float):
        yield index, value
    elif isinstance(value, (list, tuple)):
        for i, item in enumerate(value):
            yield from _numbers(item, index + (i,))


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
