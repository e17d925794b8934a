"""One line of an RS274/NGC program read into a :class:`~cnc_twin.gcode.blocks.Block`, as LinuxCNC
reads it.

Outside comments, spaces and tabs are dropped and letters are lower case (``G1 X 1 0`` is
``g1x10``). ``( ... )`` is a comment anywhere in the line (no nesting), ``;`` comments out the rest
of the line; a comment keeps its own text (leading spaces dropped), and ``(msg,...)``,
``(debug,...)`` and friends are told apart by the executor. A ``/`` first is block delete. Each
word is a letter and a real value (:mod:`~cnc_twin.gcode.expressions`); ``#n=value`` and
``#<name>=value`` set parameters after the whole line is read (``#1=7 G1 X#1`` moves to the old
``#1``). Errors carry LinuxCNC's wording; the caller adds the file and line.

Most lines of a CAM program are letters with numbers, parameters and one-operator brackets: those
are read by one regular expression; every other line, and every line it would refuse, by the
character-by-character reader, which the quick one matches value for value
(``tests/test_gcode_speed_paths.py``).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from cnc_twin.gcode.expressions import (MAX_PARAMETER, ExpressionError, Parameters, binary, read_parameter_key,
                                        read_real)

WORD_LETTERS = frozenset("abcdefghijklmnpqrstuvwxyz@^$") - {"n", "o"}
"""letters that start a word (``n`` is the line number, ``o`` an O-word, read apart; ``@`` and
``^`` are the polar radius and angle, ``$`` the spindle number of LinuxCNC 2.9)"""
NEGATIVE_REFUSED = {"f": "Negative f word used", "s": "Negative spindle speed used",
                    "t": "Negative tool id (tool not found)"}
"""words LinuxCNC refuses negative as it reads them -> its message"""
REPEATABLE = frozenset("gm")
"""letters a block may hold more than once"""


class BlockError(ValueError):
    """A line LinuxCNC would refuse; the message is its wording. ``block``: what of the line
    was read before the refusal (set by the word reader), else None."""

    block: "Block | None" = None


class BadCharacter(BlockError):
    """A character no word starts with, ``char``; LinuxCNC names a printable ASCII one as it
    is, any other by its first byte in octal (``'\\357'``: a UTF-8 byte-order mark)."""

    def __init__(self, char: str):
        self.char = char
        if "!" <= char <= "z":
            super().__init__(f"Bad character '{char}' used")
        else:
            super().__init__(f"Bad character '\\{first_byte(char):03o}' used")


def first_byte(char: str) -> int:
    """The first byte of ``char`` in the file: UTF-8, or the byte itself for one that was not
    UTF-8 (read as a surrogate escape, :meth:`~cnc_twin.gcode.source.Source.read`)."""
    try:
        return char.encode("utf-8", "surrogateescape")[0]
    except UnicodeEncodeError:  # a lone surrogate that is no escaped byte
        return char.encode("utf-8", "surrogatepass")[0]


_ASCII_LOWER = {c: c + 32 for c in range(ord("A"), ord("Z") + 1)}


def _lower(text: str) -> str:
    """``text`` with its ASCII capitals in lower case, the only ones LinuxCNC lowers (``É``
    stays, and a parameter ``#<É>`` is not ``#<é>``)."""
    return text.lower() if text.isascii() else text.translate(_ASCII_LOWER)


@dataclass
class Block:
    """One line, read.

    ``words``: letter -> value for every word but G and M; ``g`` / ``m``: their values in the
    order written; ``comments``: comment texts in order; ``assignments``: ``(index or name,
    value)`` to apply after the line; ``number``: the N word; ``block_delete``: a ``/`` first;
    ``o_word``: the text after ``o`` (name and keyword, normalised), or None; ``number_text``:
    the N word as written.
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
    number_text: str | None = None
    """the N word's digits as written (``N0030`` -> ``0030``), for the call lines; None without N"""
    codes: str = ""
    """the letters of the G and M words in the order written (``"mg"``): LinuxCNC checks each
    code as it reads it (:func:`~cnc_twin.gcode.modal.read_codes`)"""

    @property
    def empty(self) -> bool:
        return not (self.words or self.g or self.m or self.comments or self.assignments or self.o_word)


def normalise(text: str) -> tuple[str, list[str]]:
    """``text`` (one line, no newline) as LinuxCNC reads it: lower case without spaces outside
    comments, and the comments' texts apart."""
    if "(" not in text and ";" not in text:  # most lines: no comment, one pass of replaces
        if ")" in text:
            raise BlockError("Bad character ')' used")
        return _lower(text.replace(" ", "").replace("\t", "").replace("\r", "")), []
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
    return _lower("".join(out).replace(" ", "").replace("\t", "").replace("\r", "")), comments


def read_block(text: str, line: int, params: Parameters) -> Block:
    """Read one line (``line`` is its number in the file, for messages and the trace)."""
    stripped = text.lstrip(" \t")
    block_delete = stripped.startswith("/")
    if block_delete:
        stripped = stripped[1:]
    norm, comments = normalise(stripped)
    block = _simple_block(norm, line, block_delete, comments, params)
    if block is None:  # anything else, and every refusal, is read character by character
        block = _full_block(norm, Block(line=line, block_delete=block_delete, comments=comments), params)
    if block.number is not None:
        block.number_text = n_text(text)
    return block


def _full_block(norm: str, block: Block, params: Parameters) -> Block:
    """The words of ``norm`` read one character at a time into ``block``, with LinuxCNC's
    refusals."""
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
                if c == "l":
                    _check_l_word(value, "l" in block.words)
                if c in REPEATABLE:
                    (block.g if c == "g" else block.m).append(value)
                    block.codes += c
                elif c in block.words:
                    raise BlockError(f"Multiple {c} words on one line")
                else:
                    block.words[c] = value
            else:
                raise BadCharacter(c)
    except ExpressionError as exc:
        error = BlockError(str(exc))
        error.block = block
        raise error from None
    except BlockError as exc:
        exc.block = block
        raise
    return block


def _whole(value: float) -> bool:
    """``value`` reads as a whole number of at least 0 (LinuxCNC's read_integer_value: within
    1e-4 of one)."""
    if not math.isfinite(value):
        return False
    frac = value - math.floor(value)
    return (frac > 0.9999 or frac <= 0.0001) and round(value) >= 0


def _check_l_word(value: float, repeated: bool) -> None:
    """An L word (repeats, a G10 mode, a NURBS order) as LinuxCNC reads it (its read_l), in its
    order: a second L, a value that is not a whole number, a negative one."""
    if repeated:
        raise BlockError("Multiple l words on one line")
    if not math.isfinite(value) or 0.0001 < value - math.floor(value) <= 0.9999:
        raise BlockError("Non integer value for integer")
    if round(value) < 0:
        raise BlockError("Negative l word used")


# The common line, read by one regular expression: an optional N word, then words whose value
# is a plain number, a parameter, or a bracket of one operand or two around + - * /. A line of
# that shape reads exactly as character by character (same values, in the same order); any other
# line, or one whose reading would be refused, is left to the full reader. Quantifiers are
# possessive (a number is always read whole, as the full reader reads it), so a long run of
# digits never makes the expression backtrack.
NUMBER = r"[+-]?+(?:[0-9]++(?:\.[0-9]*+)?+|\.[0-9]++)"
"""a plain number as LinuxCNC reads one (no exponent), possessive: read whole or not at all"""
_PARAMETER = r"([+-]?+)#(?:<([^>]++)>|([0-9]{1,9}+))"  # sign, name | index (more digits: the full reader)
_SIMPLE_WORD = re.compile(
    rf"([a-mp-z@^$])(?:({NUMBER})|\[(?:({NUMBER})|{_PARAMETER})(?:([-+*/])(?:({NUMBER})|{_PARAMETER}))?+\]"
    rf"|{_PARAMETER})|.", re.DOTALL)
"""a word: its letter, then a number | a bracket (number | parameter, then an operator and
number | parameter) | a parameter; anything else matches as one character, every group empty"""
_N_WORD = re.compile(r"n([0-9]++)[0-9.]*+")


def _operand(plain: str, name: str, index: str, sign: str, name_of, params) -> float:
    """One operand of a quick-path bracket: a plain number, or a parameter (named or numbered)
    with its sign."""
    if plain:
        return float(plain)
    value = name_of(name) if name else _numbered(index, params)
    return -value if sign == "-" else value


def _simple_block(norm: str, line: int, block_delete: bool, comments: list[str], params: Parameters) -> Block | None:
    """``norm`` read as :data:`_SIMPLE_WORD` words, or None when it is not made of them only or
    its reading would be refused."""
    number, pos = None, 0
    if norm.startswith("n"):
        match = _N_WORD.match(norm)
        if match is None:
            return None
        number, pos = int(match.group(1)), match.end()
    words: dict[str, float] = {}
    g: list[float] = []
    m: list[float] = []
    codes = ""
    name_of = params.name
    try:
        for (letter, plain, a_plain, a_sign, a_name, a_index, op, b_plain, b_sign, b_name, b_index, sign, name,
             index) in _SIMPLE_WORD.findall(norm, pos):
            if plain:
                value = float(plain)
            elif not letter:  # a character no simple word starts with
                return None
            elif name or index:
                value = name_of(name) if name else _numbered(index, params)
                if sign == "-":
                    value = -value
            else:  # a bracket
                value = _operand(a_plain, a_name, a_index, a_sign, name_of, params)
                if op:
                    right = _operand(b_plain, b_name, b_index, b_sign, name_of, params)
                    value = value * right if op == "*" else binary(op, value, right)  # binary's product
                if not math.isfinite(value):  # the bracket's refusal
                    return None
            if letter == "g":
                g.append(value)
                codes += "g"
            elif letter == "m":
                m.append(value)
                codes += "m"
            elif (letter in words or (value < 0.0 and letter in NEGATIVE_REFUSED)
                  or (letter == "l" and not _whole(value))):
                return None
            else:
                words[letter] = value
    except ExpressionError:
        return None
    return Block(line, number, block_delete, words, g, m, comments, [], codes=codes)


def _numbered(index: str, params: Parameters) -> float:
    """The value of ``#index`` (its digits), as the full reader reads it."""
    number = int(index)
    if not 1 <= number <= MAX_PARAMETER:
        raise ExpressionError("Parameter number out of range")
    return params.number(number)


_N_DIGITS = re.compile(r"[ \t/]*.([0-9]*)", re.DOTALL)


def n_text(raw: str) -> str:
    """The N word's digits as written in the raw line (``N0030`` -> ``0030``, spaces dropped)."""
    match = _N_DIGITS.match(raw)
    if match is not None:
        end = match.end()
        if end == len(raw) or not (raw[end] in " \t" or raw[end].isdigit()):
            return match.group(1)
    digits = []
    for c in raw.lstrip(" \t/")[1:]:
        if c.isdigit():
            digits.append(c)
        elif c not in " \t":
            break
    return "".join(digits)


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
