"""The DSP's per-period task: the whiteboard exchange, record acceptance, the controller state.

Once per interpolation period, before the servo ticks::

    if port.acquire(k):                       # lockstep waits; real-time may miss
        for words in port.pop_records():
            seq, record = decode(words)       # CRC, framing
            if bad or seq != expected_seq:    # reject, count, flush the FIFO: the PC goes back
                reject; break                 # to expected_seq (it sees records_rejected grow)
            interpolator.push(seq, record); expected_seq += 1
        port.publish(status for period k)
    setpoint = interpolator.next_period()     # honours hold / override
    state: IDLE -> RUNNING <-> FEED_HOLD (starved) -> FINISHED; any -> STOPPING -> FAULT

A lost planner (process exited or heartbeat stopped) makes a controlled stop: the interpolator
holds (decelerating along the path within every axis's acceleration limit), no further
exchanges are attempted, and the state becomes FAULT once the axes are at rest.
"""

from __future__ import annotations

import numpy as np

from cnc_twin.dsp.interpolator import SegmentInterpolator
from cnc_twin.dsp.servo import ServoTask
from cnc_twin.whiteboard.ports import DspPort, PlannerLost
from cnc_twin.whiteboard.records import RecordError, decode
from cnc_twin.whiteboard.status import STATUS_DTYPE, DspState, FaultCode


class DspTask:
    """Per-period logic of the card around the servo task.

    Parameters
    ----------
    servo : the servo task (its ``frame`` holds the last tick's signals for the status block).
    interpolator : the record queue and coarse interpolator.
    port : the card's side of the whiteboard.
    period : interpolation period [s].
    """

    def __init__(self, *, servo: ServoTask, interpolator: SegmentInterpolator, port: DspPort, period: float):
        self.servo = servo
        self.interpolator = interpolator
        self.port = port
        self.period = period
        self.state = DspState.IDLE
        self.fault = FaultCode.NONE
        self.fault_message = ""
        self.fault_time: float | None = None
        self.expected_seq = 1
        self.records_accepted = 0
        self.records_rejected = 0
        self.underrun_periods = 0
        self.planner_lost = False
        self._status = np.zeros(1, dtype=STATUS_DTYPE)

    @property
    def done(self) -> bool:
        """The run is over: program finished, or stopped in FAULT."""
        return self.state in (DspState.FINISHED, DspState.FAULT)

    def begin_period(self, k: int) -> None:
        """Exchange, then latch this period's setpoint into the servo task."""
        if not self.planner_lost:
            try:
                if self.port.acquire(k):
                    self._accept_records()
                    self._publish(k)
            except PlannerLost as exc:
                self.raise_fault(FaultCode.PLANNER_LOST, str(exc), k)
        interp = self.interpolator
        self.servo.begin_period(interp.next_period())
        self._update_state()
        frame, base = self.servo.frame, self.servo.period_slot
        frame[base] = self.state
        frame[base + 1] = self.fault
        frame[base + 2] = self.port.fifo.fill()
        frame[base + 3] = interp.override
        frame[base + 4] = self.port.missed_exchanges
        frame[base + 5] = self.records_rejected
        frame[base + 6] = interp.last_seq_executed

    def raise_fault(self, code: int, message: str, k: int) -> None:
        """Record a fault and start a controlled stop (the first fault wins)."""
        if self.fault == FaultCode.NONE:
            self.fault, self.fault_message, self.fault_time = code, message, k * self.period
        if code == FaultCode.PLANNER_LOST:
            self.planner_lost = True
        self.interpolator.hold = True
        self.state = DspState.STOPPING

    def _accept_records(self) -> None:
        try:
            raw_records = self.port.pop_records()
        except RecordError:
            self.records_rejected += 1
            return
        for words in raw_records:
            try:
                seq, record = decode(words)
            except RecordError:
                seq, record = None, None
            if seq != self.expected_seq:
                # Bad CRC, bad framing, or out of order: never executed. Drop the rest so the PC
                # can resend from expected_seq in order.
                self.records_rejected += 1
                self.port.fifo.flush()
                return
            self.interpolator.push(seq, record)
            self.expected_seq += 1
            self.records_accepted += 1

    def _update_state(self) -> None:
        interp = self.interpolator
        if self.state == DspState.STOPPING:
            if not interp.in_motion:
                self.state = DspState.FAULT
            return
        if self.state in (DspState.FAULT, DspState.FINISHED):
            return
        if interp.finished:
            self.state = DspState.FINISHED
        elif interp.starved:
            if self.state != DspState.IDLE:
                self.state = DspState.FEED_HOLD
                self.underrun_periods += 1
        else:
            self.state = DspState.RUNNING

    def _publish(self, k: int) -> None:
        st = self._status[0]
        frame = self.servo.frame
        n = self.servo.n_axes
        st["period"] = k
        st["state"] = self.state
        st["fault"] = self.fault
        st["fifo_fill"] = self.port.fifo.fill()
        st["expected_seq"] = self.expected_seq
        st["last_seq_executed"] = self.interpolator.last_seq_executed
        st["records_accepted"] = self.records_accepted
        st["records_rejected"] = self.records_rejected
        st["missed_exchanges"] = self.port.missed_exchanges
        st["underrun_periods"] = self.underrun_periods
        st["queued_periods"] = self.interpolator.queued_periods
        st["sim_time"] = k * self.period
        st["feed_override"] = self.interpolator.override
        st["pad_force"] = frame[3 * n]
        st["command"] = frame[0:n]
        st["actual"] = frame[n:2 * n]
        st["following_error"] = [c - a for c, a in zip(frame[0:n], frame[n:2 * n])]
        st["dac"] = frame[2 * n:3 * n]
        self.port.publish(self._status, k)
