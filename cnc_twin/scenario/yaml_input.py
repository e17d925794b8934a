"""Reading scenario and parameter files within limits: size, nesting, alias expansion, duplicate keys.

A scenario is input from anyone; what is read from it stays bounded whatever it holds:

==========================  =========================================================
limit                       why
==========================  =========================================================
:data:`MAX_FILE_BYTES`      a file is read up to this many bytes, never whole first
                            (``/dev/zero`` or a 50 MB file is refused at once)
:data:`MAX_DEPTH`           mappings and lists nested deeper are refused (the deepest
                            scenario key, a surface's control net point, is 6 deep)
:data:`MAX_VALUES`          values after expanding YAML aliases (an alias "bomb" of
                            nested anchors is a few lines that expand to billions)
duplicate keys              an error naming the key and both lines (YAML would keep
                            the last one silently)
recursive aliases           refused (an anchor inside itself)
==========================  =========================================================

Every exceeded limit is a :class:`~cnc_twin.core.errors.ScenarioError` (one line, exit 2)
naming the file, where and the limit. The YAML is read with PyYAML's safe loader only.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from cnc_twin.core.errors import ScenarioError, format_key_path

MAX_FILE_BYTES = 16 * 1024 * 1024
"""[bytes] largest scenario or parameter file read"""
MAX_DEPTH = 32
"""deepest nesting of mappings and lists"""
MAX_VALUES = 2_000_000
"""most values (mappings, lists and scalars) a document may hold once its aliases are expanded"""

_SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
"""PyYAML's safe loader, in C when libyaml is there (7x faster; the same safe subset)"""


class _DuplicateKey(yaml.YAMLError):
    def __init__(self, key: str, first: int, again: int):
        super().__init__(f"duplicate key {key!r} on lines {first} and {again}")
        self.line = again


class _Loader(_SAFE_LOADER):  # type: ignore[misc, valid-type]
    """The safe loader, refusing a key given twice in one mapping (merge keys ``<<`` aside:
    keys written next to a merge override it, as YAML means)."""

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            seen: dict[tuple[str, str], int] = {}
            for key_node, _ in node.value:
                if not isinstance(key_node, yaml.ScalarNode) or key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = (key_node.tag, key_node.value)
                line = key_node.start_mark.line + 1
                if key in seen:
                    raise _DuplicateKey(key_node.value, seen[key], line)
                seen[key] = line
        return super().construct_mapping(node, deep=deep)


def read_text(path: Path) -> str:
    """The file's text (UTF-8), read up to :data:`MAX_FILE_BYTES`; a larger file is refused."""
    try:
        with open(path, "rb") as handle:
            data = handle.read(MAX_FILE_BYTES + 1)
    except FileNotFoundError:
        raise ScenarioError(path, "", "no such file") from None
    except OSError as exc:
        raise ScenarioError(path, "", f"cannot read: {exc.strerror or exc}") from None
    if len(data) > MAX_FILE_BYTES:
        raise too_large(path)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ScenarioError(path, "", f"not UTF-8 text (byte {exc.start})") from None


def too_large(path: Path) -> ScenarioError:
    """The error for a file beyond :data:`MAX_FILE_BYTES`."""
    return ScenarioError(path, "", f"larger than {MAX_FILE_BYTES // (1024 * 1024)} MiB, the limit for an input file")


def parse(text: str, label: Path) -> Any:
    """The YAML document in ``text``, checked by :func:`check_structure`."""
    try:
        doc = yaml.load(text, Loader=_Loader)  # noqa: S506 - a safe loader, never the full one
    except _DuplicateKey as exc:
        raise ScenarioError(label, f"line {exc.line}", str(exc)) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ScenarioError(label, where, f"not valid YAML: {problem}") from None
    except RecursionError:  # the parser's own recursion, on nesting far beyond MAX_DEPTH
        raise ScenarioError(label, "", f"nested more than {MAX_DEPTH} levels deep") from None
    check_structure(doc, label)
    return doc


def check_structure(doc: Any, label: Path) -> None:
    """Refuse a document nested deeper than :data:`MAX_DEPTH`, holding more than
    :data:`MAX_VALUES` values once shared parts (YAML aliases) are counted each time they are
    used, or holding itself. Iterative (no recursion) and linear in the distinct containers."""
    sizes: dict[int, int] = {}  # id of a finished container -> values in it, expanded
    path: list[Any] = []  # keys from the top to the container being walked
    on_path: set[int] = set()
    stack: list[tuple[Any, Any, bool]] = [(doc, None, False)]
    while stack:
        node, key, finished = stack.pop()
        if not isinstance(node, (dict, list)):
            continue
        ident = id(node)
        children = list(node.items()) if isinstance(node, dict) else list(enumerate(node))
        if finished:
            on_path.discard(ident)
            path.pop()
            total = 1 + sum(sizes.get(id(child), 1) for _, child in children)
            if total > MAX_VALUES:
                raise ScenarioError(label, format_key_path(tuple(path + [key])[1:]),
                                    f"expands to more than {MAX_VALUES} values (YAML aliases?), the limit")
            sizes[ident] = total
            continue
        if ident in sizes:
            continue
        if ident in on_path:
            raise ScenarioError(label, format_key_path(tuple(path + [key])[1:]), "an alias refers to itself")
        if len(path) >= MAX_DEPTH:
            raise ScenarioError(label, format_key_path(tuple(path[1:5])) + "...",
                                f"nested more than {MAX_DEPTH} levels deep")
        on_path.add(ident)
        path.append(key)
        stack.append((node, key, True))
        stack.extend((child, name, False) for name, child in children)
