"""The package layout holds: imports run downward only, no circles, no private names across modules.

Read from the modules' own source with ``ast`` (nothing is imported), so a new upward import, a
circle between modules or packages, or a module reaching into another's underscore names fails
here with the file and the import that broke the rule. Imports under ``if TYPE_CHECKING:`` are
for type checkers only and never run, so they are left out.
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent / "cnc_twin"

MAY_IMPORT: dict[str, set[str]] = {
    # the bottom: the validated scenario in SI, axis names, units, errors
    "core": set(),
    "motion": {"core"},
    "legacy": {"motion"},
    "geometry": {"core"},
    "gcode": {"core", "geometry"},
    # shared by the PC and the card, and the card's own recording layout
    "whiteboard": {"core", "motion"},
    "dsp": {"core", "motion", "geometry", "legacy", "whiteboard"},
    "planner": {"core", "motion", "geometry", "legacy", "whiteboard"},
    "machine": {"core", "geometry", "dsp"},
    "trace": {"core", "dsp"},
    "polishing": {"core", "motion", "geometry", "dsp", "machine", "trace"},
    "view": {"core", "geometry", "machine", "trace", "whiteboard"},
    # reading a scenario checks programs against the machine and the planner before any motion
    "scenario": {"core", "motion", "geometry", "legacy", "whiteboard", "planner", "machine", "polishing", "gcode"},
    "run": {"core", "motion", "geometry", "legacy", "whiteboard", "dsp", "planner", "machine", "trace",
            "polishing", "view", "gcode"},
    "studies": {"core", "motion", "geometry", "legacy", "whiteboard", "dsp", "planner", "machine", "trace",
                "polishing", "view", "scenario", "run", "gcode"},
    "cli": {"core", "motion", "geometry", "legacy", "whiteboard", "dsp", "planner", "machine", "trace",
            "polishing", "view", "scenario", "run", "studies", "gcode"},
    # the warm server: loads everything a command uses, and becomes the command in a fork
    "server": {"core", "motion", "geometry", "legacy", "whiteboard", "dsp", "planner", "machine", "trace",
               "polishing", "view", "scenario", "run", "studies", "gcode", "cli"},
    "entry": {"cli", "core"},
    "__main__": {"entry"},
    "__init__": set(),
}
"""each part of the package and the parts it may import: what sits below it"""

TOP_LEVEL_MODULES = {"__init__", "__main__", "entry", "cli"}
MAX_LINES = 520
"""no module over about 500 lines"""


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _is_module(name: str) -> bool:
    rel = Path(*name.split("."))
    return (ROOT.parent / rel).with_suffix(".py").is_file() or (ROOT.parent / rel / "__init__.py").is_file()


def _type_checking_only(tree: ast.AST) -> set[int]:
    skip: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            skip.update(id(inner) for stmt in node.body for inner in ast.walk(stmt))
    return skip


def _imports(path: Path) -> list[tuple[int, str, str | None, str | None]]:
    """``(line, module, name, alias)`` for every cnc_twin import that runs (lazy ones included);
    ``name`` is set for ``from module import name``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    skip = _type_checking_only(tree)
    out = []
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0 and node.module.startswith("cnc_twin"):
            out += [(node.lineno, node.module, a.name, a.asname or a.name) for a in node.names]
        elif isinstance(node, ast.Import):
            out += [(node.lineno, a.name, None, a.asname) for a in node.names if a.name.startswith("cnc_twin")]
    return out


def _part(module: str) -> str:
    """The package part a module belongs to: ``cnc_twin.dsp.task`` -> ``dsp``, ``cnc_twin.cli`` -> ``cli``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def _sources() -> list[Path]:
    return sorted(ROOT.rglob("*.py"))


def _module_graph() -> dict[str, set[str]]:
    graph: dict[str, set[str]] = defaultdict(set)
    for path in _sources():
        here = _module_name(path)
        for _, module, name, _ in _imports(path):
            target = f"{module}.{name}" if name and _is_module(f"{module}.{name}") else module
            if target != here:
                graph[here].add(target)
    return graph


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``graph`` as a list of nodes, or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


def test_every_part_is_listed_and_the_top_level_holds_only_the_entry_points():
    parts = {p.name for p in ROOT.iterdir() if p.is_dir() and (p / "__init__.py").is_file()}
    top = {p.stem for p in ROOT.glob("*.py")}
    assert top == TOP_LEVEL_MODULES, f"modules at the top of cnc_twin/: {sorted(top - TOP_LEVEL_MODULES)}"
    assert parts | top == set(MAY_IMPORT), "MAY_IMPORT must name every package"


def test_each_package_says_what_it_is_what_it_imports_and_who_imports_it():
    for init in sorted(ROOT.glob("*/__init__.py")):
        doc = ast.get_docstring(ast.parse(init.read_text(encoding="utf-8"))) or ""
        assert len(doc.split()) >= 20, f"{init}: a docstring that says what the part is"
        assert "May import" in doc and "Imported by" in doc, f"{init}: the docstring names its imports both ways"


def test_the_allowed_imports_form_layers():
    assert _cycle({part: set(below) for part, below in MAY_IMPORT.items()}) is None


def test_imports_only_run_downward():
    wrong = []
    for path in _sources():
        here = _part(_module_name(path)) if path.parent != ROOT else path.stem
        for line, module, _, _ in _imports(path):
            there = _part(module)
            if module == "cnc_twin" or there == here:
                continue
            if there not in MAY_IMPORT[here]:
                wrong.append(f"{path.relative_to(ROOT.parent)}:{line}: {here} imports {module} ({there})")
    assert not wrong, "upward or sideways imports:\n" + "\n".join(wrong)


def test_no_import_circle_between_modules():
    cycle = _cycle(_module_graph())
    assert cycle is None, "import circle: " + " -> ".join(cycle)


def test_no_module_uses_another_modules_private_names():
    wrong = []
    for path in _sources():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        modules = set()  # local names bound to cnc_twin modules
        for line, module, name, alias in _imports(path):
            if name is None:
                modules.add(alias or module.split(".")[0])
            elif _is_module(f"{module}.{name}"):
                modules.add(alias)
            elif name.startswith("_"):
                wrong.append(f"{path.relative_to(ROOT.parent)}:{line}: from {module} import {name}")
        for node in ast.walk(tree):
            if (isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__")
                    and isinstance(node.value, ast.Name) and node.value.id in modules):
                wrong.append(f"{path.relative_to(ROOT.parent)}:{node.lineno}: {node.value.id}.{node.attr}")
    assert not wrong, "private names used across modules:\n" + "\n".join(wrong)


PUBLIC_UNDERSCORE = {"_replace", "_asdict", "_fields", "_make", "_field_defaults", "_value_", "_name_", "_missing_",
                     "_generate_next_value_", "_exit", "_getframe"}
"""underscore names that are public API (namedtuples, enums, ``os._exit``, ``sys._getframe``)"""
OUTSIDE_PRIVATE_ALLOWED = {("machine/mujoco_c.py", "_address")}
"""MuJoCo's Python bindings give a model's or data's C pointer only as ``_address``: read in one place"""


