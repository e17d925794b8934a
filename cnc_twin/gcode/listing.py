"""``cnc-twin gcode FILE``: a program read whole, listed as canonical calls in the text form of
LinuxCNC's ``rs274 -g`` (``--canon``, the form to diff against LinuxCNC), or summarised.

A refused program lists the calls made before the refusal (as rs274 does) and its one-line error
``FILE:LINE: message``.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from pathlib import Path

from cnc_twin.gcode.interpreter import ProgramError, read_program
from cnc_twin.gcode.modal import G
from cnc_twin.gcode.source import Source, SourceError
from cnc_twin.gcode.state import ToolTable

MOVES = ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "ARC_FEED", "NURBS_FEED", "DWELL")
"""calls the summary counts as motion"""


def read_tool_table(path: Path | None, units: str) -> ToolTable:
    """The tool table at ``path`` (LinuxCNC's format) in ``units`` (``mm`` / ``inch``); none: empty."""
    code = G.G21 if units == "mm" else G.G20
    if path is None:
        return ToolTable(units=code)
    try:
        return ToolTable.parse(Path(path).read_text(), units=code)
    except OSError as exc:
        raise ValueError(f"{path}: cannot read the tool table ({exc.strerror})") from None
    except (KeyError, ValueError):
        raise ValueError(f"{path}: not a LinuxCNC tool table (expected lines like 'T1 P1 Z0.5 D2')") from None


def list_program(path: Path, tool_table: Path | None, tool_units: str, canon: bool,
                 subroutine_path: Sequence[Path] = (), *, max_calls: int | None = None) -> tuple[list[str], str | None]:
    """The listing's lines and the error line (None when the program was read whole);
    ``subroutine_path``: folders to look for called subroutines' files in after the program's;
    ``max_calls``: the reader's bound on calls (None: its default)."""
    missing = next((folder for folder in subroutine_path if not Path(folder).is_dir()), None)
    if missing is not None:
        return [], f"{missing}: no such folder (--subroutine-path)"
    try:
        tools = read_tool_table(tool_table, tool_units)
        source = Source.read(path)
    except ValueError as exc:
        return [], str(exc)
    except SourceError as exc:
        return [], f"{path}: {exc}"
    except OSError as exc:
        return [], f"{path}: cannot read the program ({exc.strerror})"
    try:
        reading = read_program(source, tools, subroutine_path=subroutine_path,
                               **({} if max_calls is None else {"max_calls": max_calls}))
        calls, printed, error = reading.calls, reading.printed, None
    except ProgramError as exc:
        calls, printed, error = exc.calls, exc.printed, f"{exc.file or path}:{exc.line}: {exc.message}"
    if canon:
        return [call.text(k) for k, call in enumerate(calls, start=1)] + printed, error
    counts = Counter(call.name for call in calls)
    lines = [f"{path}: {len(source.lines)} lines, {len(calls)} canonical calls"]
    lines += [f"  {name:<18} {counts[name]}" for name in MOVES if counts[name]]
    if error is None:
        lines += _reach(calls)
    return lines + printed, error


def _reach(calls) -> list[str]:
    """The line saying how far the tool tip goes, after the program's own offsets (where it
    starts is not known here: from the first motion on)."""
    from cnc_twin.gcode.extents import describe, extents
    from cnc_twin.gcode.toolpath import ToolpathError, operations

    try:
        box = extents(operations(calls))
    except ToolpathError:  # an arc as the first motion: from where the machine stands, not known here
        return []
    return [] if box is None else [f"  reaches {describe(box)} (the tool tip, after the program's offsets)"]
