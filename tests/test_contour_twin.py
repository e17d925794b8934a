"""Contours run by NURBS, point-by-point and DDA interpolation on the twin, with pulse or analog output."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from cnc_twin.dsp.step_interpolator import StepRun
from cnc_twin.core.errors import ScenarioError
from cnc_twin.geometry.kinematics import HeadGeometry
from cnc_twin.scenario.load import load_scenario, scenario_from_dict
from cnc_twin.run.twin import run_scenario
from cnc_twin.whiteboard.records import STEP_ARC, STEP_DDA, STEP_POINT_BY_POINT, StepContour
from cnc_twin.motion.scurve import SCurve
from conftest import REPO


@pytest.fixture(scope="module")
def three_ways():
    """circle_three_ways.yaml as shipped (pulse output), run once."""
    scenario = load_scenario(REPO / "scenarios" / "circle_three_ways.yaml")
    return scenario, run_scenario(scenario)


def test_the_circle_runs_three_ways_and_reports_the_passes_side_by_side(three_ways):
    scenario, result = three_ways
    assert result.metrics["final_state"] == "FINISHED"
    passes = result.metrics["contour"]["passes"]
    assert [p["method"] for p in passes] == ["nurbs", "point_by_point", "dda"]
    for p in passes:
        assert p["ran"]
        # the same S-curve feed along the same length: the passes take the same time within a period
        assert p["duration_s"] == pytest.approx(passes[0]["duration_s"], abs=2e-3)
        # [um] the compliant machine's loops (X 33.8 / Y 42.3 1/s): 41 um at most on 2026-11-27
        assert 0.5 < p["contour_error_um"]["rms"] < p["contour_error_um"]["max"] < 60.0
    nurbs, pbp, dda = passes
    assert nurbs["command_deviation_um"]["max"] <= 1.0  # chord tolerance 1 um
    # every lattice point within one pulse (1 um) of the circle; 8 R steps around a full circle
    assert pbp["command_deviation_um"]["max"] <= 1.0 + 1e-9
    assert dda["command_deviation_um"]["max"] <= 1.0 + 1e-9
    assert pbp["steps"] == dda["steps"] == 8 * 20000
    assert result.metrics["pulse_limited_ticks"] == dict.fromkeys("XYZABC", 0)


def test_step_passes_end_exactly_on_their_lattice_end_point(three_ways):
    scenario, result = three_ways
    trace = result.trace
    mark = trace.period_signals["mark"]
    start = scenario.program.lattice[0].start
    for number in (2, 3):
        ticks = np.flatnonzero(mark == number)
        assert tuple(trace.command[ticks[-1], :2]) == start
        # the commands are whole counts: the card's lattice, not a line between period setpoints
        assert np.array_equal(trace.command[ticks, :2], np.round(trace.command[ticks, :2]))


def test_no_pulse_is_lost_between_the_card_and_the_drives(three_ways):
    scenario, result = three_ways
    if any(axis.compensation is not None and axis.compensation.backlash for axis in scenario.axes):
        # the backlash compensation sends pulses of its own, which the trace's command leaves out:
        # here every pulse is to be found in the command
        result = run_scenario(load_scenario(REPO / "scenarios" / "circle_three_ways.yaml",
                                             overrides={f"axes.{a}.compensation.backlash": 0 for a in "XYZ"}))
    trace = result.trace
    # in pulse output the dac columns hold the pulses of each tick: their sum is the last command
    sent = trace.dac.astype(np.int64).sum(axis=0)
    assert np.array_equal(sent, np.floor(trace.command[-1] + 0.5).astype(np.int64))


def test_lockstep_contour_runs_are_bit_identical(three_ways):
    scenario, first = three_ways
    again = run_scenario(scenario)
    for name in ("command", "actual", "dac"):
        assert np.array_equal(getattr(first.trace, name), getattr(again.trace, name))


def _contour(**program) -> dict:
    base = {"type": "contour", "start": [0, 0], "z": 20, "feed": 2400,
            "elements": [{"line": {"to": [15, 5]}},
                         {"arc": {"to": [20, 10], "center": [20, 5], "direction": "cw"}},
                         {"line": {"to": [20, 20]}}],
            "method": ["point_by_point", "dda"], "dwell": 0.05, "settle": 0.05}
    base.update(program)
    return {"name": "contour_parts", "program": base}


def test_lines_and_arcs_with_analog_output_step_exactly_their_pulses():
    scenario = scenario_from_dict(_contour())
    result = run_scenario(scenario)
    assert result.metrics["final_state"] == "FINISHED"
    lat = scenario.program.lattice
    # point-by-point: |dx| + |dy| steps per line, the arc's quadrant pieces likewise
    expected = sum(abs(e.end[0] - e.start[0]) + abs(e.end[1] - e.start[1]) for e in lat)
    for p in result.metrics["contour"]["passes"]:
        assert p["steps"] == expected
        assert p["command_deviation_um"]["max"] <= 1.0 + 1e-9
        assert p["contour_error_um"]["max"] < 40.0


def test_the_step_clock_follows_the_s_curve():
    profile = SCurve.plan(0.02 * np.pi / 2, 0.0, 0.0, v_max=0.05, a_max=1.0, j_max=50.0)
    held = [0.0] * 6
    for method in (STEP_POINT_BY_POINT, STEP_DDA):
        rec = StepContour(method=method, kind=STEP_ARC, start=(20000, 0), end=(0, 20000), center=(0, 0),
                          clockwise=False, profile=profile)
        run = StepRun(rec, held)
        assert run.point_at(0.0)[:2] == [20000.0, 0.0]
        assert run.end[:2] == [0.0, 20000.0]
        t = np.linspace(0.0, profile.duration, 500)
        pts = np.array([run.point_at(x)[:2] for x in t])
        # never backwards along the quarter (x falls, y rises), within one pulse of the circle
        assert np.all(np.diff(pts[:, 0]) <= 0) and np.all(np.diff(pts[:, 1]) >= 0)
        assert np.abs(np.hypot(pts[:, 0], pts[:, 1]) - 20000).max() <= 1.0
        # the lattice position follows the S-curve: a quarter of the way in time is not a quarter
        # of the way along the arc (the ramp), but the middle of the profile is the middle of the arc
        mid = run.point_at(profile.duration / 2)[:2]
        assert abs(np.degrees(np.arctan2(mid[1], mid[0])) - 45.0) < 0.01


@pytest.mark.parametrize("change, key, message", [
    ({"elements": [{"arc": {"to": [10, 10.5], "center": [0, 10], "direction": "ccw"}}], "start": [0, 0]},
     "program.elements", "radius"),
    ({"elements": [{"line": {"to": [5, 0]}, "arc": {"to": [5, 0], "center": [0, 0], "direction": "cw"}}]},
     "program.elements[0]", "exactly one of"),
    ({"method": []}, "program.method", "at least one"),
    ({"method": "bresenham"}, "program.method", ""),
    ({"elements": [{"line": {"to": [0, 0]}}]}, "program.elements", "zero.length|shorter"),
])
def test_bad_contours_are_refused_with_the_key_path(change, key, message):
    with pytest.raises(ScenarioError) as info:
        scenario_from_dict(_contour(**change))
    assert info.value.key_path.startswith(key)
    assert re.search(message, info.value.message)


def test_an_arc_end_off_the_pulse_lattice_circle_is_refused():
    from cnc_twin.geometry.contour import Arc
    from cnc_twin.scenario.contour import _lattice

    cpu = (1e6, 1e6)
    ok = _lattice(Arc((0.01, 0.0), (0.0, 0.01), (0.0, 0.0), False), (0.0, 0.0), cpu, Path("s.yaml"), "k")
    assert (ok.start, ok.end, ok.center) == ((10000, 0), (0, 10000), (0, 0))
    # 3 pulses beyond the circle at the end: the cards' end judgement would never reach it
    with pytest.raises(ScenarioError, match=r"radius 10\.0000 mm at the start, 10\.0030 mm at the end"):
        _lattice(Arc((0.01, 0.0), (0.0, 0.010003), (0.0, 0.0), False), (0.0, 0.0), cpu, Path("s.yaml"), "k")


def _sampled_distance(points: np.ndarray, elements, spacing: float = 0.5e-6) -> np.ndarray:
    """Each point's distance [m] to the lines and arcs sampled every ``spacing`` m (an outside
    check of the exact distance the metrics use: nearest sample by a k-d tree; it overstates a
    distance d by at most (spacing / 2)^2 / (2 d))."""
    from scipy.spatial import cKDTree

    from cnc_twin.geometry.contour import Line

    samples = []
    for el in elements:
        start, end = np.asarray(el.start), np.asarray(el.end)
        if isinstance(el, Line):
            t = np.linspace(0.0, 1.0, int(np.ceil(np.linalg.norm(end - start) / spacing)) + 1)
            samples.append(start + t[:, None] * (end - start))
            continue
        centre = np.asarray(el.center)
        radius = np.linalg.norm(start - centre)
        a0, a1 = (np.arctan2(*(q - centre)[::-1]) for q in (start, end))
        sweep = (a1 - a0) % (2 * np.pi) if not el.clockwise else -((a0 - a1) % (2 * np.pi))
        if sweep == 0.0:  # end == start: the full circle
            sweep = -2 * np.pi if el.clockwise else 2 * np.pi
        angle = a0 + np.linspace(0.0, sweep, int(np.ceil(abs(sweep) * radius / spacing)) + 1)
        samples.append(centre + radius * np.column_stack([np.cos(angle), np.sin(angle)]))
    return cKDTree(np.vstack(samples)).query(points)[0]


def test_the_contour_figures_are_the_distances_to_the_lines_and_arcs(three_ways):
    scenario, result = three_ways
    trace = result.trace
    ticks = np.flatnonzero(trace.period_signals["mark"] == 1)
    cpu = scenario.axes[0].counts_per_unit
    xy = trace.actual[ticks, :2] / cpu + np.array(scenario.home[:2])
    d = _sampled_distance(xy, scenario.program.elements) * 1e6
    first = result.metrics["contour"]["passes"][0]
    assert d.max() == pytest.approx(first["encoder_contour_error_um"]["max"], abs=0.01)
    # the tool's true position (its recorded tip, the tool vertical): within the encoders' count of theirs
    periods = np.flatnonzero(trace.periods["mark"][:len(trace.tool)] == 1)
    head = HeadGeometry.from_model(result.model)
    tip, pivot = trace.tool[periods, :3], trace.tool[periods, 3:]
    true = _sampled_distance(head.axes_from_pose(tip, pivot - tip)[:, :2], scenario.program.elements) * 1e6
    assert true.max() == pytest.approx(first["contour_error_um"]["max"], abs=0.01)
    # the compliant machine's table parts from its motors by the screws' deflection under the
    # accelerating force, m a / k: X 350 kg x 2 m/s^2 / 80 N/um = 8.8 um at the most
    assert abs(true.max() - d.max()) < 350.0 * 2.0 / 80.0