def _foreign_private_reads(source: str) -> list[tuple[int, str]]:
    """``(line, "x._name")`` for each attribute ``x._name`` read on an object other than ``self``,
    ``cls`` or ``super()`` whose name this source does not define itself (as ``self._name =``, a
    ``def _name`` or a module-level ``_name``): one module reaching into another's private state."""
    tree = ast.parse(source)
    defined = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            defined.add(node.name)
        targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(
            node, (ast.AnnAssign, ast.AugAssign)) else []
        for target in targets:
            for t in ast.walk(target):
                if isinstance(t, ast.Attribute) and isinstance(t.value, ast.Name) and t.value.id in ("self", "cls"):
                    defined.add(t.attr)
                elif isinstance(t, ast.Name):
                    defined.add(t.id)
    found = []
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__")):
            continue
        owner = node.value
        if isinstance(owner, ast.Name) and owner.id in ("self", "cls"):
            continue
        if isinstance(owner, ast.Call) and isinstance(owner.func, ast.Name) and owner.func.id == "super":
            continue
        if node.attr in PUBLIC_UNDERSCORE or node.attr in defined:
            continue
        found.append((node.lineno, ast.unparse(node)))
    return sorted(found)


def test_no_module_reads_another_objects_private_state():
    """What a part shares with another is public and documented (the card's state that the batch
    kernel runs, a stepper's state vector ...), never read as ``obj._x`` from outside its module."""
    wrong = []
    for path in _sources():
        rel = str(path.relative_to(ROOT))
        for line, expr in _foreign_private_reads(path.read_text(encoding="utf-8")):
            if (rel, expr.rsplit(".", 1)[1]) not in OUTSIDE_PRIVATE_ALLOWED:
                wrong.append(f"{rel}:{line}: {expr}")
    assert not wrong, "private state read across modules:\n" + "\n".join(wrong)


@pytest.mark.parametrize("path", _sources(), ids=lambda p: str(p.relative_to(ROOT)))
def test_modules_stay_small(path):
    lines = len(path.read_text(encoding="utf-8").splitlines())
    assert lines <= MAX_LINES, f"{path.relative_to(ROOT.parent)} has {lines} lines: split it along a seam"


def test_the_checks_catch_what_they_are_for(tmp_path):
    """The checks above fail on a circle and on an upward import (so their silence means something)."""
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": set()}) is None
    bad = tmp_path / "bad.py"
    bad.write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from cnc_twin.run.twin import Twin\n"
                   "def f():\n    from cnc_twin.run.twin import Twin\n")
    found = _imports(bad)
    assert [(line, module) for line, module, _, _ in found] == [(5, "cnc_twin.run.twin")]
    assert "run" not in MAY_IMPORT["dsp"] and "dsp" in MAY_IMPORT["run"]
    reader = ("class A:\n    def __init__(self):\n        self._mine = 1\n    def f(self, other):\n"
              "        return self._mine + other._mine + other._theirs + super()._base + os._exit\n"
              "def g(interp):\n    return interp._current, interp.current\n")
    assert _foreign_private_reads(reader) == [(5, "other._theirs"), (7, "interp._current")]


def test_the_public_api_imports_from_the_top():
    """What README and docs/ show is importable from ``cnc_twin`` itself, whatever the folders hold."""
    import cnc_twin
    from cnc_twin import (  # noqa: F401
        PlannerPool, RecordingProcess, RunResult, Scenario, ScenarioError, Twin, analyse, load_scenario,
        run_scenario, sweep,
    )

    assert set(cnc_twin.__all__) == {"PlannerPool", "RecordingProcess", "RunResult", "Scenario", "ScenarioError",
                                     "Twin", "analyse", "load_scenario", "run_scenario", "sweep"}
    assert callable(sweep.run_local) and Twin.__module__ == "cnc_twin.run.twin"
