"""G38.2 - G38.5 probing read as LinuxCNC 2.9's rs274 reads it: each code in mm and inch, G90
and G91, after offsets; the block's refusals; what the lines after a probe read (#5061 .. #5070,
and the point where the machine stopped), each matched call for call by rs274. Then the probe as
the interface the twin will answer (:mod:`cnc_twin.gcode.probing`), the runner's refusal of a
probing program at its line, and the outside programs that probe (pcb2gcode's auto-levelling
files, which read #5063 in expressions) matched with a T1-T99 tool table."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

import gcode_conformance
import oracle
import shared_data
from gcode_conformance import assert_refused_alike, compare, ours
from cnc_twin.gcode.interpreter import read_program
from cnc_twin.gcode.probing import ProbeMove, ProbeResult, standalone_probe
from cnc_twin.gcode.source import Source
from cnc_twin.gcode.state import ToolTable
from cnc_twin.gcode.toolpath import Probe, ToolpathError, operations

# -- programs rs274 reads whole -----------------------------------------------------------------

PROGRAMS = {
    # rs274's probe "trips" at its target (#5061..), reports not tripping (#5070 0) and stops
    # backed off 0.254 mm toward the start: the next G1 starts there and moves X to #5063
    "G38.2 mm, parameters read after": "G21 G0 X1 Y2 Z3\nG38.2 Z-5 F100\n(debug, #5061 #5062 #5063 #5070)\n"
                                       "G1 X[#5063]\n(debug, #<_z>)\nM2\n",
    "G38.3 of no length": "G38.3 Z0 F100\n(debug, #5061 #5063 #5070 #<_z>)\nM2\n",
    "G38.4 inch, backs off 0.01": "G20 G38.4 X1 Y1 F10\n(debug, #5061 #5062 #<_x> #<_y>)\nG1 X2\nM2\n",
    "G38.5 incremental": "G0 X1\nG91 G38.5 X1 Z-2 F5\n(debug, #5061 #5063 #<_x> #<_z>)\nG1 X1\nZ-1\nM2\n",
    "G38.2 of a rotary axis alone": "G38.2 A10 F100\n(debug, #5064 #<_a>)\nG0 A0\nM2\n",
    "G38.2 in polar coordinates": "G38.2 @2 ^30 F10\n(debug, #5061 #5062)\nM2\n",
    "G38.2 stays the motion mode": "G38.2 Z-1 F10\nZ-2\n(debug, #5063 #<_z> #<_motion_mode>)\nG1 Z5\nM2\n",
    "inverse time after a move": "G93\nG1 X1 F2\n(debug, #<_feed>)\nG38.2 Z-1 F7\n(debug, #<_feed> #<_z>)\nM2\n",
    "inverse time after units per minute": "G1 F10 X1\nG93\nG38.2 Z-1\nM2\n",
    # the canon measures the move from its own point, which the G43 since the last move has not moved
    "after G43": "G0 Z1\nG43 H1\nG38.2 Z-5 F50\n(debug, #5063 #<_z>)\nG1 Z0\nG49\n(debug, #<_z>)\nM2\n",
    "in G55 with G92": "G10 L2 P2 X5 Y5\nG55 G0 X1 Y1 Z1\nG38.2 X2 Y3 Z-1 F20\n"
                       "(debug, #5061 #5062 #5063 #<_x> #<_y> #<_z>)\nG92 X0\nG38.5 X-1 F20\n(debug, #5061 #<_x>)\nM2\n",
    "units changed after a probe": "G20 G0 Z1\nG38.2 Z-1 F10\nG21\n(debug, #5063 #<_z>)\nG1 X1\nM2\n",
    "with a tool change in the block": "G38.2 Z-3 F100 M6 T1\nG43\n(debug, #<_z>)\nM2\n",
    "tested in a flow line": "G38.2 Z-3 F100\no100 if [#5070 EQ 0]\n(debug, not tripped #5063)\no100 endif\nM30\n",
    "auto-levelling style": "G21 G90\n#100 = 0\nG0 Z2 X0 Y0\nG38.2 Z-2 F30\n#100 = #5063\nG0 Z2\n"
                            "G1 X5 Z[#100 + 0.5] F100\nM2\n",
}


@pytest.mark.parametrize("program", list(PROGRAMS.values()), ids=list(PROGRAMS))
def test_probing_programs_are_read_whole(program):
    calls, _, error = ours(program)
    assert error is None, f"line {error.line}: {error.message}"
    assert ("STRAIGHT_PROBE" in [name for name, _ in calls]) or "G38.3 Z0" in program


@pytest.mark.parametrize("program", list(PROGRAMS.values()), ids=list(PROGRAMS))
def test_probing_programs_are_read_as_rs274_reads_them(program, tmp_path):
    oracle.require()
    verdict = compare(program, tmp_path)
    assert (verdict.kind, verdict.detail) == ("matched", ""), verdict.detail


def test_a_probe_prints_rs274_s_calls():
    calls, printed, error = ours("G21 G0 X1 Y2 Z3\nG38.2 Z-5 F100\n(debug, #5063 #5070 #<_z>)\nM2\n")
    assert error is None
    names = [name for name, _ in calls]
    k = names.index("STRAIGHT_PROBE")
    assert names[k - 1:k + 2] == ["TURN_PROBE_ON", "STRAIGHT_PROBE", "TURN_PROBE_OFF"]
    assert calls[k][1] == "1.0000, 2.0000, -5.0000, 0.0000, 0.0000, 0.0000"
    assert ("MESSAGE", '" -5.000000 0.000000 -4.746000"') in calls


# -- refused alike ------------------------------------------------------------------------------

REFUSED = {
    "zero feed": ("G38.2 Z-5\nM2\n", "Cannot probe with zero feed rate", 1),
    "inverse time, no move yet": ("G93 G38.2 Z-1 F100\nM2\n", "Cannot probe with zero feed rate", 1),
    "G38.2 going nowhere": ("G0 Z1\nG38.2 Z1 F100\nM2\n", "Start point too close to probe point", 2),
    "G38.4 going nowhere": ("G38.4 X0 F100\nM2\n", "Start point too close to probe point", 1),
    "no axis": ("G38.2 F100\nM2\n", "All axes missing with motion code", 1),
    "G53": ("G53 G38.2 Z-1 F10\nM2\n", "Must use g0 or g1 with g53", 1),
    "with G92 in the block": ("G92 G38.2 Z-1 F10\nM2\n", "Cannot use two g codes that both use axis values", 1),
}


@pytest.mark.parametrize("program, message, line", list(REFUSED.values()), ids=list(REFUSED))
def test_bad_probes_are_refused(program, message, line):
    _, _, error = ours(program)
    assert error is not None and (error.line, error.message) == (line, message)


@pytest.mark.parametrize("program, message, line", list(REFUSED.values()), ids=list(REFUSED))
def test_bad_probes_are_refused_as_rs274_refuses_them(program, message, line, tmp_path):
    assert_refused_alike(program, message, tmp_path)


# -- the probe as an interface ----------------------------------------------------------------------

def test_the_standalone_probe_backs_off_toward_the_start():
    mm = standalone_probe(ProbeMove(2, (0, 0, 3, 0, 0, 0), (4, 0, 0, 5, 0, 0), 210, 1))
    assert not mm.tripped and mm.trip == (4, 0, 0, 5, 0, 0)
    assert mm.stop[:3] == pytest.approx((4 - 0.254 * 0.8, 0, 0.254 * 0.6)) and mm.stop[3] == 5
    inch = standalone_probe(ProbeMove(3, (0, 0, 1, 0, 0, 0), (0, 0, -1, 0, 0, 0), 200, 1))
    assert inch.stop[2] == pytest.approx(-0.99)
    still = standalone_probe(ProbeMove(3, (1, 2, 3, 0, 0, 0), (1, 2, 3, 9, 0, 0), 210, 1))
    assert still.stop == (1, 2, 3, 9, 0, 0)


def test_the_machine_s_answer_is_what_the_program_reads():
    """A probe the machine answers (as the twin will): #5061.. the trip point, #5070 1, and the
    next move starts where the machine stopped; the move it is given is the canon's."""
    moves = []

    def machine(move: ProbeMove) -> ProbeResult:
        moves.append(move)
        return ProbeResult(True, (1.0, 2.0, -1.25, 0.0, 0.0, 0.0), (1.0, 2.0, -1.5, 0.0, 0.0, 0.0))

    text = "G21 G0 X1 Y2 Z3\nG43.1 Z1\nG38.3 Z-5 F100\n(debug, #5063 #5070 #<_z>)\nG1 X[#5063]\nM2\n"
    reading = read_program(Source(text), ToolTable(units=210), probe=machine)
    assert moves == [ProbeMove(3, (1.0, 2.0, 3.0, 0.0, 0.0, 0.0), (1.0, 2.0, -5.0, 0.0, 0.0, 0.0), 210, 3)]
    assert reading.printed == [] and ("MESSAGE", (" -1.250000 1.000000 -1.500000",)) in \
        [(c.name, c.values) for c in reading.calls]
    feed = [c for c in reading.calls if c.name == "STRAIGHT_FEED"][-1]
    assert feed.values == (-1.25, 2.0, -1.5, 0.0, 0.0, 0.0) and feed.line == 5


