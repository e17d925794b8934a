"""Where an outside PC program finds the card: a private folder with the whiteboard and two doorbells.

The twin's own planner inherits its doorbells as pipes. A program the user starts by itself opens
them by name instead, from the *attach folder* the twin makes (mode 0700)::

    whiteboard   the shared-memory segment (a symbolic link to /dev/shm/<name>): open it read-write
                 and map all of it; its size is 2 x the layout's words
    to_dsp       named pipe: the PC writes one byte after each acknowledgement (its mailbox word)
    to_pc        named pipe: the card writes one byte after each status it posts

The shared memory stays the source of truth, as with the inherited pipes
(:mod:`cnc_twin.whiteboard.doorbell`): a byte only wakes the other side, which then reads the
mailbox word. The PC side opens ``to_pc`` for reading and ``to_dsp`` for writing (neither blocks:
the card holds an end of each already), spins on the mailbox briefly, then sleeps in ``poll`` on
``to_pc``.

The card knows the PC program is gone when its end of ``to_dsp`` reports a hang-up: every writer
closed it, as the kernel does when a process exits however it ends (SIGKILL too). Before the
program first opens ``to_dsp`` there is no hang-up (Linux reports one only once a writer came and
left), so a program may take its time to start, up to ``planner.start_timeout``.
"""

from __future__ import annotations

import os
import select
import tempfile
from pathlib import Path

from cnc_twin.whiteboard.doorbell import Doorbell

WHITEBOARD = "whiteboard"
TO_DSP = "to_dsp"
TO_PC = "to_pc"
FOLDER_PREFIX = "cnc-twin-pc-"


class AttachPoint:
    """The attach folder of one run, made for the segment ``shm_name``; the card's doorbells.

    ``folder``: where to make it (it must not exist; its parent must); None: a new private folder
    in the temporary directory. :meth:`close` removes it (and only what it made).
    """

    def __init__(self, shm_name: str, folder: Path | None = None):
        if folder is None:
            self.folder = Path(tempfile.mkdtemp(prefix=FOLDER_PREFIX))
        else:
            self.folder = Path(folder)
            self.folder.mkdir(mode=0o700)
        self._made = True
        try:
            os.symlink(f"/dev/shm/{shm_name}", self.folder / WHITEBOARD)
            os.mkfifo(self.folder / TO_DSP, 0o600)
            os.mkfifo(self.folder / TO_PC, 0o600)
            # The card's ends, opened without waiting for the PC: reading to_dsp (a writer may come
            # later), and to_pc read-write (so the ring never blocks or fails for want of a reader).
            wait_fd = os.open(self.folder / TO_DSP, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
            ring_fd = os.open(self.folder / TO_PC, os.O_RDWR | os.O_NONBLOCK | os.O_CLOEXEC)
        except BaseException:
            self.close()
            raise
        self.wait_pc = Doorbell(wait_fd)
        self.ring_pc = Doorbell(ring_fd)
        self._hangup = select.poll()
        self._hangup.register(wait_fd, select.POLLHUP)

    def pc_gone(self) -> bool:
        """Whether the PC program opened ``to_dsp`` and every writer has closed it since (it exited)."""
        return any(event & select.POLLHUP for _, event in self._hangup.poll(0))

    def close(self) -> None:
        """Close the card's ends and remove the folder."""
        for name in ("wait_pc", "ring_pc"):
            bell = self.__dict__.pop(name, None)
            if bell is not None:
                bell.close()
        if self._made:
            self._made = False
            for name in (WHITEBOARD, TO_DSP, TO_PC):
                try:
                    (self.folder / name).unlink()
                except FileNotFoundError:
                    pass
            try:
                self.folder.rmdir()
            except OSError:  # something else was put in it: left as it is
                pass
