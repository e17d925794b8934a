"""G-code expressions against LinuxCNC's interpreter: a table of values and errors (each row was
first seen from `rs274`, and the oracle tests re-run them whenever it is unpacked), and a few
hundred random expressions whose values must agree to LinuxCNC's four printed decimals."""

from __future__ import annotations

import random

import pytest

import oracle
from cnc_twin.gcode.expressions import ExpressionError, Parameters, evaluate

# (expression as written in a program, value or LinuxCNC's error message)
TABLE = [
    ("2+3*4", 14.0), ("2**3**2", 64.0), ("-2**2", 4.0), ("[-2]**2", 4.0), ("2*-3", -6.0), ("3-2-1", 0.0),
    ("10/4*2", 5.0), ("2 ** -1", 0.5), ("1 + + 2", 3.0), ("--2", 2.0), ("-[2]", -2.0), ("-sin[30]", -0.5),
    ("7 mod 3", 1.0), ("-7 mod 3", 2.0), ("7 mod -3", 1.0), ("2.5 mod 1", 0.5), ("5 MOD 2.5", 0.0),
    ("round[2.5]", 3.0), ("round[-2.5]", -3.0), ("round[0.5]", 1.0), ("round[-0.5]", -1.0), ("round[1.49999]", 1.0),
    ("fix[-2.5]", -3.0), ("fup[-2.5]", -2.0), ("fix[-0.00001]", -1.0), ("fix[2.999999999]", 2.0),
    ("1 eq 1", 1.0), ("2 gt 1 and 0", 0.0), ("1 or 0 * 5", 1.0), ("1 xor 1", 0.0), ("0.5 and 2", 1.0),
    ("1 lt 2 lt 3", 1.0), ("3 ne 3.00001", 0.0), ("3 ne 3.0001", 1.0), ("3 eq 3.00009", 1.0),
    ("1 eq 1.0000000001", 1.0), ("3 ge 3.00001", 0.0), ("3 le 2.99999", 0.0), ("3 lt 3.00001", 1.0),
    ("atan[1]/[1]", 45.0), ("atan[-1]/[-1]", -135.0), ("sin[30]", 0.5), ("asin[1]", 90.0), ("abs[-3]", 3.0),
    ("ABS[-1]", 1.0), ("exp[1]", 2.718281828459045), ("ln[2.718281828]", 1.0), ("2**0.5", 2 ** 0.5),
    ("0**0", 1.0), ("1.", 1.0), (".5", 0.5), ("+3", 3.0), ("[1]", 1.0), ("[[2]]", 2.0),
    ("#1", 2.0), ("-#1", -2.0), ("#[1]", 2.0), ("##1", 0.0), ("#<v>", 3.0), ("-#<v>", -3.0), ("#5000", 0.0),
    ("#1.00001", 2.0), ("exists[#<_foo>]", 0.0), ("exists[#<v>]", 1.0), ("exists[#1]", 1.0),
    ("sqrt[-1]", "Negative argument to sqrt"), ("1/0", "Attempt to divide by zero"),
    ("1e3", "Unknown operation name starting with e"), ("acos[2]", "Argument to acos out of range"),
    ("asin[2]", "Argument to asin out of range"), ("[-8]**[1/3]", "Attempt to raise negative to non integer power"),
    ("2 mod 0", "Calculation resulted in 'not a number'"), ("0**-1", "Calculation resulted in 'infinity'"),
    ("1.2.3", "bad number format (trailing characters) parsing '1.2.3'"),
    ("1 and", "bad number format (conversion failed) parsing ''"), ("1 foo 2", "Unknown operation"),
    ("sqrt[4", "Unknown operation"), ("atan[1]", "Slash missing after first atan argument"),
    ("atan[1]/2", "Left bracket missing after slash with atan"), ("sin 30", "Left bracket missing after unary operation name"),
    ("exists[1]", "Expected # reading parameter"), ("ln[0]", "Zero or negative argument to ln"),
    ("#<foo>", "Named parameter #<foo> not defined"), ("#1.5", "Non integer value for integer"),
    ("#0", "Parameter number out of range"), ("#6000", "Parameter number out of range"),
    ("#-1", "Parameter number out of range"),
    ("2 mod 0 ge 1", 0.0), ("[2 mod 0] ge 1", "Calculation resulted in 'not a number'"),
    ("exp[1000] gt 1", "Calculation resulted in 'infinity'"), ("1 ax 2", "Unknown operation name starting with a"),
    ("1 q 2", "Unknown operation"),
    # a name LinuxCNC does not know where a value starts (first, after a sign or an operator):
    # named by its first letter when a function starts with it, as a binary operator is
    ("foo[1]", "Unknown word starting with f"), ("1 + rnd[2]", "Unknown word starting with r"),
    ("abc[1]", "Unknown word starting with a"), ("aco[1]", "Unknown word starting with a"),
    ("csc[1]", "Unknown word starting with c"), ("2 * exits[#1]", "Unknown word starting with e"),
    ("lg[2]", "Unknown word starting with l"), ("-sqr[4]", "Unknown word starting with s"),
    ("1 - tn[1]", "Unknown word starting with t"), ("bar[1]", "Unknown word where unary operation could be"),
    ("1 / pi", "Unknown word where unary operation could be"), ("1 and x", "Unknown word where unary operation could be"),
    ("cosh[1]", "Left bracket missing after unary operation name"), ("1 gtx 2", "Unknown word where unary operation could be"),
    ("1 am 2", "Unknown operation name starting with a"), ("1 md 2", "Unknown operation name starting with m"),
    ("1 on 2", "Unknown operation name starting with o"), ("1 xr 2", "Unknown operation name starting with x"),
    ("1 en 2", "Unknown operation name starting with e"), ("1 nq 2", "Unknown operation name starting with n"),
    ("1 gq 2", "Unknown operation name starting with g"), ("1 lq 2", "Unknown operation name starting with l"),
    ("1 b 2", "Unknown operation"), ("1 # 2", "Unknown operation"),
]
SETUP = "#1=2\n#<v>=3\n"
"""parameters the table's rows read, set the same way for both readers"""


