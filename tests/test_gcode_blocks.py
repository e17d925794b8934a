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
