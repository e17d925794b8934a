"""A G-code scenario's program read as a stream: its canonical calls made as they are asked for
(:meth:`~cnc_twin.gcode.interpreter.Interpreter.stream`) and turned into operations as they come
(:func:`~cnc_twin.gcode.toolpath.iter_operations`), so a CAM program of millions of lines is held
a batch of calls and a feed path at a time, never whole. A problem is a
:class:`~cnc_twin.core.errors.ScenarioError` at the program's line (``FILE:LINE: message``, the
program's own file or a subroutine file's), raised when the reading reaches it."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

from cnc_twin.core.errors import ScenarioError

CALL_BATCH = 4096
"""canonical calls the reader makes before the operations take them"""


class Where:
    """Errors at a program line: ``FILE:LINE: message`` (exit 2 in the CLI)."""

    def __init__(self, path: Path):
        self.path = path

    def __call__(self, line: int, message: str) -> ScenarioError:
        return ScenarioError(f"{self.path}:{line}", "", message)


class ProgramStream:
    """The program at ``path`` opened for reading with its tool table (``tool_table``, None: an
    empty one; lengths in ``tool_units``): the file and the table are read now (a ScenarioError
    on ``label``'s key when they cannot be), the program when :meth:`~ProgramStream.operations` is
    iterated.

    ``reader``: :class:`~cnc_twin.gcode.interpreter.Interpreter`'s keywords (``start``,
    ``parameters``, ``subroutine_path``, ``probe``, ``max_calls``); ``shaping``:
    :func:`~cnc_twin.gcode.toolpath.iter_operations`'s (``default_blend``, ``axis_tolerance``,
    ``start``, ``air``)."""

    def __init__(self, path: Path, tool_table: Path | None, tool_units: str, label: Path, *, reader: dict,
                 shaping: dict):
        from cnc_twin.gcode.listing import read_tool_table
        from cnc_twin.gcode.source import Source, SourceError

        self.path, self.reader, self.shaping = path, reader, shaping
        self.where = Where(path)
        try:
            self.tools = read_tool_table(tool_table, tool_units)
        except ValueError as exc:
            raise ScenarioError(label, "program.tool_table", str(exc)) from None
        try:
            self.source = Source.read(path)
        except SourceError as exc:
            raise (self.where(exc.line, str(exc)) if exc.line else ScenarioError(path, "", str(exc))) from None
        except OSError as exc:
            raise ScenarioError(label, "program.file", f"cannot read {path} ({exc.strerror})") from None
        self.files: dict[Path, str] = {}
        """the subroutine files the program called (path -> text), once :meth:`operations` is read to its end"""
        self.moved = False
        """a traverse or a feed path came by (once :meth:`operations` is read)"""
        self.lowest: float | None = None
        """[mm] the lowest point the operations reach (tip Z, workpiece frame, as run), when
        ``shaping`` raises the program into the air; else None"""

    def calls(self) -> Iterator:
        """The program's canonical calls, in order, made as they are asked for."""
        from cnc_twin.gcode.interpreter import Interpreter, ProgramError

        interpreter = Interpreter(self.source, self.tools, **self.reader)
        try:
            for batch in interpreter.stream(CALL_BATCH):
                yield from batch
            self.files = interpreter.flow.files.texts()
        except ProgramError as exc:
            raise Where(exc.file or self.path)(exc.line, exc.message) from None
        finally:  # however the reading ends: the interpreter's cycle then holds no program text
            interpreter.flow.release()

    def operations(self) -> Iterator:
        """The program's operations (:mod:`cnc_twin.gcode.toolpath`), in order, read as they are
        asked for."""
        from cnc_twin.gcode import toolpath as tp
        from cnc_twin.gcode.paths_ahead import HELPER_LINES
        from cnc_twin.gcode.extents import operation_points

        in_air = bool(self.shaping.get("air"))
        if self.source.o_lines:
            # a program with O-words may loop without end: read it through first, its calls only
            # counted (the reader's bound catches a runaway in seconds, in a batch's memory),
            # before its operations are shaped and made into steps, which cost far more a call
            for _ in self.calls():
                pass
        calls = self.calls()
        try:
            # a long program's feed paths fitted in a helper process while its lines are read on
            helper = len(self.source.lines) >= HELPER_LINES
            for op in tp.iter_operations(calls, helper=helper, **self.shaping):
                if isinstance(op, (tp.Traverse, tp.FeedPath)):
                    self.moved = True
                if in_air and (points := operation_points(op)) is not None:
                    low = float(points[:, 2].min())
                    self.lowest = low if self.lowest is None else min(self.lowest, low)
                yield op
            for _ in calls:  # the calls after the program's end (its reset): the reading ends
                pass
        except tp.ToolpathError as exc:
            raise self.where(exc.line, exc.message) from None

    def box(self):
        """``(low, high)`` [mm] around everything the program reaches
        (:func:`~cnc_twin.gcode.extents.extents`), read again from the start; as far as it reads
        when a refusal ends it; None when nothing moves."""
        from cnc_twin.gcode.extents import extents

        def until_refused():
            try:
                yield from self.operations()
            except ScenarioError:
                return

        return extents(until_refused())
