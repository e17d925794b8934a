"""NURBS direct interpolation in the whole twin: planner process, whiteboard, DSP, machine."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import yaml

from cnc_twin import load_scenario, run_scenario
from cnc_twin.resources import scenarios_dir
from cnc_twin.scenario import scenario_from_dict
from cnc_twin.whiteboard.status import DspState

CURVES = ["nurbs_circle.yaml", "nurbs_freeform.yaml"]


@pytest.fixture(scope="module", params=CURVES)
def curve_run(request):
    scenario = load_scenario(scenarios_dir() / request.param)
    return scenario, run_scenario(scenario)


def test_curve_run_meets_every_interpolation_figure(curve_run):
    scenario, result = curve_run
    assert result.status == "complete" and result.metrics["final_state"] == "FINISHED"
    path = result.metrics["path"]
    assert path["feed_fluctuation"]["max"] <= 1e-6
    assert path["chord_error_um"]["max"] <= path["chord_error_um"]["tolerance"]
    for axis, peaks in path["axis_peaks"].items():
        for kind in ("velocity", "acceleration", "jerk"):
            assert peaks[kind] <= peaks[f"{kind}_limit"] * 1.01, (axis, kind)
    assert 0 < path["contour_error_um"]["rms"] <= path["contour_error_um"]["max"] < 100
    assert path["planning"]["ratio_execution_over_planning"] > 1  # planning stays ahead
    assert result.metrics["mujoco_warnings"] == {}


def test_curve_run_ends_on_the_curve_end(curve_run):
    scenario, result = curve_run
    prog = scenario.program
    tpp = scenario.timing.ticks_per_period
    u = result.trace.period_signals["path_u"][tpp - 1::tpp]
    assert u.max() == pytest.approx(1.0)
    end = np.asarray(prog.control_points[-1])  # clamped: the curve ends on its last control point
    cmd = result.trace.command[-1, :3] / result.trace.counts_per_unit[:3] + np.asarray(scenario.home[:3])
    assert np.allclose(cmd, end, atol=1e-9)


def test_curve_lockstep_runs_are_bit_identical():
    scenario = load_scenario(scenarios_dir() / "nurbs_freeform.yaml")
    a, b = run_scenario(scenario).trace.columns(), run_scenario(scenario).trace.columns()
    for name in a:
        assert np.array_equal(a[name], b[name]), name


def test_starved_curve_holds_within_limits_and_resumes():
    """Real time, 20 ms look-ahead, planner stalled 500 ms mid-curve: the card runs dry at speed,
    decelerates along the path within its limits, waits, and finishes the curve."""
    raw = yaml.safe_load((scenarios_dir() / "nurbs_freeform.yaml").read_text())
    raw.update(timing={"mode": "realtime"}, planner={"lookahead": 20.0},
               faults=[{"type": "planner_stall", "at": 2.5, "duration": 500.0}])
    scenario = scenario_from_dict(raw)
    result = run_scenario(scenario)
    assert result.status == "complete" and result.metrics["final_state"] == "FINISHED"
    override = result.trace.period_signals["feed_override"]
    assert override.min() < 0.05  # it held ...
    path = result.metrics["path"]
    for axis, peaks in path["axis_peaks"].items():  # ... without breaking an axis limit
        assert peaks["acceleration"] <= peaks["acceleration_limit"] * 1.01, axis
    assert path["chord_error_um"]["max"] <= path["chord_error_um"]["tolerance"]
    assert result.metrics["whiteboard"]["missed_exchanges"] > 50


def test_cli_runs_a_curve_and_reports_contour_error(tmp_path):
    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "cnc_twin", "run", str(scenarios_dir() / "nurbs_circle.yaml"),
                           "--out", str(out)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "contour error" in proc.stdout
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["path"]["contour_error_um"]["max"] > 0


@pytest.mark.parametrize("change, key, fragment", [
    ({"knots": [0, 0, 0, 0.5, 1, 1]}, "program.knots", "n + degree + 1"),
    ({"weights": [1, 1, 1, 1, 1, 1, 1, 1, -1]}, "program.weights", "> 0"),
    ({"control_points": [[40, 0, 20]] * 8 + [[900, 0, 20]]}, "program.control_points", "travel"),
    ({"feed": -5}, "program.feed", "greater than 0"),
    ({"tool_axis": {"A": 120}}, "program.tool_axis.A", "travel"),
])
def test_bad_curve_programs_name_the_key(write_scenario, change, key, fragment):
    from cnc_twin.errors import ScenarioError

    raw = yaml.safe_load((scenarios_dir() / "nurbs_circle.yaml").read_text())
    raw["program"].update(change)
    with pytest.raises(ScenarioError) as info:
        load_scenario(write_scenario(raw))
    assert info.value.key_path == key and fragment in info.value.message
