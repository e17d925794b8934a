"""RS274/NGC expressions as LinuxCNC evaluates them: ``[...]`` with binary operators, unary
functions, parameters; never Python's ``eval``.

Input is a block's text already normalised the way LinuxCNC reads it (lower case, no spaces or
tabs outside comments). Semantics, each checked against LinuxCNC's own interpreter
(``tests/test_gcode_expressions.py``):

- binary operators, tightest first: ``**``; ``* / mod``; ``+ -``; ``eq ne gt ge lt le``;
  ``and or xor``; each level left to right (``2**3**2`` is 64);
- a sign belongs to the value after it (``-2**2`` is 4, ``--2`` is 2, ``-[2]``, ``-#1``);
- ``eq`` / ``ne`` compare within 1e-4; the other comparisons are exact; results are 1 or 0;
  ``and or xor`` take any non-zero value as true;
- ``mod`` is never negative for a positive divisor (``-7 mod 3`` is 2);
- functions ``abs acos asin cos exp fix fup ln round sin sqrt tan`` take ``[...]``, angles in
  degrees; ``atan[y]/[x]`` is the two-argument arc tangent; ``round`` rounds half away from
  zero; ``fix`` / ``fup`` are floor / ceiling; ``exists[#<name>]`` is 1 if the parameter exists;
- numbers are digits with at most one point (no exponent: ``1e3`` is an error);
- errors carry LinuxCNC's wording (``Attempt to divide by zero``, ``Negative argument to sqrt``...).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable

from cnc_twin.gcode.long_double import to_degrees, trig

EQUAL_TOLERANCE = 1e-4
"""``eq`` / ``ne`` treat values closer than this as equal (LinuxCNC's tolerance)"""
INTEGER_TOLERANCE = 1e-4
"""a value this close to a whole number is that number where an integer is needed"""
MAX_PARAMETER = 5601
"""highest numbered parameter a program may name (``#1`` .. ``#5601``: LinuxCNC keeps 5602, ``#0``
unused)"""

# binary operators by precedence (higher binds tighter), longest spelling first where they share a start
_OPERATORS = (("**", 4), ("*", 3), ("/", 3), ("mod", 3), ("+", 2), ("-", 2), ("eq", 1), ("ne", 1), ("gt", 1),
              ("ge", 1), ("lt", 1), ("le", 1), ("and", 0), ("or", 0), ("xor", 0))
_OPERATOR_INITIALS = frozenset(name[0] for name, _ in _OPERATORS if name[0].isalpha())
_FUNCTIONS = ("abs", "acos", "asin", "atan", "cos", "exists", "exp", "fix", "fup", "ln", "round", "sin", "sqrt",
              "tan")
_FUNCTION_INITIALS = frozenset(name[0] for name in _FUNCTIONS)


class ExpressionError(ValueError):
    """A program's expression LinuxCNC would refuse; the message is its wording."""


class Parameters:
    """The values ``#n`` and ``#<name>`` read: numbered ones default to 0, named ones must exist.

    ``numbered``: index -> value; ``named``: lower-case name -> value.
    """

    def __init__(self):
        self.numbered: dict[int, float] = {}
        self.named: dict[str, float] = {}
        self.live_numbered: dict[int, Callable[[], float]] = {}
        """read-only parameters computed from the interpreter's state when read (``#5420``...)"""
        self.live_named: dict[str, Callable[[], float]] = {}
        """read-only named parameters computed when read (``#<_x>``, ``#<_metric>``...)"""
        self.read_only_named: set[str] = set()
        """stored named parameters only the interpreter sets (``#<_value>``...)"""

    def check_assignable(self, key: int | str) -> None:
        """LinuxCNC's refusal of a program's setting of a read-only parameter: the live ones
        (``#5420``, ``#<_x>``...) and those the interpreter keeps for itself."""
        if isinstance(key, str):
            if key in self.live_named or key in self.read_only_named:
                raise ExpressionError(f"Cannot assign to read-only parameter #<{key}>")
        elif key in self.live_numbered:
            raise ExpressionError("Parameter is readonly")

    def number(self, index: int) -> float:
        live = self.live_numbered.get(index)
        if live is not None:
            return live()
        return self.numbered.get(index, 0.0)

    def name(self, name: str) -> float:
        live = self.live_named.get(name)
        if live is not None:
            return live()
        try:
            return self.named[name]
        except KeyError:
            raise ExpressionError(f"Named parameter #<{name}> not defined") from None

    def has_name(self, name: str) -> bool:
        return name in self.named or name in self.live_named


def evaluate(text: str, pos: int, params: Parameters) -> tuple[float, int]:
    """The value of the bracketed expression starting at ``text[pos]`` (``'['``) and the index
    just after its closing ``']'``."""
    return _Reader(text, params).expression(pos)


def read_real(text: str, pos: int, params: Parameters) -> tuple[float, int]:
    """A real value at ``text[pos]`` (a number, ``[...]``, a parameter, a function, with an
    optional sign) and the index after it: what follows a word's letter."""
    plain = _plain_number(text, pos)  # most words are a plain number: read it without a reader
    return plain if plain is not None else _Reader(text, params).real(pos)


def read_parameter_key(text: str, pos: int, params: Parameters) -> tuple[int | str, int]:
    """The parameter ``#n`` or ``#<name>`` at ``text[pos]`` (``'#'``) names, and the index after
    it: what a parameter setting assigns to."""
    return _Reader(text, params).key(pos)


def integer_of(value: float) -> int:
    """``value`` as a whole number, or LinuxCNC's error when it is not close to one."""
    whole = round(value)
    if abs(value - whole) >= INTEGER_TOLERANCE:
        raise ExpressionError("Non integer value for integer")
    return int(whole)


_PLAIN = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)")
"""a signed number with at most one point"""
_DIGITS = re.compile(r"[0-9.]*")


