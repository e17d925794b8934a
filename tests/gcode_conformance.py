"""One program through both readers, LinuxCNC's ``rs274 -g`` and ours, and the verdict: matched
call for call (both may end in the same error), refused by us with a named reason before any
difference, or differing (the goal is none)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import oracle
from cnc_twin.gcode.interpreter import UNSUPPORTED_MARK, ProgramError, read_program
from cnc_twin.gcode.source import Source
from cnc_twin.gcode.state import ToolTable

TOOLS = ToolTable.parse(oracle.TOOL_TABLE, units=200)
"""the oracle's tool table; rs274 reads tool lengths in inches"""


@dataclass
class Verdict:
    kind: str  # "matched", "refused" or "differs"
    detail: str = ""


def ours(text: str) -> tuple[list[tuple[str, str]], list[str], ProgramError | None]:
    """Our reader's calls (name, arguments as printed), printed lines and refusal."""
    try:
        reading = read_program(Source(text, "program.ngc"), TOOLS)
        return [(c.name, c.arguments) for c in reading.calls], reading.printed, None
    except ProgramError as exc:
        return [(c.name, c.arguments) for c in exc.calls], exc.printed, exc


def compare(text: str, folder: Path) -> Verdict:
    theirs, other = oracle.run(text, folder)
    calls, printed, error = ours(text)
    if error is not None and UNSUPPORTED_MARK in error.message:
        made = calls[:-2]  # the two resets that end every run
        if made == theirs[:len(made)]:
            return Verdict("refused", f"line {error.line}: {error.message}")
        return Verdict("differs", f"calls before our refusal differ ({error.message})")
    if calls != theirs:
        k = next((i for i, (a, b) in enumerate(zip(calls, theirs)) if a != b), min(len(calls), len(theirs)))
        return Verdict("differs", f"call {k + 1}: ours {calls[k:k + 1]} rs274 {theirs[k:k + 1]}")
    # rs274's other lines: what (print,...) printed, then an error and the line it refused
    expected = list(printed)
    if error is not None:
        # rs274 shows the refused line as it read it (nothing for an empty one), at most the 254
        # characters its line buffer holds (a line too long to read)
        line_text = Source(text).lines[error.line - 1][:254].strip() if error.line else ""
        expected += [error.message] + ([line_text] if line_text else [])
    if [o.strip() for o in other] != [e.strip() for e in expected]:
        return Verdict("differs", f"messages: ours {expected} rs274 {other}")
    return Verdict("matched", error.message if error else "")


def assert_refused_alike(program: str, message: str, folder: Path) -> None:
    """rs274 refuses ``program`` first with ``message`` (else the test's table is wrong), and ours
    refuses it alike, after the same calls."""
    oracle.require()
    _, said = oracle.run(program, folder)
    assert said[:1] == [message], "the table is wrong"
    verdict = compare(program, folder)
    assert (verdict.kind, verdict.detail) == ("matched", message), verdict.detail
