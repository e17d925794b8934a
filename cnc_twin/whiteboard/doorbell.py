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
    end : a pipe end: a raw file descriptor, or a ``multiprocessing`` connection (only its file
        descriptor is used, with raw ``os.read`` / ``os.write``).
    """

    def __init__(self, end: Connection | int):
        self.conn = end if not isinstance(end, int) else None
        self.fd = end if isinstance(end, int) else end.fileno()
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
        if self.conn is not None:
            self.conn.close()
        else:
            try:
                os.close(self.fd)
            except OSError:
                pass


class PipeDoorbells:
    """Both directions as OS pipes, for a planner started as a plain subprocess: the planner's
    ends (:meth:`~PipeDoorbells.pc_fds`) are inherited through ``pass_fds`` and closed here once it
    started."""

    def __init__(self):
        to_pc_r, to_pc_w = os.pipe()
        to_dsp_r, to_dsp_w = os.pipe()
        self._pc_fds = (to_pc_r, to_dsp_w)
        self.ring_pc = Doorbell(to_pc_w)
        self.wait_pc = Doorbell(to_dsp_r)

    def pc_fds(self) -> tuple[int, int]:
        """``(wait_dsp, ring_dsp)`` descriptors for the planner."""
        return self._pc_fds

    def release_pc_ends(self) -> None:
        """Close this process's copies of the planner's ends (after it started)."""
        for fd in self._pc_fds:
            try:
                os.close(fd)
            except OSError:
                pass
        self._pc_fds = ()

    def close(self) -> None:
        self.release_pc_ends()
        self.ring_pc.close()
        self.wait_pc.close()


class Doorbells:
    """Both directions, made by the DSP side; :meth:`~Doorbells.pc_ends` go to the planner process.

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
        """``(wait_dsp, ring_dsp)`` connection ends for the planner's
        :class:`~cnc_twin.whiteboard.ports.PcPort`."""
        return self._to_pc[0], self._to_dsp[1]

    def close(self) -> None:
        for conn in (*self._to_pc, *self._to_dsp):
            conn.close()
