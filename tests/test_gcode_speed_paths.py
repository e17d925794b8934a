"""The reader's quick paths read exactly as its full paths: the common line read by one regular
expression (``blocks._simple_block``) against the character-by-character reader, the block of
axis words and F alone (``Interpreter._plain_move``) against the whole of ``_execute``, and a CAM
program's common lines run at once (``gcode/common_lines.py``) against the line-by-line reader,
on random programs and on every outside program and LinuxCNC example. Each side
is the same reader with the quick path switched off, so any difference in values, calls, N text,
refusal or wording shows. Lines and programs are random (seeded) and aimed at the quick paths'
edges: signs, ``-0``, numbers past a float's range, parameters out of range or undefined,
division by zero, overflow, duplicate and negative words, mixed case, comments, block delete."""

from __future__ import annotations

import random

import pytest

import oracle
import shared_data
from cnc_twin.gcode import blocks, interpreter
from cnc_twin.gcode.blocks import read_block
from cnc_twin.gcode.expressions import Parameters
from cnc_twin.gcode.interpreter import ProgramError, read_program
from cnc_twin.gcode.source import Source
from cnc_twin.gcode.state import ToolTable

NUMBERS = ("1", "0", "-0", "+0", "2.5", "-2.5", ".5", "-.5", "5.", "+5.", "007", "1" * 330, "-" + "9" * 330, "0.1",
           "3.14159", "123456789012", "1.2.3", ".", "1e3")
PARAMETERS = ("#1", "#2", "#3", "#12", "#0", "#5601", "#5602", "#5420", "#01", "#<a>", "#<yscale>", "#<big>", "#<nope>",
              "#<_x>", "#<_line>", "#999999999", "#1234567890", "#<>")


def _parameters() -> Parameters:
    params = Parameters()
    params.named.update(a=1.5, yscale=-2.0, big=1e308)
    params.numbered.update({1: 2.0, 2: 0.0, 3: 7.25, 12: -3.0})
    params.live_named.update(_x=lambda: 4.5, _line=lambda: 17.0)
    params.live_numbered[5420] = lambda: -2.0
    return params


def _value(rng: random.Random) -> str:
    def operand() -> str:
        if rng.random() < 0.5:
            return rng.choice(NUMBERS)
        return rng.choice(("", "", "-", "+")) + rng.choice(PARAMETERS)
    kind = rng.random()
    if kind < 0.5:
        return operand()
    if kind < 0.6:
        return f"[{operand()}]"
    return f"[{operand()}{rng.choice(('+', '-', '*', '/', '**', 'mod'))}{operand()}]"


def _line(rng: random.Random) -> str:
    text = rng.choice(("", "", "n10", "N0030", "n1.5", "N12.", "n.5", "N 1 2", "n7..8", "N1²"))
    for _ in range(rng.randint(0, 5)):
        text += rng.choice("xyzabcfstgmijkpqrlhd@^$euoxyzgm") + _value(rng)
    if rng.random() < 0.3:
        text = "".join(c.upper() if rng.random() < 0.3 else c for c in text)
    if rng.random() < 0.3:
        k = rng.randint(0, len(text))
        text = text[:k] + rng.choice((" ", "\t", "(c)", "(msg,x)", ";x", ")", "(", "/", "#1=3")) + text[k:]
    return rng.choice(("", "", " ", "/", " /")) + text


def _read(text: str):
    params = _parameters()
    try:
        block = read_block(text, 3, params)
    except Exception as exc:  # noqa: BLE001 - a refusal, or the full reader's crash on `#` + 330 digits
        return type(exc).__name__, str(exc)
    values = (block.words, block.g, block.m, block.assignments)
    return (block.number, block.number_text, block.block_delete, block.comments, block.o_word, repr(values),
            sorted(params.named))


@pytest.mark.parametrize("seed", range(4))
def test_a_line_reads_the_same_with_and_without_the_quick_path(seed, monkeypatch):
    rng = random.Random(seed)
    lines = [_line(rng) for _ in range(3000)]
    simple, taken = blocks._simple_block, []
    monkeypatch.setattr(blocks, "_simple_block", lambda *args: taken.append(simple(*args)) or taken[-1])
    quick = [_read(text) for text in lines]
    monkeypatch.setattr(blocks, "_simple_block", lambda *args: None)
    full = [_read(text) for text in lines]
    assert sum(block is not None for block in taken) > 500  # the quick path read a good share itself
    for text, ours, theirs in zip(lines, quick, full):
        assert ours == theirs, text


