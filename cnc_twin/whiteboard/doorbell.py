"""Mailbox interrupts: a doorbell each side rings right after writing its mailbox word.

On the card, writing a mailbox word raises an interrupt on the other side. Here each direction
is a pipe: ``ring()`` writes one byte (never blocks; a full pipe already holds wake-ups), and
``wait(timeout)`` blocks in ``select`` until a byte arrives or the timeout passes, then drains
the pipe. The shared-memory mailbox stays the source of truth: a waiter always re-checks it, so a
spurious or stale ring costs one extra check and a missed one costs at most ``timeout``.

Why not only spin: a waiting process that stays runnable competes with the one doing the work
(measured here: a planner spinning on the second vCPU made the DSP several times slower).
Waiters therefore spin for a few microseconds (``SPIN_POLLS``) for the fast answer and then
sleep on the doorbell.
"""

from __future__ import annotations

import os
import select
from multiprocessing.connection import Connection

SPIN_POLLS = 200
"""mailbox polls (about 20-30 us) before a waiter blocks on its doorbell"""


class Doorbell:
    """One direction: the ringing side holds the write end, the waiting side the read end.

    Parameters
    ----------
    conn : a ``multiprocessing`` pipe end (picklable to a spawned process); only its file
        descriptor is used, with raw ``os.read`` / ``os.write``.
    """

    def __init__(self, conn: Connection):
        self.conn = conn
        self.fd = conn.fileno()
        os.set_blocking(self.fd, False)

    def ring(self) -> None:
        """Wake the other side (one byte; a full pipe means it has wake-ups pending)."""
        try:
            os.write(self.fd, b"\x01")
        except (BlockingIOError, BrokenPipeError):
            pass

    def wait(self, timeout: float) -> None:
        """Block until rung or ``timeout`` [s] passes; drain pending rings."""
        select.select([self.fd], [], [], timeout)
        self.drain()

    def drain(self) -> None:
        try:
            while os.read(self.fd, 4096):
                pass
        except (BlockingIOError, OSError):
            pass

    def close(self) -> None:
        self.conn.close()


class Doorbells:
    """Both directions, made by the DSP side; :meth:`pc_ends` go to the planner process.

    Parameters
    ----------
    ctx : the multiprocessing context that starts the planner (its pipes pickle to the child).
    """

    def __init__(self, ctx):
        self._to_pc = ctx.Pipe(duplex=False)   # (read end: PC, write end: DSP)
        self._to_dsp = ctx.Pipe(duplex=False)  # (read end: DSP, write end: PC)
        self.ring_pc = Doorbell(self._to_pc[1])
        self.wait_pc = Doorbell(self._to_dsp[0])

    def pc_ends(self) -> tuple[Connection, Connection]:
        """``(wait_dsp, ring_dsp)`` connection ends for the planner's :class:`PcPort`."""
        return self._to_pc[0], self._to_dsp[1]

    def close(self) -> None:
        for conn in (*self._to_pc, *self._to_dsp):
            conn.close()
