"""Wiring: build the plant, the card and the planner process for a scenario; run the clock.

The clock, on simulated time; real-time mode also paces each period to the wall clock::

    create the whiteboard; start the planner process (a plain subprocess; or take the idle one a
    PlannerPool kept from an earlier clean run) and hand it the job; wait until it attached
    for k = 0, 1, ...:
        injector.begin_period(k)             # injected card/machine faults due now (if any)
        if the card's task hangs (dsp_hang): # no exchange, no servo interrupt: the DACs hold;
            step the plant tick by tick      # the watchdog disables the drives after its timeout
            continue
        dsp.begin_period(k)                  # supervisor, whiteboard exchange, records, state, setpoint
        for each of ticks_per_period servo ticks:
            volts = servo.tick(j, plant.axis_positions(), plant.pad_force())
                                             # drives disabled by a stop: servo.tick_disabled
            plant.apply_volts(volts)         # DAC -> drives (zero-order hold)
            plant.step(substeps_per_tick)    # MuJoCo, drive loops in C
            recorder.record_tick(t, frame)   # typed preallocated columns
        (analog output, drives on, no injected card faults: the ticks, the physics and the
        recording of the whole period run as one compiled call, cnc_twin.run.servo_kernel;
        lockstep and solo, in the steady middle of a curve block, move or dwell: up to 64 whole
        periods, the card's task included, run as one compiled call, cnc_twin.run.period_kernel)
        stop when the program finished, a fault stopped the machine, time ran out, or a stop
        was requested (signal)
    finally: tell the planner the run is over; close it (EOF, then terminate/kill if needed) or,
    with a pool and a clean run, keep it for the next run; unlink the whiteboard

In lockstep mode the DSP waits for the planner's answer every period, so the same scenario
gives the same trace bit for bit. In real-time mode the DSP never waits: a late answer is a
missed exchange, and a starved card holds (FEED_HOLD) until records arrive again.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cnc_twin.core.axes import AXES
from cnc_twin.core.config import PLANNER_FAULTS, ContourProgram, MotionChipProgram, NurbsProgram, Scenario, SurfaceProgram
from cnc_twin.dsp.interpolator import SegmentInterpolator
from cnc_twin.dsp import curve_kernel
from cnc_twin.run import servo_kernel
from cnc_twin.dsp.servo import ServoTask
from cnc_twin.dsp.supervisor import STOP_DISABLE, Supervisor
from cnc_twin.dsp.task import DspTask
from cnc_twin.run.faults import FaultInjector
from cnc_twin.planner.launch import PlannerPool, PlannerProcess
from cnc_twin.planner.process import PlannerJob
from cnc_twin.machine.plant import Plant, add_obstacles, load_model_with_obstacles
from cnc_twin.run.path_metrics import path_metrics
from cnc_twin.trace.record import RECORDING_FILE, Recorder, Trace, compute_metrics, write_run_dir
from cnc_twin.whiteboard.block import Whiteboard
from cnc_twin.whiteboard.layout import Layout
from cnc_twin.whiteboard.ports import DspPort, PlannerLost, signal_shutdown
from cnc_twin.whiteboard.status import DspState, FaultCode

ProgressCallback = Callable[[int, int], None]
"""called as ``progress(periods_done, periods_expected)`` a few hundred times per run"""

FAULT_LINGER = 0.05
"""simulated time recorded after a fault brought the machine to rest [s]"""
STOP_ALLOWANCE = 5.0
"""simulated time a stop after the run's time limit may take to reach rest [s]"""