def _plain_number(text: str, pos: int) -> tuple[float, int] | None:
    """A signed number at ``text[pos]`` and the index after it, or None when what is there is
    more (an expression, a parameter...) or a malformed number (the reader then says why)."""
    plain = _PLAIN.match(text, pos)
    if plain is None or (plain.end() < len(text) and text[plain.end()] == "."):
        return None
    return float(plain.group()), plain.end()
_RANKS = dict(_OPERATORS)


def _operator_at(text: str, pos: int) -> tuple[str, int] | None:
    """The binary operator at ``text[pos]`` (the longest spelling that fits), or None."""
    for width in (3, 2, 1):
        name = text[pos:pos + width]
        rank = _RANKS.get(name)
        if rank is not None:
            return name, rank
    return None


class _Reader:
    def __init__(self, text: str, params: Parameters):
        self.text, self.params = text, params

    def expression(self, pos: int) -> tuple[float, int]:
        """``[`` value (operator value)* ``]``, reduced by precedence, left to right."""
        text = self.text
        values: list[float] = []
        ops: list[tuple[str, int]] = []
        pos += 1  # the '['
        value, pos = self.real(pos)
        values.append(value)
        while True:
            if pos < len(text) and text[pos] == "]":
                break
            op = _operator_at(text, pos)
            if op is None and pos >= len(text):
                raise ExpressionError("Unclosed expression")
            if op is None:
                if pos < len(text) and text[pos] in _OPERATOR_INITIALS:
                    raise ExpressionError(f"Unknown operation name starting with {text[pos]}")
                raise ExpressionError("Unknown operation")
            pos += len(op[0])
            while ops and ops[-1][1] >= op[1]:
                self._reduce(values, ops)
            ops.append(op)
            value, pos = self.real(pos)
            values.append(value)
        while ops:
            self._reduce(values, ops)
        # checked once per bracket, as LinuxCNC does: a NaN inside may still compare to 0 or 1
        return _finite(values[0]), pos + 1

    @staticmethod
    def _reduce(values: list[float], ops: list[tuple[str, int]]) -> None:
        right, left = values.pop(), values.pop()
        values.append(binary(ops.pop()[0], left, right))

    def real(self, pos: int) -> tuple[float, int]:
        text = self.text
        if pos >= len(text):
            raise ExpressionError("No characters found in reading real value")
        c = text[pos]
        if c == "[":
            return self.expression(pos)
        plain = _plain_number(text, pos)
        if plain is not None:
            return plain
        if c in "+-":
            value, pos = self.real(pos + 1)
            return (-value if c == "-" else value), pos
        if c == "#":
            return self.parameter(pos)
        if "a" <= c <= "z":  # LinuxCNC reads a lower-case ASCII letter as a function's name
            return self.function(pos)
        return self.number(pos)

    def number(self, pos: int) -> tuple[float, int]:
        text = self.text
        end = _DIGITS.match(text, pos).end()
        token = text[pos:end]
        if token.count(".") > 1:
            raise ExpressionError(f"bad number format (trailing characters) parsing '{token}'")
        if not any(ch.isdigit() for ch in token):
            raise ExpressionError(f"bad number format (conversion failed) parsing '{token}'")
        return float(token), end

    def key(self, pos: int) -> tuple[int | str, int]:
        """The parameter named at ``text[pos]`` (``'#'``): a name, or an index in range."""
        text = self.text
        if pos + 1 < len(text) and text[pos + 1] == "<":
            end = text.find(">", pos + 2)
            if end < 0:
                raise ExpressionError("Named parameter not terminated")
            return text[pos + 2:end], end + 1
        value, pos = self.real(pos + 1)
        index = integer_of(value)
        if not 1 <= index <= MAX_PARAMETER:
            raise ExpressionError("Parameter number out of range")
        return index, pos

    def parameter(self, pos: int) -> tuple[float, int]:
        key, pos = self.key(pos)
        return (self.params.name(key) if isinstance(key, str) else self.params.number(key)), pos

    def function(self, pos: int) -> tuple[float, int]:
        text = self.text
        name = next((f for f in _FUNCTIONS if text.startswith(f, pos)), None)
        if name is None:
            # LinuxCNC names the first letter when a function starts with it, as its binary
            # operators do theirs (``Unknown operation name starting with ...``)
            if text[pos] in _FUNCTION_INITIALS:
                raise ExpressionError(f"Unknown word starting with {text[pos]}")
            raise ExpressionError("Unknown word where unary operation could be")
        pos += len(name)
        if pos >= len(text) or text[pos] != "[":
            raise ExpressionError("Left bracket missing after unary operation name")
        if name == "exists":
            return self.exists(pos)
        value, pos = self.expression(pos)
        if name == "atan":
            if pos >= len(text) or text[pos] != "/":
                raise ExpressionError("Slash missing after first atan argument")
            if pos + 1 >= len(text) or text[pos + 1] != "[":
                raise ExpressionError("Left bracket missing after slash with atan")
            x, pos = self.expression(pos + 1)
            return to_degrees(math.atan2(value, x)), pos
        return unary(name, value), pos

    def exists(self, pos: int) -> tuple[float, int]:
        text = self.text
        if text[pos + 1:pos + 2] != "#":
            raise ExpressionError("Expected # reading parameter")
        if text[pos + 2:pos + 3] == "<":
            end = text.find(">", pos + 3)
            if end < 0 or text[end + 1:end + 2] != "]":
                raise ExpressionError("Unknown operation")
            return (1.0 if self.params.has_name(text[pos + 3:end]) else 0.0), end + 2
        _, end = self.parameter(pos + 1)  # a numbered parameter always exists
        if text[end:end + 1] != "]":
            raise ExpressionError("Unknown operation")
        return 1.0, end + 1


