"""G10 L1 / L10 / L11, a program's edits of its tool table, and G10 L0, its reload, as
LinuxCNC's interpreter makes them (its convert_setup_tool; rs274 prints each edit as a
``SET_TOOL_TABLE_ENTRY`` call).

G10 L1 P<tool> sets the given offsets (X Y Z in program units, A B C in degrees), R the radius,
I J the front and back angles, Q the orientation. G10 L10 sets each given axis's offset so that
the current point, with it applied, is the given value in the active work system; L11 the same
in G59.3 (system 9) without the G92 offsets. The table is kept in machine units
(:class:`~cnc_twin.gcode.state.ToolTable`); the edit is the program's own reading's (a copy),
never the caller's table. As in LinuxCNC, an edit of the tool at the current pocket (the
tool the last M6 loaded; tool index 1 before any) also reaches the spindle slot that G43 without
H and #5401 .. read; an edit of another tool reaches only G43 H<tool> and later tool changes.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from cnc_twin.gcode.blocks import Block, BlockError
from cnc_twin.gcode.state import G92_ENABLED, G92_PARAMETER, SYSTEM_PARAMETER

if TYPE_CHECKING:  # the interpreter that runs this step; only its type is needed here
    from cnc_twin.gcode.interpreter import Interpreter

TOOL_EDITS = (0, 1, 10, 11)
"""the L words of G10 that edit (1, 10, 11) or reload (0) the tool table"""
FIXTURE_SYSTEM = 9
"""G10 L11 measures in G59.3"""
OFFSET_WORDS = "xyzabcrqij"
"""the words a G10 L1 / L10 / L11 sets something with"""


def edit_tool_table(interpreter: Interpreter, block: Block) -> None:
    """The G10 step of a G10 L0 / L1 / L10 / L11 block (its L and P checked with the block).

    :type block: ~cnc_twin.gcode.blocks.Block
    """
    if round(block.words["l"]) == 0:
        _reload(interpreter)
    else:
        _setup_tool(interpreter, block)


def _reload(interpreter: Interpreter) -> None:
    """G10 L0: the tool data read again, refused with a tool in the spindle. rs274 has no tool
    data to read but its own table, edits included; its point is re-read from the canon, as after
    a tool change."""
    s = interpreter.state
    if s.tool_data > 0:
        raise BlockError(f"G10 L0 not allowed with loaded tool <{s.tool_data}>")
    interpreter.emit("RELOAD_TOOLDATA")
    s.resynchronise()


def _setup_tool(interpreter: Interpreter, block: Block) -> None:
    s = interpreter.state
    words = block.words
    number = int(words["p"] + 0.5)  # the block's check took P within 0.0001 of a whole number >= 1
    if number not in s.tools.lengths:
        raise BlockError(f"Requested tool {number} not found in the tool table")
    if not any(letter in words for letter in OFFSET_WORDS):
        raise BlockError("G10 L1 without offsets has no effect")
    offsets = list(s.tools.offsets(number))
    given = {axis: words[letter] for axis, letter in enumerate("xyzabc") if letter in words}
    if round(words["l"]) == 1:
        for axis, value in given.items():
            offsets[axis] = s.program_to_user(axis, value)
    else:
        _measured(s, round(words["l"]) == 11, given, offsets)
    diameter = s.tools.diameters.get(number, 0.0)
    front, back, orientation = s.tools.shapes.get(number, (0.0, 0.0, 0))
    if "r" in words:
        diameter = s.program_to_user(0, words["r"]) * 2.0
    front, back = words.get("i", front), words.get("j", back)
    if "q" in words and words["q"] != -1.0:  # LinuxCNC's "no Q" is Q -1
        orientation = int(words["q"] + 0.5)
        if not abs(orientation - words["q"]) < 0.0001:
            raise BlockError("Q number in G10 is not an integer")
        if orientation > 9:
            raise BlockError("Invalid tool orientation")
    index = s.tools.index(number)
    if index != s.pocket and number == s.tool_data and s.slot_tools is None:
        s.slot_tools = s.tools  # the spindle slot keeps the data it was loaded with
    s.tools = s.tools.with_tool(number, offsets, diameter, (front, back, orientation))
    entry = (number, *offsets, 0.0, 0.0, 0.0, front, back, orientation)  # the machine has no U V W
    interpreter.emit("SET_TOOL_TABLE_ENTRY", index, *entry)
    if index == s.pocket:
        interpreter.emit("SET_TOOL_TABLE_ENTRY", 0, *entry)
        s.tool_data, s.slot_tools = number, None
    s.tool_in_spindle = s.tool_data  # #5400 is the spindle slot's tool again


def _measured(s, fixture: bool, given: dict[int, float], offsets: list[float]) -> None:
    """G10 L10 / L11: each given axis's offset (machine units) such that the current point,
    without the tool length offset in use and with the new one, reads the given value in the
    active system (L10) or in G59.3 without the G92 offsets (L11); LinuxCNC's order of
    operations (its find_current_in_system_without_tlo), rotations included."""
    params = s.params
    system = FIXTURE_SYSTEM if fixture else s.system
    base = SYSTEM_PARAMETER + 20 * system
    t = [s.position[k] + s.g92[k] for k in range(6)]
    t[0], t[1] = _rotate(t[0], t[1], 0.0)  # the interpreter's XY rotation, always 0 here
    for k in range(6):
        t[k] = t[k] + s.g5x[k] + s.tool_offset[k] - s.user_to_program(k, params.number(base + k))
    rotation = params.number(base + 9)  # the system's R, #5210 + 20 n
    t[0], t[1] = _rotate(t[0], t[1], -rotation)
    if params.number(G92_ENABLED):
        stored = [s.user_to_program(k, params.number(G92_PARAMETER + k)) for k in range(6)]
        for k in range(6):
            t[k] -= stored[k]
        if fixture:  # L11 measures from the fixture's origin, which G92 does not move
            for k in range(6):
                t[k] += stored[k]
    if 0 in given and 1 in given:
        x, y = _rotate(t[0] - given[0], t[1] - given[1], rotation)
    elif 0 in given or 1 in given:
        # the table's offset across the given axis (in the system's possibly rotated frame) stays
        axis = 0 if 0 in given else 1
        old = list(_rotate(s.user_to_program(0, offsets[0]), s.user_to_program(1, offsets[1]), -rotation))
        old[axis] = 0.0
        old = _rotate(old[0], old[1], rotation)
        moved = [0.0, 0.0]
        moved[axis] = t[axis] - given[axis]
        moved = _rotate(moved[0], moved[1], rotation)
        x, y = moved[0] + old[0], moved[1] + old[1]
    if 0 in given or 1 in given:
        offsets[0], offsets[1] = s.program_to_user(0, x), s.program_to_user(1, y)
    for k in range(2, 6):
        if k in given:
            offsets[k] = s.program_to_user(k, t[k] - given[k])


def _rotate(x: float, y: float, degrees: float) -> tuple[float, float]:
    """LinuxCNC's rotate: (x, y) turned by ``degrees`` about the origin, computed as it does
    (so a turn by 0 keeps each value, down to the sign of a zero, as it does)."""
    t = degrees * math.pi / 180.0
    return x * math.cos(t) - y * math.sin(t), x * math.sin(t) + y * math.cos(t)
