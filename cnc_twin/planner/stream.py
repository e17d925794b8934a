"""Streaming records into the card's FIFO: planned chunks fed in
(:class:`~cnc_twin.planner.stream.Feeder`) and written as FIFO space, chunk size and look-ahead
allow, with go-back-N on rejects (:class:`~cnc_twin.planner.stream.Streamer`)."""

from __future__ import annotations

import queue
import sys
import threading
import time

import numpy as np

from cnc_twin.core.gcode_config import ProbeAnswer
from cnc_twin.planner.job import PlannerJob, plan_for
from cnc_twin.whiteboard.codec import encode, split
from cnc_twin.whiteboard.ports import PcPort
from cnc_twin.whiteboard.records import CurveBlock, Move, Probe, Record
from cnc_twin.whiteboard.status import DspState


class Feeder:
    """Moves planned chunks into the streamer; the planning itself runs ahead in a thread.

    Lockstep takes the next chunk only when fewer than ``BACKLOG`` records wait unsent, and none
    after a probing move until the card's status brings its result (:meth:`see`), decisions that
    depend on the exchange sequence alone, so the stream is the same on every run; the
    thread has usually planned that chunk already (the planner's process has a core of its own
    while the card simulates), and the exchange waits for it only when planning falls behind.
    Real time hands over whatever is planned at each exchange.
    """

    BACKLOG = 8
    SWITCH_INTERVAL = 1e-4
    """[s] how long the planning thread may hold the GIL while an exchange waits to be answered
    (Python's default, 5 ms, would delay answers by up to that)"""

    def __init__(self, job: PlannerJob, streamer: "Streamer"):
        self.streamer = streamer
        self.job = job
        self.awaiting = False
        """lockstep: a probing move was handed to the streamer and the card has not answered yet
        (nothing after it is planned before the answer)"""
        self.probes_seen = 0
        """probe results read from the card's status"""
        self._answers: queue.SimpleQueue = queue.SimpleQueue()
        self._waiting = False  # the thread waits for a probe's answer
        started = time.perf_counter()
        self.program = plan_for(job)
        self.plan_seconds = time.perf_counter() - started
        self.chunks = self.program.chunks()
        self.blocks = 0
        self._ready: list[tuple[list[Record], list[int]]] = []
        self._planned = threading.Condition()
        self._done = False
        self._error: BaseException | None = None
        self.threaded = not job.lockstep
        sys.setswitchinterval(self.SWITCH_INTERVAL)
        threading.Thread(target=self._run, name="planner-windows", daemon=True).start()

    def _next(self) -> tuple[list[Record], list[int]] | None:
        started = time.perf_counter()
        try:
            chunk = next(self.chunks)
        except StopIteration:
            return None
        finally:
            self.plan_seconds += time.perf_counter() - started
        self.blocks += sum(isinstance(r, (Move, CurveBlock)) for r in chunk[0])
        return chunk

    def _run(self) -> None:
        try:
            while (chunk := self._next()) is not None:
                probing = any(type(r) is Probe for r in chunk[0])
                with self._planned:
                    self._ready.append(chunk)
                    self._waiting = probing
                    self._planned.notify()
                if probing:  # what follows a probe is planned from the card's answer
                    self.program.answer(self._answers.get())
                    with self._planned:
                        self._waiting = False
        except BaseException as exc:  # reported from the exchange loop
            self._error = exc
        with self._planned:
            self._done = True
            self._planned.notify()

    def _take(self) -> tuple[list[Record], list[int]] | None:
        """The next planned chunk, waiting for the thread if it has not planned it yet; None at the end."""
        with self._planned:
            while not self._ready and not self._done:
                self._planned.wait()
            if self._ready:
                return self._ready.pop(0)
        if self._error is not None:
            raise self._error
        return None

    def plan_ahead(self, chunks: int) -> None:
        """Wait until the thread has ``chunks`` planned chunks waiting (or planned them all): before
        the planner reports ready, so the card's first exchanges never wait for a window."""
        with self._planned:
            while len(self._ready) < chunks and not self._done and not self._waiting:
                self._planned.wait()

    def see(self, status: np.ndarray) -> None:
        """Read a probe's result from the card's ``status`` when a new one is there, and let the
        planning go on past the probe with it."""
        st = status[0]
        if int(st["probes"]) <= self.probes_seen:
            return
        self.probes_seen = int(st["probes"])
        self.awaiting = False
        self._answers.put(ProbeAnswer.from_counts(st["probe_tripped"], st["probe_latch"], st["probe_stop"],
                                                  self.job.axes, self.job.home))

    def top_up(self) -> None:
        """Hand planned records to the streamer: lockstep by the backlog rule, real time all there is."""
        if self.threaded:
            with self._planned:
                ready, self._ready = self._ready, []
                done = self._done
            for chunk in ready:
                self.streamer.add(*chunk)
            if self._error is not None:  # the thread failed: the run cannot go on
                raise self._error
            if done:
                self.streamer.complete = True
            return
        while not self.streamer.complete and not self.awaiting and self.streamer.backlog < self.BACKLOG:
            chunk = self._take()
            if chunk is None:
                self.streamer.complete = True
            else:
                self.streamer.add(*chunk)
                self.awaiting = any(type(r) is Probe for r in chunk[0])