def test_the_quick_path_reads_most_common_lines_itself():
    params = _parameters()
    for text in ("N120Y[#<yscale>*-56.12]Z[#<zscale>*-27.725]", "G1 X1 Y-2.5 F[#<a>*3]", "x#1 y-#<a> z[#3/4]"):
        params.named["zscale"] = 1.0
        assert blocks._simple_block(blocks.normalise(text)[0], 1, False, [], params) is not None


def _axis_line(rng: random.Random) -> str:
    def value(letter: str) -> str:
        if letter == "F":
            return rng.choice(("100", "#1", "[#<a>*3]", "2.5", "0", "-1"))
        return rng.choice((f"{rng.uniform(-50, 50):.3f}", f"[#<a>*{rng.uniform(-9, 9):.3f}]", "#1", "-#<a>", "0",
                           "-0", ".5", "[1/0]" if rng.random() < 0.05 else "5."))
    words = [letter + value(letter) for letter in rng.sample("XYZABCF", rng.randint(0, 4))]
    if rng.random() < 0.3:
        words.insert(0, rng.choice(("N10", "n0030", "N 12", "/N5", "N7.5")))
    return rng.choice(("", " ")).join(words)


MODES = ("G0", "G1", "G2 I1", "G3 J-1", "G80", "G93", "G94", "G20", "G21", "G90", "G91", "G18", "G17", "F100", "F0",
         "(msg,hi)", "#1=2", "#<a>=-1.5", "G53 G0 X1", "G5.2 X1 Y1 P1 L3", "G5.3", "G43 H1", "T1 M6", "G92 X1", "M3 S100",
         "G81 X1 Y1 Z-1 R2", "G91.1", "G90.1", "G19", "G6.2 X1 Y1 L3 P1 K0", "G43.1 Z1", "M6 T1 G43 H1")


def _common_line(rng: random.Random) -> str:
    """A line shaped as (or near) a common line of :mod:`cnc_twin.gcode.common_lines`: G0 .. G3,
    axis words, I J K R, F, S, an N word, a comment at the end; now and then out of order,
    negative, doubled, with a tab, another code, or arc words without an arc."""
    def number() -> str:
        return rng.choice((f"{rng.uniform(-9, 9):.4f}", "0", "-0", "1.", ".5", "-2", "3", "007"))
    rare = lambda: rng.random() < 0.04  # noqa: E731 - a line the full path refuses, or reads otherwise
    code = rng.choice(("0", "1", "2", "3", "00", "01", "02", "03", "", "")) if not rare() else \
        rng.choice(("1.0", "001", "4", "1 0"))
    words = ["G" + code] if code else []
    if code in ("2", "3", "02", "03") and not rare():  # R far longer than any chord here, full circles
        words += rng.choice((["X" + number(), "Y" + number(), rng.choice(("R40", "R-40"))], ["I1"],
                             ["Z" + number(), "J1", "I0"], ["A" + number(), "I-1.5", "J0.5"]))
    else:
        words += [letter + number() for letter in rng.sample("XYZABC", rng.randint(0, 3))]
        if rare():
            words += rng.choice((["I" + number(), "J" + number()], ["R" + number()], ["K1"], ["P2", "I1"]))
    if rng.random() < 0.3:
        words.append("F" + (rng.choice(("100", "2.5", "1")) if not rare() else rng.choice(("0", "-1", "-0"))))
    if rng.random() < 0.1:
        words.append("S" + (rng.choice(("2000", "0")) if not rare() else "-5"))
    if rare() and len(words) > 1:
        k = rng.randrange(len(words) - 1)
        words[k], words[k + 1] = words[k + 1], words[k]
    if rare():
        words.append(rng.choice(words) if words else "X1")
    if rng.random() < 0.3:
        words.insert(0, rng.choice(("N10", "n0030", "N 12", "N12 3", "N7.5", "N2000")))
    text = rng.choice((" ", "", " ", "  ") if not rare() else ("\t",)).join(words)
    if rng.random() < 0.2:
        text = text.lower()
    if rng.random() < 0.2:
        text += rng.choice(("(c)", " ( Penetrate)", "(print,x=#<_x> line #<_line>)", "(debug,#<_feed>)", "(msg,hi)",
                            " (c) ", "(é)", "(a)(b)", ";c") if not rare() else ("(unclosed", "(c) X1"))
    elif rng.random() < 0.05:
        text = rng.choice(("(alone)", "  (print,#<_line>)", "(log,x)", "()", "\t(tab)"))
    return text


def _program(rng: random.Random) -> str:
    lines = [rng.choice(("G21", "G20")) + rng.choice((" G1 F100", " G1 F100", " G93 G1 F2", " G0", "")),
             "#<a>=1.5 #1=2 #<big>=[10**300]"]
    for _ in range(rng.randint(1, 15)):
        lines.append(_axis_line(rng) if rng.random() < 0.8 else rng.choice(MODES))
    lines.append(rng.choice(("M2", "M30", "M2", "")))
    return "\n".join(lines) + "\n"


