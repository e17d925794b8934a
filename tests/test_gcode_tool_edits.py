"""G10 L1 / L10 / L11 (a program's tool table edits) and G10 L0 (its reload) read as LinuxCNC
2.9's rs274 reads them: the ``SET_TOOL_TABLE_ENTRY`` calls, the offsets L10 / L11 measure from
the current point, what a later G43 H, G43 and #5400 .. #5410 read (the spindle slot takes an
edit only of the tool at rs274's current pocket), in mm and inch, G90 and G91, and the block's
refusals, each matched call for call by rs274 with the tool table below. An edit is the
reading's own: the caller's table is never changed."""

from __future__ import annotations

import pytest

import gcode_conformance
import oracle
from gcode_conformance import assert_refused_alike, compare, ours
from cnc_twin.gcode.interpreter import read_program
from cnc_twin.gcode.source import Source
from cnc_twin.gcode.state import ToolTable

TABLE = "T1 P1 Z0.511 D0.125\nT2 P2 Z0.1 D0.0625\nT3 P3 X0.1 Z0.2 A5 C-2 I10 J20 Q3 D0.2\n"
"""the oracle's two tools and one with rotary offsets and lathe data (inches, as rs274 reads them)"""


@pytest.fixture(autouse=True)
def _tools(monkeypatch):
    """Both readers read TABLE, written as gcode_conformance writes the oracle's."""
    monkeypatch.setattr(oracle, "TOOL_TABLE", TABLE)
    monkeypatch.setattr(gcode_conformance, "TOOLS", ToolTable.parse(TABLE, units=200))


PROGRAMS = {
    "L1 then G43 H": "G10 L1 P1 Z2\nG43 H1\n(debug, #5403 #<_z>)\nG1 Z0 F100\nM2\n",
    "L1 of every word, then M6 and G43": "G10 L1 P1 R0.5 X1 Y2 Z3 A4 B5 C6 I1 J2 Q2\nT1 M6\nG43\n"
                                         "(debug, #5401 #5402 #5403 #5404 #5405 #5406 #5410)\nG0 X0 Y0 Z0 A0\nM2\n",
    "L1 in inch": "G20 G0 Z1\nG10 L1 P2 Z0.5\nG43 H2\n(debug, #<_z>)\nG1 X1 Z0 F10\nM2\n",
    "L1 keeps the table's rotary and lathe data": "G10 L1 P3 Z1\nT3 M6\nG43\n(debug, #5401 #5403 #5404 #5406 #5410)\n"
                                                 "G0 X1 A1 C1\nM2\n",
    "P rounds half up": "G10 L1 P1.5 Z1\nG43 H2\nM2\n",
    "Q -1 is no Q": "G10 L1 P1 Q-1\nM2\n",
    # rs274's standalone canon starts at pocket 1: an edit of the table's first tool reaches the slot
    "the first tool reaches the slot": "(debug, #5403 #5400)\nG10 L1 P1 Z1\n(debug, #5403 #5400 #<_current_tool>)\n"
                                       "G43\n(debug, #5403 #5400)\nM2\n",
    "another tool does not": "(debug, #5403 #5400)\nG10 L1 P2 Z1\n(debug, #5403 #5400)\nG43\nM2\n",
    "after M6, the loaded tool's edit": "T2 M6\nG10 L1 P2 Z1\n(debug, #5403 #5400)\nG10 L1 P1 Z3\n(debug, #5403)\n"
                                        "G43\nG43 H1\nM2\n",
    "after T0 M6 the slot keeps the old data": "T2 M6\nT0 M6\nG10 L1 P2 Z1 R2\nG43\n(debug, #5403 #5410 #5400)\n"
                                               "G43 H2\nG43 H0\nT2 M6\nG43\n(debug, #5403 #5410)\nM2\n",
    "M6 and G43 in one block": "G10 L1 P1 Z1 R2\nG43 H0\nT2 M6 G43\nG43\nM2\n",
    "L10 G90": "G0 X1 Y2 Z3\nG10 L10 P1 Z1\nG43 H1\n(debug, #<_z>)\nG1 Z0 F10\nM2\n",
    "L10 G91": "G21 G91 G0 X1 Y1 Z1\nG10 L10 P1 X0.5 Z-2\nG43 H1\nG0 X1\n(debug, #<_x> #<_z>)\nM2\n",
    "L10 and L11 in inch with offsets": "G20 G0 X1 Y2 Z3\nG10 L2 P1 X0.5\nG92 Z1\nG43 H2\nG10 L10 P1 X1 Y2 Z-1\n"
                                        "G10 L11 P2 X1 Z0.3\n(debug, #5401 #5402 #5403)\nG43 H2\nG1 X2 F10\nM2\n",
    "L11 in G59.3": "G10 L2 P9 Z5\nG0 Z3\nG10 L11 P2 Y1 A3\nG43 H2\nG0 X0\nM2\n",
    "L10 of X or Y alone keeps the other": "G10 L10 P2 X1\nG10 L1 P2 Y3\nG10 L10 P2 X2\nG10 L10 P2 Y-2\nG43 H2\n"
                                           "G0 X0 Y0\nM2\n",
    "L10 of rotary axes in G55": "G10 L2 P2 A10 C5\nG55 G0 A30 C20\nG43 H3\nG10 L10 P3 X2 A1\nG43 H3\nG0 X0 A0\nM2\n",
    "L0 re-reads the point": "G0 Z1\nG43 H2\n(debug, #<_z>)\nG10 L0 P0\n(debug, #<_z>)\nG43 H1\n(debug, #<_z>)\nM2\n",
    "L0 with any P": "G10 L0 P5\n(debug, #5400)\nG10 L0 X1\nM2\n",
}


