"""Speed figures (run with ``python -m pytest benchmarks/ --benchmark-only``); not part of the tests.

The figure that matters is the ratio measured in one process run: full twin wall time over bare
``mj_step`` for the same physics step count (``test_twin_over_bare_ratio`` prints it and stores it
in the benchmark's ``extra_info``). Absolute times vary with the machine's load.
"""

from __future__ import annotations

import numpy as np
import pytest

from cnc_twin.studies.bench import bench_scenario, time_bare_steps
from cnc_twin.scenario.resources import default_scenario
from cnc_twin.scenario.load import load_scenario
from cnc_twin.run.twin import Twin


@pytest.fixture(scope="module")
def scenario():
    return load_scenario(default_scenario())


def test_bare_mj_step(benchmark, scenario):
    steps = Twin(scenario).run().metrics["physics_steps"]
    benchmark.pedantic(time_bare_steps, args=(scenario.model_file,),
                       kwargs={"timestep": scenario.timing.physics_timestep, "steps": steps,
                               "drives": scenario.drives}, rounds=3)


def test_full_twin_run(benchmark, scenario):
    def run():
        Twin(scenario).run()

    benchmark.pedantic(run, rounds=3)


def test_servo_tick(benchmark, scenario):
    """Cost of one DSP servo tick (six axes: QEP, PID+FF, DAC; load-cell ADC)."""
    servo = Twin(scenario).servo
    servo.begin_period([100.0, -50.0, 20.0, 10.0, 5.0, 1.0])
    positions = np.array([1e-4, -5e-5, 2e-5, 1e-4, 5e-5, 1e-3])
    benchmark(servo.tick, 0, positions, 0.0)


def _period(twin: Twin, compiled: bool):
    """One interpolation period of servo ticks and physics, compiled or on the reference path."""
    from cnc_twin.trace.recorder import Recorder

    recorder = Recorder(1, twin.scenario.timing.ticks_per_period, scratch=True)
    servo, plant, substeps = twin.servo, twin.plant, twin.scenario.timing.substeps_per_tick
    servo.begin_period([100.0, -50.0, 20.0, 10.0, 5.0, 1.0])
    if compiled:
        twin.kernel.warm_up()
        return lambda: twin.kernel.run_period(recorder, 0)

    def reference():
        for j in range(servo.ticks_per_period):
            plant.apply_volts(servo.tick(j, plant.data.qpos, plant.pad_force()))
            plant.step(substeps)
            recorder.record_tick(j, servo.frame)
    return reference


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "python"])
def test_servo_period_with_physics(benchmark, scenario, compiled):
    """One 1 ms period: four servo ticks, four physics steps, four recorded rows."""
    benchmark(_period(Twin(scenario), compiled))


def test_twin_over_bare_ratio(benchmark):
    """On the reference curve (nurbs_circle: 1 ms interpolation, 0.25 ms servo and physics)."""
    from cnc_twin.scenario.resources import scenarios_dir

    figures = benchmark.pedantic(bench_scenario, args=(scenarios_dir() / "nurbs_circle.yaml",),
                                 kwargs={"repeat": 3}, rounds=1)
    benchmark.extra_info.update(figures)
    print(f"\ntwin / bare mj_step = {figures['ratio_twin_over_bare']:.2f} "
          f"({figures['twin_us_per_tick']:.1f} vs {figures['bare_us_per_step']:.1f} us)")


def test_rerun_recording_after_the_run(benchmark):
    """The wait after the run for its rerun recording, as ``cnc-twin run`` records (a recording
    process fed during the run), over the run's clock; and the in-process export after the run."""
    from cnc_twin.studies.bench import time_rerun_export, time_streamed_recording
    from cnc_twin.scenario.resources import scenarios_dir

    circle = scenarios_dir() / "nurbs_circle.yaml"
    figures = benchmark.pedantic(time_streamed_recording, args=(circle,), kwargs={"repeat": 5}, rounds=1)
    export_s, _ = time_rerun_export(circle, repeat=3)
    benchmark.extra_info.update(figures, rerun_export_s=export_s)
    ratio = figures["rerun_streamed_tail_s"] / figures["rerun_streamed_run_alone_s"]
    benchmark.extra_info["rerun_streamed_tail_over_run"] = ratio
    print(f"\nrecording after the run: {figures['rerun_streamed_tail_s'] * 1e3:.1f} ms = "
          f"{ratio:.1%} of the run (target 10 %); the run "
          f"{figures['rerun_streamed_run_slowdown']:+.1%} with the recording process; in-process "
          f"export after the run {export_s * 1e3:.1f} ms")


@pytest.mark.parametrize("period_ms", [1.0, 0.25])
def test_card_waits_for_the_planner_on_the_butterfly(benchmark, period_ms):
    """The published butterfly at 2.4 m/min, lockstep: the card's longest wait for a planner answer
    (the planner plans its windows in a thread of its own, ahead of the card) and the real-time
    factor. Target: the wait under one interpolation period."""
    from cnc_twin.scenario.resources import scenarios_dir

    overrides = {"timing.interpolation_period": period_ms, "timing.servo_period": min(0.25, period_ms),
                 "timing.physics_timestep": min(0.25, period_ms)}
    scenario = load_scenario(scenarios_dir() / "published" / "farfalla.yaml", overrides=overrides)
    result = benchmark.pedantic(lambda: Twin(scenario).run(), rounds=1)
    wait_ms = result.metrics["whiteboard"]["exchange_latency_us"]["max"] / 1e3
    benchmark.extra_info.update(longest_wait_ms=wait_ms, real_time_factor=result.metrics["real_time_factor"])
    print(f"\nbutterfly at {period_ms:g} ms: longest wait for the planner {wait_ms:.2f} ms, "
          f"real-time factor {result.metrics['real_time_factor']:.1f}")
