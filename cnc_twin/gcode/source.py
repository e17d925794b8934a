"""A program's text as LinuxCNC's interpreter walks it: its lines, where it ends, and its O-word
lines, so control flow can jump without reading the program twice.

- A program whose first non-blank line is ``%`` ends at the next line of ``%`` alone (the interpreter's
  ``FINISH``); lines after it are never read. Without a leading ``%``, the program must end with
  M2 / M30 before the file does (``File ended with no percent sign or program end``).
- An O-word line is ``o<name> keyword [argument...]`` or ``o123 keyword ...``: the name is lower
  case without spaces (as every line outside comments), the keyword one of :data:`KEYWORDS`.
  Control flow finds its partner lines (``endsub``, ``else``, ``endwhile`` ...) by name, as
  LinuxCNC does, not by nesting.
"""

from __future__ import annotations

import bisect
import re
from dataclasses import dataclass
from pathlib import Path

from cnc_twin.gcode.blocks import BlockError, normalise

KEYWORDS = ("sub", "endsub", "call", "return", "if", "elseif", "else", "endif", "while", "endwhile", "do",
            "repeat", "endrepeat", "break", "continue")
"""O-word keywords, LinuxCNC's set"""
O_NAME = r"<[^>]*>|\d+"
"""an O-word's name as normalised: ``<name>`` or a number"""
_O_LINE = re.compile(rf"^(?:n[\d.]*)?o({O_NAME})([a-z]*)(.*)$")
_BLOCK_DELETE = re.compile(r"^\s*/")


class SourceError(ValueError):
    """A program file that cannot be read at all (not text); ``line`` is 0 when it is the file."""

    def __init__(self, line: int, message: str):
        self.line = line
        super().__init__(message)


@dataclass(frozen=True)
class OLine:
    """An O-word line: ``name`` (``<name>`` or the number's digits), ``keyword``, ``rest`` (the
    normalised text after the keyword: arguments or a condition), ``index`` (0-based line)."""

    name: str
    keyword: str
    rest: str
    index: int


C_SPACE = " \t\n\v\f\r"
"""white space as C's ``isspace`` has it, which LinuxCNC strips from the end of a line"""
_ESCAPED = re.compile("[\udc80-\udcff]")
"""a byte that is not UTF-8, decoded as a surrogate escape"""


def _byte_length(line: str) -> int:
    """Bytes of ``line`` in the file (a surrogate escape is its one byte)."""
    return len(line.encode("utf-8", "surrogateescape")) if not line.isascii() else len(line)


MAX_LINE = 253
"""characters (bytes) in a line, newline not counted, that LinuxCNC refuses as too long"""


