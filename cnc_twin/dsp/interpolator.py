"""Coarse interpolation: one setpoint per axis per interpolation period, from the record queue.

Inputs: records accepted from the FIFO, in sequence order (:mod:`cnc_twin.whiteboard.records`).
Move records become segments from the programmed position to their end; modal records (feed
override, force setpoint, spindle) take effect when they reach the head of the queue, in program
order; end of program finishes the run. Output per period: the commanded position at the *end*
of the period [counts], relative to the encoder's power-on position, for the servo task to
fine-interpolate towards.

Feed override and hold scale the segment's own clock: ``tau += lambda * T`` per period and
``p = start + s(tau) * d``. The axis acceleration is then ``d (s'' lambda^2 + s' lambda')``; it
stays within every axis's limit when ``|s'' lambda^2 + s' lambda'| <= a_lim`` with
``a_lim = min_i a_max_i / |d_i|``, which bounds how fast lambda may fall (hold) or rise
(resume)::

    lambda' >= -(a_lim + s'' lambda^2) / s'      (decelerate)
    lambda' <= +(a_lim - s'' lambda^2) / s'      (accelerate)

applied per period with a 0.9 margin for the discrete step. ``lambda`` is also capped so the
scaled profile stays within the velocity and acceleration limits (override above 1).

Curves (CurveGeometry + CurveBlock records): the block clock runs the same way; each period the
path advances ``ds = s(tau_new) - s(tau)`` of the block's S-curve (continuing into the next queued
blocks within the period), and :class:`~cnc_twin.dsp.curve_stepper.CurveStepper` turns that arc
length into the next point on the NURBS curve. A change of scale there (hold, resume, override,
the force loop's feed factor) is jerk-limited: the path moves to the target's speed and
acceleration within the block's own budgets (:mod:`cnc_twin.dsp.feed_slew`). When the queued path
(the rest of the running block plus every queued block) ends at speed and is no longer than the
stopping distance (the FIFO is running dry), the card holds, across block boundaries, and stops
inside what it has; it resumes once new blocks have made the queued path longer than a full-speed
stop again.

Curves, surfaces, the force loop and the spindle run as :mod:`cnc_twin.dsp.path_blocks` items.

Step contours (StepContour records, the older cards' point-by-point and DDA interpolation):
each element runs its own clock along its S-curve (:mod:`cnc_twin.dsp.step_interpolator`) and
hands the servo task a lattice point for every tick (``tick_commands``); hold and override
scale that clock like a move's (capped at 1: the S-curve already runs at the programmed feed).
Mark records set ``mark``, which the trace records; a G-code path sets it to the line it runs.

Motion-chip commands (ChipCommand, :mod:`cnc_twin.dsp.chip`) run one chip cycle per period from
where the axes are commanded when they start; they read the switch ``inputs`` and the encoder
counts ``actual`` the period task hands in, and raise ``events``. A program of chip commands
holds no Move records (a chip command's end is known only when it ends).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence

from cnc_twin.core.config import AxisConfig
from cnc_twin.dsp import feed_slew
from cnc_twin.dsp.chip import ChipRun, IndexMarks
from cnc_twin.dsp.force import ForceController, ForceState
from cnc_twin.dsp.probe import ProbeSegment, ProbeState
from cnc_twin.dsp.path_blocks import SLEW_MARGIN, Block, Curve, ForceWait, Surface, SurfaceRun, slew, stop_reserve
from cnc_twin.dsp.record_intake import MODAL, RecordIntake
from cnc_twin.dsp.spindle import spindle_turn
from cnc_twin.dsp.step_interpolator import StepRun
from cnc_twin.motion.segments import MoveSegment
from cnc_twin.whiteboard.records import ChipCommand, Dwell, Record, SurfaceGeometry


class SegmentInterpolator(RecordIntake):
    """Executes the queue of accepted records, one interpolation period at a time.

    Parameters
    ----------
    - axes : the six axes (limits and encoder resolution).
    - power_on : per axis position where the encoders were cleared [m | rad], shape ``(6,)``.
    - period : interpolation period [s].
    - ticks_per_period : servo ticks per period (a step interpolator gives a point for each).
    - compiled : step curves with the compiled stepper (:mod:`cnc_twin.dsp.curve_stepper`, the
      default) or its Python source; the setpoints are the same bit for bit.
    """

    def __init__(self, *, axes: Sequence[AxisConfig], power_on: Sequence[float], period: float,
                 ticks_per_period: int = 1, compiled: bool = True):
        self.compiled = compiled
        self.axes = tuple(axes)
        self.counts_per_unit = [a.counts_per_unit for a in axes]
        self.power_on = [float(p) for p in power_on]
        self.period = period
        self.ticks_per_period = ticks_per_period
        self.mark = 0
        """the last Mark record's number (0 before any)"""
        self.inputs = [0] * len(axes)
        """switch inputs per axis, set by the period task (:data:`~cnc_twin.core.axes.SWITCH_HOME` ...)"""
        self.actual = [0] * len(axes)
        """encoder counts per axis at the last tick, set by the period task"""
        self.events: list[tuple[int, int, int]] = []
        """``(axis, event bit, value)`` raised in the last period (:mod:`cnc_twin.dsp.chip`)"""
        self.index_marks = [IndexMarks(a.counts_per_unit, a.index_period, a.index_offset, p)
                            if a.index_period > 0 else None for a, p in zip(axes, power_on)]
        self.programmed = tuple(self.power_on)
        """end position of the last move accepted [m | rad]"""
        # the running state is public: the batch kernel (run/period_batch) reads it and writes it back
        self.queue: deque[tuple[int, Record | MoveSegment]] = deque()
        """accepted records and segments waiting to run, ``(seq, item)``"""
        self.current: tuple[int, MoveSegment | Dwell] | None = None
        """the running ``(seq, segment)`` (a move, dwell, curve block, force wait ...), or None"""
        self.tau, self.dwell_left = 0.0, 0
        """the running segment's own clock [s] (advancing by ``override`` periods); a dwell's periods left"""
        self.lam_max, self.start_counts, self.delta_counts = math.inf, [], []
        """the running move's largest time scale (every axis's limits), start and displacement [counts]"""
        self._a_lim = self._v_lim = math.inf
        self.override_target = 1.0
        self.override = 1.0
        """effective time scale lambda of the running segment (0 while held)"""
        self.hold = False
        """request a controlled stop along the path (lambda -> 0); clearing it resumes"""
        self.finished = False
        """end of program reached"""
        self.last_seq_executed = 0
        self.force_setpoint = 0.0
        self.spindle_on, self.spindle_speed = False, 0.0
        self.hold_counts = [0.0] * len(self.counts_per_unit)
        """the last period's path setpoint without the force loop's and the spindle's offsets [counts]"""
        self._queued_periods = 0
        self._pending_curve: Curve | SurfaceRun | None = None
        self._surface: Surface | None = None
        self.force = ForceController(period)
        """the grinding-force loop (see :mod:`cnc_twin.dsp.force`)"""
        self.measured_force = 0.0
        """load-cell force of the last servo tick [N], set by the period task before each period"""
        self.path_s = 0.0
        """path length run since the last surface definition [m] (the force profile's abscissa)"""
        self.tool_axis = (0.0, 0.0, 1.0)
        """tool axis of the last surface pose or force-control start (world frame), for the force offset"""
        c_axis = self.axes[5] if len(self.axes) > 5 else None
        self.spindle_accel = SLEW_MARGIN * c_axis.max_acceleration if c_axis is not None else math.inf
        """the spindle's speed ramp [rad/s^2] (C's acceleration with the slew margin)"""
        self.spin = 0.0
        """spindle speed commanded this period [rad/s]"""
        self.c_offset = 0.0
        """C angle turned by the spindle so far [rad], added to every C setpoint"""
        self._curve: Curve | None = None
        self.block_s = 0.0
        """path length done of the running curve block at the end of the last period [m]"""
        self.starved_hold = False
        """the queued path ran short of the stopping distance: the feed stops until records come"""
        self.queued_path = 0.0
        """length of the curve blocks queued behind the running one [m]"""
        self.path_open = False
        """the last queued record is a curve block ending at speed: the path continues beyond it"""
        self._arrivals = 0
        self._arrivals_at_latch = 0
        self._stop_reserve = 0.0
        self.block_state: tuple[float, float, float] | None = None
        """``(s, v, a)`` [m, m/s, m/s^2] of the running block at ``tau``, or None (its S-curve's then)"""
        self.path_accel: float | None = None
        """path acceleration [m/s^2] while the feed slews to a new scale (:mod:`~cnc_twin.dsp.feed_slew`)"""
        self.path_u = -1.0
        """curve parameter at the end of the last period; -1 when not on a curve"""
        self.path_ds = 0.0
        """arc length commanded in the last period [m]"""
        self.probe = ProbeState()
        """the probing move's state and the last probe's result (:mod:`cnc_twin.dsp.probe`)"""
        self.tick_commands: list[list[float]] | None = None
        """a step interpolator's command for every servo tick of the coming period [counts], or
        None (the servo task interpolates linearly to the period's setpoint)"""

    # --- queue -------------------------------------------------------------------------------
    @property
    def starved(self) -> bool:
        """Nothing running or queued and the program has not ended."""
        return self.current is None and not self.queue and not self.finished

    @property
    def in_motion(self) -> bool:
        return self.current is not None and type(self.current[1]) in MOVING and self.override > 0.0

    @property
    def queued_records(self) -> int:
        return len(self.queue) + (self.current is not None)

    def wants_records(self, ahead: int) -> bool:
        """Decode more records? ``ahead`` behind the running one, and on an open curve path
        enough blocks to cover twice a full-speed stop (the rest stay in the FIFO)."""
        if len(self.queue) < ahead:
            return True
        # Holding for data always wants more. The reserve covers a stop from the fastest of the
        # last queued block and the running one: the hold checks the running block's speed, so a
        # reserve sized from a slow block queued behind a fast one would hold the card with
        # records still waiting in the FIFO.
        reserve = self._stop_reserve
        if self.current is not None and type(self.current[1]) is Block:
            reserve = max(reserve, stop_reserve(self.current[1].profile, self.period))
        return self.path_open and (self.queued_path < reserve or self.starved_hold)

    @property
    def holding_for_data(self) -> bool:
        """Holding on a curve because the queued path ran short (a FIFO underrun feed hold)."""
        return self.starved_hold and self.current is not None

    @property
    def on_curve(self) -> bool:
        """A curve block is running or next in line."""
        if self.current is not None and type(self.current[1]) is Block:
            return True
        return bool(self.queue) and type(self.queue[0][1]) in ON_PATH

    @property
    def pending(self) -> int:
        """Records waiting behind the running one."""
        return len(self.queue)

    @property
    def queued_periods(self) -> int:
        """Motion time still queued, including what is left of the running segment [periods]."""
        left = 0
        if self.current is not None:
            seg = self.current[1]
            if type(seg) is Dwell:
                left = self.dwell_left
            elif type(seg) in MOVING and type(seg) is not ChipRun:  # a move, curve block or step run
                left = math.ceil(max(0.0, seg.profile.duration - self.tau) / self.period - 1e-9)
            # a force wait or a chip command takes as long as it needs: not motion the planner queued
        return self._queued_periods + left

    @property
    def path_position(self) -> tuple[float, ...]:
        """Axis positions [m | rad] of the last period's path setpoint, shape ``(6,)``: without the
        force loop's offset along the tool axis and the spindle's turn of C."""
        return self._position_of(self.hold_counts)

    # --- per period --------------------------------------------------------------------------
    def next_period(self) -> list[float]:
        """Commanded position at the end of the coming period [counts], shape ``(6,)``."""
        force = self.force
        was_off = force.state == ForceState.OFF
        depth = 0.0 if was_off else force.update(self.measured_force, self.path_s)
        self.tick_commands, self.events = None, []
        if self.current is None:
            self._start_next()
            if was_off and force.state != ForceState.OFF:  # started now: hold at the standoff, no jump
                depth = force.depth
        self.path_ds = 0.0
        if self.current is None:
            counts = list(self.hold_counts)
        else:
            seq, seg = self.current
            counts, depth = ADVANCE[type(seg)](self, seq, seg, depth)
        self.hold_counts = counts
        if depth != 0.0:  # the force loop pushes the tool along its axis (into the surface: -axis)
            cpu, axis = self.counts_per_unit, self.tool_axis
            counts = [counts[0] - depth * axis[0] * cpu[0], counts[1] - depth * axis[1] * cpu[1],
                      counts[2] - depth * axis[2] * cpu[2], *counts[3:]]
        if self.spindle_on or self.spin != 0.0:  # C in speed mode: ramped within C's acceleration
            target = self.spindle_speed if self.spindle_on else 0.0
            self.spin, turned = spindle_turn(self.spin, target, self.spindle_accel * self.period, self.period)
            self.c_offset += turned
        if self.c_offset != 0.0:
            counts = [*counts[:5], counts[5] + self.c_offset * self.counts_per_unit[5]]
        elif counts is self.hold_counts:
            counts = list(counts)
        return counts

    def _start_next(self) -> None:
        while self.queue and self.current is None and not self.finished:
            seq, item = self.queue.popleft()
            START.get(type(item), SegmentInterpolator._apply_modal)(self, seq, item)

    # --- starting each kind of queue item (START) ---------------------------------------------
    def _start_block(self, seq: int, block: Block) -> None:
        self._queued_periods -= block.periods
        self._begin_block(seq, block, 0.0)

    def _start_steps(self, seq: int, run: StepRun) -> None:
        self._queued_periods -= run.periods
        self.current = (seq, run)
        self.tau = 0.0

    def _start_chip(self, seq: int, command: ChipCommand) -> None:  # from where the axes are commanded now
        self.current = (seq, ChipRun(command, list(self.hold_counts), dt=self.period, marks=self.index_marks))

    def _start_path(self, seq: int, path: Curve | SurfaceRun) -> None:
        self._curve = path
        self.last_seq_executed = seq

    def _start_force_wait(self, seq: int, wait: ForceWait) -> None:
        self.current = (seq, wait)
        if wait.on:
            self.force.start(wait.record.params)
        else:
            self.force.stop()

    def _start_surface(self, seq: int, _record: SurfaceGeometry) -> None:
        self.path_s = 0.0
        self.last_seq_executed = seq

    def _start_move(self, seq: int, seg: MoveSegment) -> None:
        self._queued_periods -= seg.periods
        self._begin_move(seq, seg)

    def _start_dwell(self, seq: int, dwell: Dwell) -> None:
        self._queued_periods -= dwell.periods
        self.current = (seq, dwell)
        self.dwell_left = dwell.periods

    def _apply_modal(self, seq: int, record: Record) -> None:
        modal = MODAL.get(type(record))
        if modal is not None:
            modal(self, record)
        self.last_seq_executed = seq

    # --- one period of each kind of running item (ADVANCE): (counts, the force loop's depth) ----
    def _run_block(self, seq: int, block: Block, depth: float) -> tuple[list[float], float]:
        return self._advance_block(seq, block), depth

    def _run_steps(self, seq: int, run: StepRun, depth: float) -> tuple[list[float], float]:
        self.path_u = -1.0
        return self._advance_steps(seq, run), depth

    def _run_chip(self, seq: int, chip: ChipRun, depth: float) -> tuple[list[float], float]:
        self.path_u = -1.0
        counts = list(chip.step(self.inputs, self.actual))
        self.events = chip.events
        if chip.done:
            self._complete(seq)
            self.programmed = self._position_of(counts)
        return counts, depth

    def _run_force_wait(self, seq: int, wait: ForceWait, depth: float) -> tuple[list[float], float]:
        self.path_u = -1.0
        self.tool_axis = wait.axis
        counts = self.counts_of(wait.base)
        if self.force.state == (ForceState.TRACK if wait.on else ForceState.OFF):
            self._complete(seq)
            if not wait.on:  # retracted: from here on the pose is the clear pose, no offset
                counts = self.counts_of(wait.clear_pose)
                depth = 0.0
        return counts, depth

    def _run_dwell(self, seq: int, _dwell: Dwell, depth: float) -> tuple[list[float], float]:
        self.path_u = -1.0
        self.dwell_left -= 1
        counts = list(self.hold_counts)
        if self.dwell_left <= 0:
            self._complete(seq)
        return counts, depth

    def _start_probe(self, seq: int, seg: ProbeSegment) -> None:
        self._start_move(seq, seg)
        self.probe.start(seg, self.measured_force)

    def _run_probe(self, seq: int, seg: ProbeSegment, depth: float) -> tuple[list[float], float]:
        self.path_u = -1.0
        stopping = self.probe.watch(seg, self.measured_force, self.actual)  # stops along its path once tripped
        counts = self._advance_move(seq, seg, stopping=stopping)
        if self.current is not None and stopping and self.override == 0.0:
            self._complete(seq)
        if self.current is None:  # at rest after the crossing, or at its end without one
            self.probe.finish(seg, counts, self.actual)
            self.programmed = self._position_of(counts)
        return counts, depth

    def _run_move(self, seq: int, seg: MoveSegment, depth: float) -> tuple[list[float], float]:
        self.path_u = -1.0
        return self._advance_move(seq, seg), depth

    def _begin_move(self, seq: int, seg: MoveSegment) -> None:
        a_lim = v_lim = math.inf
        for cfg, p0, p1 in zip(self.axes, seg.start, seg.end):
            d = abs(p1 - p0)
            if d > 0.0:
                a_lim = min(a_lim, cfg.max_acceleration / d)
                v_lim = min(v_lim, cfg.max_velocity / d)
        self._a_lim = a_lim
        self.path_accel = None  # a move's scale slews on its own clock
        prof = seg.profile
        lam_max = math.inf
        if prof.v_peak > 0.0:
            lam_max = min(lam_max, v_lim / prof.v_peak)
        if prof.accel > 0.0:
            lam_max = min(lam_max, math.sqrt(a_lim / prof.accel))
        self.lam_max = lam_max
        self.tau = 0.0
        self.current = (seq, seg)
        # Start and displacement in counts, so each period is one multiply-add per axis.
        self.start_counts = [(p - z) * c for p, z, c in zip(seg.start, self.power_on, self.counts_per_unit)]
        self.delta_counts = [(p1 - p0) * c for p0, p1, c in zip(seg.start, seg.end, self.counts_per_unit)]

    def _advance_move(self, seq: int, seg: MoveSegment, stopping: bool = False) -> list[float]:
        """Advance the segment clock one period; the setpoint in counts (``stopping``: the move
        stops along its path, as held)."""
        prof = seg.profile
        lam = self.override
        target = 0.0 if self.hold or stopping else min(self.override_target, self.lam_max)
        if lam != target:
            _, sd, sdd = prof.evaluate(self.tau)
            lam = slew(lam, target, sd, sdd, self._a_lim, self.period)
            self.override = lam
        self.tau += lam * self.period
        if self.tau >= prof.duration - 1e-9 * self.period:
            self._complete(seq)
            return self.counts_of(seg.end)
        s = prof.evaluate(self.tau)[0]
        return [c0 + s * dc for c0, dc in zip(self.start_counts, self.delta_counts)]

    def _advance_steps(self, seq: int, run: StepRun) -> list[float]:
        """One period of a step interpolator: its lattice point at every tick; the last is the setpoint."""
        target = 0.0 if self.hold else min(self.override_target, 1.0)
        ticks, self.tau, self.override, done = run.advance(self.tau, self.override, target, self.period,
                                                           self.ticks_per_period)
        self.tick_commands = ticks
        if done:
            self._complete(seq)
        return ticks[-1]

    def _begin_block(self, seq: int, block: Block, tau: float) -> None:
        """Make ``block`` the running segment, ``tau`` [s] into its clock (0 at a fresh start;
        the rest of a period when the previous block ended inside it)."""
        self.queued_path -= block.profile.length
        self.current = (seq, block)
        self.tau = tau
        self.block_s = block.profile.state(tau)[0] if tau > 0.0 else 0.0
        self.block_state = None

    def _advance_block(self, seq: int, block: Block) -> list[float]:
        """One period along a curve block; the setpoint in counts."""
        prof = block.profile
        tau = self.tau
        s_now, v, a = self.block_state if self.block_state is not None else prof.state(tau)
        # Running dry? The queued path ends at speed and is no longer than the stopping distance.
        remaining = prof.length - s_now + self.queued_path
        open_end = self.path_open if self.queue else prof.v1 > 0.0
        a_stop, j_stop = SLEW_MARGIN * prof.a_max, SLEW_MARGIN * prof.j_max
        lam = self.override
        if not open_end:
            self.starved_hold = False
        elif not self.starved_hold:
            accel = lam * lam * a if self.path_accel is None else self.path_accel
            if remaining <= feed_slew.stop_distance(lam * v, accel, a_stop, j_stop, self.period):
                self.starved_hold = True
                self._arrivals_at_latch = self._arrivals
        elif self._arrivals != self._arrivals_at_latch:  # new blocks came: resume if a full stop fits
            full = max(v, prof.vp)
            if remaining > feed_slew.stop_distance(full, 0.0, a_stop, j_stop, self.period):
                self.starved_hold = False
            else:
                self._arrivals_at_latch = self._arrivals
        force = self.force
        if self.hold or self.starved_hold or force.path_gate:
            target = 0.0
        else:
            target = self.override_target * force.feed_factor
        if lam != target or self.path_accel is not None:  # the path moves to the target's feed, jerk-limited
            tau, self.override, self.path_accel = feed_slew.advance(
                prof, tau, (s_now, v, a), lam, self.path_accel, target, self.period, a_stop, j_stop)
        else:
            tau += lam * self.period
        if tau < prof.duration:
            state = prof.state(tau)  # the next period starts from this state
            self.block_state = state
            s_new = state[0]
            ds = s_new - self.block_s
            self.block_s = s_new
            self.tau = tau
        else:  # block done within this period: finish it, continue into the next blocks if queued
            ds = prof.length - self.block_s
            self.block_state = None
            self._complete(seq)
            rest = tau - prof.duration  # [s] of this period's path time left after the block
            while self.queue and type(self.queue[0][1]) is Block:
                seq_next, nxt = self.queue.popleft()
                self._queued_periods -= nxt.periods
                self._begin_block(seq_next, nxt, rest)
                if rest < nxt.profile.duration:
                    ds += self.block_s
                    break
                # a block shorter than what is left of the period runs whole within it (blocks
                # between close critical points at a short period): on to the next one
                ds += nxt.profile.length
                self._complete(seq_next)
                rest -= nxt.profile.duration
        curve = block.curve
        stepper = curve.stepper
        point = stepper.step(ds) if ds > 0.0 else stepper.point
        self.path_u = stepper.u
        self.path_ds = ds
        pose = curve.pose(point, stepper.u)
        if type(curve) is SurfaceRun:
            self.tool_axis = curve.axis
            self.path_s += ds
        elif curve.line_us:  # a G-code path joins several program lines: the one it runs now
            self.mark = curve.line_at(stepper.u)
        return self.counts_of(pose)

    def counts_of(self, positions) -> list[float]:
        return [(p - zero) * cpu for p, zero, cpu in zip(positions, self.power_on, self.counts_per_unit)]

    def _position_of(self, counts) -> tuple[float, ...]:
        """The inverse of :meth:`_counts_of`: axis positions [m | rad] of commands [counts]."""
        return tuple(c / cpu + zero for c, cpu, zero in zip(counts, self.counts_per_unit, self.power_on))

    def _complete(self, seq: int) -> None:
        self.current = None
        self.last_seq_executed = seq


