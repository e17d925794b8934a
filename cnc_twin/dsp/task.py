"""The DSP's per-period task: the whiteboard exchange, record acceptance, the controller state.

Once per interpolation period, before the servo ticks::

    acquired = port.acquire(k)                # lockstep waits; real-time may miss. Snapshots the
                                              # FIFO's write index while the DSP owns the bus.
               (during a stop: port.poll(), never waits and takes no snapshot)
    top up: while fewer than QUEUE_AHEAD records wait behind the running one, pop one from
            the FIFO (up to the snapshot):
        seq, record = decode(words)           # CRC, framing; geometry parts are joined and
                                              # the whole curve or surface pushed with the last
        if bad or seq != expected_seq:        # reject, count, flush the FIFO: the PC goes back
            reject; stop                      # to expected_seq (it sees records_rejected grow)
        interpolator.push(seq, record); expected_seq += 1
    if acquired and not port.quiet(): port.publish(status for period k)
                                              # (quiet: the PC's next record does not fit the
                                              # FIFO yet; it asked to be woken when it does)
    setpoint = interpolator.next_period()     # honours hold / override

The FIFO is the card's command buffer: records stay there until the card needs them, so its
fill and free space are real and throttle the planner.

::

    state: IDLE -> RUNNING <-> FEED_HOLD (starved) -> FINISHED; any -> STOPPING -> FAULT

A lost planner (process exited or heartbeat stopped) makes a controlled stop: the interpolator
holds (decelerating along the path within every axis's acceleration limit), no further
exchanges are attempted, and the state becomes FAULT once the axes are at rest.

During any stop (STOPPING, then FAULT) the card needs nothing more from the planner: it neither
waits for answers nor checks the planner's liveness, takes no new records (no FIFO snapshot; it
may still decode what the last snapshot held, the same on every run) and publishes its status
only when the PC has answered the last one. Lockstep runs stay bit-identical: whether and when
the PC answers from then on changes nothing in the trace.

The supervisor (:mod:`cnc_twin.dsp.supervisor`) checks every period, before the setpoint is
made; a trip raises its fault with its stop. A later trip with a harsher stop (controlled <
retract < disable) escalates; other later trips are not acted on again. Every fault raised is
kept in ``fault_log``; ``fault`` is the first.
"""

from __future__ import annotations

from array import array
from time import perf_counter_ns

from cnc_twin.dsp.chip import EVENT_HOME_FOUND
from cnc_twin.dsp.interpolator import SegmentInterpolator
from cnc_twin.dsp.servo import PERIOD_FIELDS, ServoTask
from cnc_twin.dsp.supervisor import STOP_CONTROLLED, STOP_DISABLE, STOP_RETRACT, Retract, Supervisor
from cnc_twin.geometry.kinematics import rotation_ab
from cnc_twin.whiteboard.codec import GeometryJoiner, RecordError, decode
from cnc_twin.whiteboard.ports import DspPort, PlannerLost
from cnc_twin.whiteboard.status import DspState, FaultCode

SOLO_LIVENESS_PERIODS = 64
"""while solo or quiet (no exchange under way), how often the card checks that the planner
process is still there [periods]"""

REST_PERIODS = 20
"""drives disabled: the axes count as at rest once no encoder has moved for this many periods"""

_SEVERITY = {STOP_CONTROLLED: 0, STOP_RETRACT: 1, STOP_DISABLE: 2}

QUEUE_AHEAD = 2
"""records the card keeps decoded behind the running one (the rest wait in the FIFO); on a curve
it decodes blocks until their path covers twice a full-speed stop"""


TIMED_PERIODS = 1 << 20
"""periods on a curve whose interpolation cost is kept (17 minutes at 1 ms; 8 MB)"""


