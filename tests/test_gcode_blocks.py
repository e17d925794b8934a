"""Reading one line of G-code as LinuxCNC reads it: spaces, case, comments, block delete, line
numbers, parameter settings after the line; refusals in its words. The oracle rows check the
X/Y/Z our reader reads against the STRAIGHT_FEED LinuxCNC makes of the same lines."""

from __future__ import annotations

import pytest

import oracle
from cnc_twin.gcode.blocks import BlockError, apply_assignments, read_block
from cnc_twin.gcode.expressions import Parameters


def _read(lines: list[str]):
    """Read ``lines`` in order as a program does (each line's settings applied after it)."""
    params, blocks = Parameters(), []
    for number, text in enumerate(lines, start=1):
        block = read_block(text, number, params)
        apply_assignments(block, params)
        blocks.append(block)
    return blocks


def test_spaces_case_and_comments():
    (block,) = _read(["G1 X1 0 y-2 (a Comment) F100 ; rest (x)"])
    assert block.g == [1.0] and block.words == {"x": 10.0, "y": -2.0, "f": 100.0}
    assert block.comments == ["a Comment"]
    (block,) = _read(["  ( leading spaces dropped, CAPS kept )"])
    assert block.comments == ["leading spaces dropped, CAPS kept "] and not block.words


def test_line_numbers_block_delete_and_o_words():
    a, b, c = _read(["N10 G1 X1 F100", "/N1.5 G0 Y2", "o100 sub"])
    assert (a.number, a.block_delete) == (10, False)
    assert (b.number, b.block_delete, b.g) == (1, True, [0.0])
    assert c.o_word == "100sub" and not c.words


def test_a_parameter_set_on_a_line_takes_effect_after_it():
    blocks = _read(["#1=5", "#1=7 G1 X#1 F100", "G1 X#1", "#<My Var>=4", "G1 X#<my var>"])
    assert [b.words.get("x") for b in blocks] == [None, 5.0, 7.0, None, 4.0]


def test_a_named_parameter_exists_from_its_setting_on_and_holds_its_value_after_the_line():
    blocks = _read(["#<new>=-3 Z#<new>", "Z#<new>", "#<e>=[#<e>+1]", "Z#<e>"])
    assert [b.words.get("z") for b in blocks] == [0.0, -3.0, None, 1.0]
    with pytest.raises(BlockError, match="Named parameter #<later> not defined"):
        _read(["G1 Z#<later> #<later>=-3"])


REFUSED = [
    ("G1 X1 (a (b) c) F100", "Nested comment found"),
    ("G1 X1 F100 )", "Bad character ')' used"),
    ("(unclosed", "Unclosed comment found"),
    ("G1 X1 X2 F100", "Multiple x words on one line"),
    ("G1 X1 F100 Q", "No characters found in reading real value"),
    ("#1 5", "Equal sign missing in parameter setting"),
    ("#1=", "No characters found in reading real value"),
    ("N G1 X1 F100", "Bad format unsigned integer"),
    ("#<abc", "Named parameter not terminated"),
    ("G1 X1 F100 N5", "Bad character 'n' used"),
    ("G1 X#<my var> F100", "Named parameter #<myvar> not defined"),
    ("G1 X[1/0] F100", "Attempt to divide by zero"),
]


@pytest.mark.parametrize("text, message", REFUSED, ids=[r[1] for r in REFUSED])
def test_refused_lines_in_linuxcnc_words(text, message):
    with pytest.raises(BlockError) as info:
        _read([text])
    assert str(info.value) == message


def test_refusals_are_what_linuxcnc_says(tmp_path):
    oracle.require()
    for k, (text, message) in enumerate(REFUSED):
        calls, said = oracle.run(f"G21 G90\n{text}\nM2\n", tmp_path / str(k))
        assert not oracle.straight_feeds(calls) and said and said[0] == message, (text, said)