def test_a_probe_becomes_a_probing_operation_and_the_path_goes_on_from_its_stop():
    """The probing move as an operation (start, end, where the answer stopped, the program's
    frame), and the next move starts from the stop: rs274's standalone answer, backed off
    0.254 mm toward the start."""
    reading = read_program(Source("G21 G0 X1 Z5\nG1 X2 F100\nG38.2 Z-5 F100\nG1 X[#5063 + 3]\nM2\n"), ToolTable())
    ops = operations(reading.calls, start=(0.0, 0.0, 50.0, 0.0, 0.0, 0.0))
    k = next(i for i, op in enumerate(ops) if isinstance(op, Probe))
    probe, after = ops[k], ops[k + 1]
    assert (probe.kind, probe.line, probe.feed, probe.scale) == (2, 3, 100.0, 1.0)
    assert probe.start[:3] == (2.0, 0.0, 5.0) and probe.end[:3] == (2.0, 0.0, -5.0)
    assert probe.stop[2] == pytest.approx(-5.0 + 0.254, abs=1e-12)
    assert after.elements[0].start[2] == pytest.approx(probe.stop[2], abs=1e-12)
    assert after.elements[-1].end[0] == pytest.approx(-5.0 + 3.0)  # X[#5063 + 3]: the trip's Z


