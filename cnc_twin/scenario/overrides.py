"""Scenario overrides by dotted path, for scripts and sweeps.

    load_scenario("scenarios/jog_axes.yaml", overrides={"servo.X.kp": 60, "program.moves[0].feed": 3000})

A path addresses the scenario as written (the YAML keys), with list items as ``[i]`` or ``.i``.
Shorthands, expanded first:

==========================  ====================================================
shorthand                   means
==========================  ====================================================
``servo.<axis>.<gain>``     ``axes.<axis>.servo.<gain>`` (kp, ki, kd, kvff, kaff, ...)
``encoder.<axis>.<key>``    ``axes.<axis>.encoder.<key>``
``planner.feed``            ``program.feed`` for curves; every move's ``feed`` for moves
``force.<key>``             ``program.force.<key>``: the grinding-force loop of a surface
                            polishing program (kp, ki, setpoint, ramp_time, ...)
``timing.<key>``, ...       unchanged (any other path is taken as written)
==========================  ====================================================

Values are validated by the scenario schema after they are applied, so an unknown key or a
wrong type fails exactly as in a file, and the message names the override.
"""

from __future__ import annotations

import copy
import re
from collections.abc import Mapping
from typing import Any

from cnc_twin.core.axes import AXES
from cnc_twin.core.errors import ScenarioError, format_key_path

_PART = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def parse_path(path: str) -> list[str | int]:
    """``"program.moves[2].X"`` -> ``["program", "moves", 2, "X"]``; ``.2`` works like ``[2]``."""
    parts: list[str | int] = []
    for name, index in _PART.findall(path):
        if index:
            parts.append(int(index))
        elif name.isdigit():
            parts.append(int(name))
        else:
            parts.append(name)
    if not parts or "".join(str(p) for p in parts).replace(".", "") == "":
        raise ValueError(f"empty override path {path!r}")
    return parts


def expand(path: str, raw: Mapping[str, Any]) -> list[list[str | int]]:
    """The concrete key paths a (possibly shorthand) override path stands for."""
    parts = parse_path(path)
    head = parts[0]
    if head in ("servo", "encoder") and len(parts) >= 3 and parts[1] in AXES:
        return [["axes", parts[1], head, *parts[2:]]]
    if head == "force" and len(parts) >= 2:
        return [["program", "force", *parts[1:]]]
    if parts == ["planner", "feed"]:
        program = raw.get("program", {})
        if isinstance(program, Mapping) and "moves" in program and isinstance(program["moves"], list):
            return [["program", "moves", i, "feed"] for i in range(len(program["moves"]))]
        return [["program", "feed"]]
    return [parts]


def apply_overrides(raw: Mapping[str, Any], overrides: Mapping[str, Any], *, label: str = "<overrides>") -> dict:
    """A copy of the scenario mapping ``raw`` with every override set (not yet validated).

    Raises
    ------
    ScenarioError
        If a path runs through something that is not a mapping or list, or past a list's end.
    """
    out = copy.deepcopy(dict(raw))
    for path, value in overrides.items():
        try:
            targets = expand(path, out)
        except ValueError as exc:
            raise ScenarioError(label, path, str(exc)) from None
        for target in targets:
            node: Any = out
            for i, key in enumerate(target[:-1]):
                nxt = target[i + 1]
                if isinstance(node, list):
                    if not isinstance(key, int) or not 0 <= key < len(node):
                        raise ScenarioError(label, path, f"no item {key} in the list at {_show(target[:i])}")
                    node = node[key]
                    continue
                if not isinstance(node, dict):
                    raise ScenarioError(label, path, f"{_show(target[:i])} is not a mapping")
                if key not in node:
                    node[key] = [] if isinstance(nxt, int) else {}
                node = node[key]
            last = target[-1]
            if isinstance(node, list):
                if not isinstance(last, int) or not 0 <= last < len(node):
                    raise ScenarioError(label, path, f"no item {last} in the list at {_show(target[:-1])}")
            elif not isinstance(node, dict):
                raise ScenarioError(label, path, f"{_show(target[:-1])} is not a mapping")
            node[last] = copy.deepcopy(value)
    return out


def _show(parts: list[str | int]) -> str:
    return format_key_path(tuple(parts)) or "the top level"
