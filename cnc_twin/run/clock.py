"""The run's clock: interpolation periods on simulated time, until the program ends.

One period, the path every period takes::

    stop here? (time limit -> a controlled stop first; a stop request -> now)
    real time: wait for the period's wall-clock start
    injected faults due now (if any)
    card's task:   dsp.begin_period(k)           # supervisor, exchange, records, state, setpoint
    servo ticks:   ticks_per_period x (servo tick -> volts -> plant.step(substeps) -> record)
    after:         removal map (polishing), progress and observer reports
    program done? (finished; or a fault, then FAULT_LINGER of simulated time at rest)

Where periods differ, the variants are named:

- **hung card** (:meth:`Clock.hung_period`, fault ``dsp_hang``): no task, no servo interrupt;
  the plant steps on with the DACs held and the watchdog counts the missed ticks;
- **batch** (:class:`cnc_twin.run.period_batch.PeriodBatch`): lockstep and solo, in the steady
  middle of a curve block (a surface path's, with the force loop tracking, too), a move or a
  dwell, up to 64 whole periods (task, ticks and removal updates) in one compiled call; it ends
  before any period that would do anything else, which then takes the path above;
- the servo ticks, one of (:meth:`Clock.servo_ticks` picks):
  **compiled** (analog output, drives on, no injected card fault: the four ticks with their
  physics and recording in one call, :mod:`cnc_twin.run.servo_kernel`), **drives off** (a stop
  disabled the amplifiers), **analog** (the Python reference servo) or **pulse** (step pulses
  into the amplifiers' position loops).

The compiled variants give the same trace bit for bit as the Python reference
(``tests/test_servo_kernel.py``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, NamedTuple

from cnc_twin.core import units
from cnc_twin.core.errors import ScenarioError
from cnc_twin.core.heap import resident_bytes
from cnc_twin.dsp.supervisor import STOP_DISABLE
from cnc_twin.dsp.task import DspTask
from cnc_twin.trace.recorder import Recorder
from cnc_twin.whiteboard.status import DspState, FaultCode

if TYPE_CHECKING:
    from cnc_twin.run.twin import Twin

ProgressCallback = Callable[[int, int], None]
"""called as ``progress(periods_done, periods_expected)`` a few hundred times per run"""

FAULT_LINGER = 0.05
"""simulated time recorded after a fault brought the machine to rest [s]"""
STOP_ALLOWANCE = 5.0
"""simulated time a stop after the run's time limit may take to reach rest [s]"""
REPORTS_PER_RUN = 200
"""progress and observer reports per run (batches end at report periods when someone listens)"""


MAX_PHYSICS_STEPS = 500_000_000
"""most MuJoCo steps a run may take (about a day of wall time on one core)"""
MAX_TRACE_TICKS = 100_000_000
"""most servo ticks a run may record (6.9 hours at 0.25 ms: a trace.parquet of about 20 GB)"""


def check_run_size(sc, planned: int, max_periods: int) -> None:
    """Refuse (a :class:`~cnc_twin.core.errors.ScenarioError`, exit 2, before the clock starts) a
    run whose periods would take more physics steps or trace rows than the limits: a tiny timestep
    or a huge dwell is a bad input, not a run that never ends."""
    timing = sc.timing
    steps = max_periods * timing.ticks_per_period * timing.substeps_per_tick
    label = sc.source_file or sc.name
    if steps > MAX_PHYSICS_STEPS:
        raise ScenarioError(label, "timing.physics_timestep",
                            f"{timing.physics_timestep / units.MS:g} ms gives {steps:.3g} physics steps for this program "
                            f"({max_periods * timing.interpolation_period:g} s simulated at most); the limit is "
                            f"{MAX_PHYSICS_STEPS:.3g}")
    ticks = (planned + 2) * timing.ticks_per_period
    if ticks > MAX_TRACE_TICKS:
        raise ScenarioError(label, "timing.servo_period",
                            f"{timing.servo_period / units.MS:g} ms gives {ticks:.3g} trace rows for this program "
                            f"({planned * timing.interpolation_period:g} s); the limit is {MAX_TRACE_TICKS:.3g}")


class ClockResult(NamedTuple):
    """What :meth:`Clock.run` returns."""

    wall_time: float
    """[s] the loop's wall-clock time"""
    periods: int
    """interpolation periods run"""
    late_periods: int
    """real-time mode: periods that started more than a period late"""
    missed_ticks: int
    """servo ticks the card's task missed at the end (a hung task, ``dsp_hang``)"""


