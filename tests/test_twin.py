"""The whole chain: planner -> DSP servo task -> drives -> MuJoCo, recorded and written."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from cnc_twin import load_scenario, run_scenario
from cnc_twin.trace.parquet import read_trace
from cnc_twin.scenario.resources import default_scenario
from cnc_twin.scenario.load import scenario_from_dict
from conftest import single_move

SETTLE = 0.6  # s simulated after each test move
# (target in mm | deg, max following error during the move [counts], settle tolerance [counts])
# Settle tolerances, from the encoder resolution:
#  X/Y/Z: 1 um/count; +/-3 counts (3 um), i.e. quantisation plus a 1-2 count friction limit cycle.
#  C:     0.036 deg/count; +/-2 counts.
#  A/B:   0.00036 deg/count, 8x finer than one 12-bit DAC step can steer at kp = 30/s against the
#         harmonic drive's friction, so they rest within +/-30 counts (0.011 deg): a stick-slip
#         band of a few DAC LSB that the integrator walks through. On the compliant machine A's
#         position loop is 47 1/s behind a drive with loops of its own (crossing over at 33.5 Hz),
#         and Y's acceleration tilts it by up to 65 counts (2026-11-27): 80.
#  X/Y/Z following errors: the compliant machine's position loops (X 33.8, Y 42.3, Z 74.1 1/s)
#  behind its drives' own loops (first crossovers 22, 30, 51 Hz, behind their 1 ms torque
#  filters), and its bridge rocking at 45 Hz as X accelerates (X 176, Y 126, Z 67 counts
#  measured on these rapids, 2026-11-27).
CASES = {
    "X": (150.0, 220, 3),
    "Y": (-120.0, 160, 3),
    "Z": (-100.0, 90, 3),
    "A": (25.0, 250, 80),
    "B": (-25.0, 250, 80),
    "C": (180.0, 20, 2),
}


@pytest.fixture(scope="module", params=list(CASES))
def axis_run(request):
    axis = request.param
    target = CASES[axis][0]
    scenario = scenario_from_dict(single_move(axis, target, settle=SETTLE))
    return axis, scenario, run_scenario(scenario)


def test_axis_follows_trapezoid_with_bounded_error_and_settles(axis_run):
    axis, scenario, result = axis_run
    target, max_ferr, tolerance = CASES[axis]
    i = "XYZABC".index(axis)
    cfg = scenario.axes[i]
    trace = result.trace
    target_counts = target * (math.pi / 180 if cfg.rotary else 1e-3) * cfg.counts_per_unit
    settle_ticks = round(SETTLE / scenario.timing.servo_period)
    moving = slice(0, len(trace) - settle_ticks)

    # The command is a trapezoid: ends exactly on target, speed and acceleration within limits.
    cmd = trace.command[:, i]
    assert cmd[-1] == pytest.approx(target_counts, abs=1e-6)
    period = scenario.timing.interpolation_period
    per_period = cmd[scenario.timing.ticks_per_period - 1 :: scenario.timing.ticks_per_period]
    v = np.diff(per_period) / period / cfg.counts_per_unit
    a = np.diff(v) / period
    assert np.max(np.abs(v)) <= cfg.max_velocity * 1.001
    assert np.max(np.abs(a)) <= cfg.max_acceleration * 1.001
    assert np.max(np.abs(v)) > 0.5 * min(cfg.max_velocity, 1.0)  # it really moved

    ferr = trace.following_error[:, i]
    assert np.max(np.abs(ferr[moving])) <= max_ferr
    assert result.metrics["following_error"][axis]["max_counts"] <= max_ferr

    # Settled: the last 0.1 s within tolerance of the target, in counts.
    last = trace.actual[-round(0.1 / scenario.timing.servo_period):, i]
    assert np.max(np.abs(last - target_counts)) <= tolerance + 0.5  # + the target's own fraction of a count

    # The other axes held still within their settle tolerance, once past servo-on: at power-up Z
    # dips (the counterbalance is 88 N short of the Z weight at Z = 0) until the integrator holds it.
    servo_on = round(0.2 / scenario.timing.servo_period)
    if axis != "Z":
        assert np.max(np.abs(trace.following_error[:servo_on, 2])) <= 15
    for j, other in enumerate("XYZABC"):
        if other != axis:
            assert np.max(np.abs(trace.following_error[servo_on:, j])) <= CASES[other][2] + 1, other
    assert result.metrics["mujoco_warnings"] == {}
    assert result.metrics["dac_saturation_ticks"][axis] == 0


def test_same_scenario_twice_is_bit_identical():
    scenario = load_scenario(default_scenario())
    a, b = run_scenario(scenario).trace, run_scenario(scenario).trace
    for name, column in a.columns().items():
        assert np.array_equal(column, b.columns()[name]), name
    assert a.actual.any()


def test_run_writes_run_directory_and_repeat_runs_match(tmp_path):
    dirs = []
    for n in (1, 2):
        out = tmp_path / f"run{n}"
        proc = subprocess.run([sys.executable, "-m", "cnc_twin", "run", "--out", str(out)],
                              capture_output=True, text=True, timeout=300, cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr
        assert f"run directory: {out}" in proc.stdout
        assert "max ferr" in proc.stdout  # the summary table
        dirs.append(out)
    first, second = (read_trace(d / "trace.parquet") for d in dirs)
    assert list(first) == list(second)
    for name in first:
        assert np.array_equal(first[name], second[name]), name
    metrics = json.loads((dirs[0] / "metrics.json").read_text())
    assert metrics["status"] == "complete" and metrics["servo_ticks"] == len(first["time"])
    for axis in "XYZABC":
        assert set(metrics["following_error"][axis]) >= {"max_counts", "rms_counts", "max", "rms", "unit"}
        assert f"command_{axis}" in first and f"ferr_{axis}" in first and f"dac_{axis}" in first
    assert "pad_force" in first
    assert metrics["real_time_factor"] > 0 and metrics["wall_time_s"] > 0
    assert (dirs[0] / "scenario.yaml").read_text() == default_scenario().read_text()
    assert not list(tmp_path.glob(".*partial*"))  # no temporary folders left behind


def test_run_refuses_to_overwrite_an_existing_run_directory(tmp_path):
    (tmp_path / "taken").mkdir()
    proc = subprocess.run([sys.executable, "-m", "cnc_twin", "run", "--out", str(tmp_path / "taken")],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "already exists" in proc.stderr


def test_jog_axes_moves_every_axis_and_keeps_the_tool_clear():
    result = run_scenario(load_scenario(default_scenario()))
    span = result.trace.actual.max(axis=0) - result.trace.actual.min(axis=0)
    assert np.all(span > 1000)  # every axis travelled more than 1000 counts
    # never touched anything [N]: the load cell reads only the pad's inertia as the head
    # accelerates (0.54 N at most, 2026-11-27); a touch of the pad reads tens of newtons
    assert np.max(np.abs(result.trace.pad_force)) < 1.0


@pytest.mark.parametrize("sig, code", [("SIGINT", 130), ("SIGTERM", 143)])
def test_signal_stops_run_and_keeps_what_was_recorded(tmp_path, write_scenario, sig, code):
    """A long run is signalled mid-way: it stops at a period boundary and writes a readable run."""
    import signal
    import time

    settle = 240.0  # about 16 s of wall clock on a 2-core VM
    path = write_scenario({"name": "long", "program": {"type": "point_to_point", "settle": settle,
                                                       "moves": [{"X": 50}]}})
    # A signal that comes while the run still starts (planner, kernels) keeps an empty run, as it
    # should; on a loaded machine that takes seconds, so the signal comes later on each try until
    # one lands inside the run. Every try must keep a whole, readable run marked interrupted.
    for attempt, delay in enumerate((1.0, 3.0, 6.0)):
        out = tmp_path / f"run{attempt}"
        proc = subprocess.Popen([sys.executable, "-m", "cnc_twin", "run", str(path), "--out", str(out)],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        started = proc.stderr.readline()  # printed once the signal handlers are in place
        assert "running" in started, started
        time.sleep(delay)
        proc.send_signal(getattr(signal, sig))
        stdout, stderr = proc.communicate(timeout=120)
        assert proc.returncode == code, stderr
        assert "Traceback" not in stderr
        metrics = json.loads((out / "metrics.json").read_text())
        assert metrics["status"] == "interrupted" and metrics["stop_reason"] == sig
        trace = read_trace(out / "trace.parquet")
        n = len(trace["time"])
        assert n < settle / 0.00025 and n % 4 == 0  # whole periods only
        if n > 0:
            break
    assert n > 0, "no try's signal landed inside the run"
    assert metrics["servo_ticks"] == n
    # the recording, made while the run ran, holds every period recorded up to the signal
    from rrd_read import rrd_rows

    assert rrd_rows(out / "recording.rrd")[0]["/axes/X/position"] == n // 4
    # nothing beside the run directories (no staged recording left)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([f"run{i}" for i in range(attempt + 1)] +
                                                               ["scenario.yaml"])


def test_the_progress_bar_ends_at_the_time_simulated():
    """The last report is (periods run, periods run): the bar's end shows the simulated time,
    not the planner's estimate of it."""
    import io

    from cnc_twin.run.progress import ProgressBar

    calls = []
    scenario = scenario_from_dict({"name": "p", "program": {"type": "point_to_point", "settle": 0.05,
                                                            "moves": [{"X": 5}, {"Y": 3}]}})
    result = run_scenario(scenario, progress=lambda done, total: calls.append((done, total)))
    assert calls[0][0] == 0  # the first call: the run has begun
    done, total = calls[-1]
    assert done == total and done * scenario.timing.interpolation_period == pytest.approx(result.metrics["sim_time_s"],
                                                                                            abs=2e-3)
    stream = io.StringIO()
    stream.isatty = lambda: True
    bar = ProgressBar("p", period=scenario.timing.interpolation_period, stream=stream)
    bar(done, total)
    assert f"{result.metrics['sim_time_s']:.2f} / {result.metrics['sim_time_s']:.2f} s sim" in stream.getvalue()
    log = io.StringIO()  # not a terminal: the start line once, no bar
    bar = ProgressBar("p", period=scenario.timing.interpolation_period, stream=log, start_line="p: running")
    for call in calls:
        bar(*call)
    assert log.getvalue() == "p: running\n"


