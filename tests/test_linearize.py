"""The linearised servo loop against the nonlinear twin's small-signal step."""

from __future__ import annotations

import control
import numpy as np
import pytest

from cnc_twin.studies.linearize import analyse, axis_plant
from cnc_twin.scenario.resources import BUNDLED_MACHINES, default_scenario
from cnc_twin.scenario.load import load_scenario, scenario_from_dict
from cnc_twin.run.twin import run_scenario

RIGID = dict(BUNDLED_MACHINES["rigid"])


@pytest.mark.parametrize("kp, ki", [(40.0, 400.0), (70.0, 0.0)])
def test_linear_step_matches_the_twin_within_10_percent(kp, ki):
    """1 mm step on X of the rigid machine (a one-period move, feed-forward off): rise time,
    overshoot, settling. (The compliant machine's linear model against its nonlinear one:
    tests/test_drive_feedback.py, tests/test_drive_delay.py, tests/test_drive_tuning.py.)"""
    raw = {"name": "step", "axes": {"X": {"max_velocity": 1e9, "max_acceleration": 1e9,
                                          "servo": {"kp": kp, "ki": ki, "kvff": 0.0, "kaff": 0.0}}},
           "program": {"type": "point_to_point", "settle": 0.5, "moves": [{"X": 1.0}]}}
    scenario = scenario_from_dict(raw | {"machine": {"model": "scene_rigid.xml", "parameters": "polisher_rigid.yaml"}})
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
    """Static check of the rigid machine's linear plant: a constant voltage gives speed_per_volt
    (friction off)."""
    scenario = load_scenario(default_scenario(), overrides=RIGID)
    plant = axis_plant(scenario, "X")
    cfg = scenario.axis("X")
    resp = control.forced_response(plant, T=np.arange(4000) * scenario.timing.servo_period, U=np.ones(4000))
    speed = np.diff(resp.outputs[-2:])[0] / scenario.timing.servo_period / cfg.counts_per_unit
    damping = 1500.0  # X viscous damping [N s/m]; drive kv = 450000
    assert speed == pytest.approx(cfg.speed_per_volt * 450000 / (450000 + damping), rel=1e-3)


def test_margins_of_the_rigid_machines_gains():
    """The rigid machine's parameter file's gains (from `cnc-twin tune`): at least 45 deg and 6 dB,
    about 50 Hz: what its ideal drives allow."""
    report, _, _ = analyse(load_scenario(default_scenario(), overrides=RIGID), "Y")
    assert 45 < report.phase_margin_deg < 60 and report.gain_margin_db > 6
    assert 45 < report.crossover_hz < 60 and report.bandwidth_hz > report.crossover_hz


def test_margins_of_the_default_machines_gains():
    """The compliant default's position loop on Y (its drive's velocity loop inside, the screw's
    two-mass mode): the margins the tuner kept, at a crossover a fifth of the rigid machine's or
    less (linearised: 82 deg, 23 dB, 18 Hz)."""
    report, _, _ = analyse(load_scenario(default_scenario()), "Y")
    assert report.phase_margin_deg >= 45 and report.gain_margin_db >= 6
    assert 5 < report.crossover_hz < 30 and report.bandwidth_hz > report.crossover_hz