def _ours(expression: str) -> float | str:
    """Our value of ``G1 X[expression]`` (the block normalised as LinuxCNC reads it), or our error."""
    params = Parameters()
    params.numbered[1], params.named["v"] = 2.0, 3.0
    text = "g1x[" + expression.lower().replace(" ", "") + "]f100"
    try:
        value, end = evaluate(text, 3, params)
    except ExpressionError as exc:
        return str(exc)
    if text[end:] != "f100":
        return "Unknown operation"  # the block goes on with what is not a word
    return value


@pytest.mark.parametrize("expression, expected", TABLE, ids=[row[0] for row in TABLE])
def test_expression_table(expression, expected):
    ours = _ours(expression)
    if isinstance(expected, str):
        assert ours == expected
    else:
        assert ours == pytest.approx(expected, abs=5e-5)


def _oracle_x(calls) -> float | None:
    feeds = oracle.straight_feeds(calls)
    return float(feeds[0][0]) if feeds else None


def test_the_table_is_what_linuxcnc_says(tmp_path):
    """Each row through `rs274`: the values in one program, a move each, the same to its four
    decimals; each refusal in a program of its own, its error message."""
    oracle.require()
    values = [(e, v) for e, v in TABLE if not isinstance(v, str)]
    calls, said = oracle.run("G21 G90\n" + SETUP + "".join(f"G1 X[{e}] F100\n" for e, _ in values) + "M2\n",
                             tmp_path / "values")
    xs = [float(feed[0]) for feed in oracle.straight_feeds(calls)]
    assert said == [] and len(xs) == len(values)
    assert [(e, x) for (e, _), x in zip(values, xs) if f"{_ours(e):.4f}" != f"{x:.4f}"] == []
    for k, (expression, message) in enumerate((e, v) for e, v in TABLE if isinstance(v, str)):
        calls, said = oracle.run(f"G21 G90\n{SETUP}G1 X[{expression}] F100\nM2\n", tmp_path / str(k))
        assert _oracle_x(calls) is None and said and said[0].startswith(_ours(expression)), (expression, said)


def _random_expression(rng: random.Random, depth: int = 0) -> str:
    """An expression over numbers, parameters, operators and functions (no domain errors
    avoided: what errors for us must error for LinuxCNC, checked in one program per error)."""
    if depth > 3 or rng.random() < 0.3:
        kind = rng.random()
        if kind < 0.6:
            return rng.choice(["", "-"]) + f"{rng.uniform(0, 20):.{rng.randint(0, 3)}f}"
        if kind < 0.8:
            return rng.choice(["#1", "#<v>", "-#1", "#2"])
        name = rng.choice(["abs", "cos", "sin", "tan", "fix", "fup", "round", "sqrt", "exp", "ln"])
        return f"{name}[{_random_expression(rng, depth + 1)}]"
    op = rng.choice(["+", "-", "*", "/", "**", "mod", "eq", "ne", "gt", "ge", "lt", "le", "and", "or", "xor"])
    left, right = _random_expression(rng, depth + 1), _random_expression(rng, depth + 1)
    return f"[{left} {op} {right}]" if rng.random() < 0.5 else f"{left} {op} {right}"


def test_random_expressions_agree_with_linuxcnc(tmp_path):
    """400 random expressions: those we evaluate go to `rs274` in one program (one move each),
    the same values to four decimals; those we refuse, LinuxCNC refuses with the same words
    (the first 20, one program each)."""
    oracle.require()
    rng = random.Random(20261124)
    good, bad = [], []
    for _ in range(400):
        expression = _random_expression(rng)
        ours = _ours(expression)
        if isinstance(ours, str):
            bad.append((expression, ours))
        elif abs(ours) < 1e9:  # beyond, four printed decimals are below a double's resolution
            good.append((expression, ours))
    program = "G21 G90\n" + SETUP + "".join(f"G1 X[{e}] F100\n" for e, _ in good) + "M2\n"
    calls, said = oracle.run(program, tmp_path / "good")
    xs = [float(feed[0]) for feed in oracle.straight_feeds(calls)]
    assert said == [] and len(xs) == len(good)
    differing = [(e, v, x) for (e, v), x in zip(good, xs) if f"{v:.4f}" != f"{x:.4f}"]
    assert differing == []
    assert len(good) > 200 and len(bad) > 20
    for k, (expression, message) in enumerate(bad[:20]):
        calls, said = oracle.run(f"G21 G90\n{SETUP}G1 X[{expression}] F100\nM2\n", tmp_path / f"bad{k}")
        assert _oracle_x(calls) is None and said and said[0].startswith(message), (expression, message, said)
