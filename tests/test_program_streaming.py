"""A long program is read as a stream: its lines held as one text (``Source.lines``), its calls
handed out in batches (``Interpreter.stream``), its operations made as the calls come
(``toolpath.iter_operations``), a feed path cut at ``PATH_ELEMENTS`` programmed elements with
an exact stop on its vertex. What is checked: the same lines, calls and operations as the whole
reading makes, and the memory of reading a program four times as long no larger."""

from __future__ import annotations

import math
import tracemalloc

import numpy as np
from hypothesis import given, settings, strategies as st

from cnc_twin.gcode import toolpath as tp
from cnc_twin.gcode.interpreter import Interpreter, read_program
from cnc_twin.gcode.source import Source
from cnc_twin.gcode.state import ToolTable
from cnc_twin.scenario.resources import programs_dir


def _raster(passes: int, points: int = 400) -> str:
    """A CAM-style raster under G64 P0.01: ``passes`` zig-zag passes of ``points`` G1 lines over
    a waved surface (one chain of blended lines: one feed path unless it is cut)."""
    out = ["G21 G90 G64 P0.01", "G0 X0 Y0 Z5", "G1 Z0 F600", "F3000"]
    for k in range(passes):
        xs = [0.1 * j for j in range(points + 1)]
        for x in (xs if k % 2 == 0 else xs[::-1])[1 if k else 1:]:
            out.append(f"G1 X{x:.4f} Y{0.5 * k:.4f} Z{0.5 * math.sin(x / 3.0) * math.cos(k / 7.0):.4f}")
    return "\n".join(out + ["G0 Z5", "M2"]) + "\n"


def _split_lines(text: str) -> list[str]:
    """The lines as a list of strings would hold them (LinuxCNC's: a newline ends a line, the
    white space ending it stripped)."""
    raw = text.split("\n")
    if raw[-1] == "":
        raw.pop()
    return [line.rstrip(" \t\n\v\f\r") for line in raw]


@settings(max_examples=300, deadline=None)
@given(st.lists(st.sampled_from(["G1 X1", "", " ", "%", " % ", "o100 sub", "(o)", "\r", "\t", "M2", "g0x1 \f",
                                 "x\u00e9y", "%G0"]), max_size=12), st.sampled_from(["\n", "\r\n"]),
       st.booleans())
def test_the_lines_are_those_a_list_of_strings_holds(parts, newline, ends_with_newline):
    text = newline.join(parts) + (newline if ends_with_newline and parts else "")
    source = Source(text)
    lines = _split_lines(text)
    assert list(source.lines) == lines
    assert len(source.lines) == len(lines)
    assert [source.lines[k] for k in range(len(lines))] == lines
    assert source.lines[1:] == lines[1:]
    assert source.text == "\n".join(lines) + "\n"
    # the program's range and its O-word lines, found by one search of the text, as line by line
    first = next((k for k, line in enumerate(lines) if line.strip()), None)
    if first is not None and lines[first].strip() == "%":
        closing = next((j for j in range(first + 1, len(lines)) if lines[j].strip() == "%"), None)
        assert (source.first, source.end) == (first + 1, len(lines) if closing is None else closing)
    else:
        assert (source.first, source.end) == (0, len(lines))
    assert set(source.o_lines) <= {k for k, line in enumerate(lines) if "o" in line.lower()}


def test_the_calls_in_batches_are_the_calls_read_whole():
    text = (programs_dir() / "cam_raster.ngc").read_text()
    whole = read_program(Source(text), ToolTable()).calls
    interpreter = Interpreter(Source(text), ToolTable())
    batches = list(interpreter.stream(100))
    streamed = [call for batch in batches for call in batch]
    assert len(batches) > 10 and max(map(len, batches)) < 2 * 100  # handed out as they were made
    assert [(c.name, c.values, c.line) for c in streamed] == [(c.name, c.values, c.line) for c in whole]


def test_a_long_feed_path_is_cut_with_an_exact_stop_on_its_vertex():
    text = _raster(12)  # 4800 lines, one blended chain
    calls = read_program(Source(text), ToolTable()).calls
    whole = [op for op in tp.operations(calls) if isinstance(op, tp.FeedPath)]
    cut = [op for op in tp.iter_operations(calls, path_elements=1000) if isinstance(op, tp.FeedPath)]
    assert max(_programmed(op) for op in whole) > 4000
    assert max(_programmed(op) for op in cut) <= 1000 and len(cut) >= 5
    # the same programmed path, each cut path starting where the last one stopped
    poly = np.concatenate([tp.programmed_geometry(op.program)[0][1:] for op in cut])
    assert np.array_equal(poly, np.concatenate([tp.programmed_geometry(op.program)[0][1:] for op in whole]))
    for before, after in zip(cut, cut[1:]):
        assert np.array_equal(before.end, after.start)  # a programmed vertex, not a blend's end
        assert np.array_equal(before.end, tp.programmed_geometry(before.program)[0][-1])
    # below the bound, nothing changes
    kept = [op for op in tp.iter_operations(calls, path_elements=10**6) if isinstance(op, tp.FeedPath)]
    assert [(op.line, len(op.elements)) for op in kept] == [(op.line, len(op.elements)) for op in whole]


def _programmed(op) -> int:
    """Programmed elements of a feed path (a chain's lines each)."""
    return sum(len(e.lines) if isinstance(e, tp.LineChain) else 1 for e in op.program)


def test_a_chain_turns_as_its_lines_do():
    from cnc_twin.gcode.feed_paths import element_turn, chain_turns

    calls = read_program(Source((programs_dir() / "cam_raster.ngc").read_text()), ToolTable()).calls
    for op in tp.iter_operations(calls):
        for item in getattr(op, "program", []):
            if isinstance(item, tp.LineChain):
                lines = [tp.line_element(p, q, 0) for p, q in zip(item.points, item.points[1:])]
                assert chain_turns(item.points) == [element_turn(a, b) for a, b in zip(lines, lines[1:])]


def _peak_reading(text: str) -> float:
    """[MB] the most Python held while reading ``text`` into operations, each dropped as it came."""
    source = Source(text)
    tracemalloc.start()
    interpreter = Interpreter(source, ToolTable())

    calls = (call for batch in interpreter.stream(1000) for call in batch)
    for _ in tp.iter_operations(calls, path_elements=1000):
        pass
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak / 2**20


def test_reading_a_program_four_times_as_long_takes_no_more_memory():
    short, long = _raster(6, 300), _raster(24, 300)  # 1800 and 7200 lines
    assert _peak_reading(long) < 1.3 * _peak_reading(short)


def test_the_planner_is_given_the_steps_alone_and_plans_the_same():
    import pickle

    from cnc_twin.planner.gcode_program import GcodePlan
    from cnc_twin.run.program_kinds import kind_of
    from cnc_twin.scenario.load import load_scenario
    from cnc_twin.scenario.resources import scenarios_dir

    sc = load_scenario(scenarios_dir() / "gcode_cam_raster.yaml")
    prog = sc.program
    given = kind_of(prog).for_planner(prog)
    assert given.text == "" and all(p.reference is None for p in given.paths)
    assert all(p.reference is not None for p in prog.paths)  # the twin's own copy keeps them
    assert len(pickle.dumps(given)) < 0.5 * len(pickle.dumps(prog))

    def records(program):
        plan = GcodePlan(program, sc.axes, sc.home, sc.timing.interpolation_period, window=0.05)
        return [(repr(r), n) for chunk, periods in plan.chunks() for r, n in zip(chunk, periods)]

    assert records(given) == records(prog)