@dataclass
class RunResult:
    """What a run produced. Nothing is written to disk unless :meth:`write` is called."""

    scenario: Scenario
    trace: Trace
    metrics: dict[str, Any]
    run_dir: Path | None = field(default=None)
    model: Any = field(default=None, repr=False)
    """the compiled MJCF the run used (for exports)"""
    exchange_latency: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)
    """(period, latency [us]) of every answered exchange: wall clock, so kept out of the trace"""
    removal: Any = field(default=None, repr=False)
    """the removal map of a surface polishing run (:class:`cnc_twin.polishing.removal.PrestonModel`)"""

    @property
    def status(self) -> str:
        """``complete``, ``fault`` or ``interrupted``."""
        return self.metrics["status"]

    def dataframe(self):
        """The trace as a pandas DataFrame (columns as in trace.parquet); needs pandas installed."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("RunResult.dataframe() needs pandas: pip install pandas") from None
        return pd.DataFrame(self.trace.columns())

    def write(self, run_dir: str | Path, *, recording: bool | Callable[[], Path | None] = True) -> Path:
        """Write ``scenario.yaml``, ``trace.parquet``, ``metrics.json`` and, unless
        ``recording=False``, ``recording.rrd`` (rerun) to ``run_dir``, exported now.

        ``recording`` may instead be a callable, called once the trace is written, that returns
        the path of a finished recording of this run to move in (one a
        :class:`~cnc_twin.view.rerun_stream.RecordingProcess` made during it, on the same file
        system), or None to export it now after all."""
        def extra(folder: Path) -> None:
            if self.removal is not None:
                self.removal.save(folder)
            finished = recording() if callable(recording) else None
            if finished is not None:
                os.replace(finished, folder / RECORDING_FILE)
            elif recording:
                self.export_rerun(rrd=folder / RECORDING_FILE)
        self.run_dir = write_run_dir(Path(run_dir), scenario=self.scenario, trace=self.trace, metrics=self.metrics,
                                     extra=extra)
        return self.run_dir

    def export_rerun(self, *, rrd: Path | None = None, spawn: bool = False) -> None:
        """Write a rerun recording of the run and/or open it in a spawned viewer."""
        from cnc_twin.view.rerun_export import export_run

        export_run(self.trace, self.scenario, self.metrics, rrd=rrd, spawn=spawn, model=self.model,
                   exchange_latency=self.exchange_latency)


class Twin:
    """One run's plant, card and planner, built from a scenario.

    Parameters
    ----------
    scenario : a validated scenario (see :func:`cnc_twin.scenario.load.load_scenario`).
    compiled : run the servo periods in the compiled kernel where it applies and step NURBS
        curves with the compiled stepper (the default); ``False`` runs the pure-Python reference
        servo and stepper throughout. Traces are the same bit for bit.
    batch : with ``compiled``, run the steady middle of curve blocks, moves and dwells many
        periods per compiled call (:mod:`cnc_twin.run.period_kernel`; the default). The trace is
        the same either way.
    record : keep the trace (the default). ``False`` writes every tick into a one-period scratch
        buffer instead, only to measure what recording costs: the result's trace is the last
        period and its metrics are the timing figures alone.
    """

    def __init__(self, scenario: Scenario, *, compiled: bool = True, record: bool = True, batch: bool = True):
        self.record = record
        self.batch = batch
        self.scenario = scenario
        timing = scenario.timing
        self.tiling = self.removal = None
        obstacles = [(f.position, f.size) for f in scenario.faults if f.kind == "collision"]
        if isinstance(scenario.program, SurfaceProgram):
            from cnc_twin.planner.surface_program import build_surface
            from cnc_twin.polishing.polish import RemovalTracker
            from cnc_twin.machine.workpiece import build_model

            surface = build_surface(scenario.program)
            model, self.tiling = build_model(scenario.model_file, surface,
                                             tile_size=scenario.program.surface_tile_size,
                                             edit=lambda spec: add_obstacles(spec, obstacles))
            self.plant = Plant(model, timestep=timing.physics_timestep)
            self.removal = RemovalTracker(scenario.program, surface, self.plant.model, self.plant.data,
                                          timing.interpolation_period)
        else:
            self.plant = Plant(load_model_with_obstacles(scenario.model_file, obstacles),
                               timestep=timing.physics_timestep)
        self.servo = ServoTask(
            scenario.axes, timing=timing, power_on=scenario.home, force_sensor=scenario.force_sensor,
            output=scenario.command_output,
        )
        self.drives = None
        if scenario.command_output == "pulse":
            from cnc_twin.machine.drive import PositionModeDrives

            self.drives = PositionModeDrives(scenario.axes, tick=timing.servo_period, power_on=scenario.home)
        self.interpolator = SegmentInterpolator(
            axes=scenario.axes, power_on=scenario.home, period=timing.interpolation_period,
            ticks_per_period=timing.ticks_per_period, compiled=compiled,
        )
        self.job = PlannerJob(
            program=scenario.program,
            axes=scenario.axes,
            home=scenario.home,
            period=timing.interpolation_period,
            layout_words=scenario.whiteboard.words,
            chunk_words=scenario.whiteboard.chunk_words,
            lookahead_periods=_lookahead_periods(scenario),
            faults=tuple(f for f in scenario.faults if f.kind in PLANNER_FAULTS),
            lockstep=timing.mode == "lockstep",
        )
        self.supervisor = Supervisor(scenario.axes, scenario.supervisor, power_on=scenario.home,
                                     period=timing.interpolation_period, ticks_per_period=timing.ticks_per_period,
                                     referenced=not isinstance(scenario.program, MotionChipProgram))
        card_faults = [f for f in scenario.faults if f.kind not in PLANNER_FAULTS]
        self.injector = FaultInjector(tuple(card_faults), servo=self.servo, plant=self.plant,
                                      period=timing.interpolation_period, servo_period=timing.servo_period,
                                      seed=scenario.seed) if card_faults else None
        self.kernel = None
        if compiled and self.drives is None and self.injector is None and servo_kernel.available():
            self.kernel = servo_kernel.CompiledServo(self.servo, self.plant, substeps=timing.substeps_per_tick)
        self.stop_reason: str | None = None
        """set (e.g. from a signal handler) to stop the run at the next period boundary"""
        self.plan_us = self.plan_blocks = 0
        self.observer = None
        self.port = self.process = None
        self.expected_periods = 0
        self.recorder: Recorder | None = None
        self.period_batch = None
        """the run's :class:`~cnc_twin.run.period_kernel.PeriodBatch`, if it had one"""

    def request_stop(self, reason: str) -> None:
        """Stop at the next interpolation period; what was recorded so far is kept."""
        self.stop_reason = reason

    def run(self, *, progress: ProgressCallback | None = None,
            observer: Callable[["Twin"], None] | None = None, planners: PlannerPool | None = None) -> RunResult:
        """Run the program on the simulated clock and return the result.

        ``observer(twin)`` is called a few hundred times during the run, after whole periods, with
        ``twin.recorder.count`` ticks recorded so far (:meth:`partial_trace` reads them), e.g. to
        stream the run into a live viewer.

        ``planners``: a :class:`~cnc_twin.planner.launch.PlannerPool` to take the planner process
        from and give it back to (runs in a loop then skip the planner's start-up); without one,
        the run starts its own planner and closes it at the end.
        """
        self.observer = observer
        sc = self.scenario
        wb = Whiteboard.create(Layout(sc.whiteboard.words))
        planner: PlannerProcess | None = None
        port = None
        try:
            planner = planners.acquire() if planners is not None else PlannerProcess()
            # kept for a later run only after a clean lockstep run without planner faults (a
            # real-time planner may still be planning in its thread when the run ends)
            planner.reusable = sc.timing.mode == "lockstep" and not self.job.faults
            planner.submit(wb.name, self.job)
            if self.kernel is not None:  # compiles (or loads) while the planner starts and plans
                self.kernel.warm_up()
            if self.interpolator.compiled and isinstance(sc.program, NurbsProgram):
                curve_kernel.warm_up()
            bells, process = planner.bells, planner.popen
            port = DspPort(wb, lockstep=sc.timing.mode == "lockstep", planner_alive=lambda: process.poll() is None,
                           heartbeat_timeout=sc.planner.heartbeat_timeout, ring_pc=bells.ring_pc,
                           wait_pc=bells.wait_pc)
            self.port, self.process = port, process  # for observers (diagnostics, tests)
            dsp = DspTask(servo=self.servo, interpolator=self.interpolator, port=port,
                          period=sc.timing.interpolation_period, read_inputs=self.plant.switch_inputs,
                          supervisor=self.supervisor)
            try:
                planned = port.wait_ready(sc.planner.start_timeout)
            except PlannerLost as exc:
                dsp.raise_fault(FaultCode.PLANNER_START, str(exc), 0)
                planned = 0
            wall_time, periods = self._clock(dsp, planned, progress)
            retransmits = int(wb.retransmits[0])
            self.plan_us, self.plan_blocks = int(wb.plan_us[0]), int(wb.plan_blocks[0])
        finally:
            # Every step guarded: whatever failed above, the planner is reaped and the segment unlinked.
            try:
                signal_shutdown(wb, planner.bells.ring_pc if planner is not None else None)
            finally:
                try:
                    _release(planner, planners)
                finally:
                    port = None
                    wb.close()
        return self._result(dsp, wall_time, periods, retransmits)

    def _clock(self, dsp: DspTask, planned: int, progress: ProgressCallback | None) -> tuple[float, int]:
        sc = self.scenario
        timing = sc.timing
        period_s = timing.interpolation_period
        max_time = sc.max_time if sc.max_time is not None else 2.0 * planned * period_s + 5.0
        max_periods = max(1, round(max_time / period_s))
        linger = round(FAULT_LINGER / period_s)
        self.expected_periods = planned + 1
        ticks_per_period = timing.ticks_per_period
        substeps = timing.substeps_per_tick
        self.recorder = recorder = Recorder(planned + 2, ticks_per_period, scratch=not self.record)
        record_tick, record_period = recorder.record_tick, recorder.record_period
        plant, servo = self.plant, self.servo
        frame = servo.frame
        first_period_field = servo.period_slot
        kernel = self.kernel
        room = recorder.room
        axis_positions, pad_force, apply_volts, step = (
            plant.axis_positions, plant.pad_force, plant.apply_volts, plant.step,
        )
        tick = servo.tick
        tick_range = range(ticks_per_period)
        realtime = timing.mode == "realtime"
        report_every = max(1, self.expected_periods // 200)
        removal = self.removal
        removal_every = removal.every if removal is not None else 0
        self.late_periods = 0
        self.missed_ticks = 0
        k = 0
        t = 0
        # the steady middle of curve blocks, moves and dwells, many periods per compiled call
        # (lockstep only: real time paces every period; not for surfaces: the removal map updates
        # between periods)
        self.period_batch = batch = None
        if kernel is not None and self.batch and not realtime and removal is None:
            from cnc_twin.run.period_kernel import PeriodBatch

            self.period_batch = batch = PeriodBatch(dsp, kernel, recorder)
            batch.warm_up()
        wall_start = time.perf_counter()
        drives = self.drives
        if drives is not None:
            tick_pulses, drive = servo.tick_pulses, drives.update
        injector = self.injector
        reporting = progress is not None or self.observer is not None  # batches stop at report periods
        timed_out = False
        while True:
            if k >= max_periods:
                if timed_out:  # the stop after the time limit did not come to rest either
                    break
                # A controlled stop, run to rest like any fault's (within STOP_ALLOWANCE).
                dsp.raise_fault(FaultCode.RUN_TIMEOUT, f"program not finished after {max_time:g} s simulated", k)
                timed_out = True
                max_periods = k + round(STOP_ALLOWANCE / period_s)
            if self.stop_reason is not None:
                break
            if realtime:
                self._pace(wall_start + k * period_s, period_s)
            if t + ticks_per_period > room:
                recorder.grow()
                room = recorder.room
            if injector is not None and k >= injector.next_period:
                injector.begin_period(k)
            if injector is not None and injector.hang_ticks:
                if kernel is not None:
                    kernel.store()
                record_period(k, frame, first_period_field)
                t = self._hung_period(dsp, k, t)
                k += 1
                continue
            if batch is not None:
                ran = batch.run(k, t, min(max_periods - k, (room - t) // ticks_per_period,
                                          report_every - k % report_every if reporting else max_periods))
                if ran:
                    k += ran
                    t += ran * ticks_per_period
                    if k % report_every == 0:
                        self._report(progress, recorder, k, t)
                    continue
            dsp.begin_period(k)
            record_period(k, frame, first_period_field)
            if kernel is not None and dsp.drives_enabled:
                kernel.load()
                kernel.run_period(recorder, t)
                t += ticks_per_period
            else:
                if kernel is not None:
                    kernel.store()
                if not dsp.drives_enabled:
                    self._drives_off()  # at the first such period: the stop just disabled them
                    tick_disabled = servo.tick_disabled
                    for j in tick_range:
                        apply_volts(tick_disabled(j, axis_positions(), pad_force()))
                        step(substeps)
                        record_tick(t, frame)
                        t += 1
                elif drives is None:
                    for j in tick_range:
                        apply_volts(tick(j, axis_positions(), pad_force()))
                        step(substeps)
                        record_tick(t, frame)
                        t += 1
                else:  # step pulses -> the amplifiers' position loops -> their speed loops
                    for j in tick_range:
                        positions = axis_positions()
                        apply_volts(drive(tick_pulses(j, positions, pad_force()), positions))
                        step(substeps)
                        record_tick(t, frame)
                        t += 1
            k += 1
            if removal_every and k % removal_every == 0:
                removal.update()
            if k % report_every == 0:
                self._report(progress, recorder, k, t)
            if dsp.done:
                if dsp.state == DspState.FINISHED:
                    break
                linger -= 1
                if linger < 0:
                    break
        wall_time = time.perf_counter() - wall_start
        recorder.count = t
        if kernel is not None:
            kernel.store()  # the metrics read the DACs' saturation counts
        if progress is not None and self.stop_reason is None:
            progress(self.expected_periods, self.expected_periods)
        return wall_time, k

    def _report(self, progress: ProgressCallback | None, recorder: Recorder, k: int, t: int) -> None:
        """Progress and the observer, a few hundred times per run (``k`` periods, ``t`` ticks done)."""
        if progress is not None:
            progress(min(k, self.expected_periods), self.expected_periods)
        if self.observer is not None:
            recorder.count = t
            self.observer(self)

    def _hung_period(self, dsp: DspTask, k: int, t: int) -> int:
        """One period with the card's task hung: no exchange, no servo interrupt. The DACs hold
        their last output; the encoder counters run on (recorded, so the trace shows the drift).
        The watchdog disables the drives once the task has missed ``watchdog`` seconds of ticks."""
        sc, plant, servo, injector = self.scenario, self.plant, self.servo, self.injector
        timing = sc.timing
        n = servo.n_axes
        frame = servo.frame
        watchdog_ticks = round(sc.supervisor.watchdog / timing.servo_period) if sc.supervisor.watchdog > 0 else 0
        for _ in range(timing.ticks_per_period):
            plant.step(timing.substeps_per_tick)
            if injector.hang_ticks:  # once it is over, the task runs again from the next period
                injector.hang_ticks -= 1
                self.missed_ticks += 1
                if watchdog_ticks and self.missed_ticks >= watchdog_ticks and dsp.drives_enabled:
                    # the watchdog resets the card; the amplifiers lose their enable at once
                    self._drives_off()
                    dsp.raise_fault(FaultCode.WATCHDOG, f"no servo interrupt for {sc.supervisor.watchdog * 1e3:g} ms",
                                    k, stop=STOP_DISABLE)
                    injector.hang_ticks = 0
            positions = plant.axis_positions()
            for i, encoder in enumerate(servo.encoders):
                frame[n + i] = encoder.sample(positions[i])
            self.recorder.record_tick(t, frame)
            t += 1
        if not injector.hang_ticks:
            self.missed_ticks = 0
        return t

    def _drives_off(self) -> None:
        """The amplifiers disabled (brakes on) and the card's outputs and loops cleared; once."""
        if self.plant.drives_enabled:
            self.plant.disable_drives()
            self.servo.disable()

    def partial_trace(self, *, copy: bool = True) -> Trace:
        """The signals recorded so far, as a :class:`~cnc_twin.trace.record.Trace` (a copy, unless
        ``copy=False`` once the run is over)."""
        sc = self.scenario
        return self.recorder.trace(servo_period=sc.timing.servo_period, copy=copy,
                                   counts_per_unit=np.array([a.counts_per_unit for a in sc.axes]))

    def _pace(self, deadline: float, period_s: float) -> None:
        """Real-time mode: wait for the wall-clock start of the period (sleep, then spin)."""
        now = time.perf_counter()
        if now > deadline + period_s:
            self.late_periods += 1
            return
        if deadline - now > 0.0005:
            time.sleep(deadline - now - 0.0003)
        while time.perf_counter() < deadline:
            pass

    def _result(self, dsp: DspTask, wall_time: float, periods: int, retransmits: int) -> RunResult:
        sc = self.scenario
        assert self.recorder is not None
        trace = self.partial_trace(copy=False)  # by now, the whole run
        if not self.record:
            return RunResult(scenario=sc, trace=trace, metrics={"status": "complete", "wall_time_s": wall_time,
                                                                "periods": periods}, model=self.plant.model)
        metrics = compute_metrics(
            trace, sc, wall_time=wall_time, dac_saturations=self.servo.dac_saturations,
            warnings=self.plant.warnings(),
        )
        port = dsp.port
        latency = np.asarray(port.latency_ns, dtype=np.float64) / 1e3
        metrics["mode"] = sc.timing.mode
        metrics["command_output"] = sc.command_output
        if self.drives is not None:
            metrics["pulse_limited_ticks"] = dict(zip(AXES, self.servo.pulse_limited_ticks))
        metrics["final_state"] = DspState.NAMES[dsp.state]
        metrics["fault"] = None if dsp.fault == FaultCode.NONE else {
            "code": FaultCode.NAMES[dsp.fault], "message": dsp.fault_message, "time_s": dsp.fault_time,
            "stop": dsp.stop,
        }
        metrics["faults"] = [
            {"time_s": time_s, "code": FaultCode.NAMES[code], "axis": AXES[axis] if axis >= 0 else None,
             "message": message, "stop": stop}
            for time_s, code, axis, message, stop in dsp.fault_log]
        if dsp.fault != FaultCode.NONE and dsp.state == DspState.FAULT:
            metrics["fault"]["at_rest_s"] = dsp.at_rest_time
        metrics["whiteboard"] = {
            "periods": periods,
            "exchanges": len(port.latency_ns),
            "missed_exchanges": port.missed_exchanges,
            "records_accepted": dsp.records_accepted,
            "records_rejected": dsp.records_rejected,
            "records_retransmitted": retransmits,
            "underrun_periods": dsp.underrun_periods,
            "exchange_latency_us": {
                "median": float(np.median(latency)) if len(latency) else None,
                "p99": float(np.percentile(latency, 99)) if len(latency) else None,
                "max": float(latency.max()) if len(latency) else None,
            },
        }
        if sc.timing.mode == "realtime":
            metrics["late_periods"] = self.late_periods
        if isinstance(sc.program, NurbsProgram):
            metrics["path"] = path_metrics(trace, sc, interpolator_ns=np.asarray(dsp.interpolator_ns),
                                           plan_us=self.plan_us, plan_blocks=self.plan_blocks)
        if dsp.event_log:
            from cnc_twin.dsp.chip import EVENT_NAMES

            def shown(axis: int, count: int) -> float:  # [mm | deg]
                cfg = sc.axes[axis]
                return (count / cfg.counts_per_unit + sc.home[axis]) * cfg.display_factor

            metrics["events"] = [
                {"time_s": t, "axis": AXES[axis], "event": EVENT_NAMES[code], "count": value,
                 "position": shown(axis, value)}
                for t, axis, code, value in dsp.event_log]
        if isinstance(sc.program, ContourProgram):
            from cnc_twin.run.contour_metrics import contour_metrics

            metrics["contour"] = contour_metrics(trace, sc)
        if isinstance(sc.program, SurfaceProgram):
            from cnc_twin.polishing.polish import force_metrics, preston_by_hand, removal_metrics

            metrics["polish"] = {
                "force": force_metrics(trace, sc.program),
                "removal": {**removal_metrics(self.removal, sc.program, wall_time),
                            "preston_by_hand_mm3": preston_by_hand(trace, sc.program) * 1e9},
                "collision_tiles": list(self.tiling.tiles),
                "tile_hull_gap_mm": self.tiling.hull_gap * 1e3,
                "path_length_mm": sc.program.path_length * 1e3,
                "sections": len(sc.program.sections),
            }
        if self.stop_reason is not None:
            metrics["status"] = "interrupted"
            metrics["stop_reason"] = self.stop_reason
        elif dsp.fault != FaultCode.NONE:
            metrics["status"] = "fault"
        latency = (np.asarray(port.latency_period, dtype=np.int64), np.asarray(port.latency_ns, dtype=np.float64) / 1e3)
        return RunResult(scenario=sc, trace=trace, metrics=metrics, model=self.plant.model, exchange_latency=latency,
                         removal=None if self.removal is None else self.removal.model_removal)


def _lookahead_periods(scenario: Scenario) -> int:
    """The planner's look-ahead [periods]; 0 = no limit.

    On a curve the card must always hold enough path to stop in, so a look-ahead is never less
    than twice the time to stop from the programmed feed (jerk-limited).
    """
    period = scenario.timing.interpolation_period
    periods = math.ceil(scenario.planner.lookahead / period - 1e-9)
    if periods and isinstance(scenario.program, (NurbsProgram, SurfaceProgram, ContourProgram)):
        lim = scenario.program.limits
        a, j = lim.tangential_acceleration, lim.tangential_jerk
        stop_time = lim.feed / a + a / j
        periods = max(periods, math.ceil(2.0 * stop_time / period))
    return periods


def _release(planner: PlannerProcess | None, planners: PlannerPool | None) -> None:
    """After the shutdown word: keep the planner in the pool if its run ended cleanly, else close
    it (EOF, then terminate, then kill)."""
    if planner is None:
        return
    if planners is not None and planner.reusable and planner.finish():
        planners.release(planner)
    else:
        planner.reusable = False
        planner.close()


def run_scenario(scenario: Scenario, *, progress: ProgressCallback | None = None,
                 planners: PlannerPool | None = None) -> RunResult:
    """Build a :class:`Twin` for ``scenario`` and run it (the planner from ``planners`` if
    given, see :meth:`Twin.run`). Writes no files."""
    return Twin(scenario).run(progress=progress, planners=planners)
