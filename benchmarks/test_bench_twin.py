"""Speed figures (run with ``python -m pytest benchmarks/ --benchmark-only``); not part of the tests.

The figure that matters is the ratio measured in one process run: full twin wall time over bare
``mj_step`` for the same physics step count (``test_twin_over_bare_ratio`` prints it and stores it
in the benchmark's ``extra_info``). Absolute times vary with the machine's load.
"""

from __future__ import annotations

import pytest

from cnc_twin.bench import bench_scenario, time_bare_steps
from cnc_twin.resources import default_scenario
from cnc_twin.scenario import load_scenario
from cnc_twin.twin import Twin


@pytest.fixture(scope="module")
def scenario():
    return load_scenario(default_scenario())


def test_bare_mj_step(benchmark, scenario):
    steps = Twin(scenario).run().metrics["physics_steps"]
    benchmark.pedantic(time_bare_steps, args=(scenario.model_file,),
                       kwargs={"timestep": scenario.timing.physics_timestep, "steps": steps}, rounds=3)


def test_full_twin_run(benchmark, scenario):
    def run():
        Twin(scenario).run()

    benchmark.pedantic(run, rounds=3)


def test_servo_tick(benchmark, scenario):
    """Cost of one DSP servo tick (six axes: QEP, PID+FF, DAC; load-cell ADC)."""
    servo = Twin(scenario).servo
    servo.begin_period([100.0, -50.0, 20.0, 10.0, 5.0, 1.0])
    positions = [1e-4, -5e-5, 2e-5, 1e-4, 5e-5, 1e-3]
    benchmark(servo.tick, 0, positions, 0.0)


def test_twin_over_bare_ratio(benchmark):
    figures = benchmark.pedantic(bench_scenario, args=(default_scenario(),), kwargs={"repeat": 3}, rounds=1)
    benchmark.extra_info.update(figures)
    print(f"\ntwin / bare mj_step = {figures['ratio_twin_over_bare']:.2f} "
          f"({figures['twin_us_per_tick']:.1f} vs {figures['bare_us_per_step']:.1f} us)")
