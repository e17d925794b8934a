"""One line of an RS274/NGC program read into a :class:`Block`, as LinuxCNC reads it.

Outside comments, spaces and tabs are dropped and letters are lower case (``G1 X 1 0`` is
``g1x10``). ``( ... )`` is a comment anywhere in the line (no nesting), ``;`` comments out the rest
of the line; a comment keeps its own text (leading spaces dropped), and ``(msg,...)``,
``(debug,...)`` and friends are told apart by the executor. A ``/`` first is block delete. Each
word is a letter and a real value (:mod:`~cnc_twin.gcode.expressions`); ``#n=value`` and
``#<name>=value`` set parameters after the whole line is read (``#1=7 G1 X#1`` moves to the old
``#1``). Errors carry LinuxCNC's wording; the caller adds the file and line.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from cnc_twin.gcode.expressions import ExpressionError, Parameters, read_parameter_key, read_real

WORD_LETTERS = frozenset("abcdefghijklmnpqrstuvwxyz@^$") - {"n", "o"}
"""letters that start a word (``n`` is the line number, ``o`` an O-word, read apart; ``@`` and
``^`` are the polar radius and angle, ``$`` the spindle number of LinuxCNC 2.9)"""
NEGATIVE_REFUSED = {"f": "Negative f word used", "s": "Negative spindle speed used",
                    "t": "Negative tool id (tool not found)"}
"""words LinuxCNC refuses negative as it reads them -> its message"""
REPEATABLE = frozenset("gm")
"""letters a block may hold more than once"""


class BlockError(ValueError):
    """A line LinuxCNC would refuse; the message is its wording."""


@dataclass
class Block:
    """One line, read.

    ``words``: letter -> value for every word but G and M; ``g`` / ``m``: their values in the
    order written; ``comments``: comment texts in order; ``assignments``: ``(index or name,
    value)`` to apply after the line; ``number``: the N word; ``block_delete``: a ``/`` first;
    ``o_word``: the text after ``o`` (name and keyword, normalised), or None.
    """

    line: int
    number: int | None = None
    block_delete: bool = False
    words: dict[str, float] = field(default_factory=dict)
    g: list[float] = field(default_factory=list)
    m: list[float] = field(default_factory=list)
    comments: list[str] = field(default_factory=list)
    assignments: list[tuple[int | str, float]] = field(default_factory=list)
    o_word: str | None = None

    @property
    def empty(self) -> bool:
        return not (self.words or self.g or self.m or self.comments or self.assignments or self.o_word)


def normalise(text: str) -> tuple[str, list[str]]:
    """``text`` (one line, no newline) as LinuxCNC reads it: lower case without spaces outside
    comments, and the comments' texts apart."""
    comments: list[str] = []
    out: list[str] = []
    k, n = 0, len(text)
    while k < n:
        # whole stretches between comments at a time: a program is mostly such stretches
        opening, semicolon = text.find("(", k), text.find(";", k)
        end = min(x for x in (opening, semicolon, n) if x >= 0)
        chunk = text[k:end]
        if ")" in chunk:
            raise BlockError("Bad character ')' used")
        out.append(chunk)
        if end == n or end == semicolon:
            break
        close = text.find(")", end + 1)
        if close < 0:
            raise BlockError("Unclosed comment found")
        inner = text[end + 1:close]
        if "(" in inner:
            raise BlockError("Nested comment found")
        comments.append(inner.lstrip(" \t"))
        k = close + 1
    return "".join(out).replace(" ", "").replace("\t", "").replace("\r", "").lower(), comments


def read_block(text: str, line: int, params: Parameters) -> Block:
    """Read one line (``line`` is its number in the file, for messages and the trace)."""
    block = Block(line=line)
    stripped = text.lstrip(" \t")
    if stripped.startswith("/"):
        block.block_delete = True
        stripped = stripped[1:]
    norm, block.comments = normalise(stripped)
    pos = 0
    if norm.startswith("n"):
        pos = 1
        while pos < len(norm) and (norm[pos].isdigit() or norm[pos] == "."):
            pos += 1
        digits = norm[1:pos].split(".")[0]
        if not digits:
            raise BlockError("Bad format unsigned integer")
        block.number = int(digits)
    if norm.startswith("o", pos):
        block.o_word = norm[pos + 1:]
        return block
    try:
        while pos < len(norm):
            c = norm[pos]
            if c == "#":
                pos = _assignment(norm, pos, params, block)
            elif c in WORD_LETTERS:
                value, pos = read_real(norm, pos + 1, params)
                if value < 0.0 and c in NEGATIVE_REFUSED:
                    raise BlockError(NEGATIVE_REFUSED[c])
                if c in REPEATABLE:
                    (block.g if c == "g" else block.m).append(value)
                elif c in block.words:
                    raise BlockError(f"Multiple {c} words on one line")
                else:
                    block.words[c] = value
            else:
                raise BlockError(f"Bad character '{c}' used" if c.isprintable() else "Bad character used")
    except ExpressionError as exc:
        raise BlockError(str(exc)) from None
    return block


def _assignment(norm: str, pos: int, params: Parameters, block: Block) -> int:
    """``#index=value`` or ``#<name>=value`` at ``norm[pos]``; the index after it."""
    key, pos = read_parameter_key(norm, pos, params)
    params.check_assignable(key)
    if isinstance(key, str):
        # the name exists from here on in the line (0 until the line's settings apply), as in
        # LinuxCNC: `#<d>=-3 Z#<d>` reads 0, `#<e>=[#<e>+1]` sets 1; read before it, not defined
        params.named.setdefault(key, 0.0)
    if not norm.startswith("=", pos):
        raise BlockError("Equal sign missing in parameter setting")
    value, pos = read_real(norm, pos + 1, params)
    block.assignments.append((key, value))
    return pos


def apply_assignments(block: Block, params: Parameters) -> None:
    """The line's parameter settings, once it has been read whole (left to right)."""
    for key, value in block.assignments:
        if isinstance(key, str):
            params.named[key] = value
        else:
            params.numbered[key] = value
