"""Validating a parsed scenario against its schema: the first problem as one
:class:`~cnc_twin.core.errors.ScenarioError` naming the file and the key path."""

from __future__ import annotations

import reprlib
import types
import typing
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


_WORDING = (("Input should be less than or equal to", "expected at most"),
            ("Input should be greater than or equal to", "expected at least"),
            ("Input should be greater than", "expected more than"),
            ("Input should be less than", "expected less than"),
            ("Input should be", "expected"))
"""pydantic's words for a bad value, and the plainer ones a message uses"""


def validate(model_cls: type[BaseModel], data: Any, label: Path, prefix: tuple = ()) -> Any:
    """``data`` validated as ``model_cls``; its first problem raised as one ScenarioError
    (:func:`first_error`, key paths below ``prefix``)."""
    try:
        return model_cls.model_validate(data)
    except ValidationError as exc:
        raise first_error(exc, label, prefix, model_cls) from None


MORE_NAMED = 3
"""the further problems of one scenario whose places the error line names"""


def first_error(exc: ValidationError, label: Path, prefix: tuple, model_cls: type[BaseModel] | None = None
                ) -> ScenarioError:
    """The ScenarioError of pydantic's ``exc``: its first problem's key path (below ``prefix``) and
    message in the twin's words, and where the next few others are."""
    errors = exc.errors(include_url=False)
    err = errors[0]
    loc = prefix + tuple(part for part in err["loc"] if part not in UNION_TAGS)
    cause = err.get("ctx", {}).get("error")
    kind = err["type"]
    if isinstance(cause, KeyedValueError):
        loc = loc + cause.loc
        message = str(cause)
    elif kind == "extra_forbidden":
        known = known_keys(model_cls, err["loc"][:-1]) if model_cls is not None else None
        message = "unknown key" + (f" (expected one of: {', '.join(known)})" if known else "")
    elif kind == "missing":
        message = "required key is missing"
    elif kind in ("union_tag_invalid", "union_tag_not_found"):  # the program's or a fault's `type`
        loc = loc + (err["ctx"]["discriminator"].strip("'"),)
        tags = err["ctx"].get("expected_tags") or (union_tags(model_cls, err["loc"]) if model_cls else "")
        message = (f"expected one of {tags}, got {_SHORT.repr(err['ctx']['tag'])}" if kind == "union_tag_invalid"
                   else f"required key is missing (one of {tags})" if tags else "required key is missing")
    elif kind in ("model_type", "model_attributes_type", "dict_type"):
        message = f"expected a mapping of keys, got {_SHORT.repr(err['input'])}"
    else:
        text = str(cause) if kind == "value_error" and cause is not None else err["msg"]
        for pydantic_words, ours in _WORDING:
            text = text.replace(pydantic_words, ours, 1)
        message = f"{text[0].lower()}{text[1:]}, got {_SHORT.repr(err['input'])}"
    more = len(errors) - 1
    if more:
        # where the others are, so one fix-and-retry finds them all (the first is said in full)
        places = [format_key_path(prefix + tuple(part for part in e["loc"] if part not in UNION_TAGS))
                  for e in errors[1:]]
        named = ", ".join(places[:MORE_NAMED]) + (", ..." if more > MORE_NAMED else "")
        message += f" (and {more} more problem{'s' if more > 1 else ''}, at {named})"
    return ScenarioError(label, format_key_path(loc), message)


def known_keys(model_cls: type[BaseModel], loc: tuple) -> list[str] | None:
    """The keys the mapping at ``loc`` (pydantic's error location, union tags included) accepts,
    or None where the schema there is not one model."""
    node = _model_of(_annotation_at(model_cls, loc))
    return list(node.model_fields) if isinstance(node, type) and issubclass(node, BaseModel) else None


def union_tags(model_cls: type[BaseModel], loc: tuple) -> str:
    """The ``type`` values the tagged union at ``loc`` accepts, quoted, comma separated."""
    return ", ".join(repr(_tag_of(m)) for m in _members(_annotation_at(model_cls, loc)) if _tag_of(m) is not None)


def _annotation_at(model_cls: type[BaseModel], loc: tuple) -> Any:
    """The schema's annotation at ``loc`` (None where it cannot be followed)."""
    node: Any = model_cls
    for part in loc:
        node = _model_of(node)
        if node is None or isinstance(part, int):
            continue  # a list item: the list's element, found by _model_of
        if part in UNION_TAGS:  # pydantic names the union member it tried
            members = [m for m in _members(node) if _tag_of(m) == part]
            node = members[0] if members else None
            continue
        field = node.model_fields.get(part) if isinstance(node, type) and issubclass(node, BaseModel) else None
        if field is None:
            return None
        node = field.annotation
    return node


def _members(annotation: Any) -> list:
    """The alternatives of a union annotation (the annotation alone otherwise)."""
    if typing.get_origin(annotation) is typing.Annotated:
        annotation = typing.get_args(annotation)[0]
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        return [m for arg in typing.get_args(annotation) for m in _members(arg)]
    return [annotation]


def _model_of(annotation: Any) -> Any:
    """``annotation`` with Optional, Annotated and list[...] peeled off: a model, a union, or None."""
    members = [m for m in _members(annotation) if m is not type(None)]
    if len(members) != 1:
        return annotation  # a union of models, resolved by the tag that follows in the location
    member = members[0]
    if typing.get_origin(member) in (list, tuple):
        return _model_of(typing.get_args(member)[0])
    return member


def _tag_of(model: Any) -> Any:
    """A tagged union member's ``type`` literal."""
    field = getattr(model, "model_fields", {}).get("type")
    args = typing.get_args(field.annotation) if field is not None else ()
    return args[0] if args else None