class Streamer:
    """Which records go out in answer to a status. Sequence numbers start at 1.

    Records are added as they are planned (:meth:`add`); ``complete`` is set after the last.

    Parameters
    ----------
    chunk_words, lookahead_periods : limits per exchange (0 look-ahead = none).
    """

    def __init__(self, *, chunk_words: int, lookahead_periods: int):
        self.encoded: list[np.ndarray] = []
        self.cumulative: list[int] = [0]
        self.chunk_words = chunk_words
        self.lookahead_periods = lookahead_periods
        self.next_index = 0
        self.complete = False
        self._rejected_seen = 0
        self.retransmitted = 0
        self.wake_free = 0
        """after :meth:`answer`: 0, or the free FIFO words the next record needs when it stopped
        for want of room (no exchange can write anything before the card has freed that much)"""

    def add(self, records: list[Record], periods: list[int]) -> None:
        """Encode ``records`` (``periods`` each) in order; a curve or surface longer than one
        exchange's chunk goes as GeometryPart records, the periods counted on the last part."""
        for record, n in zip(records, periods):
            pieces = split(record, self.chunk_words)
            for i, piece in enumerate(pieces):
                self.encoded.append(encode(piece, len(self.encoded) + 1))
                self.cumulative.append(self.cumulative[-1] + (n if i == len(pieces) - 1 else 0))

    @property
    def backlog(self) -> int:
        """Records planned and not yet sent."""
        return len(self.encoded) - self.next_index

    @property
    def all_sent(self) -> bool:
        return self.complete and self.next_index >= len(self.encoded)

    def answer(self, status: np.ndarray, port: PcPort, *, corrupt=None) -> int:
        """Write records for one exchange; returns how many were written."""
        st = status[0]
        rejected = int(st["records_rejected"])
        if rejected != self._rejected_seen:
            self._rejected_seen = rejected
            resend_from = int(st["expected_seq"]) - 1
            self.retransmitted += max(0, self.next_index - resend_from)
            self.next_index = resend_from
        # Motion queued on the card, as it reported, plus what is in flight (sent, not yet accepted).
        # The record after the running one always goes, whatever the look-ahead: a card holding
        # because it ran dry does not drain its queue, and must not wait for itself.
        accepted = int(st["expected_seq"]) - 1
        executed = int(st["last_seq_executed"])
        on_card = int(st["queued_periods"])
        budget = self.chunk_words
        written = 0
        fifo = port.fifo
        free = fifo.free()
        self.wake_free = 0
        while self.next_index < len(self.encoded):
            queued = on_card + (self.cumulative[self.next_index] - self.cumulative[accepted])
            if (self.lookahead_periods and queued >= self.lookahead_periods and self.next_index > executed + 1
                    and int(st["state"]) != DspState.FEED_HOLD):  # a card holding for data gets data
                break
            words = self.encoded[self.next_index]
            if len(words) > free:  # the FIFO must drain first, whatever the chunk budget
                self.wake_free = len(words)
                break
            # a record longer than the chunk goes alone, first in its exchange (else it never would)
            if len(words) > budget and written:
                break
            if corrupt is not None:
                words = corrupt(words)
            fifo.write(words)
            budget -= len(words)
            free -= len(words)
            self.next_index += 1
            written += 1
        return written