def test_a_feed_above_what_the_axes_allow_is_said_once_before_the_run_and_kept(write_scenario, tmp_path):
    """A point-to-point feed of 50000 mm/min on an X move: the X axis (24000 mm/min) sets the
    speed. The command says so before the run, with the key and the speed used, and metrics.json
    keeps it; the trace shows that speed and no more. A feed the axes allow says nothing."""
    from conftest import run_cli

    path = write_scenario({"name": "fast", "program": {"type": "point_to_point", "settle": 0.0, "moves": [
        {"X": 100, "feed": 50000}, {"X": 0, "feed": 6000}]}})
    code, _, err = run_cli("run", path, "--out", tmp_path / "run", "--no-rrd", "--quiet")
    assert code == 0, err
    notes = [line for line in err.splitlines() if line.startswith("note:")]
    assert len(notes) == 1 and "program.moves[0].feed" in notes[0] and "24000 mm/min" in notes[0], err
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert metrics["notices"] == [notes[0].split(f"{path}: ", 1)[1]]
    trace = read_trace(tmp_path / "run" / "trace.parquet")
    x_mm = trace["command_X"] / 1000.0  # 1 um per count
    speed = np.abs(np.diff(x_mm)) / np.diff(trace["time"]) * 60.0  # [mm/min]
    assert 0.97 * 24000 <= speed.max() <= 24000 * 1.001


