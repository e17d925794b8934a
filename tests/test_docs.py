"""What README, CONTRIBUTING and docs/ show, the code does: every Python block runs as written (each on its
own, as a reader pastes it), every YAML block is a scenario (or a part of one) that validates, the
usage block names every command and option of the CLI and nothing else, and every command line
the docs quote parses and names files that exist."""

from __future__ import annotations

import argparse
import re
import shlex
from pathlib import Path

import pytest
import yaml

from cnc_twin.cli import build_parser
from cnc_twin.scenario.load import scenario_from_dict

ROOT = Path(__file__).parents[1]
DOCS = [ROOT / "README.md", ROOT / "CONTRIBUTING.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)


def blocks(language: str) -> list[tuple[str, str]]:
    """``(id, code)`` of every fenced block of ``language`` in the docs, in order."""
    found = []
    for path in DOCS:
        text = path.read_text(encoding="utf-8")
        for match in FENCE.finditer(text):
            if match.group(1) == language:
                line = text.count("\n", 0, match.start()) + 1
                found.append((f"{path.name}:{line}", match.group(2)))
    return found


@pytest.mark.parametrize("where,code", blocks("python"), ids=[b[0] for b in blocks("python")])
def test_python_blocks_run_as_written(where, code, tmp_path, monkeypatch):
    """In a scratch folder holding the repository's scenarios/ (as in a clone), in a namespace of
    its own: a block that needs a name defined by another block fails here."""
    for folder in ("scenarios", "programs"):
        (tmp_path / folder).symlink_to(ROOT / folder)
    monkeypatch.chdir(tmp_path)
    # A block that writes a run directory is pasted twice, as a reader trying it again does: the
    # second works too (a fixed folder name used to stop it with a traceback)
    for _ in range(2 if ".write(" in code else 1):
        exec(compile(code, where, "exec"), {"__name__": "__main__"})


@pytest.mark.parametrize("where,code", blocks("yaml"), ids=[b[0] for b in blocks("yaml")])
def test_yaml_blocks_are_scenarios_that_validate(where, code):
    """A whole scenario validates as it is; a part of one (no `name`) on top of a one-move program.
    Every block is one a reader can paste: none is elided (a `...` in a list would read as the
    string "..." and fail here), and none is let through unchecked."""
    raw = yaml.safe_load(code)
    if "name" not in raw:
        raw = {"name": "docs", "program": {"type": "point_to_point", "moves": [{"X": 1}]}, **raw}
    scenario_from_dict(raw, source_file=ROOT / "scenarios" / "docs.yaml")


def _subcommands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def test_the_usage_block_names_every_command_and_option_and_nothing_else():
    """docs/cli.md's first block is the usage of every command."""
    page = (ROOT / "docs" / "cli.md").read_text(encoding="utf-8")
    usage = page.split("```", 2)[1]
    sections = re.split(r"^(?=cnc-twin )", usage, flags=re.M)
    shown: dict[str, set[str]] = {}
    for section in sections:
        if section.startswith("cnc-twin "):
            command = section.split()[1]
            shown[command] = set(re.findall(r"(?<![\w-])--[a-z][a-z-]*", section))
    commands = _subcommands()
    assert set(shown) == set(commands)
    for name, sub in commands.items():
        options = {opt for a in sub._actions for opt in a.option_strings if opt.startswith("--") and opt != "--help"}
        assert shown[name] == options, name


def quoted_commands() -> list[tuple[str, str]]:
    """``(where, command)`` of each concrete `cnc-twin ...` line the docs quote (in backticks or
    as a block's line), placeholders in capitals left out."""
    found = []
    for path in DOCS:
        if path.name == "getting-started.md":
            continue  # its commands make the files they name: tests/test_getting_started.py runs the page whole
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
            for command in re.findall(r"`(cnc-twin [^`]+)`", line) + re.findall(r"^(cnc-twin .+?)(?:\s+#.*)?$", line):
                if re.search(r"[A-Z]{3,}|\[|\.\.\.", command):
                    continue  # a syntax line (FILE, RUN_DIR, [options]), checked against the parser above
                if len(command.split()) == 2 and command.split()[1] not in ("run", "bench"):
                    continue  # the command's name in a sentence ("from `cnc-twin tune`")
                found.append((f"{path.name}:{number}", command.strip()))
    return found


@pytest.mark.parametrize("where,command", quoted_commands(), ids=[c[0] for c in quoted_commands()])
def test_quoted_command_lines_parse_and_name_files_that_exist(where, command):
    args = build_parser().parse_args(shlex.split(command)[1:])
    for name in ("scenario", "scenarios"):
        for path in (getattr(args, name, None) if name == "scenarios" else [getattr(args, name, None)]) or []:
            if path is not None:
                assert (ROOT / path).is_file(), f"{where}: {path} does not exist"


RUNS = sorted({command for _, command in quoted_commands() if command.split()[1] == "run"})


@pytest.mark.parametrize("command", RUNS)
def test_quoted_run_commands_run(command, tmp_path, monkeypatch):
    """Each distinct `cnc-twin run ...` the docs quote runs to a complete run directory (in a
    scratch folder holding scenarios/ and programs/, recording skipped: the small-input version of it)."""
    import json

    from conftest import run_cli

    for folder in ("scenarios", "programs"):
        (tmp_path / folder).symlink_to(ROOT / folder)
    monkeypatch.chdir(tmp_path)
    code, _, err = run_cli(*shlex.split(command)[1:], "--out", "run", "--quiet", "--no-rrd")
    assert code == 0, err
    assert json.loads((tmp_path / "run" / "metrics.json").read_text())["status"] == "complete"


def test_the_readme_is_a_front_page_that_does_not_go_stale():
    """README: at most 200 lines, no dated measurement, no issue number; its reference is in docs/."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= 200
    assert not re.search(r"\b20\d\d-\d\d-\d\d\b", readme), "a dated note in README"
    assert not re.search(r"(?i)\bissue\s*#?\d+", readme), "an issue number in README"
    for target in re.findall(r"\]\(((?:docs/)?[\w./-]+\.(?:md|png))(?:#[\w-]+)?\)", readme):
        assert (ROOT / target).is_file(), f"README links {target}, which does not exist"
