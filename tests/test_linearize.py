"""The linearised servo loop against the nonlinear twin's small-signal step."""

from __future__ import annotations

import control
import numpy as np
import pytest

from cnc_twin.studies.linearize import analyse, axis_plant
from cnc_twin.scenario.resources import default_scenario
from cnc_twin.scenario.load import load_scenario, scenario_from_dict
from cnc_twin.run.twin import run_scenario


@pytest.mark.parametrize("kp, ki", [(40.0, 400.0), (70.0, 0.0)])
def test_linear_step_matches_the_twin_within_10_percent(kp, ki):
    """1 mm step on X (a one-period move, feed-forward off): rise time, overshoot, settling."""
    raw = {"name": "step", "axes": {"X": {"max_velocity": 1e9, "max_acceleration": 1e9,
                                          "servo": {"kp": kp, "ki": ki, "kvff": 0.0, "kaff": 0.0}}},
           "program": {"type": "point_to_point", "settle": 0.5, "moves": [{"X": 1.0}]}}
    scenario = scenario_from_dict(raw)
    trace = run_scenario(scenario).trace
    command, actual, time = trace.command[:, 0], trace.actual[:, 0], trace.time
    start = int(np.argmax(command > 0)) - 1
    t, r, y = time[start:] - time[start], command[start:], actual[start:]
    twin = control.step_info(y, t, yfinal=1000.0)
    report, _, closed = analyse(scenario, "X")
    linear = control.step_info(control.forced_response(closed, T=t, U=r).outputs, t, yfinal=1000.0)
    assert linear["RiseTime"] == pytest.approx(twin["RiseTime"], rel=0.10)
    assert linear["SettlingTime"] == pytest.approx(twin["SettlingTime"], rel=0.10)
    assert linear["Peak"] == pytest.approx(twin["Peak"], rel=0.02)  # overshoot, in counts of 1000
    assert report.phase_margin_deg > 30 and report.crossover_hz > 1


def test_plant_is_a_mass_behind_a_velocity_drive():
    """Static check of the linear plant: a constant voltage gives speed_per_volt (friction off)."""
    scenario = load_scenario(default_scenario())
    plant = axis_plant(scenario, "X")
    cfg = scenario.axis("X")
    resp = control.forced_response(plant, T=np.arange(4000) * scenario.timing.servo_period, U=np.ones(4000))
    speed = np.diff(resp.outputs[-2:])[0] / scenario.timing.servo_period / cfg.counts_per_unit
    damping = 1500.0  # X viscous damping [N s/m]; drive kv = 450000
    assert speed == pytest.approx(cfg.speed_per_volt * 450000 / (450000 + damping), rel=1e-3)


def test_margins_of_the_default_gains():
    report, _, _ = analyse(load_scenario(default_scenario()), "Y")
    assert 60 < report.phase_margin_deg < 80 and report.gain_margin_db > 6
    assert 5 < report.crossover_hz < 8 and report.bandwidth_hz > report.crossover_hz


def test_tune_proposes_gains_that_the_twin_confirms(tmp_path):
    import re
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-m", "cnc_twin", "tune", str(default_scenario()), "--axis", "X",
                           "--out", str(tmp_path)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    row = next(line for line in proc.stdout.splitlines() if line.startswith("proposed"))
    kp, ki, pm, gm, fc, rise, overshoot, settle = (float(x) for x in re.findall(r"[-\d.]+|inf|nan", row))
    before = next(line for line in proc.stdout.splitlines() if line.startswith("before"))
    fc_before = float(re.findall(r"[-\d.]+|inf|nan", before)[4])
    assert pm >= 45 and gm >= 6 and fc > fc_before  # a faster loop that keeps its margins ...
    assert np.isfinite(settle) and overshoot < 25  # ... and behaves on the nonlinear twin
    assert (tmp_path / "X_bode.png").stat().st_size > 10_000 and (tmp_path / "X_step.png").is_file()
