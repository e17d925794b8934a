"""Sphinx extension: the ``scenario-reference`` directive, a reference of every key a scenario file
may hold, rendered from the scenario format's JSON Schema as ``cnc-twin schema`` writes it
(:func:`cnc_twin.scenario.json_schema.scenario_schema`, called at build time: the page shows the
models of the code it is built from, never a stale copy).

Written in a page (MyST)::

    ```{scenario-reference}
    ```

It takes no arguments and no content. It gives one section per part of the file (the top-level
keys, then each section such as ``timing`` or ``axes``, then ``faults`` and ``program``, one
subsection per fault or program ``type``), each a list of key paths as they are written in YAML
(``program.moves[].feed``: ``[]`` an item of a list; ``axes.{X,Y,Z,A,B,C}.servo.kp``: any one of
those keys, which share one schema) with the type, the default, the allowed values and the
description (units in brackets). The nodes are built directly, not parsed from markup, so a
description's characters never turn into markup, in a Markdown page or an rST one alike.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from docutils import nodes
from sphinx.application import Sphinx
from sphinx.util.docutils import SphinxDirective

BOUND_NOTE = ("Every number lies within ±{:g} (the loader refuses larger ones) unless a key says a tighter "
              "range; the bound is in the schema, left out below.")
"""said once at the top instead of at every number"""
LITERAL = re.compile(r"``?([^`]+)``?")
"""an inline literal as the models' words write a key, a value or a command (rST's double backticks,
Markdown's single ones)"""
MAX_DEPTH = 12
"""deepest key path followed (a schema that refers to itself would otherwise never end; the
scenario format's deepest path is 6 keys)"""


@dataclass(frozen=True)
class _Entry:
    """One key path: what the reference says about it."""

    path: str
    """as written in YAML: ``program.moves[].feed``"""
    node: dict[str, Any]
    """its schema"""
    required: bool


class ScenarioReference(SphinxDirective):
    """``scenario-reference``: every key of a scenario file, from its JSON Schema."""

    has_content = False
    required_arguments = 0
    optional_arguments = 0

    def run(self) -> list[nodes.Node]:
        from cnc_twin.scenario import json_schema
        from cnc_twin.scenario.schema_base import LARGEST_VALUE

        # the page is made from the models: a change to any of them rebuilds it
        for source in Path(json_schema.__file__).parent.glob("*.py"):
            self.env.note_dependency(str(source))
        schema = json_schema.scenario_schema()
        walker = _Walker(schema["$defs"], LARGEST_VALUE)
        top_level = []
        sections = []
        for key, prop in schema["properties"].items():
            required = key in schema.get("required", ())
            node = walker.resolve(prop)
            variants = walker.variants(node)
            items = walker.resolve(node.get("items", {})) if node.get("type") == "array" else None
            if variants:  # program: one subsection per type
                sections.append(self._variant_section(key, key, prop, variants, walker))
            elif items is not None and walker.variants(items):  # faults: a list of types
                sections.append(self._variant_section(key, f"{key}[]", prop, walker.variants(items), walker))
            elif walker.mapping(node) is not None:
                mapping = walker.mapping(node)
                entries = walker.entries(mapping, key)
                sections.append(self._section(key, [_description(prop, mapping)], entries, walker))
            else:
                top_level.append(_Entry(key, prop, required))
        intro = [schema.get("description", ""), BOUND_NOTE.format(LARGEST_VALUE)]
        made = [self._section("Top level", intro, top_level, walker), *sections]
        # every node where the directive stands: Sphinx's transforms (and its warnings) ask a node's line
        source, line = self.get_source_info()
        for section in made:
            for element in section.findall(nodes.Element):
                element.source, element.line = source, line
        return made

    def _variant_section(self, title: str, prefix: str, prop: dict, variants: list[tuple[str, dict]],
                         walker: "_Walker") -> nodes.section:
        """A section per union (``program``, ``faults``), a subsection per ``type``."""
        section = self._section(title, [_description(prop, {}), f"One of {len(variants)} kinds, chosen by its type key."],
                                [], walker)
        for tag, model in variants:
            entries = walker.entries(model, prefix)
            section += self._section(f"{title}: type {tag}", [model.get("description", "")], entries, walker)
        return section

    def _section(self, title: str, texts: list[str], entries: list[_Entry], walker: "_Walker") -> nodes.section:
        section = nodes.section()
        section["names"].append(nodes.fully_normalize_name(f"scenario keys {title}"))
        self.state.document.note_implicit_target(section, section)
        section += nodes.title(text=title)
        for text in texts:
            if text:
                section += _paragraph(text)
        if entries:
            listing = nodes.definition_list()
            for entry in entries:
                listing += _item(entry, walker)
            section += listing
        return section


