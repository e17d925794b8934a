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
from array import array
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cnc_twin.gcode.blocks import BlockError, normalise

KEYWORDS = ("sub", "endsub", "call", "return", "if", "elseif", "else", "endif", "while", "endwhile", "do",
            "repeat", "endrepeat", "break", "continue")
"""O-word keywords, LinuxCNC's set"""
O_NAME = r"<[^>]*>|\d+"
"""an O-word's name as normalised: ``<name>`` or a number"""
_O_LINE = re.compile(rf"^(?:n[\d.]*)?o({O_NAME})([a-z]*)(.*)$")
_BLOCK_DELETE = re.compile(r"^\s*/")
_TRAILING_SPACE = re.compile(r"[ \t\v\f\r]+(?=\n)")
"""white space that ends a line (C's ``isspace`` less the newline), which LinuxCNC strips"""
_LETTER_O = re.compile(r"[oO]")
_PERCENT_ALONE = re.compile(r"^[^\S\n]*%[^\S\n]*$", re.MULTILINE)
"""a line of ``%`` alone, white space around it (``str.strip``'s)"""


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


NEWLINE_CHUNK = 1 << 22
"""characters searched for newlines at a time (a long program's temporaries stay this small)"""


def _newlines(text: str) -> np.ndarray:
    """Offsets of ``text``'s newline characters, increasing (int64)."""
    if text.isascii():  # a byte a character: numpy finds them at memory speed, a chunk at a time
        found = [np.flatnonzero(np.frombuffer(text[k:k + NEWLINE_CHUNK].encode("ascii"), np.uint8) == 10) + k
                 for k in range(0, len(text), NEWLINE_CHUNK)]
        return np.concatenate(found) if found else np.zeros(0, np.int64)
    return np.fromiter((m.start() for m in re.finditer("\n", text)), np.int64)


class Lines:
    """A program's lines as a sequence of strings (no newline characters), held as one ``text``
    (each line ended by a newline) and the offset of each line's start: indexing cuts the line out."""

    def __init__(self, text: str, ends: np.ndarray):
        self.text = text
        starts = np.empty(len(ends) + 1, np.int64)
        starts[0] = 0
        np.add(ends, 1, out=starts[1:])
        self.starts = array("q")
        self.starts.frombytes(memoryview(starts).cast("B"))
        """each line's first character, then the text's length (one past the last newline): line
        ``k`` is ``text[starts[k]:starts[k + 1] - 1]`` (the reader's fast path cuts it so)"""

    def __len__(self) -> int:
        return len(self.starts) - 1

    def __getitem__(self, k):
        starts = self.starts
        if k.__class__ is int and k >= 0:  # the reader's every line: past the last, starts[k + 1] raises
            return self.text[starts[k]:starts[k + 1] - 1]
        if isinstance(k, slice):
            return [self[j] for j in range(*k.indices(len(self)))]
        if k < 0:
            k += len(self)
        if not 0 <= k < len(self):
            raise IndexError("line index out of range")
        return self.text[starts[k]:starts[k + 1] - 1]

    def __iter__(self):
        starts, text = self.starts, self.text
        for k in range(len(starts) - 1):
            yield text[starts[k]:starts[k + 1] - 1]

    def line_at(self, offset: int) -> int:
        """The index of the line the text's character ``offset`` is on."""
        return bisect.bisect_right(self.starts, offset) - 1

    def containing(self, pattern: re.Pattern, start: int = 0):
        """Indices (from ``start`` on, increasing) of the lines ``pattern`` matches in (searched
        in the whole text at once: compiled with ``re.MULTILINE``, ``^`` and ``$`` are a line's
        ends; a pattern must not match across a newline)."""
        if start >= len(self):
            return
        last = -1
        for match in pattern.finditer(self.text, self.starts[start]):
            k = self.line_at(match.start())
            if k != last:
                last = k
                yield k


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
        # line), without the white space that ends them. A CAM program of millions of lines is
        # kept as one text and its lines' offsets, not a list of strings (a tenth of the memory)
        newlines = _newlines(text)
        raw_ends = newlines if not text or text.endswith("\n") else np.append(newlines, len(text))
        raw_lengths = np.diff(raw_ends, prepend=-1) - 1  # each line's characters, its newline not counted
        self.escaped: dict[int, str] = {}
        """0-based index -> the line with its bytes that are not UTF-8 as surrogate escapes (the
        text :meth:`read` gives), for the lines that have some: ``lines`` holds them as U+FFFD,
        one for one"""
        body = _TRAILING_SPACE.sub("", text if not text or text.endswith("\n") else text + "\n")
        # nothing stripped (a CAM program): the same newlines
        self.lines = Lines(body, newlines if body is text else _newlines(body))
        if not text.isascii():
            for match in _ESCAPED.finditer(body):
                k = self.lines.line_at(match.start())
                self.escaped.setdefault(k, self.lines[k])
            self.lines.text = _ESCAPED.sub("\ufffd", body)  # one character for one: the offsets hold
        # LinuxCNC reads a line into 255 bytes: one of MAX_LINE bytes or more before its newline
        # (a CR counts) is "Command too long" wherever it is read, a line passed over too
        self.too_long = [int(k) for k in np.flatnonzero(raw_lengths >= MAX_LINE)
                         if _byte_length(text[raw_ends[k] - raw_lengths[k]:raw_ends[k]]) >= MAX_LINE]
        self.first, self.end, self.percent_end = 0, len(self.lines), False
        self.percent_start = False
        for k, line in enumerate(self.lines):
            if line.strip():
                if line.strip() == "%":
                    self.first, self.percent_start = k + 1, True
                    # closed by a line of "%" alone; a "%" with more on its line is read as a block
                    # (and refused there, "Bad character '%' used", as LinuxCNC does)
                    closing = self._percent_line(k + 1)
                    if closing is not None:
                        self.end, self.percent_end = closing, True
                break
        self.o_lines: dict[int, OLine] = {}
        for k in self.lines.containing(_LETTER_O):
            if not self.first <= k < self.end:
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
        return self.percent_start and self._percent_line(index + 1) is None

    def _percent_line(self, start: int) -> int | None:
        """The first line from index ``start`` on that is a ``%`` alone (white space around it)."""
        return next((k for k in self.lines.containing(_PERCENT_ALONE, start)), None)

    @property
    def text(self) -> str:
        """The lines as read, each ended by a newline (an empty file: one newline)."""
        return self.lines.text or "\n"

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
        text = data.decode("utf-8", errors="surrogateescape")
        del data  # a long program held once, as its text
        source = cls(text, Path(path).name)
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
