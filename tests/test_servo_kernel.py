"""The compiled period kernel (cnc_twin.run.servo_kernel: whole interpolation periods, the card's
tasks and the machine's steps in one numba call, batches of them) against the per-tick path (the
card's tasks orchestrated in Python, a servo tick at a time, Twin(compiled=False)): the same trace,
bit for bit. Both call the same compiled card blocks (servo_tick and the blocks under it); that
each compiled block computes what its own Python source does is tests/test_block_kernels.py's
check (every block, servo_tick among them, against its ``py_func``)."""

from __future__ import annotations

import numpy as np
import pytest

from cnc_twin.run import servo_kernel
from cnc_twin.scenario.resources import scenarios_dir
from cnc_twin.scenario.load import load_scenario
from cnc_twin.run.twin import Twin

TIMING_KEYS = {"wall_time_s", "real_time_factor", "whiteboard", "path", "memory_mb"}
"""wall-clock figures, different between any two runs (the rest of metrics must agree)"""


def _run_both(name: str, overrides: dict | None = None):
    scenario = load_scenario(scenarios_dir() / f"{name}.yaml", overrides=overrides)
    compiled = Twin(scenario)
    assert compiled.kernel is not None, "the compiled servo should apply to this scenario"
    reference = Twin(scenario, compiled=False)
    assert reference.kernel is None
    return compiled, compiled.run(), reference.run()


def _assert_same_trace(a, b) -> None:
    cols_a, cols_b = a.trace.columns(), b.trace.columns()
    assert cols_a.keys() == cols_b.keys()
    for key in cols_a:
        assert cols_a[key].dtype == cols_b[key].dtype, key
        assert np.array_equal(cols_a[key], cols_b[key]), key
    for key in a.metrics.keys() - TIMING_KEYS:
        assert a.metrics[key] == b.metrics[key], key


def test_kernel_is_available_here():
    assert servo_kernel.available()


def test_nurbs_circle_is_bit_identical():
    twin, compiled, reference = _run_both("nurbs_circle")
    _assert_same_trace(compiled, reference)
    assert compiled.metrics["path"]["contour_error_um"] == reference.metrics["path"]["contour_error_um"]
    assert compiled.metrics["final_state"] == "FINISHED"


def test_saturation_and_a_stop_with_the_drives_disabled_are_bit_identical():
    """X with 30 times the feed-forward it needs: the PID clamps its output, the DAC saturates, the integrator stops
    integrating; the supervisor's DAC-saturation check then disables the drives, so the run goes
    on in the reference path (follow-up) after handing the state over mid-run."""
    overrides = {"servo.X.kvff": 30.0, "supervisor.dac_saturation_time": 4.0}
    twin, compiled, reference = _run_both("jog_axes", overrides)
    _assert_same_trace(compiled, reference)
    assert twin.period_batch.periods > 0  # batches ran, and ended where the saturation run grew
    dac_x = compiled.trace.dac[:, 0]
    assert (np.abs(dac_x) >= 2047).any(), "the case should saturate the DAC"
    assert compiled.metrics["dac_saturation_ticks"]["X"] > 0
    assert compiled.metrics["fault"]["code"] == "DAC_SATURATION"
    assert compiled.metrics["fault"]["stop"] == "disable"
    disabled = np.flatnonzero(compiled.trace.period_signals["state"] == 3)  # STOPPING
    assert len(disabled) and disabled[-1] < len(compiled.trace) - 1


def test_following_error_stop_hands_the_state_back_mid_run():
    overrides = {"axes.Y.following_error_limit": 0.002, "supervisor.following_error_stop": "disable"}
    twin, compiled, reference = _run_both("jog_axes", overrides)
    _assert_same_trace(compiled, reference)
    assert compiled.metrics["fault"]["code"] == "FOLLOWING_ERROR"
    assert twin.period_batch.periods > 0


def test_recording_off_runs_the_same_loop_into_one_period():
    scenario = load_scenario(scenarios_dir() / "nurbs_circle.yaml")
    twin = Twin(scenario, record=False)
    result = twin.run()
    assert result.metrics["status"] == "complete" and result.metrics["wall_time_s"] > 0
    assert twin.recorder.capacity == scenario.timing.ticks_per_period
    assert len(result.trace) == scenario.timing.ticks_per_period
    full = Twin(scenario).run()
    # the scratch period holds the run's last period, the same as the full trace's
    tpp = scenario.timing.ticks_per_period
    assert np.array_equal(result.trace.command, full.trace.command[-tpp:])
    assert np.array_equal(result.trace.actual, full.trace.actual[-tpp:])


@pytest.mark.parametrize("name", ["circle_three_ways", "collision_stop"])
def test_the_reference_path_serves_what_the_kernel_does_not(name):
    """Pulse output and injected card faults run the reference servo only."""
    twin = Twin(load_scenario(scenarios_dir() / f"{name}.yaml"))
    assert twin.kernel is None