class _Walker:
    """Follows the schema's references and turns its nodes into key paths and words."""

    def __init__(self, defs: dict[str, Any], largest: float):
        self.defs = defs
        self.largest = largest
        """the bound on every number (left out where a key gives no tighter one)"""

    def resolve(self, node: dict[str, Any]) -> dict[str, Any]:
        """``node`` with a ``$ref`` replaced by what it names (its own keys, e.g. a description, kept over it)."""
        seen = 0
        while "$ref" in node and seen < MAX_DEPTH:
            target = self.defs[node["$ref"].rsplit("/", 1)[1]]
            node = {**target, **{k: v for k, v in node.items() if k != "$ref"}}
            seen += 1
        return node

    def members(self, node: dict[str, Any]) -> list[dict[str, Any]]:
        """The alternatives of a union (``anyOf`` / ``oneOf``), ``null`` left out; ``[node]`` otherwise."""
        union = node.get("anyOf") or node.get("oneOf")
        if union is None:
            return [node]
        return [self.resolve(member) for member in union if member.get("type") != "null"]

    def mapping(self, node: dict[str, Any]) -> dict[str, Any] | None:
        """The model ``node`` holds (itself, or its one non-null alternative), or None."""
        members = self.members(self.resolve(node))
        if len(members) == 1 and "properties" in members[0]:
            return members[0]
        return None

    def variants(self, node: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
        """``(type tag, model)`` of a tagged union (``discriminator``), in the schema's order; [] otherwise."""
        tag = node.get("discriminator", {}).get("propertyName")
        if tag is None:
            return []
        models = [self.resolve(member) for member in node.get("oneOf", [])]
        return [(model["properties"][tag].get("const", "?"), model) for model in models]

    def entries(self, model: dict[str, Any], prefix: str, depth: int = 0) -> list[_Entry]:
        """Every key path below ``model`` (whose own path is ``prefix``), in the schema's order;
        neighbouring keys with one schema shown as one path (``{X,Y,Z}``)."""
        found: list[_Entry] = []
        if depth > MAX_DEPTH:
            return found
        required = set(model.get("required", ()))
        for names, prop in _grouped(model.get("properties", {}), required):
            key = names[0] if len(names) == 1 else "{" + ",".join(names) + "}"
            path = f"{prefix}.{key}"
            found.append(_Entry(path, prop, names[0] in required))
            found += self._below(prop, path, depth)
        return found

    def _below(self, prop: dict[str, Any], path: str, depth: int) -> list[_Entry]:
        """The key paths under one key: a mapping's keys, a list's items' keys, a dict's values' keys."""
        node = self.resolve(prop)
        mapping = self.mapping(node)
        if mapping is not None:
            return self.entries(mapping, path, depth + 1)
        for member in self.members(node):
            items = self.mapping(member.get("items", {})) if member.get("type") == "array" else None
            if items is not None:
                return self.entries(items, f"{path}[]", depth + 1)
            values = member.get("additionalProperties")
            if isinstance(values, dict) and self.mapping(values) is not None:
                names = member.get("propertyNames", {}).get("enum")
                key = "{" + ",".join(names) + "}" if names else "<name>"
                return self.entries(self.mapping(values), f"{path}.{key}", depth + 1)
        return []

    def type_name(self, node: dict[str, Any]) -> str:
        """What a key holds, in words: ``number``, ``list of number``, ``mapping``, ``integer or null``."""
        node = self.resolve(node)
        union = node.get("anyOf") or node.get("oneOf")
        if union is not None:
            names = [self.type_name(member) for member in union]
            return " or ".join(dict.fromkeys(names))  # each once, in order
        kind = node.get("type")
        if kind == "array":
            return "list of " + self.type_name(node.get("items", {})) if node.get("items") else "list"
        if kind == "object" or "properties" in node:
            return "mapping"
        return kind or "any"

    def allowed(self, node: dict[str, Any]) -> str:
        """The values a key takes beyond its type: a range, choices, lengths, a pattern."""
        node = self.resolve(node)
        said: list[str] = []
        for member in self.members(node) if ("anyOf" in node or "oneOf" in node) else [node]:
            said += _limits(member, self.largest)
            if member.get("type") == "array" and member.get("items"):
                inner = self.allowed(member["items"])
                if inner:
                    said.append(f"each item {inner}")
        return "; ".join(dict.fromkeys(said))


def _limits(node: dict[str, Any], largest: float) -> list[str]:
    """One schema node's own constraints, in words (the bound ``largest`` on every number left out)."""
    said = []
    if "const" in node:
        said.append(f"exactly {_value(node['const'])}")
    if "enum" in node:
        said.append("one of " + ", ".join(_value(choice) for choice in node["enum"]))
    bounds = [(key, sign) for key, sign in (("minimum", "≥"), ("exclusiveMinimum", ">"), ("maximum", "≤"),
                                            ("exclusiveMaximum", "<")) if key in node and abs(node[key]) != largest]
    if bounds:
        said.append(", ".join(f"{sign} {_value(node[key])}" for key, sign in bounds))
    for low, high, unit in (("minLength", "maxLength", "characters"), ("minItems", "maxItems", "items")):
        if low in node or high in node:
            said.append(_count(node.get(low), node.get(high), unit))
    if "pattern" in node:
        said.append(f"matching ``{node['pattern']}``")
    if "enum" in node.get("propertyNames", {}):
        said.append("keys one of " + ", ".join(node["propertyNames"]["enum"]))
    return said


def _count(low: int | None, high: int | None, unit: str) -> str:
    """``exactly 3 items``, ``1 to 100 characters``, ``at least 1 item``."""
    def units(count: int) -> str:
        return unit[:-1] if count == 1 else unit

    if low is not None and low == high:
        return f"exactly {low} {units(low)}"
    if low is not None and high is not None:
        return f"{low} to {high} {units(high)}"
    return f"at least {low} {units(low)}" if low is not None else f"at most {high} {units(high)}"


def _value(value: Any) -> str:
    """A value as it is written in YAML: ``0.25``, ``1e+09``, ``lockstep``, ``[0, 0, 0]``, ``null``."""
    if isinstance(value, bool) or value is None:
        return json.dumps(value)
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, str):
        return value or '""'  # the empty string, seen
    return json.dumps(value)


