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