class Source:
    """The lines of one program.

    ``lines``: the raw lines (no newline characters); ``first``, ``end``: the range of 0-based
    line indices the interpreter reads (after a leading ``%``, up to a closing one);
    ``percent_start``: whether a ``%`` line opens the file; ``percent_end``: whether ``end`` is a
    closing ``%`` line; ``o_lines``: 0-based index -> OLine
    for every O-word line in that range; ``too_long``: 0-based indices of the lines LinuxCNC
    refuses as too long, increasing.
    """

    def __init__(self, text: str, name: str = "program.ngc"):
        self.name = name
        self.path: Path | None = None
        """the file read (:meth:`read`), else None"""
        # LinuxCNC's lines end at a newline only (a CR, a form feed... are characters of the
        # line), without the white space that ends them
        raw = text.split("\n")
        if raw[-1] == "":
            raw.pop()
        self.lines = [line.rstrip(C_SPACE) for line in raw]
        self.escaped: dict[int, str] = {}
        """0-based index -> the line with its bytes that are not UTF-8 as surrogate escapes (the
        text :meth:`read` gives), for the lines that have some: ``lines`` holds them as U+FFFD,
        one for one"""
        if not text.isascii():
            for k, line in enumerate(self.lines):
                if _ESCAPED.search(line):
                    self.escaped[k] = line
                    self.lines[k] = _ESCAPED.sub("\ufffd", line)
        # LinuxCNC reads a line into 255 bytes: one of MAX_LINE bytes or more before its newline
        # (a CR counts) is "Command too long" wherever it is read, a line passed over too
        longest = max(map(len, raw), default=0)  # most files have no line that long: known at once
        self.too_long = [k for k, line in enumerate(raw) if len(line) >= MAX_LINE and _byte_length(line) >= MAX_LINE
                         ] if longest >= MAX_LINE else []
        self.first, self.end, self.percent_end = 0, len(self.lines), False
        self.percent_start = False
        for k, line in enumerate(self.lines):
            if line.strip():
                if line.strip() == "%":
                    self.first, self.percent_start = k + 1, True
                    # closed by a line of "%" alone; a "%" with more on its line is read as a block
                    # (and refused there, "Bad character '%' used", as LinuxCNC does)
                    closing = next((j for j in range(k + 1, len(self.lines)) if self.lines[j].strip() == "%"), None)
                    if closing is not None:
                        self.end, self.percent_end = closing, True
                break
        self.o_lines: dict[int, OLine] = {}
        for k in range(self.first, self.end):
            text_k = self.lines[k]
            if "o" not in text_k and "O" not in text_k:
                continue
            o_line = self._o_line(k)
            if o_line is not None:
                self.o_lines[k] = o_line
        self._o_order = sorted(self.o_lines)

    @property
    def eof_message(self) -> str:
        """LinuxCNC's refusal of a file that ends before the program does: a file opened by ``%``
        wanted its closing ``%``."""
        if self.percent_start:
            return "File ended with no percent sign"
        return "File ended with no percent sign or program end"

    def percent_missing_after(self, index: int) -> bool:
        """After a program end at ``index`` in a file opened by ``%``: no line after it is a
        lone ``%`` (LinuxCNC then notes it in a comment)."""
        return self.percent_start and not any(line.strip() == "%" for line in self.lines[index + 1:])

    def o_lines_after(self, start: int) -> list[OLine]:
        """The O-word lines after index ``start``, in order."""
        return [self.o_lines[k] for k in self._o_order[bisect.bisect_right(self._o_order, start):]]

    @classmethod
    def read(cls, path: Path) -> "Source":
        """The program in ``path``; a file that is not text is refused in one line. A byte
        that is not UTF-8 reads as U+FFFD (LinuxCNC's messages name the byte itself:
        :attr:`escaped`)."""
        data = Path(path).read_bytes()
        if b"\0" in data:
            raise SourceError(0, "not a text file (it contains NUL bytes)")
        source = cls(data.decode("utf-8", errors="surrogateescape"), Path(path).name)
        source.path = Path(path)
        return source

    def _o_line(self, k: int) -> OLine | None:
        text = self.lines[k]
        if _BLOCK_DELETE.match(text):
            return None
        try:
            norm, _ = normalise(text)
        except BlockError:
            return None  # the line's own reading reports it
        match = _O_LINE.match(norm)
        if match is None:
            return None
        return OLine(match.group(1), match.group(2), match.group(3), k)

    def find_forward(self, start: int, name: str, keywords: tuple[str, ...]) -> OLine | None:
        """The first O-word line after index ``start`` with ``name`` and one of ``keywords``."""
        for k in self._o_order[bisect.bisect_right(self._o_order, start):]:
            o_line = self.o_lines[k]
            if o_line.name == name and o_line.keyword in keywords:
                return o_line
        return None

    def find_backward(self, start: int, name: str, keywords: tuple[str, ...]) -> OLine | None:
        """The nearest O-word line before index ``start`` with ``name`` and one of ``keywords``."""
        for k in reversed(self._o_order[:bisect.bisect_left(self._o_order, start)]):
            o_line = self.o_lines[k]
            if o_line.name == name and o_line.keyword in keywords:
                return o_line
        return None