def test_a_probe_as_the_first_motion_is_refused_when_the_start_is_not_known():
    reading = read_program(Source("G21 G38.2 Z-5 F100\nM2\n"), ToolTable())
    with pytest.raises(ToolpathError) as refused:
        operations(reading.calls)
    assert refused.value.line == 1 and "\n" not in refused.value.message


# -- outside programs that probe --------------------------------------------------------------------

MACHINE_TOOLS = "".join(f"T{n} P{n} Z0 D0.1\n" for n in range(1, 100))
"""T1-T99, as the outside programs are read with (scripts/outside_programs.py)"""


def test_outside_programs_that_probe_are_read_through_their_probes(monkeypatch):
    """pcb2gcode's auto-levelling programs read whole, probing (rs274's own comparison of them is
    tests/test_outside_corpus.py's)."""
    folder = shared_data.require(shared_data.OUTSIDE_GCODE)
    probing = [p for p in sorted(folder.iterdir()) if re.search(r"G38", p.read_text(errors="replace"))]
    assert len(probing) >= 5
    monkeypatch.setattr(gcode_conformance, "TOOLS", ToolTable.parse(MACHINE_TOOLS, units=200))
    for path in probing:  # each compared with rs274 call for call in tests/test_outside_corpus.py
        text = path.read_text(errors="replace")
        calls, _, error = ours(text)
        assert error is None or "not supported" not in error.message, f"{path.name}: {error.message}"
        assert any(name == "STRAIGHT_PROBE" for name, _ in calls), path.name


def test_backing_off_is_along_the_move():
    """The stop point is 0.254 mm from the trip point, on the line back to the start."""
    result = standalone_probe(ProbeMove(4, (0, 0, 0, 0, 0, 0), (3, 4, 0, 0, 0, 0), 210, 1))
    assert math.dist(result.stop[:3], result.trip[:3]) == pytest.approx(0.254)
    assert math.dist(result.stop[:3], (0, 0, 0)) == pytest.approx(5 - 0.254)