TOOLS = ToolTable.parse("T1 P1 Z0.511 D0.125\n", units=210)


def _run(text: str):
    try:
        reading = read_program(Source(text, "program.ngc"), TOOLS)
        calls, printed, error = reading.calls, reading.printed, None
    except ProgramError as exc:
        calls, printed, error = exc.calls, exc.printed, (exc.line, exc.message)
    return [call.text(k) for k, call in enumerate(calls, start=1)], printed, error


@pytest.mark.parametrize("seed", range(3))
def test_a_program_runs_the_same_with_and_without_the_quick_paths(seed, monkeypatch):
    rng = random.Random(seed)
    programs = [_program(rng) for _ in range(300)]
    quick = [_run(text) for text in programs]
    monkeypatch.setattr(blocks, "_simple_block", lambda *args: None)
    monkeypatch.setattr(interpreter, "PLAIN_WORDS", frozenset())
    monkeypatch.setattr(interpreter, "COMMON_LINES", False)
    full = [_run(text) for text in programs]
    assert sum(error is None for _, _, error in quick) > 30  # some run whole
    for text, ours, theirs in zip(programs, quick, full):
        assert ours == theirs, text


def _common_program(rng: random.Random) -> str:
    """A program mostly of common lines, in any of the states they may or may not run in."""
    lines = [rng.choice(("G21", "G20", "G21 G91", "G21", "G20", "G18", "G90.1")) +
             rng.choice((" G1 F100", " G1 F100", " G1 F100", " G0 F20", " G93 G1", " G80 F10"))]
    for _ in range(rng.randint(1, 25)):
        lines.append(_common_line(rng) if rng.random() < 0.9 else rng.choice(MODES))
    lines.append(rng.choice(("M2", "M30", "M2", "")))
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("seed", range(3))
def test_common_lines_run_as_the_full_path_runs_them(seed, monkeypatch):
    rng = random.Random(seed)
    programs = [_common_program(rng) for _ in range(400)]
    fast = [_run(text) for text in programs]
    monkeypatch.setattr(interpreter, "COMMON_LINES", False)
    full = [_run(text) for text in programs]
    assert sum(error is None for _, _, error in fast) > 30  # some run whole (most stop at a refusal, also compared)
    assert sum(len(calls) for calls, _, _ in fast) > 5000
    for text, ours, theirs in zip(programs, fast, full):
        assert ours == theirs, text


def _reading(path, monkeypatch, fast: bool) -> tuple:
    """Everything the reader makes of ``path`` (the calls' values and geometry exactly, by repr),
    with the common lines' fast path on or off."""
    monkeypatch.setattr(interpreter, "COMMON_LINES", fast)
    try:
        reading = read_program(Source.read(path), OUTSIDE_TOOLS)
        calls, printed, error = reading.calls, reading.printed, None
    except ProgramError as exc:
        calls, printed, error = exc.calls, exc.printed, (exc.line, exc.message, exc.file)
    return [repr((c.name, c.values, c.line, c.number, c.payload)) for c in calls], printed, error


OUTSIDE_TOOLS = ToolTable.parse((shared_data.ROOT / "models" / "polisher.tbl").read_text(), units=210)
"""the bundled machine's tool table (T1-T99), which the outside programs are read with"""


def test_every_outside_and_example_program_reads_the_same_on_the_fast_path(monkeypatch):
    """The whole outside corpus and LinuxCNC's 185 example programs, with the common lines' fast
    path and without it: every call (name, values, line, N text, an arc's or a curve's geometry),
    every printed line and refusal alike; the fast path runs most of their lines itself."""
    oracle.require()  # the examples are in the oracle's package
    outside = sorted(shared_data.require(shared_data.OUTSIDE_GCODE).iterdir())
    examples = sorted((oracle.ROOT / "usr" / "share" / "linuxcnc" / "ncfiles").rglob("*.ngc"))
    assert len(outside) >= 90 and len(examples) == 185
    full_steps = []
    execute = interpreter.Interpreter._execute
    monkeypatch.setattr(interpreter.Interpreter, "_execute",
                        lambda self, block: full_steps.append(block.line) or execute(self, block))
    still_full = steps = 0
    for path in outside + examples:
        fast = _reading(path, monkeypatch, True)
        still_full += len(full_steps)
        full_steps.clear()
        assert fast == _reading(path, monkeypatch, False), path.name
        steps += len(full_steps)  # every block the program runs (O-word lines apart)
        full_steps.clear()
    assert still_full < 0.4 * steps, (still_full, steps)  # (loops of parameter settings stay on the full path)
