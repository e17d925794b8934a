"""The exchange protocol: one exchange per interpolation period, pipelined by one period.

Bus hand-over: the DSP owns the bus while it reads the FIFO and writes the status block. It then
grants the bus (``HOLDA = 1``) and posts the DSP -> PC mailbox. The PC raises ``HOLD``, checks
the grant, reads the status, writes records and the FIFO write index, drops ``HOLD`` and posts
the PC -> DSP mailbox (its acknowledgement). The DSP takes the bus back (``HOLDA = 0``) only
after it has seen that acknowledgement with ``HOLD`` low. Every word has a single writer and each
side only ever waits for the other's word, so the hand-over is safe with x86 store ordering
(no two-flag mutual exclusion, which would need memory fences).

Per period ``k`` on the DSP::

    acquire(k):  lockstep  -> wait for the PC's ack of the last status (planner-lost checks while waiting)
                 real-time -> if no ack yet or HOLD high: missed exchange, skip the rest this period
                 (no status outstanding, the card having skipped its last publish: nothing to wait for)
    poll():      during a stop, either mode -> take the bus only if the PC has answered; else skip
                 the rest this period (no wait, no miss counted, no FIFO snapshot)
    (on the PC's answer the FIFO's write index is snapshotted: records up to it are consumed as
    the card needs them; and the PC's ALL_SENT and WAKE_FREE words are read)
    publish(status):  status block; HOLDA = 1; mailbox DSP -> PC = (k + 1) & 0xFFFF
                 skipped while ``quiet()``: the PC asked for the next exchange only once the FIFO
                 has WAKE_FREE free words (its next record does not fit before), so until then
                 every answer would be empty

The PC-side wake is the card's FIFO-threshold interrupt: instead of an empty exchange every period
while the FIFO is full, one exchange when the next record fits. The records reach the card in
the same periods as with an exchange every period, so a lockstep trace is the same either way.

On the PC, in a loop::

    wait_status() -> copy of the status block when the DSP -> PC mailbox changes
    begin(): HOLD = 1, wait for HOLDA;  [write records through .fifo];  end(): HOLD = 0, ack

The PC answers status ``k`` while the DSP runs period ``k``; the DSP reads the answer at the
start of period ``k + 1``, as the card does with its exchange interrupt. Mailbox values are
``period + 1`` modulo 2^16, so 0 means "nothing posted yet".
"""

from __future__ import annotations

import array
import os
import time
from collections.abc import Callable

import numpy as np

from cnc_twin.whiteboard import layout as L
from cnc_twin.whiteboard.block import Whiteboard
from cnc_twin.whiteboard.capture import BEFORE_FIRST_STATUS, StreamCapture
from cnc_twin.whiteboard.doorbell import SPIN_POLLS, Doorbell
from cnc_twin.whiteboard.fifo import FifoReader, FifoWriter
from cnc_twin.whiteboard.status import STATUS_DTYPE, STATUS_STRUCT

WAKE_INTERVAL = 0.002
"""longest a blocked waiter sleeps before re-checking liveness and heartbeat [s]"""


def signal_shutdown(wb: Whiteboard, ring_pc: Doorbell | None, end: tuple[int, int] | None = None) -> None:
    """Tell the planner the run is over: the state and fault it ended with (``end``, when the card
    ran), the shutdown word, then a ring so it wakes to see it."""
    if end is not None:
        dsp = wb.layout.dsp_control
        wb.words[dsp + L.DSP_END_STATE], wb.words[dsp + L.DSP_END_FAULT] = end
    wb.words[wb.SHUTDOWN] = 1
    if ring_pc is not None:
        ring_pc.ring()


class PlannerLost(RuntimeError):
    """The planner process exited or its heartbeat stopped."""


def mailbox_value(period: int) -> int:
    """The mailbox word that says ``period``: ``period + 1`` in 16 bits."""
    return (period + 1) & 0xFFFF


