"""What is bundled: the scenarios and NC programs a user can name without a path
(``cnc-twin run nurbs_circle``), each with its one-line description, for ``cnc-twin list``."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from cnc_twin.scenario.resources import programs_dir, scenarios_dir


@dataclass(frozen=True)
class BundledInput:
    """One bundled scenario or program."""

    kind: str
    """``scenario`` or ``program``"""
    name: str
    """what to type: its path under its folder, without the suffix (``published/farfalla``)"""
    description: str
    """a scenario's ``description:``, a program's first comment; empty where it has none"""


def bundled_inputs() -> list[BundledInput]:
    """Every bundled scenario, then every bundled program, each kind sorted by name."""
    found = []
    for kind, folder, suffix, describe in (("scenario", scenarios_dir(), ".yaml", _scenario_description),
                                           ("program", programs_dir(), ".ngc", _program_description)):
        for path in sorted(folder.rglob(f"*{suffix}")):
            found.append(BundledInput(kind, path.relative_to(folder).with_suffix("").as_posix(), describe(path)))
    return found


def _scenario_description(path: Path) -> str:
    """The scenario's ``description:``, on one line (the file is read, not validated)."""
    import yaml

    try:
        raw = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError:
        return ""
    text = raw.get("description", "") if isinstance(raw, dict) else ""
    return " ".join(str(text).split())


def _program_description(path: Path) -> str:
    """The program's first comment: a ``; ...`` line or a line that is one ``( ... )``, with the
    comment lines after it while it ends in a comma or a colon (a sentence carried on)."""
    found: list[str] = []
    with path.open(encoding="utf-8", errors="replace") as lines:
        for line in lines:
            text = line.strip()
            if text.startswith(";"):
                comment = text[1:].strip()
            elif text.startswith("(") and text.endswith(")"):
                comment = text[1:-1].strip()
            elif found or (text and text != "%"):
                break
            else:
                continue
            found.append(comment)
            if not comment.endswith((",", ":")):
                break
    return " ".join(found)


def catalogue_lines() -> list[str]:
    """``cnc-twin list``: the scenarios, then the programs, a name and its description's first
    sentence per line."""
    entries = bundled_inputs()
    width = max(len(entry.name) for entry in entries)
    lines = []
    for kind, heading in (("scenario", "scenarios (cnc-twin run NAME):"), ("program", "programs (cnc-twin run NAME.ngc):")):
        lines += ([""] if lines else []) + [heading]
        for entry in entries:
            if entry.kind == kind:
                first = entry.description.split(". ", 1)[0]  # its first sentence: one line each
                lines.append(f"  {entry.name:<{width}}  {first}".rstrip())
    return lines