def test_compiled_kinematics_replay_matches_the_python_loop():
    from cnc_twin.machine.model_file import load_model
    from cnc_twin.view.rerun_export import _Kinematics

    scenario = load_scenario(scenarios_dir() / "nurbs_tilted.yaml")
    model = load_model(scenario.model_file)
    kin, loop = _Kinematics(model), _Kinematics(model, compiled=False)
    assert kin.compiled and not loop.compiled
    rng = np.random.default_rng(3)
    q = np.asarray(scenario.home) + rng.uniform(-0.2, 0.2, size=(50, 6))
    compiled = kin.poses(q)
    reference = loop.poses(q)
    for a, b in zip(compiled, reference):
        assert np.array_equal(a, b)


def _batched_and_unbatched(scenario):
    batched, unbatched = Twin(scenario), Twin(scenario, batch=False)
    a, b = batched.run(), unbatched.run()
    assert unbatched.period_batch is None
    _assert_same_trace(a, b)
    return batched, a


@pytest.mark.parametrize("name", ["nurbs_circle", "jog_axes", "nurbs_tilted"])
def test_batched_periods_give_the_same_trace_and_carry_most_of_the_run(name):
    """nurbs_tilted: a tool-axis curve, the head's inverse kinematics (asin, atan2, sin, cos) in
    the batch, against the Python reference too."""
    scenario = load_scenario(scenarios_dir() / f"{name}.yaml")
    batched, result = _batched_and_unbatched(scenario)
    periods = len(result.trace.period_signals.per_period("state"))
    assert batched.period_batch.periods > 0.9 * periods
    _assert_same_trace(result, Twin(scenario, compiled=False).run())
    if "path" in result.metrics:  # the batches time their interpolation, as the Python task does
        assert result.metrics["path"]["interpolator_us_per_period"]["median"] > 0.0


def test_a_soft_limit_clamp_ends_the_batch_before_the_clamped_period():
    import dataclasses

    sc = load_scenario(scenarios_dir() / "jog_axes.yaml")
    x = dataclasses.replace(sc.axes[0], soft_limits=(-0.05, 0.05))  # the first move goes to 200 mm
    scenario = dataclasses.replace(sc, axes=(x, *sc.axes[1:]))
    batched, result = _batched_and_unbatched(scenario)
    assert result.metrics["fault"]["code"] == "SOFT_LIMIT" and batched.period_batch.periods > 0


def test_batches_into_a_scratch_recorder_keep_the_last_period():
    scenario = load_scenario(scenarios_dir() / "nurbs_circle.yaml")
    a, b = Twin(scenario, record=False).run(), Twin(scenario, record=False, batch=False).run()
    assert np.array_equal(a.trace.command, b.trace.command)
    assert np.array_equal(a.trace.periods, b.trace.periods)


def test_a_planner_lost_during_batches_is_noticed_at_the_same_liveness_check(monkeypatch):
    """The card checks the planner every 64 periods while solo; batches make that check first."""
    import cnc_twin.run.twin as twin_module

    class DyingPort(twin_module.DspPort):
        checks = 0

        def __init__(self, *args, planner_alive, **kwargs):
            super().__init__(*args, planner_alive=self._alive, **kwargs)
            self._really_alive = planner_alive

        def _alive(self):  # the 12th check while solo finds the planner gone
            if self.solo:
                DyingPort.checks += 1
                if DyingPort.checks >= 12:
                    return False
            return self._really_alive()

    monkeypatch.setattr(twin_module, "DspPort", DyingPort)
    scenario = load_scenario(scenarios_dir() / "nurbs_circle.yaml")
    results = []
    for batch in (True, False):
        DyingPort.checks = 0
        twin = Twin(scenario, batch=batch)
        results.append(twin.run())
        assert (twin.period_batch is not None) == batch
    batched, unbatched = results
    assert batched.metrics["fault"]["code"] == "PLANNER_LOST"
    assert round(batched.metrics["fault"]["time_s"] * 1000) % 64 == 0
    _assert_same_trace(batched, unbatched)


def test_the_cli_says_when_it_compiles_the_kernels(monkeypatch, capsys, tmp_path):
    from cnc_twin import cli
    from cnc_twin.run import period_kernel

    Twin(load_scenario(scenarios_dir() / "jog_axes.yaml")).run()
    assert period_kernel.kernels_cached()  # numba cached the kernels it compiled or loaded
    monkeypatch.setattr(period_kernel, "kernels_cached", lambda: False)  # as on a fresh install
    assert cli.main(["run", "--no-rrd", "--out", str(tmp_path / "run")]) == 0
    assert "compiling the twin's kernels" in capsys.readouterr().err


def test_an_empty_numba_cache_is_seen_as_kernels_to_compile(tmp_path):
    """A fresh install: numba's cache directory (here NUMBA_CACHE_DIR, empty) holds no index of
    the kernels, and kernels_cached says so (importing compiles nothing)."""
    import os
    import subprocess
    import sys

    code = "from cnc_twin.run import period_kernel; print(period_kernel.kernels_cached())"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env)
    assert proc.returncode == 0 and proc.stdout.split() == ["False"], proc.stderr