def test_tune_proposes_gains_that_the_twin_confirms(tmp_path):
    """From slow gains (kp 40 / ki 400) on Z, whose home is at the top of its travel: the
    verification step goes down, inside the soft limits, and the proposal is a faster loop that
    keeps its margins and behaves on the nonlinear twin."""
    import re
    import subprocess
    import sys

    scenario = tmp_path / "slow_z.yaml"  # the rigid machine: the linear loop's tuner
    raw = default_scenario().read_text().replace("model: scene.xml", "model: scene_rigid.xml").replace(
        "parameters: polisher.yaml", "parameters: polisher_rigid.yaml")
    scenario.write_text(raw.replace("name:", "axes: {Z: {servo: {kp: 40, ki: 400}}}\nname:", 1))
    proc = subprocess.run([sys.executable, "-m", "cnc_twin", "tune", str(scenario), "--axis", "Z", "--step", "0.1",
                           "--out", str(tmp_path)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    # the position loop's table comes last (the velocity loop's, with its own before / proposed rows, first)
    row = [line for line in proc.stdout.splitlines() if line.startswith("proposed")][-1]
    kp, ki, pm, gm, fc, rise, overshoot, settle = (float(x) for x in re.findall(r"[-\d.]+|inf|nan", row))
    before = [line for line in proc.stdout.splitlines() if line.startswith("before")][-1]
    kp_before, fc_before = (float(re.findall(r"[-\d.]+|inf|nan", before)[i]) for i in (0, 4))
    assert kp_before == 40.0
    assert pm >= 45 and gm >= 6 and fc > fc_before  # a faster loop that keeps its margins ...
    assert np.isfinite(settle) and overshoot < 30  # ... and behaves on the nonlinear twin
    assert (tmp_path / "Z_bode.png").stat().st_size > 10_000 and (tmp_path / "Z_step.png").is_file()


def test_the_verification_step_goes_the_way_that_stays_inside_the_soft_limits():
    from cnc_twin.studies.tuning import step_direction

    scenario = load_scenario(default_scenario())
    assert step_direction(scenario, 2, 1.0) == -1.0  # Z: home at 0, soft limits -385..0 mm
    assert step_direction(scenario, 0, 1.0) == 1.0
    with pytest.raises(ValueError, match="soft limits"):
        step_direction(scenario, 2, 1000.0)


def _tune(*args: str) -> tuple[int, str, str]:
    from conftest import run_cli

    return run_cli("tune", default_scenario(), *args)


def _row(text: str, name: str) -> dict[str, float]:
    import re

    line = [line for line in text.splitlines() if line.startswith(name)][-1]  # the position loop's table
    values = [float(x) for x in re.findall(r"[-\d.]+|inf|nan", line[len(name):])]
    return dict(zip(("kp", "ki", "pm", "gm", "fc", "rise", "overshoot", "settle"), values))


@pytest.mark.parametrize("axis", list("C"))
def test_tune_never_recommends_what_the_twin_did_not_show_better(axis):
    """jog_axes, default margins and step: either gains whose printed twin step settles sooner
    (by 10 %) with no more overshoot than the current gains', or, on an axis tuned on its measured
    mechanics whose current gains overshoot the tool beyond 2 % (+0.5 for the count), gains that
    settle within 2 %; or the current gains kept with the reason and no recommendation. C: the
    linear loop's tuner. The measured-mechanics tuner (half a minute or more of the suite's time
    per axis) is held to the same rule on X in tests/test_drive_tuning.py, tuned from the rigid
    machine's gains, which overshoot; A's run (38 s) left the suite on 2026-11-27 to keep it
    within its 10 minutes when the served viewer's photograph came in."""
    code, out, err = _tune("--axis", axis)
    assert code == 0, err
    before = _row(out, "before")
    if "to use:" in out:
        proposed = _row(out, "proposed")
        measured = "velocity loop" in out  # a drive with loops of its own: the measured mechanics
        if measured and before["overshoot"] > 2.5:
            assert np.isfinite(proposed["settle"]) and proposed["overshoot"] <= 2.0, out
        else:
            assert proposed["settle"] < before["settle"] * 0.9 or not np.isfinite(before["settle"]), out
            assert proposed["overshoot"] <= before["overshoot"] + 0.5, out
        assert proposed["pm"] >= 45, out
        import re

        use = re.search(r"to use: axes: \{(\w): \{servo: \{kp: ([\d.e+]+), ki: ([\d.e+]+)\}", out)
        assert use and use.group(1) == axis and abs(float(use.group(2)) - proposed["kp"]) < 0.06, out
    else:
        position_table = out.split("targets phase margin")[-1]
        assert "keeping the current gains: none of the" in out and "proposed" not in position_table, out


def test_tune_refuses_what_it_cannot_do_in_one_line():
    code, _, err = _tune("--axis", "X", "--phase-margin", "95")
    assert code == 2 and "--phase-margin: expected more than 0 and less than 90 deg" in err
    # beyond X's 3 mm following-error limit (the rigid machine's: the compliant one measures its
    # mechanics first, a minute, before the same step ends the same way)
    code, _, err = _tune("--axis", "X", "--step", "5", "--machine", "rigid")
    assert code == 2 and "ends in a fault on the twin (FOLLOWING_ERROR" in err and "smaller --step" in err
    assert err.strip().splitlines()[-1].startswith("error: ") and "Traceback" not in err


def test_sigterm_ends_tune_like_ctrl_c_with_nothing_left():
    """SIGTERM during tune's twin runs: exit 143 with one line, no planner process left."""
    import signal
    import subprocess
    import sys
    import time

    proc = subprocess.Popen([sys.executable, "-m", "cnc_twin", "tune", str(default_scenario()), "--axis", "X"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    deadline = time.monotonic() + 60
    while "each checked on the twin" not in (line := proc.stderr.readline()) and time.monotonic() < deadline:
        assert line, "tune ended before its twin runs"
    time.sleep(1.0)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143 and "terminated (SIGTERM)" in err and "Traceback" not in err, err
    time.sleep(0.5)
    left = subprocess.run(["ps", "-o", "pid=,stat=", "-g", str(proc.pid)], capture_output=True, text=True).stdout
    assert [line for line in left.splitlines() if line.split()[1][0] != "Z"] == []
