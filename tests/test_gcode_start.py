"""Where a program starts: the work offsets, active system and G92 offsets a parameter file holds
(LinuxCNC's ``.var``), read as rs274 reads them with ``-v``, and the machine's position at the start
(LinuxCNC's interpreter starts from where the machine stands; rs274 alone from 0)."""

from __future__ import annotations

import pytest

import oracle
from gcode_conformance import TOOLS
from cnc_twin.gcode.interpreter import read_program
from cnc_twin.gcode.source import Source
from cnc_twin.gcode.state import ToolTable

PROGRAM = """G21
(debug, #5220 #5221 #5222 #5223 #<_x> #<_y> #<_z>)
G1 X1 F100
G91 G0 Z3
G90 G55 G0 X0
G54 G92.3
G0 Y2
M2
"""

VARS = [
    {5220: 1.0, 5221: 10.0, 5222: -20.0, 5223: 5.0},
    {5220: 2.0, 5221: 1.0, 5241: -3.0, 5242: 0.5, 5243: 2.0, 5244: 30.0},
    {5220: 1.0, 5221: 2.0, 5210: 1.0, 5211: 0.25, 5212: -0.5, 5213: 1.0},
    {5220: 1.0, 5210: 0.0, 5211: 0.25, 5212: -0.5, 5213: 1.0, 5226: 15.0},
]
"""parameter files: G54 offsets; G55 active with an A offset; saved G92 offsets in force (#5210),
and saved but not in force (G92.3 restores them); in inches, rs274's machine units"""


def _ours(text: str, parameters=None, start=None, tools=TOOLS) -> tuple[list[tuple[str, str]], list[str]]:
    reading = read_program(Source(text, "program.ngc"), tools, parameters=parameters, start=start)
    return [(c.name, c.arguments) for c in reading.calls], reading.printed


@pytest.mark.parametrize("parameters", VARS)
def test_a_parameter_file_s_offsets_start_the_program_as_rs274_starts_it(parameters, tmp_path):
    oracle.require()
    theirs, said = oracle.run(PROGRAM, tmp_path, parameters)
    calls, printed = _ours(PROGRAM, parameters)
    assert calls == theirs
    assert [line.strip() for line in said] == [line.strip() for line in printed]


def test_the_start_is_where_the_machine_stands_less_the_offsets():
    """A first G1 X moves X only, from the machine's position: Y and Z stay where the machine
    stands (a program read from 0 would take Z down to Z0 on its first move)."""
    start = (0.0, 0.0, 290.0, 0.0, 0.0, 0.0)
    offsets = {5221: -40.0, 5222: 25.0, 5223: 10.0}  # mm: the twin's machine units
    calls, _ = _ours("G21 G90\nG1 X5 F100\nM2\n", offsets, start, ToolTable())
    feed = next(args for name, args in calls if name == "STRAIGHT_FEED")
    # program point: X5, Y = 0 - 25, Z = 290 - 10, as rs274 prints it (program coordinates)
    assert [float(v) for v in feed.split(", ")][:3] == [5.0, -25.0, 280.0]