class DspPort:
    """The card's side of the whiteboard.

    Parameters
    ----------
    wb : the whiteboard (created by this side).
    lockstep : wait for the PC's answer every period (deterministic) or never wait (real-time).
    planner_alive : returns False once the planner process has exited.
    heartbeat_timeout : wall-clock seconds without a PC heartbeat before the planner is lost.
    ring_pc, wait_pc : doorbells: rung after the DSP -> PC mailbox; rung by the PC after its ack.
    """

    def __init__(self, wb: Whiteboard, *, lockstep: bool, planner_alive: Callable[[], bool],
                 heartbeat_timeout: float, ring_pc: Doorbell, wait_pc: Doorbell):
        self.wb = wb
        self.ring_pc = ring_pc
        self.wait_pc = wait_pc
        self.words = wb.words
        self.lockstep = lockstep
        self.planner_alive = planner_alive
        self.heartbeat_timeout = heartbeat_timeout
        self.fifo = FifoReader(wb.fifo_ring, wb.fifo_write, wb.fifo_read)
        self.last_posted: int | None = None
        self.solo = False
        """the planner reported the whole program sent: no exchanges until the card needs one"""
        self.wake_free = 0
        """0, or the free FIFO words before which the PC wants no exchange (its WAKE_FREE word)"""
        self.answered = True
        """no status is outstanding: the PC answered the last one posted (or none was posted)"""
        self.idle = False
        """the last :meth:`acquire` found no exchange under way (solo, or no status outstanding
        after a skipped publish): the card waited for nothing, so it checks the planner's liveness"""
        self.missed_exchanges = 0
        self.post_ns = 0
        self.latency_ns = array.array("q")
        """per answered exchange: DSP post -> PC acknowledgement, wall clock [ns]"""
        self.latency_period = array.array("q")
        """the period each latency belongs to (the period whose status was answered)"""
        self._pc_ack_time = np.ndarray((1,), dtype="<u8", buffer=wb.shm.buf, offset=2 * (wb.layout.pc_control + L.PC_ACK_TIME))
        self._status_offset = 2 * wb.layout.status_base
        self.capture: StreamCapture | None = None
        """when set, every exchange the card takes is kept in it (an outside PC program's stream)"""

    def wait_ready(self, timeout: float) -> int:
        """Wait until the planner attached and announced its program; returns its length [periods]."""
        deadline = time.monotonic() + timeout
        while self.wb.pc_magic[0] != L.MAGIC or self.words[self.wb.PC_STATE] == L.PcState.NONE:
            if self.words[self.wb.PC_STATE] == L.PcState.ERROR:
                raise PlannerLost("planner failed while starting (see its error output above)")
            if not self.planner_alive():
                raise PlannerLost("planner process exited before it attached")
            if time.monotonic() > deadline:
                raise PlannerLost(f"planner did not attach within {timeout:g} s")
            time.sleep(0.001)
        return int(self.wb.program_periods[0])

    def acquire(self, period: int) -> bool:
        """Take the bus for this period's exchange; False when the exchange is missed (real-time)
        or not needed (``solo``: the whole program is already in the FIFO)."""
        if self.solo:
            self.idle = True
            return False
        self.idle = self.between_exchanges
        if self.idle:  # the last publish was skipped: the PC has written nothing since its answer
            return True
        if self.last_posted is not None:
            ack = mailbox_value(self.last_posted)
            words, hold, mailbox = self.words, self.wb.HOLD, self.wb.MAILBOX_TO_DSP
            if self.lockstep:
                if words[mailbox] != ack or words[hold]:
                    self._wait_ack(ack)
            elif words[mailbox] != ack or words[hold]:
                self.missed_exchanges += 1
                return False
            self.latency_ns.append(int(self._pc_ack_time[0]) - self.post_ns)
            self.latency_period.append(self.last_posted)
        self.answered = True
        self.words[self.wb.HOLDA] = 0
        before = self.fifo.limit
        self.fifo.snapshot()
        # Read while the DSP owns the bus, right after the PC's answer: the same period on every
        # lockstep run, so going solo or quiet never changes what the card does.
        all_sent = int(self.words[self.wb.ALL_SENT])
        self.solo = bool(all_sent)
        self.wake_free = int(self.words[self.wb.WAKE_FREE])
        if self.capture is not None:
            answered = BEFORE_FIRST_STATUS if self.last_posted is None else self.last_posted
            self.capture.take(answered, all_sent, self.wake_free, self.fifo.published_since(before))
        return True

    @property
    def between_exchanges(self) -> bool:
        """A status was posted and answered, and none posted since (the card skipped its publish):
        the next :meth:`acquire` has nothing to wait for."""
        return self.answered and self.last_posted is not None

    def quiet(self) -> bool:
        """The PC asked for no exchange before the FIFO has ``wake_free`` free words, and it has
        fewer (the card's view: its last snapshot of the write index, its own read index)."""
        return self.wake_free > 0 and self.fifo.free() < self.wake_free

    def exchange_due(self) -> bool:
        """Whether the coming period may exchange with the PC: not solo, and not between
        exchanges while quiet (a period that pops no records stays quiet)."""
        return not (self.solo or (self.between_exchanges and self.quiet()))

    def resume(self) -> None:
        """Exchange from the next period on, whatever the PC said (a rejected record: it must resend)."""
        self.solo = False
        self.wake_free = 0

    def poll(self) -> bool:
        """Take the bus only if the PC has already answered the last status: the card's exchange
        once it needs nothing more from the planner (a stop under way). Never waits, never counts
        a missed exchange and takes no FIFO snapshot, so whatever the PC does or fails to do from
        here on changes nothing the card executes or records; True when the card may publish."""
        if self.solo:
            return False
        if self.last_posted is not None and not self.answered:
            if self.words[self.wb.MAILBOX_TO_DSP] != mailbox_value(self.last_posted) or self.words[self.wb.HOLD]:
                return False  # not answered yet: the status block stays the PC's until it is
            self.latency_ns.append(int(self._pc_ack_time[0]) - self.post_ns)
            self.latency_period.append(self.last_posted)
        self.answered = True
        self.words[self.wb.HOLDA] = 0
        return True

    def _wait_ack(self, ack: int) -> None:
        words, hold, mailbox = self.words, self.wb.HOLD, self.wb.MAILBOX_TO_DSP
        for _ in range(SPIN_POLLS):
            if words[mailbox] == ack and not words[hold]:
                return
        heartbeat = self.wb.pc_heartbeat
        last_beat = int(heartbeat[0])
        last_change = time.monotonic()
        while words[mailbox] != ack or words[hold]:
            self.wait_pc.wait(WAKE_INTERVAL)
            if words[mailbox] == ack and not words[hold]:
                return
            now = time.monotonic()
            beat = int(heartbeat[0])
            if beat != last_beat:
                last_beat, last_change = beat, now
            elif now - last_change > self.heartbeat_timeout:
                raise PlannerLost(f"planner heartbeat stopped for more than {self.heartbeat_timeout * 1e3:g} ms")
            if not self.planner_alive():
                raise PlannerLost("planner process exited")

    def pop_records(self) -> list[np.ndarray]:
        """Words of every record published up to this exchange's snapshot (bulk transfers)."""
        return self.fifo.pop_records()

    def publish(self, status: np.ndarray | None, period: int, *, values: tuple | None = None) -> None:
        """Write the status block, grant the bus, post the mailbox.

        Pass either a ``STATUS_DTYPE`` record or the flat ``values`` for ``STATUS_STRUCT``
        (the lean path: one ``pack_into`` straight into the shared memory).
        """
        if values is not None:
            STATUS_STRUCT.pack_into(self.wb.shm.buf, self._status_offset, *values)
        else:
            self.wb.status[0] = status[0]
        self.wb.dsp_heartbeat[0] = period & 0xFFFFFFFF
        self.words[self.wb.HOLDA] = 1
        self.post_ns = time.perf_counter_ns()
        self.words[self.wb.MAILBOX_TO_PC] = mailbox_value(period)
        self.ring_pc.ring()
        self.last_posted = period
        self.answered = False