def test_a_curve_feed_above_what_the_axes_allow_is_said_once_before_the_run(write_scenario, tmp_path):
    """A straight NURBS along X at F60000: X (24000 mm/min) holds it. Said before the run with the
    key and the speed, kept in metrics.json; the trace's X speed reaches 24000 mm/min and no more."""
    from conftest import run_cli

    path = write_scenario({"name": "fast_curve", "program": {
        "type": "nurbs_curve", "degree": 1, "control_points": [[-150, 0, 20], [150, 0, 20]], "weights": [1, 1],
        "knots": [0, 0, 1, 1], "feed": 60000, "chord_tolerance": 0.001, "tool_axis": {"A": 0, "B": 0},
        "settle": 0.0}})
    code, _, err = run_cli("run", path, "--out", tmp_path / "run", "--no-rrd", "--quiet")
    assert code == 0, err
    notes = [line for line in err.splitlines() if line.startswith("note:")]
    assert len(notes) == 1 and "program.feed" in notes[0] and "24000 mm/min" in notes[0], err
    assert json.loads((tmp_path / "run" / "metrics.json").read_text())["notices"] == [notes[0].split(f"{path}: ", 1)[1]]
    trace = read_trace(tmp_path / "run" / "trace.parquet")
    on_curve = trace["path_u"][1:] >= 0
    speed = np.abs(np.diff(trace["command_X"] / 1000.0)) / np.diff(trace["time"]) * 60.0  # [mm/min]
    assert 0.97 * 24000 <= speed[on_curve].max() <= 24000 * 1.001
