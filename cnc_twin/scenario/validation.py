"""Validating a parsed scenario against its schema: the first problem as one
:class:`~cnc_twin.core.errors.ScenarioError` naming the file and the key path."""

from __future__ import annotations

import reprlib
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from cnc_twin.core.errors import ScenarioError, format_key_path
from cnc_twin.scenario.faults import FAULT_TAGS
from cnc_twin.scenario.schema_base import KeyedValueError

UNION_TAGS = FAULT_TAGS | {"point_to_point", "nurbs_curve", "surface_polish", "contour", "motion_chip"}
"""union tags pydantic puts in an error's location; a key path leaves them out"""


_SHORT = reprlib.Repr()
"""the input a message quotes, cut short (a value may be a large or deep structure)"""
_SHORT.maxlevel, _SHORT.maxstring, _SHORT.maxother, _SHORT.maxlist, _SHORT.maxdict = 2, 60, 60, 4, 4


def validate(model_cls: type[BaseModel], data: Any, label: Path, prefix: tuple = ()) -> Any:
    try:
        return model_cls.model_validate(data)
    except ValidationError as exc:
        raise first_error(exc, label, prefix) from None


def first_error(exc: ValidationError, label: Path, prefix: tuple) -> ScenarioError:
    errors = exc.errors(include_url=False)
    err = errors[0]
    loc = prefix + tuple(part for part in err["loc"] if part not in UNION_TAGS)
    cause = err.get("ctx", {}).get("error")
    if isinstance(cause, KeyedValueError):
        loc = loc + cause.loc
        message = str(cause)
    elif err["type"] == "extra_forbidden":
        message = "unknown key"
    elif err["type"] == "missing":
        message = "required key is missing"
    else:
        text = str(cause) if err["type"] == "value_error" and cause is not None else err["msg"]
        message = f"{text[0].lower()}{text[1:]}, got {_SHORT.repr(err['input'])}"
    more = len(errors) - 1
    if more:
        message += f" (and {more} more problem{'s' if more > 1 else ''})"
    return ScenarioError(label, format_key_path(loc), message)