START = {Block: SegmentInterpolator._start_block, StepRun: SegmentInterpolator._start_steps,
         ChipCommand: SegmentInterpolator._start_chip, Curve: SegmentInterpolator._start_path,
         SurfaceRun: SegmentInterpolator._start_path, ForceWait: SegmentInterpolator._start_force_wait,
         SurfaceGeometry: SegmentInterpolator._start_surface, MoveSegment: SegmentInterpolator._start_move,
         Dwell: SegmentInterpolator._start_dwell, ProbeSegment: SegmentInterpolator._start_probe}
"""what each queue item does as it reaches the queue's head; any other is a modal record (MODAL)"""
ADVANCE = {Block: SegmentInterpolator._run_block, StepRun: SegmentInterpolator._run_steps,
           ChipRun: SegmentInterpolator._run_chip, ForceWait: SegmentInterpolator._run_force_wait,
           Dwell: SegmentInterpolator._run_dwell, MoveSegment: SegmentInterpolator._run_move, ProbeSegment: SegmentInterpolator._run_probe}
"""one period of each kind of running item; a new kind plugs in here, in START and in
:data:`cnc_twin.dsp.record_intake.ACCEPT`"""
MOVING = frozenset({MoveSegment, Block, StepRun, ChipRun, ProbeSegment})
"""running items that are motion (a feed hold and the override act on them)"""
ON_PATH = frozenset({Block, Curve, SurfaceRun})
"""queue items of a curve path"""