def _grouped(properties: dict[str, Any], required: set[str]) -> list[tuple[list[str], dict[str, Any]]]:
    """``properties`` as ``(names, schema)``, neighbours with one schema (its title aside) and the
    same need joined: ``X`` to ``C`` of ``axes`` are one path, not six."""
    groups: list[tuple[list[str], dict[str, Any]]] = []
    for name, prop in properties.items():
        if groups and _same(groups[-1][1], prop) and (groups[-1][0][0] in required) == (name in required):
            groups[-1][0].append(name)
        else:
            groups.append(([name], prop))
    return groups


def _same(one: dict[str, Any], other: dict[str, Any]) -> bool:
    def shape(node: dict[str, Any]) -> dict[str, Any]:
        return {key: value for key, value in node.items() if key != "title"}

    return shape(one) == shape(other)


def _description(prop: dict[str, Any], model: dict[str, Any]) -> str:
    """A key's own description, else its model's."""
    return prop.get("description") or model.get("description", "")


def _item(entry: _Entry, walker: _Walker) -> nodes.definition_list_item:
    """One key path: the path and its type as the term, then its description and its values."""
    item = nodes.definition_list_item()
    item += nodes.term("", "", nodes.literal(text=entry.path))
    item += nodes.classifier(text=walker.type_name(entry.node))
    definition = nodes.definition()
    # a mapping's own words (its model's docstring), then what the key adds (where it differs)
    model = walker.mapping(entry.node)
    texts = [model.get("description", "") if model is not None else "", entry.node.get("description", "")]
    for text in dict.fromkeys(text for text in texts if text):
        definition += _paragraph(text)
    facts = nodes.paragraph()
    if entry.required:
        facts += nodes.strong(text="required")
    elif "default" in entry.node and not isinstance(entry.node["default"], dict):
        # a section's default (a mapping) is its keys' defaults, each said at its key
        facts += nodes.Text("default: ")
        facts += nodes.literal(text=_value(entry.node["default"]))
    allowed = walker.allowed(entry.node)
    if allowed:
        if len(facts):
            facts += nodes.Text("; ")
        facts += _paragraph(f"allowed: {allowed}").children
    if len(facts):
        definition += facts
    item += definition
    return item


def _paragraph(text: str) -> nodes.paragraph:
    """``text`` as a paragraph, its ````literals```` (as docstrings write keys) shown as code."""
    paragraph = nodes.paragraph()
    for i, part in enumerate(LITERAL.split(text)):
        if part:
            paragraph += nodes.literal(text=part) if i % 2 else nodes.Text(part)
    return paragraph


def setup(app: Sphinx) -> dict[str, Any]:
    app.add_directive("scenario-reference", ScenarioReference)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
