"""G-code programs on the whole twin: the reader's calls become machine steps (offsets, lines,
exact arcs, helices, NURBS, corner blends), run through planner, card and machine, measured from
the trace against the program's own geometry."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from cnc_twin import load_scenario, run_scenario
from cnc_twin.gcode import toolpath as tp
from cnc_twin.gcode.interpreter import read_program
from cnc_twin.gcode.source import Source
from cnc_twin.gcode.state import ToolTable
from cnc_twin.geometry.bezier import bezier_pieces, elevate, join, knot_spans
from cnc_twin.geometry.kinematics import HeadGeometry, rotation_ab
from cnc_twin.geometry.nurbs import NurbsCurve
from cnc_twin.geometry.polyline import point_to_polyline
from cnc_twin.scenario.resources import scenarios_dir
from conftest import run_cli

ROOT = Path(__file__).resolve().parents[1]
THREE_PLUS_TWO = ROOT / "programs" / "polish_3plus2.ngc"


def calls_of(text: str, tmp_path: Path):
    path = tmp_path / "p.ngc"
    path.write_text(text)
    return read_program(Source.read(path), ToolTable(units=210)).calls


def ops_of(text: str, tmp_path: Path):
    return tp.operations(calls_of(text, tmp_path))


def points_of(element: tp.Element, n: int = 200) -> np.ndarray:
    """Points along an element's Bezier pieces, (m, 3) mm."""
    out = []
    t = np.linspace(0.0, 1.0, n)
    for q in element.pieces:
        p = len(q) - 1
        basis = np.array([[math.comb(p, i) * x ** i * (1 - x) ** (p - i) for i in range(p + 1)] for x in t])
        h = basis @ q
        out.append(h[:, :3] / h[:, 3:4])
    return np.vstack(out)


