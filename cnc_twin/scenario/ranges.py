"""The range a scenario field accepts, stated from the schema itself (README's tables quote it,
and a test holds them to it, so the documented range cannot drift from the enforced one)."""

from __future__ import annotations

import typing

import annotated_types
from pydantic import BaseModel

from cnc_twin.scenario.schema_base import LARGEST_VALUE

EXTRA_CHECKS = {
    "encoder.lines_per_rev": "; the 32-bit QEP counter must span the travel",
    "servo.output_limit": " (the DAC's +-10 V)",
    "servo.deflection": " each, keyed by axis (X .. C)",
    "servo.coupling": " each, keyed by axis (X .. C)",
}
"""range words of fields with a check beyond their own bounds (a validator elsewhere)"""


def _number(value: float) -> str:
    if value == 2**24:
        return "2^24"
    if float(value).is_integer() and abs(value) <= 10000:
        return str(int(value))
    mantissa, exponent = f"{value:e}".split("e")
    return f"{mantissa.rstrip('0').rstrip('.')}e{int(exponent)}"


def accepted_range(model: type[BaseModel], dotted_key: str) -> str:
    """The range of ``dotted_key`` (e.g. ``"servo.kp"``) below ``model`` in words: lower bound
    (``>`` when exclusive), upper bound, the schema-wide
    +-:data:`~cnc_twin.scenario.schema_base.LARGEST_VALUE` where the field names none. For example
    ``"0 .. 1e5"``, ``"> 0 .. 1e9"``."""
    *path, name = dotted_key.split(".")
    for part in path:
        model = model.model_fields[part].annotation
        # an optional section (``CompensationSpec | None``): the model in it
        model = next((arg for arg in typing.get_args(model) if hasattr(arg, "model_fields")), model)
    field = model.model_fields[name]
    low, high = f"-{_number(LARGEST_VALUE)}", _number(LARGEST_VALUE)
    for bound in field.metadata:
        if isinstance(bound, annotated_types.Ge):
            low = _number(bound.ge)
        elif isinstance(bound, annotated_types.Gt):
            low = f"> {_number(bound.gt)}"
        elif isinstance(bound, annotated_types.Le):
            high = _number(bound.le)
        elif isinstance(bound, annotated_types.Lt):
            high = f"< {_number(bound.lt)}"
    return f"{low} .. {high}{EXTRA_CHECKS.get(dotted_key, '')}"