def binary(op: str, a: float, b: float) -> float:
    """``a op b`` as LinuxCNC computes it (comparisons and logic give 1.0 / 0.0); a NaN or an
    infinity is left for the enclosing bracket to refuse."""
    if op == "**":
        if a < 0 and b != math.floor(b):
            raise ExpressionError("Attempt to raise negative to non integer power")
        try:
            result = math.pow(a, b)
        except OverflowError:
            result = math.inf
        except ValueError:  # 0 ** negative (C's pow gives an infinity); NaN operands
            result = math.inf if a == 0.0 else math.nan
    elif op == "*":
        result = a * b
    elif op == "/":
        if b == 0.0:
            raise ExpressionError("Attempt to divide by zero")
        result = a / b
    elif op == "mod":
        result = math.fmod(a, b) if b != 0.0 and math.isfinite(a) else math.nan
        if result < 0.0:
            result += abs(b)
    elif op == "+":
        result = a + b
    elif op == "-":
        result = a - b
    elif op == "eq":
        result = float(abs(a - b) < EQUAL_TOLERANCE)
    elif op == "ne":
        result = float(not abs(a - b) < EQUAL_TOLERANCE)
    elif op == "gt":
        result = float(a > b)
    elif op == "ge":
        result = float(a >= b)
    elif op == "lt":
        result = float(a < b)
    elif op == "le":
        result = float(a <= b)
    elif op == "and":
        result = float(a != 0.0 and b != 0.0)
    elif op == "or":
        result = float(a != 0.0 or b != 0.0)
    else:  # xor
        result = float((a != 0.0) != (b != 0.0))
    return result


_UNARY: dict[str, Callable[[float], float]] = {
    "abs": abs,
    "cos": lambda x: trig("cos", x),
    "sin": lambda x: trig("sin", x),
    "tan": lambda x: trig("tan", x),
    "exp": lambda x: math.exp(x) if x < 709.0 else math.inf,
    "fix": lambda x: float(math.floor(x)),
    "fup": lambda x: float(math.ceil(x)),
    "round": lambda x: math.copysign(math.floor(abs(x) + 0.5), x),
}


def unary(name: str, x: float) -> float:
    """A unary function of LinuxCNC's (angles in degrees)."""
    if name == "acos" or name == "asin":
        if not -1.0 <= x <= 1.0:
            raise ExpressionError(f"Argument to {name} out of range")
        return to_degrees(math.acos(x) if name == "acos" else math.asin(x))
    if name == "ln":
        if x <= 0.0:
            raise ExpressionError("Zero or negative argument to ln")
        return math.log(x)
    if name == "sqrt":
        if x < 0.0:
            raise ExpressionError("Negative argument to sqrt")
        return math.sqrt(x)
    return _finite(_UNARY[name](x))


def _finite(value: float) -> float:
    if math.isnan(value):
        raise ExpressionError("Calculation resulted in 'not a number'")
    if math.isinf(value):
        raise ExpressionError("Calculation resulted in 'infinity'")
    return value
