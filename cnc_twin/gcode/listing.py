"""``cnc-twin gcode FILE``: a program read whole, listed as canonical calls in the text form of
LinuxCNC's ``rs274 -g`` (``--canon``, the form to diff against LinuxCNC), or summarised.

A refused program lists the calls made before the refusal (as rs274 does) and its one-line error
``FILE:LINE: message``.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Sequence
from pathlib import Path

from cnc_twin.gcode.interpreter import Interpreter, ProgramError
from cnc_twin.gcode.modal import G
from cnc_twin.gcode.source import Source, SourceError
from cnc_twin.gcode.state import ToolTable

CALL_BATCH = 4096
"""calls the reader makes before the listing takes them"""
MOVES = ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "ARC_FEED", "NURBS_FEED", "DWELL")
"""calls the summary counts as motion"""


class LineWriter:
    """Lines to a text stream, written a few thousand at a time (:func:`list_program`'s ``out``):
    the same text as ``print("\\n".join(lines))`` of them all, once :meth:`~LineWriter.finish` has
    the rest."""

    def __init__(self, stream, every: int = 4096):
        self.stream, self.every, self.pending, self.wrote = stream, every, [], False

    def __call__(self, line: str) -> None:
        self.pending.append(line)
        if len(self.pending) >= self.every:
            self._flush()

    def _flush(self) -> None:
        self.stream.write("\n".join(self.pending) + "\n")
        self.pending.clear()
        self.wrote = True

    def finish(self, lines: list[str]) -> None:
        """The last ``lines``, and the newline an empty listing prints."""
        self.pending += lines
        if self.pending or not self.wrote:
            self._flush()


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
                 subroutine_path: Sequence[Path] = (), *, max_calls: int | None = None,
                 out: Callable[[str], None] | None = None) -> tuple[list[str], str | None]:
    """The listing's lines and the error line (None when the program was read whole);
    ``subroutine_path``: folders to look for called subroutines' files in after the program's;
    ``max_calls``: the reader's bound on calls (None: its default). ``out``: each line handed to
    it as the program is read (the listing of a long program is never held; the lines returned
    are then only those after the calls, the summary and the printed comments)."""
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
    kept: list[str] = []
    emit = out or kept.append
    counts: Counter = Counter()

    def reader() -> Interpreter:
        return Interpreter(source, tools, subroutine_path=subroutine_path,
                           **({} if max_calls is None else {"max_calls": max_calls}))

    interpreter = reader()

    def listed(calls):
        for call in calls:
            counts[call.name] += 1
            if canon:
                emit(call.text(counts.total()))
            yield call

    error, reach = None, []
    try:
        for batch in interpreter.stream(CALL_BATCH):
            for _ in listed(batch):
                pass
    except ProgramError as exc:  # the calls made since the last batch, then the refusal
        error = f"{exc.file or path}:{exc.line}: {exc.message}"
        for _ in listed(exc.calls):
            pass
    if not canon and error is None:  # how far it reaches: read again, into its operations (a refused
        # program, a loop without end among them, never costs them)
        reach = _reach(call for batch in reader().stream(CALL_BATCH) for call in batch)
    tail = []
    if not canon:
        tail = [f"{path}: {len(source.lines)} lines, {counts.total()} canonical calls"]
        tail += [f"  {name:<18} {counts[name]}" for name in MOVES if counts[name]]
        if error is None:
            tail += reach
    return kept + tail + interpreter.printed, error


def _reach(calls) -> list[str]:
    """The line saying how far the tool tip goes, after the program's own offsets (where it
    starts is not known here: from the first motion on), read to the program's end."""
    from cnc_twin.gcode.extents import describe, extents
    from cnc_twin.gcode.toolpath import ToolpathError, iter_operations

    try:
        box = extents(iter_operations(calls))
    except ToolpathError:  # an arc as the first motion: from where the machine stands, not known here
        box = None
    for _ in calls:  # the calls after the end (and, after a refused motion, the rest: its count)
        pass
    return [] if box is None else [f"  reaches {describe(box)} (the tool tip, after the program's offsets)"]