MOTION = ["G21 G90 F100", "G1 X1 0 Y 2", "x[1+2] (comment) y#1", "#1=7 X#1", "X#1 ; y99", "/X4 Y5",
          "N20 X[sin[30]] Y[atan[1]/[1]]", "#<Depth>=-3", "Z#<depth>", "z[#<depth>*2]", "X 1 2 . 5",
          "#<new>=-3 Z#<new>", "#<depth>=5 Z#<depth>", "#<e>=[#<e>+1] Z#<e>", "Z#<e>"]


def test_motion_lines_read_as_linuxcnc_moves(tmp_path):
    """The X/Y/Z our reader reads on each line equal LinuxCNC's STRAIGHT_FEED target (G1, G90,
    mm; axes not named keep their place)."""
    oracle.require()
    position = {"x": 0.0, "y": 0.0, "z": 0.0}
    expected = []
    for block in _read(MOTION):
        moved = {axis: block.words[axis] for axis in "xyz" if axis in block.words}
        position.update(moved)
        if moved:
            expected.append(f"{position['x']:.4f}, {position['y']:.4f}, {position['z']:.4f}")
    calls, said = oracle.run("\n".join(MOTION) + "\nM2\n", tmp_path)
    theirs = [", ".join(feed[:3]) for feed in oracle.straight_feeds(calls)]
    assert said == [] and theirs == expected


# a character no word starts with: LinuxCNC names a printable ASCII one, any other (a control
# character, one above 'z', a byte of a UTF-8 sequence) by its first byte in octal
BAD_CHARACTERS = ["{", "|", "}", "~", "\x7f", "\x01", "\x1b", "\x0b", "\x0c", "\x1c", "\x85", "\u2028", "\u00e9",
                  "\u00c9", "\u0130", "\ufeff", "\u20ac", "\u00a0", "`", "!", "'", "_", "\\", ":"]


def test_bad_characters_are_named_as_linuxcnc_names_them(tmp_path):
    """Each character mid-line, and at the end of a line (LinuxCNC strips only C's white space
    there, and ends lines at a newline only: a vertical tab or U+2028 is no line break), and a
    byte-order mark first in a file, through both readers."""
    oracle.require()
    from gcode_conformance import compare

    programs = [f"G21 G90\nG0 X1 {c} Y2\nM2\n" for c in BAD_CHARACTERS]
    programs += [f"G21 G90\nG0 X1 {c}\nG0 X2\nM2\n" for c in BAD_CHARACTERS]
    programs += ["\ufeffG21 G90\nG0 X1\nM2\n", "G21\nG0 X\u00e9\nM2\n", "G21\nG0 X1\u00e9\nM2\n",
                 "G21\nG0 X1\rG1 X2\nM2\n", "#<\u00c9>=1\nG0 X#<\u00e9>\nM2\n", "#<\u00c9>=1\nG0 X#<\u00c9>\nM2\n"]
    for k, text in enumerate(programs):
        verdict = compare(text, tmp_path / str(k))
        assert verdict.kind == "matched", (text, verdict)


def test_a_byte_that_is_not_utf8_is_named_by_its_own_value(tmp_path):
    """A Latin-1 file: its bytes are not UTF-8 (we read U+FFFD), and LinuxCNC names the byte
    itself, ``'\\351'`` for an ``é``; a comment may hold such bytes."""
    oracle.require()
    from cnc_twin.gcode.interpreter import ProgramError, read_program
    from cnc_twin.gcode.source import Source
    from gcode_conformance import TOOLS

    program = "G21 (d\xe9but)\nG0 X1 Y2 \xe9\nM2\n".encode("latin-1")
    _, said = oracle.run(program, tmp_path / "oracle")
    (tmp_path / "ours.ngc").write_bytes(program)
    with pytest.raises(ProgramError) as info:
        read_program(Source.read(tmp_path / "ours.ngc"), TOOLS)
    assert (info.value.line, info.value.message) == (2, said[0]) == (2, "Bad character '\\351' used")