@pytest.mark.parametrize("program", list(PROGRAMS.values()), ids=list(PROGRAMS))
def test_tool_table_edits_are_read_whole(program):
    calls, _, error = ours(program)
    assert error is None, f"line {error.line}: {error.message}"
    assert any(name in ("SET_TOOL_TABLE_ENTRY", "RELOAD_TOOLDATA") for name, _ in calls)


@pytest.mark.parametrize("program", list(PROGRAMS.values()), ids=list(PROGRAMS))
def test_tool_table_edits_are_read_as_rs274_reads_them(program, tmp_path):
    oracle.require()
    verdict = compare(program, tmp_path)
    assert (verdict.kind, verdict.detail) == ("matched", ""), verdict.detail


def test_an_edit_prints_rs274_s_entry():
    calls, _, error = ours("G20\nG10 L1 P3 Y0.5 R0.25\nM2\n")
    assert error is None
    # index, tool, x y z a b c u v w (inches and degrees), front and back angles, orientation
    assert ("SET_TOOL_TABLE_ENTRY", "3, 3, 0.1000 0.5000 0.2000 5.0000 0.0000 -2.0000 0.0000 0.0000 0.0000, "
            "10.0000, 20.0000, 3") in calls


def test_an_edit_is_the_reading_s_own():
    tools = ToolTable.parse(TABLE, units=200)
    before = (dict(tools.lengths), dict(tools.diameters))
    program = Source("G10 L1 P1 Z2 R1\nG43 H1\nM2\n")
    first = read_program(program, tools)
    assert (tools.lengths, tools.diameters) == before
    assert [c.values for c in read_program(program, tools).calls] == [c.values for c in first.calls]


REFUSED = {
    "unknown tool": ("G10 L1 P9 Z2\nM2\n", "Requested tool 9 not found in the tool table", 1),
    "nothing to set": ("G10 L1 P1\nM2\n", "G10 L1 without offsets has no effect", 1),
    "L10, nothing to set": ("G10 L10 P1\nM2\n", "G10 L1 without offsets has no effect", 1),
    "P0": ("G10 L1 P0 Z1\nM2\n", "P value out of range with G10 L1", 1),
    "negative P": ("G10 L10 P-1 Z1\nM2\n", "P value out of range with G10 L10", 1),
    "no P": ("G10 L11 Z1\nM2\n", "P value out of range with G10 L11", 1),
    "orientation over 9": ("G10 L1 P1 Q10 Z1\nM2\n", "Invalid tool orientation", 1),
    "orientation not whole": ("G10 L1 P1 Q2.5 Z1\nM2\n", "Q number in G10 is not an integer", 1),
    "H": ("G10 L1 P2 X1 H2\nM2\n", "H word with no G43 or G76 to use it", 1),
    "L0 with a tool loaded": ("T1 M6\nG10 L0\nM2\n", "G10 L0 not allowed with loaded tool <1>", 2),
    "L0 after the slot took an edit": ("G10 L1 P1 Z1\nG10 L0\nM2\n", "G10 L0 not allowed with loaded tool <1>", 2),
}


@pytest.mark.parametrize("program, message, line", list(REFUSED.values()), ids=list(REFUSED))
def test_bad_edits_are_refused(program, message, line):
    _, _, error = ours(program)
    assert error is not None and (error.line, error.message) == (line, message)


@pytest.mark.parametrize("program, message, line", list(REFUSED.values()), ids=list(REFUSED))
def test_bad_edits_are_refused_as_rs274_refuses_them(program, message, line, tmp_path):
    assert_refused_alike(program, message, tmp_path)