class PcPort:
    """The PC's side of the whiteboard.

    Parameters
    ----------
    wb : the whiteboard (attached).
    wait_dsp, ring_dsp : doorbells: rung by the DSP after it posts; rung here after each ack.
    """

    def __init__(self, wb: Whiteboard, *, wait_dsp: Doorbell, ring_dsp: Doorbell, spin_polls: int = 0):
        self.wb = wb
        self.spin_polls = spin_polls
        """polls before sleeping on the doorbell. The twin's planner answers status k while the
        DSP runs period k, so it has a whole period and need not spin (spinning steals a core
        from the other runs of a sweep); the round-trip benchmark spins for the fast answer."""
        self.wait_dsp = wait_dsp
        self.ring_dsp = ring_dsp
        self.words = wb.words
        self.fifo = FifoWriter(wb.fifo_ring, wb.fifo_write, wb.fifo_read)
        self.status = np.zeros(1, dtype=STATUS_DTYPE)
        self._last_seen = 0
        self._pc_ack_time = np.ndarray((1,), dtype="<u8", buffer=wb.shm.buf, offset=2 * (wb.layout.pc_control + L.PC_ACK_TIME))
        self._parent = os.getppid()

    def announce(self, program_periods: int) -> None:
        """Planner attached and planned: publish the program length, then READY."""
        wb = self.wb
        wb.program_periods[0] = program_periods
        self.words[wb.PC_VERSION] = L.VERSION
        wb.pc_magic[0] = L.MAGIC
        self.set_state(L.PcState.READY)

    def set_state(self, state: int) -> None:
        self.words[self.wb.PC_STATE] = state

    def beat(self) -> None:
        """Advance the heartbeat (the planner is alive and not stalled)."""
        hb = self.wb.pc_heartbeat
        hb[0] = (int(hb[0]) + 1) & 0xFFFFFFFF

    def wait_status(self) -> np.ndarray | None:
        """Block until the DSP posts a new status; a copy of it, or None when the run is over."""
        words, mailbox, shutdown = self.words, self.wb.MAILBOX_TO_PC, self.wb.SHUTDOWN
        last = self._last_seen
        for _ in range(self.spin_polls):
            if words[mailbox] != last:
                break
        else:
            while words[mailbox] == last:
                self.beat()
                if words[shutdown] or os.getppid() != self._parent:
                    return None
                self.wait_dsp.wait(WAKE_INTERVAL)
        if words[shutdown]:
            return None
        self._last_seen = int(words[mailbox])
        self.beat()
        self.status[0] = self.wb.status[0]
        return self.status

    def begin(self) -> None:
        """Raise HOLD and wait for the grant."""
        self.words[self.wb.HOLD] = 1
        while not self.words[self.wb.HOLDA]:  # granted with the mailbox: normally already high
            os.sched_yield()

    def end(self) -> None:
        """Drop HOLD, stamp the time, acknowledge the status just handled."""
        self.words[self.wb.HOLD] = 0
        self._pc_ack_time[0] = time.perf_counter_ns()
        self.words[self.wb.MAILBOX_TO_DSP] = self._last_seen
        self.ring_dsp.ring()

    def set_all_sent(self, value: bool) -> None:
        """Raise (or drop, before a resend) the "whole program sent" flag; call before :meth:`end`."""
        self.words[self.wb.ALL_SENT] = 1 if value else 0

    def set_wake(self, free_words: int) -> None:
        """Ask for the next exchange only once the FIFO has ``free_words`` free (0: every period);
        call before :meth:`end`."""
        self.words[self.wb.WAKE_FREE] = free_words
