"""CAM's dense G1 runs fitted as one curve within G64 P (cnc_twin.gcode.line_fit): the band
measured here independently against the program's points and segments; corners, stops and exact
modes are never fitted across."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from cnc_twin.gcode import toolpath as tp
from cnc_twin.geometry.kinematics import HeadGeometry
from test_fit import segment_distance
from test_gcode_twin import ops_of, points_of


def dense_program(mode: str, *, corner: bool = False, between: str = "", step: float = 0.4) -> tuple[str, np.ndarray]:
    """A CAM-like run of G1 lines (a gentle wave, chords within 2 um of it) under ``mode``;
    ``corner``: a 90 deg turn in the middle; ``between``: a line inserted in the middle."""
    s = np.arange(0.0, 60.0 + step / 2, step)
    pts = np.column_stack([s - 30.0, 6.0 * np.sin(s / 15.0), np.zeros_like(s)])
    if corner:
        half = len(s) // 2
        pts[half:] = pts[half] + np.column_stack([np.zeros(len(s) - half), s[half:] - s[half], np.zeros(len(s) - half)])
    pts = np.round(pts, 4)
    body = [f"G1 X{x:.4f} Y{y:.4f}" for x, y, _ in pts[1:]]
    if between:
        body.insert(len(body) // 2, between)
    text = "\n".join([f"G21 G90 G17 G94 {mode}", "G0 Z5", f"G0 X{pts[0, 0]:.4f} Y{pts[0, 1]:.4f}", "G1 Z0 F600",
                      "F3000", *body, "M2"]) + "\n"
    return text, pts


def feed_paths(ops) -> list[tp.FeedPath]:
    return [op for op in ops if isinstance(op, tp.FeedPath)]


def test_a_dense_run_becomes_one_fitted_curve_within_p_of_every_point_and_segment(tmp_path):
    text, pts = dense_program("G64 P0.01")
    paths = feed_paths(ops_of(text, tmp_path))
    path = paths[-1]  # after the plunge
    kinds = [e.kind for e in path.elements]
    assert kinds == ["line", "fit", "line"]
    fit = path.elements[1]
    assert len(fit.pieces) < len(pts) / 5  # far fewer spans than segments
    drawn = np.vstack([points_of(e, 400) for e in path.elements])
    assert segment_distance(drawn, pts).max() <= 0.01  # the path stays within P of the segments
    assert segment_distance(pts, drawn).max() <= 0.01  # and passes within P of every point
    # each piece knows its program line, increasing along the run
    assert fit.piece_lines == sorted(fit.piece_lines) and len(set(fit.piece_lines)) > 1


def test_the_fit_joins_its_half_lines_tangent_and_without_curvature(tmp_path):
    text, _ = dense_program("G64 P0.01")
    head, fit, tail = feed_paths(ops_of(text, tmp_path))[-1].elements
    assert np.allclose(head.end, fit.start) and np.allclose(fit.end, tail.start)
    assert np.dot(head.direction(True), fit.direction(False)) == pytest.approx(1.0, abs=1e-12)
    assert np.dot(fit.direction(True), tail.direction(False)) == pytest.approx(1.0, abs=1e-12)
    for piece in (fit.pieces[0], fit.pieces[-1][::-1]):  # the second difference at each end is along the line
        xyz = piece[:, :3] / piece[:, 3:4]
        second = xyz[2] - 2 * xyz[1] + xyz[0]
        along = xyz[1] - xyz[0]
        assert np.linalg.norm(np.cross(second, along)) <= 1e-9 * np.linalg.norm(along) ** 2 + 1e-12


def test_a_real_corner_is_not_fitted_across_nor_rounded_beyond_p(tmp_path):
    text, pts = dense_program("G64 P0.01", corner=True)
    path = feed_paths(ops_of(text, tmp_path))[-1]
    kinds = [e.kind for e in path.elements]
    assert kinds.count("fit") == 2 and "blend" in kinds  # a fit on each side, the corner blended
    corner = pts[len(pts) // 2]
    drawn = np.vstack([points_of(e, 400) for e in path.elements])
    # the corner kept within P (the blend's apex is at P exactly; the samples straddle it)
    assert np.min(np.linalg.norm(drawn - corner, axis=1)) <= 0.01 * (1 + 1e-4)
    assert segment_distance(drawn, pts).max() <= 0.01


@pytest.mark.parametrize("between", ["G4 P0.1", "M0", "M3 S600", "F2000", "M100 P10"])
def test_a_stop_code_between_segments_is_not_fitted_across(between, tmp_path):
    text, pts = dense_program("G64 P0.01", between=between)
    ops = ops_of(text, tmp_path)
    paths = feed_paths(ops)[1:]  # after the plunge
    assert len(paths) == 2  # the run ends where the code stands, and starts again after it
    cut = paths[0].end
    assert np.min(np.linalg.norm(pts - cut, axis=1)) < 1e-9  # at a programmed point, exactly


@pytest.mark.parametrize("mode", ["G61", "G61.1", "G64"])
def test_exact_modes_and_g64_without_p_fit_nothing(mode, tmp_path):
    text, _ = dense_program(mode)
    kinds = {e.kind for path in feed_paths(ops_of(text, tmp_path)) for e in path.elements}
    assert "fit" not in kinds


def test_a_run_too_sharp_for_p_stays_lines(tmp_path):
    """A zig-zag turning 20 deg at every 0.5 mm point (under the corner angle) cannot be followed
    within 1 um of its segments by a smooth curve: it stays lines, each corner blended."""
    turn = math.radians(20.0)
    angles = np.array([(turn / 2) * (1 if k % 2 else -1) for k in range(40)])
    steps = 0.5 * np.column_stack([np.cos(angles), np.sin(angles), np.zeros(40)])
    pts = np.vstack([[0.0, 0.0, 0.0], np.cumsum(steps, axis=0)])
    body = "\n".join(f"G1 X{x:.6f} Y{y:.6f}" for x, y, _ in pts[1:])
    text = f"G21 G90 G64 P0.001\nG0 X0 Y0 Z0\nF1000\n{body}\nM2\n"
    kinds = [e.kind for e in feed_paths(ops_of(text, tmp_path))[0].elements]
    assert "fit" not in kinds and kinds.count("blend") == 39


# -- on the twin: checked from the trace ----------------------------------------------------------

@pytest.fixture(scope="module")
def fitted_and_exact(tmp_path_factory):
    from cnc_twin import load_scenario, run_scenario

    folder = tmp_path_factory.mktemp("dense")
    out = {}
    for name, mode in (("fitted", "G64 P0.01"), ("exact", "G61.1")):
        text, pts = dense_program(mode)
        (folder / f"{name}.ngc").write_text(text)
        scenario = load_scenario(folder / f"{name}.ngc")
        out[name] = (scenario, run_scenario(scenario), pts)
    return out


def test_the_fitted_run_stays_within_p_of_the_program_in_every_period(fitted_and_exact):
    scenario, result, pts = fitted_and_exact["fitted"]
    m = result.metrics
    assert m["final_state"] == "FINISHED"
    d = m["program"]["deviation_um"]
    assert d["tolerance_um"] == pytest.approx(10.0)
    assert d["max"] <= 10.0 and d["vertices_max"] <= 10.0
    # independently: the commanded tip at every period's end on the fitted path, against the
    # program's own points and segments (workpiece frame -> world)
    trace = result.trace
    tpp = scenario.timing.ticks_per_period
    ends = slice(tpp - 1, None, tpp)
    u = trace.period_signals["path_u"][ends]
    command = trace.command[ends] / trace.counts_per_unit + np.asarray(scenario.home)
    curve = scenario.program.paths[-1].curve
    head = HeadGeometry(curve.pivot_home, curve.tool_offset, (0.0, 0.0, 0.0))
    tips = head.forward(command[:, :5])[0]
    origin = np.asarray(HeadGeometry.from_model(mujoco.MjModel.from_xml_path(str(scenario.model_file))).workpiece_origin)
    program = pts * 1e-3 + origin
    on = (u >= 0.0) & (tips[:, 2] < program[0, 2] + 1e-6)  # on a path, down at the program's height
    assert np.count_nonzero(on) > 1000
    assert segment_distance(tips[on], program).max() <= 10e-6
    assert m["path"]["limit_violations"] == []
    assert m["whiteboard"]["underrun_periods"] == 0  # the planner kept ahead of the card


def test_the_fitted_run_holds_the_feed_and_beats_segment_by_segment(fitted_and_exact):
    fitted = fitted_and_exact["fitted"][1].metrics["program"]
    exact = fitted_and_exact["exact"][1].metrics["program"]
    assert fitted["fits"]["runs"] == 1 and exact["fits"]["runs"] == 0
    assert fitted["feed"]["time_s"] <= 1.10 * fitted["feed"]["ideal_time_s"]  # within 10 % of the F-limited time
    assert fitted["feed"]["share_at_95pct"] >= 0.85
    assert exact["feed"]["time_s"] >= 3.0 * fitted["feed"]["time_s"]  # a stop at every point
    assert exact["feed"]["share_at_95pct"] <= 0.2


# -- 5-axis: G1 runs turning A / B ------------------------------------------------------------------

def tilted_program(mode: str, step: float = 0.5) -> tuple[str, np.ndarray, np.ndarray]:
    """A pass over a bump with the tool along its normal (A / B words), as 5-axis CAM writes it:
    the program, the tip points (mm) and the unit tool axes there."""
    from cnc_twin.geometry.kinematics import ab_from_axis, tool_axis

    x = np.arange(-40.0, 40.0 + step / 2, step)
    y = np.full_like(x, 5.0)
    bump = 3.0 * np.exp(-((x / 30.0) ** 2 + (y / 25.0) ** 2))  # z = 2 + bump, 2 mm above the block
    z = 2.0 + bump
    n = np.column_stack([bump * 2 * x / 900.0, bump * 2 * y / 625.0, np.ones_like(x)])  # (-dz/dx, -dz/dy, 1)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    a, b = (np.round(np.degrees(v), 4) for v in ab_from_axis(n))
    axes = np.array([tool_axis(np.radians(p), np.radians(q)) for p, q in zip(a, b)])  # as the words give them
    pts = np.round(np.column_stack([x, y, z]), 4)
    body = [f"G1 X{p[0]:.4f} Y{p[1]:.4f} Z{p[2]:.4f} A{p_a:.4f} B{p_b:.4f}" for p, p_a, p_b in zip(pts[1:], a[1:], b[1:])]
    text = "\n".join([f"G21 G90 G17 G94 {mode}", "G0 Z20", f"G0 X{pts[0, 0]:.4f} Y{pts[0, 1]:.4f} A{a[0]:.4f} B{b[0]:.4f}",
                      f"G1 Z{pts[0, 2]:.4f} F600", "F3000", *body, "G0 Z20", "M2"]) + "\n"
    return text, pts, axes


def test_a_run_turning_the_head_is_fitted_as_tip_and_tool_axis_curves(tmp_path):
    from scipy.interpolate import BSpline

    text, pts, axes = tilted_program("G64 P0.01")
    ops = ops_of(text, tmp_path)
    (run,) = [op for op in ops if isinstance(op, tp.ToolAxisPath)]
    assert not [op for op in ops if isinstance(op, tp.Traverse) and op.feed == 3000.0]  # no G1 left as a move
    u = np.linspace(run.knots[0], run.knots[-1], 8001)
    tip = BSpline(run.knots, run.points, 3)(u)
    assert segment_distance(tip, pts).max() <= 0.01 and segment_distance(pts, tip).max() <= 0.01
    chord = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    got = BSpline(run.knots, run.axis_points, 3)(chord)
    got /= np.linalg.norm(got, axis=1, keepdims=True)
    angle = np.degrees(np.arccos(np.clip(np.sum(got * axes, axis=1), -1, 1)))
    assert angle.max() <= 0.05  # the default axis tolerance [deg]
    assert len(np.unique(run.knots)) - 1 < len(pts) / 5


def test_g61_1_runs_a_head_turning_run_move_by_move(tmp_path):
    text, pts, _ = tilted_program("G61.1")
    ops = ops_of(text, tmp_path)
    assert not [op for op in ops if isinstance(op, tp.ToolAxisPath)]
    assert len([op for op in ops if isinstance(op, tp.Traverse) and op.feed == 3000.0]) == len(pts) - 1


def test_the_head_turning_run_on_the_twin_stays_within_p_and_the_axis_tolerance(tmp_path):
    from cnc_twin import load_scenario, run_scenario

    text, pts, _ = tilted_program("G64 P0.01")
    (tmp_path / "five.ngc").write_text(text)
    result = run_scenario(load_scenario(tmp_path / "five.ngc"))
    m = result.metrics
    assert m["final_state"] == "FINISHED" and m["path"]["limit_violations"] == []
    program = m["program"]
    assert program["deviation_um"]["max"] <= 10.0 and program["deviation_um"]["vertices_max"] <= 10.0
    assert program["axis_deviation_deg"]["max"] <= program["axis_deviation_deg"]["tolerance"] == 0.05
    assert program["feed"]["time_s"] <= 1.10 * program["feed"]["ideal_time_s"]


def test_a_head_turning_run_under_the_force_loop_is_refused_at_its_line(tmp_path):
    from conftest import run_cli

    text, _, _ = tilted_program("G64 P0.01")
    text = text.replace("F3000\n", "F3000\nM100 P10\n")
    (tmp_path / "p.ngc").write_text(text)
    code, _, err = run_cli("run", tmp_path / "p.ngc", "--out", tmp_path / "run")
    assert code == 2 and "turning A / B while the grinding-force loop is on" in err and not (tmp_path / "run").exists()
