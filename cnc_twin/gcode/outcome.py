"""What reading a program gives: its calls (:class:`~cnc_twin.gcode.outcome.Reading`), or its
refusal (:class:`~cnc_twin.gcode.outcome.ProgramError`), as
:func:`~cnc_twin.gcode.interpreter.read_program` returns or raises them (and the interpreter module
names them too)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from cnc_twin.gcode.canon import Call


class ProgramError(ValueError):
    """A program the reader refuses: ``line`` (1-based; 0 for the file as a whole), the message
    in LinuxCNC's wording where it has one, and ``calls`` made before it (for comparisons);
    ``file``: the subroutine file ``line`` is in, None for the program's own."""

    def __init__(self, line: int, message: str, calls: list[Call] | None = None, printed: list[str] | None = None,
                 file: Path | None = None):
        self.line = line
        self.message = message
        self.calls = calls or []
        self.printed = printed or []
        self.file = file
        super().__init__(f"line {line}: {message}")


@dataclass
class Reading:
    """A program read whole: its calls in order, what ``(print,...)`` comments printed, and
    the subroutine files it called (path -> text as read)."""

    calls: list[Call]
    printed: list[str]
    files: dict[Path, str] = field(default_factory=dict)