class DspTask:
    """Per-period logic of the card around the servo task.

    Parameters
    ----------
    servo : the servo task (its ``frame`` holds the last tick's signals for the status block).
    interpolator : the record queue and coarse interpolator.
    port : the card's side of the whiteboard.
    period : interpolation period [s].
    read_inputs : callable returning the switch inputs per axis (the card's digital inputs), or None.
    supervisor : the fault supervisor, or None for none.
    """

    def __init__(self, *, servo: ServoTask, interpolator: SegmentInterpolator, port: DspPort, period: float,
                 read_inputs=None, supervisor: Supervisor | None = None):
        self.servo = servo
        self.interpolator = interpolator
        self.port = port
        self.period = period
        self.state = DspState.IDLE
        self.fault = FaultCode.NONE
        self.fault_message = ""
        self.fault_time: float | None = None
        self.expected_seq = 1
        self.geometry_joiner = GeometryJoiner()
        self.records_accepted = 0
        self.records_rejected = 0
        self.underrun_periods = 0
        self.planner_lost = False
        self.read_inputs = read_inputs
        """callable returning the switch inputs per axis (the card's digital inputs), or None"""
        self.event_log: list[tuple[float, int, int, int]] = []
        """``(time [s], axis, event bit, value)`` of every event (:mod:`cnc_twin.dsp.chip`)"""
        self.pending_events = [0] * servo.n_axes
        """event bits per axis raised since the last published status"""
        self.index_latch = [0] * servo.n_axes
        """the last count latched at an index pulse by a home return, per axis"""
        self.supervisor = supervisor
        self.drives_enabled = True
        """False once a stop disabled the amplifiers (the twin then runs the servo in follow-up)"""
        self.stop: str | None = None
        """the stop in progress (``disable``, ``retract``, ``controlled``), None before any fault"""
        self.fault_log: list[tuple[float, int, int, str, str]] = []
        """``(time [s], code, axis or -1, message, stop)`` of every fault acted on"""
        self.retract: Retract | None = None
        self.at_rest_time: float | None = None
        """when a stop brought the machine to rest and the state became FAULT [s]"""
        self._still_periods = 0
        self._last_actual: list[int] | None = None
        self.interpolator_ns = array("q")
        """wall-clock cost of each coarse interpolation period on a curve [ns] (metrics only): the
        first :data:`TIMED_PERIODS` of them (a run of hours does not keep one per period)"""

    @property
    def done(self) -> bool:
        """The run is over: program finished, or stopped in FAULT."""
        return self.state in (DspState.FINISHED, DspState.FAULT)

    def begin_period(self, k: int) -> None:
        """Exchange, then latch this period's setpoint into the servo task."""
        acquired = False
        if self.stop is not None:
            # A stop is under way: the card needs no more records and no answer, so it never waits
            # (a planner that saw FAULT, stalls or died would otherwise hold it for the whole
            # heartbeat timeout) and no longer watches the planner. It still shows its status when
            # the PC has answered the last one; nothing it executes or records depends on that.
            if not self.planner_lost:
                acquired = self.port.poll()
        elif not self.planner_lost:
            try:
                acquired = self.port.acquire(k)
            except PlannerLost as exc:
                self.raise_fault(FaultCode.PLANNER_LOST, str(exc), k)
            if self.port.idle and k % SOLO_LIVENESS_PERIODS == 0 and not self.port.planner_alive():
                self.raise_fault(FaultCode.PLANNER_LOST, "planner process exited", k)
        if self.interpolator.wants_records(QUEUE_AHEAD):
            self._accept_records()
        # no status while the PC waits for FIFO room it has not got yet (its answer would be empty)
        if acquired and (self.stop is not None or not self.port.quiet()):
            self._publish(k)
        interp = self.interpolator
        servo = self.servo
        n = servo.n_axes
        frame = servo.frame
        interp.measured_force = frame[3 * n]
        inputs = None
        if self.read_inputs is not None:
            interp.inputs = inputs = self.read_inputs()
            interp.actual = frame[n:2 * n]
        elif interp.probe.active:  # a probe latches the encoders
            interp.actual = frame[n:2 * n]
        supervisor = self.supervisor
        if supervisor is not None and self.drives_enabled and self.state != DspState.FAULT:
            trip = supervisor.check(frame, frame[n:2 * n], servo.dac_saturations, inputs, frame[3 * n])
            if trip is not None:
                self.raise_fault(trip.code, trip.message, k, stop=trip.stop, axis=trip.axis)
        if (interp.path_u >= 0.0 or interp.on_curve) and len(self.interpolator_ns) < TIMED_PERIODS:
            started = perf_counter_ns()
            setpoint = interp.next_period()
            self.interpolator_ns.append(perf_counter_ns() - started)
        else:
            setpoint = interp.next_period()
        if interp.probe.fault is not None:
            self.raise_fault(FaultCode.PROBE, interp.probe.fault, k)
            interp.probe.fault = None
        if self.retract is not None:
            reach, direction = self.retract.offset(), self.retract.direction
            setpoint[0] += reach * direction[0]
            setpoint[1] += reach * direction[1]
            setpoint[2] += reach * direction[2]
        if supervisor is not None and self.drives_enabled:
            trip = supervisor.clamp(setpoint)
            if trip is not None:
                self.raise_fault(trip.code, trip.message, k, stop=trip.stop, axis=trip.axis)
        servo.begin_period(setpoint, interp.tick_commands, path=interp.hold_counts)
        self._update_state()
        if self.state == DspState.FAULT and self.at_rest_time is None:
            self.at_rest_time = k * self.period
        bits = 0
        for axis, code, value in interp.events:
            self.event_log.append((k * self.period, axis, code, value))
            self.pending_events[axis] |= code
            bits |= code << (4 * axis)
            if code == EVENT_HOME_FOUND:
                self.index_latch[axis] = value
        self.write_period_fields(bits)

    def write_period_fields(self, event_bits: int) -> None:
        """The period's signals into the servo's ``frame`` after the force, in the order of
        :data:`~cnc_twin.dsp.frame.PERIOD_FIELDS` (the recorder's period record reads them)."""
        interp, port = self.interpolator, self.port
        force = interp.force
        base = self.servo.period_slot
        self.servo.frame[base:base + len(PERIOD_FIELDS)] = [
            self.state, self.fault, port.fifo.fill(), interp.override, port.missed_exchanges, self.records_rejected,
            interp.last_seq_executed, interp.path_u, interp.path_ds, force.state, force.target, force.depth,
            force.feed_factor, interp.mark, event_bits]

    def raise_fault(self, code: int, message: str, k: int, *, stop: str = STOP_CONTROLLED, axis: int = -1) -> None:
        """Record a fault and start its stop (the first fault is ``fault``; a harsher stop escalates)."""
        if code == FaultCode.PLANNER_LOST:
            self.planner_lost = True
        if self.stop is not None and _SEVERITY[stop] <= _SEVERITY[self.stop]:
            return
        if self.fault == FaultCode.NONE:
            self.fault, self.fault_message, self.fault_time = code, message, k * self.period
        self.fault_log.append((k * self.period, code, axis, message, stop))
        self.stop = stop
        interp = self.interpolator
        interp.hold = True
        if stop == STOP_DISABLE:
            self.drives_enabled = False
            self.retract = None
        elif stop == STOP_RETRACT:
            self._start_retract()
        if self.state != DspState.FAULT:
            self.state = DspState.STOPPING

    def explain_planner_fault(self, reason: str) -> None:
        """Add the planner's own reason to its PLANNER_LOST / PLANNER_START fault (the card saw only
        that the process went away)."""
        planner = (FaultCode.PLANNER_LOST, FaultCode.PLANNER_START)
        self.fault_log = [(t, code, axis, f"{message}: {reason}" if code in planner else message, stop)
                          for t, code, axis, message, stop in self.fault_log]
        if self.fault in planner:
            self.fault_message = f"{self.fault_message}: {reason}"

    def _start_retract(self) -> None:
        """Freeze the force loop and move the tool up its axis (from the commanded A, B)."""
        interp, config = self.interpolator, self.supervisor.config
        interp.force.frozen = True
        a, b = interp.path_position[3:5]
        tool_axis = rotation_ab(a, b)[:, 2]  # the head's z (tool) axis in the machine frame
        cpu = interp.counts_per_unit
        accel = 0.9 * min(axis.max_acceleration for axis in interp.axes[:3])
        self.retract = Retract(config.retract, config.retract_speed, accel, self.period,
                               tuple(float(tool_axis[i]) * cpu[i] for i in range(3)))

    def _accept_records(self) -> None:
        """Pop records from the FIFO (up to the snapshot) while the interpolator wants more."""
        fifo, interp = self.port.fifo, self.interpolator
        while interp.wants_records(QUEUE_AHEAD):
            try:
                words = fifo.pop()
                if words is None:
                    return
                seq, record = decode(words)
                if seq == self.expected_seq and record.part_of_whole:
                    record = self.geometry_joiner.add(record)
            except RecordError:
                seq, record = None, None
            if seq != self.expected_seq:
                # Bad CRC, bad framing, or out of order: never executed. Drop the rest so the PC
                # can resend from expected_seq in order (exchanging again if the card was solo).
                self.records_rejected += 1
                fifo.flush()
                self.port.resume()
                return
            if record is not None:  # None: a geometry part joined, the whole record not yet complete
                interp.push(seq, record)
            self.expected_seq += 1
            self.records_accepted += 1

    def _update_state(self) -> None:
        interp = self.interpolator
        if self.state == DspState.STOPPING:
            if not self.drives_enabled:  # coasting: at rest once no encoder moves any more
                n = self.servo.n_axes
                actual = self.servo.frame[n:2 * n]
                self._still_periods = self._still_periods + 1 if actual == self._last_actual else 0
                self._last_actual = actual
                if self._still_periods >= REST_PERIODS:
                    self.state = DspState.FAULT
            elif not interp.in_motion and (self.retract is None or self.retract.done):
                self.state = DspState.FAULT
            return
        if self.state in (DspState.FAULT, DspState.FINISHED):
            return
        if interp.finished:
            self.state = DspState.FINISHED
        elif interp.holding_for_data or (interp.starved and self.port.fifo.fill() == 0):
            if self.state != DspState.IDLE:
                self.state = DspState.FEED_HOLD
                self.underrun_periods += 1
        else:
            self.state = DspState.RUNNING

    def _publish(self, k: int) -> None:
        frame = self.servo.frame
        n = self.servo.n_axes
        interp = self.interpolator
        port = self.port
        tripped, latch, stop = interp.probe.last()
        # frame[0:3n] is command, actual, DAC code: the status block's field order.
        port.publish(None, k, values=(
            k, self.state, self.fault, port.fifo.fill(), self.expected_seq, interp.last_seq_executed,
            self.records_accepted, self.records_rejected, port.missed_exchanges, self.underrun_periods,
            interp.queued_periods, k * self.period, interp.override, frame[3 * n],
            *frame[0:3 * n], *map(float.__sub__, frame[0:n], frame[n:2 * n]),
            *self.pending_events, *self.index_latch, len(interp.probe.log), tripped, *latch, *stop,
        ))
        self.pending_events = [0] * n
