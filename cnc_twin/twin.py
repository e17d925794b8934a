"""Wiring: build the plant, the card and the planner for a scenario, run the clock, own the run.

The clock (lockstep; everything on simulated time)::

    for each interpolation period:
        servo.begin_period(interpolator.next_period())          # PC -> DSP setpoint, once
        for each of ticks_per_period servo ticks:
            volts = servo.tick(j, plant.axis_positions(), plant.pad_force())
            plant.apply_volts(volts)                             # DAC -> drives (zero-order hold)
            plant.step(substeps_per_tick)                        # MuJoCo, drive loops in C
            frames.rows[k] = servo.frame                         # one preallocated row

The planner runs in this process for now: it plans all segments before motion starts.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cnc_twin.dsp.interpolator import SegmentInterpolator
from cnc_twin.dsp.servo import ServoTask
from cnc_twin.planner.ptp import plan_point_to_point
from cnc_twin.plant import Plant, load_model
from cnc_twin.record import FrameBuffer, Trace, compute_metrics, write_run_dir
from cnc_twin.config import Scenario

ProgressCallback = Callable[[int, int], None]
"""called as ``progress(periods_done, periods_total)`` a few hundred times per run"""


@dataclass
class RunResult:
    """What a run produced. Nothing is written to disk unless :meth:`write` is called."""

    scenario: Scenario
    trace: Trace
    metrics: dict[str, Any]
    run_dir: Path | None = field(default=None)

    def write(self, run_dir: str | Path) -> Path:
        """Write ``scenario.yaml``, ``trace.parquet`` and ``metrics.json`` to ``run_dir``."""
        self.run_dir = write_run_dir(Path(run_dir), scenario=self.scenario, trace=self.trace, metrics=self.metrics)
        return self.run_dir


class Twin:
    """One run's plant, card and program, built from a scenario.

    Parameters
    ----------
    scenario : a validated scenario (see :func:`cnc_twin.scenario.load_scenario`).
    """

    def __init__(self, scenario: Scenario):
        self.scenario = scenario
        timing = scenario.timing
        self.plant = Plant(load_model(scenario.model_file), timestep=timing.physics_timestep)
        self.servo = ServoTask(
            scenario.axes, timing=timing, power_on=scenario.home, force_sensor=scenario.force_sensor
        )
        self.interpolator = SegmentInterpolator(
            counts_per_unit=[a.counts_per_unit for a in scenario.axes],
            power_on=scenario.home,
            period=timing.interpolation_period,
        )
        self.segments = plan_point_to_point(
            scenario.program, scenario.axes, start=scenario.home, period=timing.interpolation_period
        )
        self.interpolator.extend(self.segments)
        self.total_periods = sum(seg.periods for seg in self.segments)
        self.frames = FrameBuffer(self.total_periods * timing.ticks_per_period, len(self.servo.frame))
        self.stop_reason: str | None = None
        """set (e.g. from a signal handler) to stop the run at the next period boundary"""

    def request_stop(self, reason: str) -> None:
        """Stop at the next interpolation period; what was recorded so far is kept."""
        self.stop_reason = reason

    def run(self, *, progress: ProgressCallback | None = None) -> RunResult:
        """Run the whole program on the simulated clock and return the result."""
        timing = self.scenario.timing
        ticks_per_period = timing.ticks_per_period
        substeps = timing.substeps_per_tick
        plant, servo, interpolator = self.plant, self.servo, self.interpolator
        rows = self.frames.rows
        frame = servo.frame
        axis_positions, pad_force, apply_volts, step = (
            plant.axis_positions, plant.pad_force, plant.apply_volts, plant.step,
        )
        tick_range = range(ticks_per_period)
        total = self.total_periods
        report_every = max(1, total // 200)
        k = 0
        wall_start = time.perf_counter()
        for period in range(total):
            if self.stop_reason is not None:
                break
            servo.begin_period(interpolator.next_period())
            for j in tick_range:
                apply_volts(servo.tick(j, axis_positions(), pad_force()))
                step(substeps)
                rows[k] = frame
                k += 1
            if progress is not None and period % report_every == 0:
                progress(period, total)
        wall_time = time.perf_counter() - wall_start
        self.frames.count = k
        if progress is not None and self.stop_reason is None:
            progress(total, total)
        trace = Trace.from_frames(
            self.frames,
            servo_period=timing.servo_period,
            ticks_per_period=ticks_per_period,
            counts_per_unit=np.array([a.counts_per_unit for a in self.scenario.axes]),
        )
        metrics = compute_metrics(
            trace, self.scenario, wall_time=wall_time, dac_saturations=servo.dac_saturations,
            warnings=plant.warnings(),
        )
        if self.stop_reason is not None:
            metrics["status"] = "interrupted"
            metrics["stop_reason"] = self.stop_reason
        return RunResult(scenario=self.scenario, trace=trace, metrics=metrics)


def run_scenario(scenario: Scenario, *, progress: ProgressCallback | None = None) -> RunResult:
    """Build a :class:`Twin` for ``scenario`` and run it. Writes no files."""
    return Twin(scenario).run(progress=progress)
