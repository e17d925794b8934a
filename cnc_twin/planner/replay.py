"""The twin's planner streaming a PC program's recorded stream again (``planner.replay``).

A :class:`~cnc_twin.whiteboard.capture.PcStream` holds, per exchange the card took, the status
period the PC program answered, the FIFO words it published and its ALL_SENT and WAKE_FREE words.
:class:`Replay` writes the same words and flags in answer to the same statuses, so the card takes
the same exchanges with the same contents: a lockstep run gives the recorded run's trace bit for
bit. It plans nothing, resends nothing (the recorded stream has the PC program's own resends) and
takes the place of both :class:`~cnc_twin.planner.stream.Feeder` and
:class:`~cnc_twin.planner.stream.Streamer` in :func:`~cnc_twin.planner.process.planner_main`.
"""

from __future__ import annotations

import numpy as np

from cnc_twin.whiteboard.capture import BEFORE_FIRST_STATUS, PcStream
from cnc_twin.whiteboard.ports import PcPort


class Replay:
    """A recorded stream, answered status by status."""

    plan_seconds = 0.0
    blocks = 0
    retransmitted = 0

    def __init__(self, stream: PcStream):
        self.stream = stream
        self._next = 0
        self.next_index = 0
        """exchanges answered so far (the PC control block's records-sent word)"""
        self.all_sent = False
        self.wake_free = 0

    @property
    def program(self) -> "Replay":
        return self

    @property
    def estimated_periods(self) -> int:
        """The program length the recorded PC program announced [periods]."""
        return self.stream.program_periods

    def see(self, status: np.ndarray) -> None:
        """Nothing to learn from the card: the stream is what it was."""

    def top_up(self) -> None:
        """Nothing to plan."""

    def plan_ahead(self, chunks: int) -> None:
        """Nothing to plan."""

    def before_first_status(self, port: PcPort) -> None:
        """Write what the PC program wrote as it attached, before the card's first status."""
        self._write_exchanges(BEFORE_FIRST_STATUS, port)

    def answer(self, status: np.ndarray, port: PcPort, *, corrupt=None) -> int:
        """Write the recorded answer to this status (nothing when there is none; ``corrupt`` is
        not used: the recorded words are written as they were)."""
        return self._write_exchanges(int(status[0]["period"]), port)

    def _write_exchanges(self, period: int, port: PcPort) -> int:
        exchanges = self.stream.exchanges
        written = 0
        while self._next < len(exchanges) and exchanges[self._next].period == period:
            exchange = exchanges[self._next]
            if len(exchange.words):
                port.fifo.write(exchange.words)
            self.all_sent, self.wake_free = bool(exchange.all_sent), exchange.wake_free
            self._next += 1
            written += 1
        self.next_index = self._next
        return written
