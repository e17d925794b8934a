"""Wiring: build the plant, the card and the planner process for a scenario; run it.

A run::

    create the whiteboard; start the planner process (a plain subprocess; or take the idle one a
    PlannerPool kept from an earlier clean run) and hand it the job; wait until it attached and
    planned its first chunks
    run the clock (cnc_twin.run.clock: one interpolation period after another on simulated time)
    finally: tell the planner the run is over; close it (EOF, then terminate/kill if needed) or,
    with a pool and a clean run, keep it for the next run; unlink the whiteboard
    the metrics: the run's, the whiteboard's, the faults, and the program kind's own

What depends on the kind of program (the plant with a workpiece, the removal map, the look-ahead,
the metrics) comes from its :class:`~cnc_twin.run.program_kinds.ProgramKind`.

In lockstep mode the DSP waits for the planner's answer every period, so the same scenario
gives the same trace bit for bit. In real-time mode the DSP never waits: a late answer is a
missed exchange, and a starved card holds (FEED_HOLD) until records arrive again.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from cnc_twin.core.axes import AXES
from cnc_twin.core.config import PLANNER_FAULTS, Scenario
from cnc_twin.core.deferred_signals import signals_deferred
from cnc_twin.core.heap import return_freed_memory
from cnc_twin.core.phases import mark
from cnc_twin.dsp.interpolator import SegmentInterpolator
from cnc_twin.dsp.servo import ServoTask
from cnc_twin.dsp.supervisor import Supervisor
from cnc_twin.dsp.task import DspTask
from cnc_twin.planner.job import PlannerJob
from cnc_twin.planner.launch import PlannerPool, PlannerProcess
from cnc_twin.run import servo_kernel
from cnc_twin.run.clock import Clock, ProgressCallback
from cnc_twin.run.external_pc import OPEN_ENDED_MAX_TIME, ExternalPc
from cnc_twin.run.faults import FaultInjector
from cnc_twin.run.metrics import compute_metrics
from cnc_twin.run.program_kinds import kind_of, lookahead_periods
from cnc_twin.run.result import RunResult
from cnc_twin.run.run_dir import TRACE_FILE
from cnc_twin.trace.parquet import ROW_GROUP_PERIODS
from cnc_twin.trace.recorder import Recorder
from cnc_twin.trace.trace import Trace
from cnc_twin.whiteboard.block import Whiteboard
from cnc_twin.whiteboard.capture import StreamCapture
from cnc_twin.whiteboard.layout import Layout
from cnc_twin.whiteboard.ports import DspPort, PlannerLost, signal_shutdown
from cnc_twin.whiteboard.status import DspState, FaultCode

__all__ = ["ProgressCallback", "RunResult", "Twin", "run_scenario"]


class Twin:
    """One run's plant, card and planner, built from a scenario.

    Parameters
    ----------
    scenario
        a validated scenario (see :func:`cnc_twin.scenario.load.load_scenario`).
    compiled
        run the servo periods in the compiled kernel where it applies and step NURBS
        curves with the compiled stepper (the default); ``False`` runs every servo tick as its own
        call from Python (the same block functions, :mod:`cnc_twin.dsp.servo`) and the curve
        stepper interpreted from its source (:mod:`cnc_twin.dsp.curve_stepper`). Traces are the
        same bit for bit.
    batch
        with ``compiled``, run the steady middle of curve blocks, moves and dwells many
        periods per compiled call (:mod:`cnc_twin.run.period_kernel`; the default). The trace is
        the same either way.
    record
        keep the trace (the default). ``False`` writes every tick into a one-period scratch
        buffer instead, only to measure what recording costs: the result's trace is the last
        period and its metrics are the timing figures alone.
    """

    def __init__(self, scenario: Scenario, *, compiled: bool = True, record: bool = True, batch: bool = True):
        self.record = record
        self.batch = batch
        self.compiled = compiled
        self.scenario = scenario
        timing = scenario.timing
        self.kind = kind_of(scenario.program)
        self.notices = self.kind.notices(scenario)
        """what the run will do otherwise than the program asks, one line each (said before the
        run by the CLI, kept in ``metrics.json``)"""
        return_freed_memory()  # what loading the program freed, before the run's memory grows
        obstacles = [(f.position, f.size) for f in scenario.faults if f.kind == "collision"]
        self.plant, self.removal, self.tiling = self.kind.build_plant(self, obstacles)
        self.servo = ServoTask(
            scenario.axes, timing=timing, power_on=self.plant.encoder_home, force_sensor=scenario.force_sensor,
            output=scenario.command_output, reversal_compensation=self.kind.reversal_compensation,
        )
        self.drives = None
        if scenario.command_output == "pulse":
            from cnc_twin.machine.drive import PositionModeDrives

            self.drives = PositionModeDrives(scenario.axes, tick=timing.servo_period, power_on=self.plant.encoder_home)
        self.interpolator = SegmentInterpolator(
            axes=scenario.axes, power_on=scenario.home, period=timing.interpolation_period,
            ticks_per_period=timing.ticks_per_period, compiled=compiled,
        )
        self.job = PlannerJob(
            program=self.kind.for_planner(scenario.program),
            axes=scenario.axes,
            home=scenario.home,
            period=timing.interpolation_period,
            layout_words=scenario.whiteboard.words,
            chunk_words=scenario.whiteboard.chunk_words,
            lookahead_periods=lookahead_periods(scenario),
            faults=tuple(f for f in scenario.faults if f.kind in PLANNER_FAULTS),
            lockstep=timing.mode == "lockstep",
            fifo_interrupt=scenario.whiteboard.fifo_interrupt,
            replay=scenario.planner.replay,
        )
        self.supervisor = Supervisor(scenario.axes, scenario.supervisor, power_on=scenario.home,
                                     period=timing.interpolation_period, ticks_per_period=timing.ticks_per_period,
                                     referenced=self.kind.referenced)
        card_faults = [f for f in scenario.faults if f.kind not in PLANNER_FAULTS]
        self.injector = FaultInjector(tuple(card_faults), servo=self.servo, plant=self.plant,
                                      period=timing.interpolation_period, servo_period=timing.servo_period,
                                      seed=scenario.seed) if card_faults else None
        self.kernel = None
        if compiled and self.drives is None and self.injector is None and servo_kernel.available():
            self.kernel = servo_kernel.CompiledServo(self.servo, self.plant, substeps=timing.substeps_per_tick)
        self.stop_reason: str | None = None
        """set (e.g. from a signal handler) to stop the run at the next period boundary"""
        self.begun = False
        """True once the clock runs (compiled, planner started): from then a stop keeps what was recorded"""
        self.plan_us = self.plan_blocks = 0
        self.before_clock: Callable[[int], None] | None = None
        """called with the program's length [periods] once the planner is ready, before the clock
        starts: it may refuse the run (an exception, no motion)"""
        self.pc_stream = None
        """after a run: what an outside PC program wrote (or the replayed stream), for the run directory"""
        self.observer = None
        self.port = self.process = None
        self.expected_periods = 0
        self.recorder: Recorder | None = None
        self.period_batch = None
        """the run's :class:`~cnc_twin.run.period_batch.PeriodBatch`, if it had one"""
        self.late_periods = self.missed_ticks = 0
        self.trace_file: Path | None = None
        """where a run longer than the recorder's window writes its trace while it runs (the
        CLI's: staged beside the run directory); None: a temporary folder of its own, removed
        with the result's trace unless :meth:`RunResult.write` moved the file into a run directory"""
        self.trace_group_periods = ROW_GROUP_PERIODS
        """[periods] per row group of the trace's file; the recorder's window is SPILL_GROUPS of them"""
        self._trace_folder: Path | None = None
        self.memory: list[int | None] = []
        """the process's resident memory [bytes] through the run (:attr:`Clock.memory <cnc_twin.run.clock.Clock.memory>`)"""

    def trace_writer(self):
        """The :class:`~cnc_twin.trace.parquet.TraceWriter` of a run that outgrew the recorder's
        window (the recorder calls it then, once)."""
        from cnc_twin.trace.parquet import TraceWriter

        path = self.trace_file
        if path is None:
            self._trace_folder = Path(tempfile.mkdtemp(prefix="cnc-twin-trace-"))
            path = self._trace_folder / TRACE_FILE
        path.parent.mkdir(parents=True, exist_ok=True)
        return TraceWriter(path, scenario_name=self.scenario.name, counts_per_unit=self._counts_per_unit(),
                           group_periods=self.trace_group_periods)

    def _counts_per_unit(self) -> np.ndarray:
        return np.array([a.counts_per_unit for a in self.scenario.axes])

    def request_stop(self, reason: str) -> None:
        """Stop at the next interpolation period; what was recorded so far is kept."""
        self.stop_reason = reason

    def run(self, *, progress: ProgressCallback | None = None,
            observer: Callable[["Twin"], None] | None = None,
            planners: PlannerPool | ExternalPc | None = None) -> RunResult:
        """Run the program on the simulated clock and return the result.

        ``observer(twin)`` is called a few hundred times during the run, after whole periods, with
        ``twin.recorder.count`` ticks recorded so far (:meth:`partial_trace` reads them), e.g. to
        stream the run into a live viewer.

        ``planners``: a :class:`~cnc_twin.planner.launch.PlannerPool` to take the planner process
        from and give it back to (runs in a loop then skip the planner's start-up); without one,
        the run starts its own planner and closes it at the end. An
        :class:`~cnc_twin.run.external_pc.ExternalPc` instead: the PC side is an outside program
        that attaches by itself (``cnc-twin serve``).
        """
        self.observer = observer
        sc = self.scenario
        wb: Whiteboard | None = None
        planner: PlannerProcess | ExternalPc | None = None
        port = dsp = None
        try:
            with signals_deferred():  # a signal's exception cannot come between creating and owning
                wb = Whiteboard.create(Layout(sc.whiteboard.words))
            planner = planners.acquire() if planners is not None else PlannerProcess()
            # kept for a later run only after a clean lockstep run without planner faults (a
            # real-time planner may still be planning in its thread when the run ends)
            planner.reusable = sc.timing.mode == "lockstep" and not self.job.faults
            planner.submit(wb.name, self.job)
            self.plant.switch_inputs()
            self.load_kernels()  # compiles (or loads) while the planner starts and plans
            mark("kernels")
            bells = planner.bells
            port = DspPort(wb, lockstep=sc.timing.mode == "lockstep", planner_alive=planner.alive,
                           heartbeat_timeout=sc.planner.heartbeat_timeout, ring_pc=bells.ring_pc,
                           wait_pc=bells.wait_pc)
            if planner.capture:  # an outside PC program's stream, kept to be replayed
                port.capture = StreamCapture()
            self.port, self.process = port, planner.popen  # for observers (diagnostics, tests)
            dsp = DspTask(servo=self.servo, interpolator=self.interpolator, port=port,
                          period=sc.timing.interpolation_period, read_inputs=self.plant.switch_inputs,
                          supervisor=self.supervisor)
            try:
                planned = port.wait_ready(sc.planner.start_timeout)
            except PlannerLost as exc:
                dsp.raise_fault(FaultCode.PLANNER_START, str(exc), 0)
                planned = 0
            mark("planner")
            attached = dsp.fault != FaultCode.PLANNER_START
            # an outside program that did not say its length (and its replay): open-ended
            if (planner.capture or sc.planner.replay is not None) and planned == 0 and sc.max_time is None:
                self.scenario = sc = replace(sc, max_time=OPEN_ENDED_MAX_TIME)
            clock = Clock(self, dsp, planned, progress)  # refuses a run too large for its limits (bad input) first
            if self.before_clock is not None:  # e.g. room for what the run will write
                self.before_clock(planned)
            # observers read the recorder during the run
            self.recorder, self.period_batch, self.expected_periods = clock.recorder, clock.batch, clock.expected_periods
            self.begun = True
            wall_time, periods, self.late_periods, self.missed_ticks = clock.run()
            mark("clock")
            self.memory = clock.memory
            if dsp.planner_lost or dsp.fault == FaultCode.PLANNER_START:
                reason = planner.failure()
                if reason is not None:
                    dsp.explain_planner_fault(reason)
            retransmits = int(wb.retransmits[0])
            self.plan_us, self.plan_blocks = int(wb.plan_us[0]), int(wb.plan_blocks[0])
            if port.capture is None:
                self.pc_stream = sc.planner.replay
            elif attached:  # what the outside program sent (nothing to replay if it never came)
                self.pc_stream = port.capture.stream(sc.whiteboard.words, int(wb.program_periods[0]))
        finally:
            # Every step guarded: whatever failed above, the planner is reaped and the segment
            # unlinked, and a long run's trace file is closed whole (readable).
            try:
                if self.recorder is not None:
                    self.recorder.finish_file()
            except Exception:
                pass  # the run's own failure, if any, is the one to tell
            try:
                if wb is not None:
                    signal_shutdown(wb, planner.bells.ring_pc if planner is not None and planner.bells is not None
                                    else None, end=None if dsp is None else (dsp.state, dsp.fault))
            finally:
                try:
                    _release(planner, planners)
                finally:
                    port = None
                    if wb is not None:
                        wb.close()
        result = self._result(dsp, wall_time, periods, retransmits)
        mark("result")
        return result

    def load_kernels(self) -> None:
        """Compile (or load from numba's cache) every kernel this twin's run calls."""
        self.servo.warm_up()
        self.supervisor.warm_up()
        if self.kernel is not None:
            self.kernel.warm_up()
        self.kind.warm_up(self)
        if self.removal is not None:
            self.removal.warm_up()

    def drives_off(self) -> None:
        """The amplifiers disabled (brakes on) and the card's outputs and loops cleared; once."""
        if self.plant.drives_enabled:
            self.plant.disable_drives()
            self.servo.disable()

    def partial_trace(self, *, copy: bool = True) -> Trace:
        """The signals recorded so far, as a :class:`~cnc_twin.trace.trace.Trace` (a copy, unless
        ``copy=False`` once the run is over); of a run longer than the recorder's window, those the
        window holds (from the trace's ``first`` tick: the rest is in the run's file)."""
        return self.recorder.trace(servo_period=self.scenario.timing.servo_period, copy=copy,
                                   counts_per_unit=self._counts_per_unit())

    def _result(self, dsp: DspTask, wall_time: float, periods: int, retransmits: int) -> RunResult:
        self.scenario = self.kind.as_run(self.scenario, dsp)  # what ran is what is measured and shown
        sc = self.scenario
        assert self.recorder is not None
        if self.recorder.spilled:  # a long run: its trace is in its file
            from cnc_twin.trace.trace_file import TraceFile

            self.recorder.finish_file()
            trace = TraceFile(self.recorder.writer.path, servo_period=sc.timing.servo_period,
                              ticks_per_period=sc.timing.ticks_per_period, counts_per_unit=self._counts_per_unit(),
                              temporary_folder=self._trace_folder)
        else:
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
        resident = [m / 1e6 for m in self.memory if m is not None]
        if resident:  # the run's own memory, beside the process's peak (which a long program's load may set)
            metrics["memory_mb"] = {"at_start": round(resident[0], 1), "run_max": round(max(resident), 1),
                                    "samples": len(resident)}
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
        metrics.update(self.kind.metrics(self, trace, dsp, wall_time))
        if sc.ballbar is not None:  # any program kind can be measured with a ballbar
            from cnc_twin.run.ballbar import ballbar_metrics

            metrics["ballbar"] = ballbar_metrics(trace, sc)
        if self.notices:
            metrics["notices"] = self.notices
        if self.stop_reason is not None:
            metrics["status"] = "interrupted"
            metrics["stop_reason"] = self.stop_reason
        elif dsp.fault != FaultCode.NONE:
            metrics["status"] = "fault"
        latency = (np.asarray(port.latency_period, dtype=np.int64), np.asarray(port.latency_ns, dtype=np.float64) / 1e3)
        return RunResult(scenario=sc, trace=trace, metrics=metrics, model=self.plant.model, exchange_latency=latency,
                         removal=None if self.removal is None else self.removal.finished_map(), pc_stream=self.pc_stream)


def _release(planner: PlannerProcess | ExternalPc | None, planners: PlannerPool | ExternalPc | None) -> None:
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