class Clock:
    """Runs ``twin``'s periods with the card's task ``dsp``; ``planned`` is the program's length
    as the planner announced it [periods]. Builds the run's :attr:`recorder` (observers read it
    during the run: the twin hands it on before :meth:`run`) and :attr:`batch`."""

    def __init__(self, twin: Twin, dsp: DspTask, planned: int, progress: ProgressCallback | None):
        self.twin, self.dsp, self.progress = twin, dsp, progress
        sc = twin.scenario
        timing = sc.timing
        self.period_s = timing.interpolation_period
        self.max_time = sc.max_time if sc.max_time is not None else 2.0 * planned * self.period_s + 5.0
        self.max_periods = max(1, round(self.max_time / self.period_s))
        self.ticks_per_period = timing.ticks_per_period
        self.substeps = timing.substeps_per_tick
        check_run_size(sc, planned, self.max_periods)
        self.realtime = timing.mode == "realtime"
        self.expected_periods = planned + 1
        """the program's length as planned, plus the last period [periods] (the progress bar's end)"""
        self.report_every = max(1, self.expected_periods // REPORTS_PER_RUN)
        self.recorder = Recorder(planned + 2, self.ticks_per_period, scratch=not twin.record, spill=twin.trace_writer,
                                 spill_group_periods=twin.trace_group_periods, servo_period=timing.servo_period)
        """the run's recorder"""
        # what the Python servo-tick variants call every tick, looked up once
        plant = twin.plant
        self._plant_calls = (plant.encoder_positions, plant.pad_force, plant.apply_volts, plant.step,
                             self.recorder.record_tick)
        """the plant's calls: the encoders' positions, the load cell, the drives, the physics; the recorder's"""
        self._last_tick = self.ticks_per_period - 1
        self.late_periods = self.missed_ticks = 0
        self.memory = [resident_bytes()]
        """the process's resident memory [bytes] when the clock starts, each time a long run's
        recorder window moves on, and at the end (None where it cannot be read)"""
        # the steady middle of curve blocks (surface paths too), moves and dwells, many periods
        # per compiled call, the removal map's updates included (lockstep only: real time paces
        # every period)
        self.batch = None
        """the :class:`~cnc_twin.run.period_batch.PeriodBatch`, if periods run in batches"""
        if twin.kernel is not None and twin.batch and not self.realtime:
            from cnc_twin.run.period_batch import PeriodBatch

            self.batch = PeriodBatch(dsp, twin.kernel, self.recorder, twin.removal, switches=twin.plant.switches)
            self.batch.warm_up()

    def run(self) -> ClockResult:
        """Run to the end."""
        twin, dsp, recorder, batch = self.twin, self.dsp, self.recorder, self.batch
        injector, removal = twin.injector, twin.removal
        frame, first_period_field = twin.servo.frame, twin.servo.period_slot
        record_period = recorder.record_period
        tpp, period_s, report_every = self.ticks_per_period, self.period_s, self.report_every
        removal_every = removal.every if removal is not None else 0
        reporting = self.progress is not None or twin.observer is not None  # batches stop at reports
        linger = round(FAULT_LINGER / period_s)
        room = recorder.room
        timed_out = False
        k = t = 0
        if self.progress is not None:  # the run has begun: the bar at 0 (or its start line)
            self.progress(0, self.expected_periods)
        wall_start = time.perf_counter()
        while True:
            if k >= self.max_periods:
                if timed_out:  # the stop after the time limit did not come to rest either
                    break
                # A controlled stop, run to rest like any fault's (within STOP_ALLOWANCE).
                dsp.raise_fault(FaultCode.RUN_TIMEOUT, f"program not finished after {self.max_time:g} s simulated", k)
                timed_out = True
                self.max_periods = k + round(STOP_ALLOWANCE / period_s)
            if twin.stop_reason is not None:
                break
            if self.realtime:
                self.pace(wall_start + k * period_s)
            if t + tpp > room:
                if twin.observer is not None:  # it reads the window before a long run's window moves on
                    recorder.count = t
                    twin.observer(twin)
                recorder.make_room(t)
                room = recorder.room
                self.memory.append(resident_bytes())
            if injector is not None and k >= injector.next_period:
                injector.begin_period(k)
            if injector is not None and injector.hang_ticks:  # variant: hung card
                record_period(k, frame, first_period_field)
                t = self.hung_period(k, t)
                k += 1
                continue
            if batch is not None:  # variant: many whole periods in one compiled call
                ran = batch.run(k, t, min(self.max_periods - k, (room - t) // tpp,
                                          report_every - k % report_every if reporting else self.max_periods))
                if ran:
                    k += ran
                    t += ran * tpp
                    if k % report_every == 0:
                        self.report(k, t)
                    continue
            dsp.begin_period(k)
            record_period(k, frame, first_period_field)
            t = self.servo_ticks(t)
            k += 1
            if removal_every and k % removal_every == 0:
                removal.update()
            if k % report_every == 0:
                self.report(k, t)
            if dsp.done:
                if dsp.state == DspState.FINISHED:
                    break
                linger -= 1
                if linger < 0:
                    break
        wall_time = time.perf_counter() - wall_start
        recorder.count = t
        self.memory.append(resident_bytes())
        if self.progress is not None and twin.stop_reason is None:
            self.progress(k, k)  # the bar ends at what was simulated, not at the estimate
        return ClockResult(wall_time, k, self.late_periods, self.missed_ticks)

    def servo_ticks(self, t: int) -> int:
        """The period's servo ticks from tick ``t``, each with its physics steps and recorded row,
        by the variant that applies now; returns the next tick."""
        twin = self.twin
        kernel = twin.kernel
        if kernel is not None and self.dsp.drives_enabled:  # variant: compiled
            kernel.run_period(self.recorder, t)
            return t + self.ticks_per_period
        servo, frame = twin.servo, twin.servo.frame
        encoders, pad_force, apply_volts, step, record_tick = self._plant_calls
        substeps = self.substeps
        if self.dsp.drives_enabled and twin.drives is not None:
            # variant: pulse; step pulses -> the amplifiers' position loops -> their speed loops
            tick_pulses, drive = servo.tick_pulses, twin.drives.update
            for j in range(self.ticks_per_period):
                positions = encoders()
                self.sample_tool(j, t)
                apply_volts(drive(tick_pulses(j, positions, pad_force()), positions))
                step(substeps)
                record_tick(t, frame)
                t += 1
            return t
        if self.dsp.drives_enabled:  # variant: analog, the Python reference servo
            tick = servo.tick
        else:  # variant: drives off
            twin.drives_off()  # at the first such period: the stop just disabled them
            tick = servo.tick_disabled
        for j in range(self.ticks_per_period):
            self.sample_tool(j, t)
            apply_volts(tick(j, encoders(), pad_force()))
            step(substeps)
            record_tick(t, frame)
            t += 1
        return t

    def sample_tool(self, j: int, t: int) -> None:
        """At the period's last tick ``j`` (tick ``t`` of the run), before its physics: the tool's
        true pose into the recorder (as the compiled servo records it)."""
        if j == self._last_tick:
            self.twin.plant.sample_tool_pose(self.recorder.tool_row(t))

    def hung_period(self, k: int, t: int) -> int:
        """One period with the card's task hung: no exchange, no servo interrupt. The DACs hold
        their last output; the encoder counters run on (recorded, so the trace shows the drift).
        The watchdog disables the drives once the task has missed ``watchdog`` seconds of ticks."""
        twin, dsp = self.twin, self.dsp
        sc, plant, servo, injector = twin.scenario, twin.plant, twin.servo, twin.injector
        timing = sc.timing
        frame = servo.frame
        watchdog_ticks = round(sc.supervisor.watchdog / timing.servo_period) if sc.supervisor.watchdog > 0 else 0
        for j in range(timing.ticks_per_period):
            plant.step(timing.substeps_per_tick)
            self.sample_tool(j, t)  # as the encoders below: after the tick's physics
            if injector.hang_ticks:  # once it is over, the task runs again from the next period
                injector.hang_ticks -= 1
                self.missed_ticks += 1
                if watchdog_ticks and self.missed_ticks >= watchdog_ticks and dsp.drives_enabled:
                    # the watchdog resets the card; the amplifiers lose their enable at once
                    twin.drives_off()
                    dsp.raise_fault(FaultCode.WATCHDOG, f"no servo interrupt for {sc.supervisor.watchdog * 1e3:g} ms",
                                    k, stop=STOP_DISABLE)
                    injector.hang_ticks = 0
            servo.read_encoders(plant.encoder_positions())
            self.recorder.record_tick(t, frame)
            t += 1
        if not injector.hang_ticks:
            self.missed_ticks = 0
        return t

    def report(self, k: int, t: int) -> None:
        """Progress and the observer, a few hundred times per run (``k`` periods, ``t`` ticks done)."""
        twin = self.twin
        if self.progress is not None:
            self.progress(min(k, self.expected_periods), self.expected_periods)
        if twin.observer is not None:
            self.recorder.count = t
            twin.observer(twin)

    def pace(self, deadline: float) -> None:
        """Real-time mode: wait for the wall-clock start of the period (sleep, then spin)."""
        now = time.perf_counter()
        if now > deadline + self.period_s:
            self.late_periods += 1
            return
        if deadline - now > 0.0005:
            time.sleep(deadline - now - 0.0003)
        while time.perf_counter() < deadline:
            pass