def distance_to_polyline(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    a, b = poly[:-1], poly[1:]
    d = b - a
    rel = points[:, None, :] - a[None, :, :]
    t = np.clip(np.sum(rel * d, axis=2) / np.maximum(np.sum(d * d, axis=1), 1e-300), 0.0, 1.0)
    return np.min(np.linalg.norm(rel - t[..., None] * d[None, :, :], axis=2), axis=1)


# -- geometry: Bezier pieces ----------------------------------------------------------------------

@pytest.mark.parametrize("seed", range(6))
def test_a_nurbs_cut_into_pieces_and_joined_is_the_same_curve(seed):
    rng = np.random.default_rng(seed)
    degree = int(rng.integers(1, 5))
    n = degree + 1 + int(rng.integers(0, 6))
    inner = np.sort(rng.uniform(0.0, 3.0, n - degree - 1))
    if len(inner) > 1:
        inner[1] = inner[0]  # a repeated knot too
    knots = np.concatenate([[0.0] * (degree + 1), inner, [3.0] * (degree + 1)])
    points = rng.normal(size=(n, 3))
    weights = rng.uniform(0.3, 2.0, n)
    curve = NurbsCurve(points, weights, knots, degree)
    pieces = bezier_pieces(points, weights, knots, degree)
    raised = [elevate(q, degree + 1) for q in pieces]
    d, k, w, p = join(raised, knot_spans(knots, degree))
    joined = NurbsCurve(p, w, k, d)
    u = np.linspace(0.0, 3.0, 301)
    assert np.max(np.abs(joined.point(u) - curve.point(u))) < 1e-11


# -- calls -> operations --------------------------------------------------------------------------

def test_work_offsets_and_units_put_the_program_zero_where_canon_does(tmp_path):
    ops = ops_of("G21 G10 L2 P2 X10 Y5 Z1\nG55\nG92 X1\nG0 X1 Y2 Z3\nG20 G0 X1\nM2\n", tmp_path)
    # G92 X1 makes the tool's point (machine X 0) read X1: G0 X1 stays at machine X 0; Y, Z take
    # the G55 offset
    assert ops[0].end[:3] == pytest.approx((0.0, 7.0, 4.0))
    assert ops[1].end[0] == pytest.approx(25.4 - 1.0)  # X1 inch, the offsets (mm) as they were


def test_a_corner_between_lines_is_blended_within_p_and_tangent(tmp_path):
    ops = ops_of("G21 G64 P0.01\nG0 X0 Y0 Z5\nG1 X10 F600\nG1 X10 Y10\nG1 X0 Y12\nM2\n", tmp_path)
    (path,) = [op for op in ops if isinstance(op, tp.FeedPath)]
    kinds = [e.kind for e in path.elements]
    assert kinds == ["line", "blend", "line", "blend", "line"]
    programmed = np.array([[0, 0, 5], [10, 0, 5], [10, 10, 5], [0, 12, 5]], dtype=float)
    for e in path.elements:
        assert distance_to_polyline(points_of(e), programmed).max() <= 0.01 + 1e-12
    for a, b in zip(path.elements, path.elements[1:]):
        assert np.array_equal(a.end, b.start)
        assert np.dot(a.direction(True), b.direction(False)) > 1 - 1e-12


def test_exact_stop_modes_and_other_feeds_stop_at_corners(tmp_path):
    for mode in ("G61", "G61.1"):
        ops = ops_of(f"G21 {mode}\nG0 X0 Y0 Z5\nG1 X10 F600\nG1 Y10\nM2\n", tmp_path)
        assert [len(op.elements) for op in ops if isinstance(op, tp.FeedPath)] == [1, 1]
    ops = ops_of("G21\nG0 X0 Y0 Z5\nG1 X10 F600\nG1 X20 F300\nM2\n", tmp_path)
    assert [op.feed for op in ops if isinstance(op, tp.FeedPath)] == [600.0, 300.0]


def test_an_arc_is_exact_and_a_helix_stays_within_the_tolerance(tmp_path):
    ops = ops_of("G21 G64 P0.002\nG0 X10 Y0 Z0\nG3 X-10 Y0 I-10 J0 F600\nG2 X-30 Y0 Z-3 I-10 J0 P2\nM2\n", tmp_path)
    # the helix leaves the plane: a kink in 3-D, so two paths (an exact stop between)
    arc, helix = [e for op in ops if isinstance(op, tp.FeedPath) for e in op.elements]
    p = points_of(arc)
    assert np.max(np.abs(np.hypot(p[:, 0], p[:, 1]) - 10.0)) < 1e-12 and np.all(p[:, 2] == 0.0)
    p = points_of(helix, 2000)
    assert np.max(np.abs(np.hypot(p[:, 0] + 20.0, p[:, 1]) - 10.0)) < 1e-11
    # clockwise about (-20, 0) from angle 0 through 1.5 turns: z falls by 3 mm over 3 pi
    turned = np.unwrap(np.arctan2(p[:, 1], p[:, 0] + 20.0))
    z_exact = -3.0 * (turned[0] - turned) / (3.0 * math.pi)
    assert np.max(np.abs(p[:, 2] - z_exact)) <= 0.25 * 0.002
    assert np.allclose(helix.end, (-30.0, 0.0, -3.0)) and np.allclose(turned[-1] - turned[0], -3.0 * math.pi)


def test_a_g6_2_curve_starts_where_the_tool_is(tmp_path):
    ops = ops_of("G21\nG0 X0 Y0 Z1\nG1 X1 F100\nG6.2 X1 Y0 R1 K0 P3\nX2 Y0 R1 K0\nX3 Y1 R1 K0\nG6.2 K1\nG6.2 K1\n"
                 "G6.2 K1\nM2\n", tmp_path)
    (path,) = [op for op in ops if isinstance(op, tp.FeedPath)]
    line, curve = path.elements
    assert curve.kind == "curve" and curve.line == 4 and np.array_equal(line.end, curve.start)


def test_a_rotary_g1_is_a_move_with_its_feed_in_degrees(tmp_path):
    ops = ops_of("G21\nG0 X0 Y0 Z5\nG1 B10 F360\nG1 X5 B0 F600\nM2\n", tmp_path)
    moves = [op for op in ops if isinstance(op, tp.Traverse)]
    assert [(m.feed, m.rotary_only) for m in moves[1:]] == [(360.0, True), (600.0, False)]


# -- the whole twin -------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def three_plus_two():
    scenario = load_scenario(scenarios_dir() / "gcode_3plus2.yaml")
    return scenario, run_scenario(scenario)


def test_the_3_plus_2_program_runs_within_every_limit_measured_from_the_trace(three_plus_two):
    scenario, result = three_plus_two
    assert result.metrics["final_state"] == "FINISHED"
    path = result.metrics["path"]
    assert path["feed_paths"] == path["paths_run"] == 2
    assert path["limit_violations"] == []
    assert path["feed_fluctuation"]["max"] < 1e-6
    assert path["chord_error_um"]["max"] <= path["chord_error_um"]["tolerance"]
    for axis, peaks in path["axis_peaks"].items():
        for kind in ("velocity", "acceleration", "jerk"):
            assert peaks[kind] <= peaks[f"{kind}_limit"] * 1.01, (axis, kind)
    assert path["contour_error_um"]["max"] < 40.0  # 26.6 um on the compliant machine (2026-11-27)


def test_the_commanded_tip_follows_the_program_within_its_blend_tolerance(three_plus_two, tmp_path):
    """Every period on a feed path, the commanded tip (encoder counts through the kinematics)
    lies within G64 P (5 um) plus the chord tolerance of the program's own lines, arcs and curve
    (built from its calls without blending)."""
    scenario, result = three_plus_two
    trace = result.trace
    tpp = scenario.timing.ticks_per_period
    on = trace.period_signals["path_u"][tpp - 1::tpp] >= 0.0
    axes = trace.command[tpp - 1::tpp][on] / trace.counts_per_unit + np.asarray(scenario.home)
    curve = scenario.program.paths[0].curve  # the head geometry, as the path metrics take it
    pivot, offset = np.asarray(curve.pivot_home), np.asarray(curve.tool_offset)
    head = HeadGeometry.from_model(mujoco.MjModel.from_xml_path(str(scenario.model_file)))
    origin = head.world_from_workpiece(np.zeros((1, 3)))[0]
    tips = np.array([q[:3] + pivot + rotation_ab(q[3], q[4]) @ offset for q in axes]) / 1e-3 - origin / 1e-3
    calls = read_program(Source.read(THREE_PLUS_TWO), ToolTable(units=210)).calls
    programmed, here = [], None
    for call in calls:  # the program's feed geometry, unblended (no offsets in this program)
        if call.name in ("STRAIGHT_FEED", "STRAIGHT_TRAVERSE"):
            end = np.array(call.values[:3], dtype=float)
            if call.name == "STRAIGHT_FEED" and here is not None:
                programmed.append(np.linspace(here, end, 400))
            here = end
        elif call.name == "ARC_FEED":
            element = tp.arc_element(here, call.payload, np.zeros(3), 1.0, 1e-4, call.line)
            programmed.append(points_of(element, 400))
            here = element.end
        elif call.name == "NURBS_FEED":
            curve = call.payload.curve()
            programmed.append(curve.point(np.linspace(*curve.domain, 4000)))
            here = np.asarray(call.payload.end)
    # (the tree-searched distance of the path metrics, tests/test_path_metrics.py: the brute force
    # above, periods x points of every element, took 10 s here)
    distance = np.min([point_to_polyline(tips, poly) for poly in programmed], axis=0)
    assert distance.max() <= 0.005 + 0.001 + 1e-3, distance.max()  # [mm] P + chord + 1 um of the sampling


def test_the_trace_shows_the_program_line_of_every_block_it_runs(three_plus_two):
    scenario, result = three_plus_two
    tpp = scenario.timing.ticks_per_period
    marks = result.trace.period_signals["mark"][tpp - 1::tpp]
    seen = list(dict.fromkeys(int(m) for m in marks if m))
    # spindle, moves 8-12, the path's lines, arcs and the G6.2 curve (its first block, line 21),
    # dwell, moves, M5, M2 (the spindle stopped at the end)
    assert seen == [7, 8, 9, 10, 11, 12, 14, 15, 16, 17, 18, 19, 21, 29, 30, 31, 32, 33]


# -- cnc-twin run part.ngc ------------------------------------------------------------------------

SHORT = "G21 G90\nG0 X0 Y0 Z5\nG1 X4 F1200\nG2 X6 Y-2 I0 J-2\nM2\n"


def test_run_takes_a_program_directly_and_keeps_it_in_the_run_directory(tmp_path):
    program = tmp_path / "short.ngc"
    program.write_text(SHORT)
    code, _, err = run_cli("run", program, "--out", tmp_path / "run")
    assert code == 0, err
    assert (tmp_path / "run" / "short.ngc").read_text() == SHORT
    code, out, err = run_cli("validate", tmp_path / "run" / "scenario.yaml")
    assert code == 0 and "1 feed path" in out, out + err


def test_run_takes_a_tool_table_and_keeps_it_so_the_run_directory_runs_again(tmp_path):
    """`cnc-twin run part.ngc --tool-table t.tbl`: G43 H1 lifts the commanded Z by the tool's
    length (LinuxCNC: machine Z = programmed Z + length); the table is kept beside the program."""
    from cnc_twin.trace.parquet import read_trace

    (tmp_path / "plain.ngc").write_text("G21 G90\nG0 X1 Z5\nM2\n")
    (tmp_path / "tooled.ngc").write_text("G21 G90\nT1 M6\nG43 H1\nG0 X1 Z5\nM2\n")
    (tmp_path / "tools.tbl").write_text("T1 P1 Z2.0 D6 ;a 2 mm tool\n")
    runs = {}
    for name, extra in (("plain", ()), ("tooled", ("--tool-table", tmp_path / "tools.tbl"))):
        code, _, err = run_cli("run", tmp_path / f"{name}.ngc", *extra, "--out", tmp_path / name, "--no-rrd", "--quiet")
        assert code == 0, err
        runs[name] = read_trace(tmp_path / name / "trace.parquet")["command_Z"][-1]
    assert runs["tooled"] - runs["plain"] == pytest.approx(2000.0, abs=1.0)  # counts: 1 um each
    assert (tmp_path / "tooled" / "tools.tbl").read_text() == (tmp_path / "tools.tbl").read_text()
    code, out, err = run_cli("validate", tmp_path / "tooled" / "scenario.yaml")
    assert code == 0, out + err
    code, _, _ = run_cli("run", tmp_path / "tooled.ngc", "--out", tmp_path / "none", "--tool-table", tmp_path / "no.tbl")
    assert code == 2 and not (tmp_path / "none").exists()


@pytest.mark.parametrize("program, line, words", [
    ("G21\nG0 X0 Y0 Z5\nG1 X900 F100\nM2\n", 3, "soft limits"),
    ("G21\nG0 X0 Y0 Z5\nM100 P20\nM2\n", 3, "no feed move follows"),
    ("G21\nG0 X0 Y0 Z5\nM100 P20\nG1 X5 F100\nG0 Z9\nM2\n", 5, "M101 first"),
    ("G21\nG0 X0 Y0 Z5\nM100 P20\nG1 X5 F100\nM100 P10\nM2\n", 5, "M101 first"),
    ("G21\nG0 X0 Y0 Z5\nG15\nM2\n", 3, "Unknown g code used"),
    ("G21\nG0 X0 Y0 Z5\nG0 Z900\nM2\n", 3, "outside its"),
])
def test_a_bad_program_is_refused_at_its_line_before_any_motion(program, line, words, tmp_path):
    path = tmp_path / "bad.ngc"
    path.write_text(program)
    code, out, err = run_cli("run", path, "--out", tmp_path / "run")
    assert code == 2 and not (tmp_path / "run").exists()
    (message,) = err.strip().splitlines()
    assert message.startswith(f"error: {path}:{line}: ") and words in message, message


def test_a_curve_record_carries_its_program_lines_to_the_card():
    from cnc_twin.whiteboard.codec import decode, encode
    from cnc_twin.whiteboard.records import CurveGeometry

    record = CurveGeometry(degree=1, knots=(0.0, 0.0, 1.0, 2.0, 2.0), weights=(1.0, 1.0, 1.0),
                           control_points=((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 1.0, 0.0)),
                           hold=(0.0, 0.0, 0.0), lines=((0.0, 12), (1.0, 13)))
    seq, back = decode(encode(record, 7))
    assert (seq, back) == (7, record)
    assert decode(encode(dataclasses.replace(record, lines=()), 8))[1].lines == ()


@pytest.mark.parametrize("mode, overrides, chord_mm", [
    ("G64 P0.02", {}, 0.02),                                   # G64 P: the card's chord tolerance
    ("G61", {}, 0.001),                                        # exact path: the default
    ("G64", {}, 0.001),                                        # G64 without P: the default
    ("G64 P0.02", {"program.chord_tolerance": 0.002}, 0.002),  # the scenario's, when it gives one
])
def test_g64_p_is_the_chord_tolerance_of_the_paths_it_governs(mode, overrides, chord_mm, tmp_path):
    (tmp_path / "p.ngc").write_text(f"G21 G90 {mode}\nG0 X0 Y0 Z5\nG1 X10 F600\nG3 X20 Y10 R10\nM2\n")
    program = load_scenario(tmp_path / "p.ngc", overrides=overrides).program
    (path,) = program.paths
    assert path.curve.limits.chord_tolerance == pytest.approx(chord_mm * 1e-3)


def test_an_f_above_what_the_axes_allow_along_a_path_is_said_once_before_the_run_and_kept(tmp_path):
    """G1 X100 F40000 along X (X's max_velocity 24000 mm/min): the command says before the run, once,
    with the line and the speed the path runs at, and metrics.json keeps it; the trace shows that
    speed and no more. The same F along the XY diagonal (24000 x sqrt 2 = 33941 mm/min allowed) is
    still too fast and runs at 33941; F30000 on the diagonal is allowed and says nothing."""
    import json

    from cnc_twin.trace.parquet import read_trace

    def run(text: str, name: str):
        program = tmp_path / f"{name}.ngc"
        program.write_text(text)
        code, _, err = run_cli("run", program, "--out", tmp_path / name, "--no-rrd", "--quiet")
        assert code == 0, err
        notes = [line for line in err.splitlines() if line.startswith("note:")]
        metrics = json.loads((tmp_path / name / "metrics.json").read_text())
        trace = read_trace(tmp_path / name / "trace.parquet")
        xy = np.stack([trace["command_X"], trace["command_Y"]], axis=1) / 1000.0  # [mm], 1 um per count
        speed = np.linalg.norm(np.diff(xy, axis=0), axis=1) / np.diff(trace["time"]) * 60.0  # [mm/min]
        speed_x = np.abs(np.diff(xy[:, 0])) / np.diff(trace["time"]) * 60.0
        on_the_path = trace["mark"][1:] == 3  # the G1's line (the G0 before it runs at the axes' own limits)
        return notes, metrics.get("notices", []), speed[on_the_path].max(), speed_x[on_the_path].max()

    notes, kept, top, _ = run("G21 G90\nG0 X0 Y0 Z5\nG1 X300 F40000\nM2\n", "along_x")
    assert len(notes) == 1 and "line 3" in notes[0] and "24000 mm/min" in notes[0], notes
    assert kept == [notes[0].split("along_x.ngc: ", 1)[1]]  # the command names the program first
    assert 0.97 * 24000 <= top <= 24000 * 1.001
    notes, kept, top, _ = run("G21 G90\nG0 X-280 Y-280 Z5\nG1 X280 Y280 F40000\nM2\n", "diagonal")
    assert len(notes) == 1 and "33941 mm/min" in notes[0], notes
    assert 0.97 * 33941 <= top <= 33941 * 1.001
    notes, kept, top, _ = run("G21 G90\nG0 X-280 Y-280 Z5\nG1 X280 Y280 F30000\nM2\n", "allowed")
    assert notes == [] and kept == []
    assert 0.97 * 30000 <= top <= 30000 * 1.001
    # a G1 that turns the head runs as one coordinated move: its cap is said too
    notes, kept, _, top_x = run("G21 G90\nG0 X0 Y0 Z5\nG1 X300 A5 F40000\nM2\n", "turning")
    assert len(notes) == 1 and "line 3" in notes[0] and "24000 mm/min" in notes[0], notes
    assert 0.97 * 24000 <= top_x <= 24000 * 1.001  # X at its limit (Y turns a little with the head)


def test_cam_output_that_selects_a_tool_and_a_router_speed_runs_on_the_bundled_machine(tmp_path):
    """T5 M6 / G43 H5 read from the machine's own tool table (models/polisher.tbl: T1-T99, length 0,
    the pad's face is the tool point); M3 S15000 on the 2700 rpm spindle is said once at load with
    its line and turns at 2700 rpm, as LinuxCNC's motion holds it, instead of a C following-error
    fault: the trace's C speed reaches 2700 rpm and no more."""
    import json

    from cnc_twin.scenario.load import load_scenario
    from cnc_twin.trace.parquet import read_trace

    program = tmp_path / "router.ngc"
    program.write_text("G21 G90\nT5 M6\nG43 H5\nM3 S15000\nG0 X10 Y10 Z20\nG4 P1\nG1 X20 F600\nM5\nM2\n")
    code, _, err = run_cli("run", program, "--out", tmp_path / "run", "--no-rrd", "--quiet")
    assert code == 0, err
    notes = [line for line in err.splitlines() if line.startswith("note:")]
    assert len(notes) == 1 and "line 4" in notes[0] and "S15000" in notes[0] and "2700 rpm" in notes[0], err
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert metrics["status"] == "complete" and metrics["final_state"] == "FINISHED"
    trace = read_trace(tmp_path / "run" / "trace.parquet")
    per_rad = load_scenario(program).axis("C").counts_per_unit
    rpm = np.abs(np.diff(trace["command_C"])) / per_rad / np.diff(trace["time"]) * 60.0 / (2.0 * np.pi)
    assert 0.99 * 2700 <= rpm.max() <= 2700 * 1.001
