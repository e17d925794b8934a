"""The shared-memory segment: created by the DSP side, attached by the planner, always unlinked.

:class:`Whiteboard` owns the ``multiprocessing.shared_memory.SharedMemory`` block and exposes
typed numpy views of it (16-bit words, aligned 32-bit fields, the status record). The creator
unlinks the segment in :meth:`Whiteboard.close` (and as a context manager, on every exit path); a
process that only attaches never unlinks, and detaches its views before closing.
"""

from __future__ import annotations

import os
import secrets
from collections.abc import Iterable
from multiprocessing import resource_tracker, shared_memory

import numpy as np

from cnc_twin.core.deferred_signals import signals_deferred
from cnc_twin.core.errors import ResourceError
from cnc_twin.whiteboard import layout as L
from cnc_twin.whiteboard.status import STATUS_DTYPE

NAME_PREFIX = "cnc_twin_"
SHM_FOLDER = "/dev/shm"
"""where Linux keeps POSIX shared memory (a tmpfs)"""


class Whiteboard:
    """Typed views of one whiteboard segment.

    Use :meth:`create` (DSP side, owner) or :meth:`attach` (planner side).

    :type shm: ~multiprocessing.shared_memory.SharedMemory
    :type layout: ~cnc_twin.whiteboard.layout.Layout

    Attributes
    ----------
    words : uint16 view of the whole RAM, shape ``(layout.words,)``.
    fifo_ring : uint16 view of the command FIFO.
    status : the status record view (``STATUS_DTYPE``, shape ``(1,)``).
    """

    def __init__(self, shm: shared_memory.SharedMemory, layout: L.Layout, *, owner: bool):
        self.shm = shm
        self.layout = layout
        self.owner = owner
        self.name = shm.name
        buf = shm.buf
        self.words = np.ndarray((layout.words,), dtype="<u2", buffer=buf)
        self.fifo_ring = self.words[layout.fifo_base:layout.fifo_base + layout.fifo_words]
        pc, dsp = layout.pc_control, layout.dsp_control
        self.pc_magic = self._u32(pc + L.PC_MAGIC)
        self.pc_heartbeat = self._u32(pc + L.PC_HEARTBEAT)
        self.fifo_write = self._u32(pc + L.PC_FIFO_WRITE)
        self.program_periods = self._u32(pc + L.PC_PROGRAM_PERIODS)
        self.records_sent = self._u32(pc + L.PC_RECORDS_SENT)
        self.retransmits = self._u32(pc + L.PC_RETRANSMITS)
        self.plan_us = self._u32(pc + L.PC_PLAN_US)
        self.plan_blocks = self._u32(pc + L.PC_PLAN_BLOCKS)
        self.fifo_read = self._u32(dsp + L.DSP_FIFO_READ)
        self.dsp_heartbeat = self._u32(dsp + L.DSP_HEARTBEAT)
        self.status = np.ndarray((1,), dtype=STATUS_DTYPE, buffer=buf, offset=2 * layout.status_base)
        if STATUS_DTYPE.itemsize > 2 * L.STATUS_WORDS:
            raise AssertionError("status block larger than its area")
        # Single 16-bit words, by address.
        self.PC_STATE = pc + L.PC_VERSION + 1
        self.PC_VERSION = pc + L.PC_VERSION
        self.HOLD = pc + L.PC_HOLD
        self.ALL_SENT = pc + L.PC_ALL_SENT
        self.WAKE_FREE = pc + L.PC_WAKE_FREE
        self.HOLDA = dsp + L.DSP_HOLDA
        self.SHUTDOWN = dsp + L.DSP_SHUTDOWN
        self.MAILBOX_TO_DSP = layout.mailbox_to_dsp
        self.MAILBOX_TO_PC = layout.mailbox_to_pc

    def _u32(self, word_address: int) -> np.ndarray:
        if word_address % 2:
            raise AssertionError(f"u32 field at odd word address {word_address}")
        return np.ndarray((1,), dtype="<u4", buffer=self.shm.buf, offset=2 * word_address)

    @classmethod
    def create(cls, layout: L.Layout | None = None) -> "Whiteboard":
        """Create and zero a new segment with a unique name (DSP side; owns and unlinks it)."""
        layout = layout or L.Layout()
        name = f"{NAME_PREFIX}{os.getpid()}_{secrets.token_hex(4)}"
        # A full /dev/shm still lets the segment be made (tmpfs allots pages when written), and the
        # zeroing below would then end the process with SIGBUS: its room is checked first.
        try:
            info = os.statvfs(SHM_FOLDER)
        except OSError as exc:
            raise ResourceError(SHM_FOLDER, f"no shared memory for the whiteboard: {exc.strerror}") from None
        free = info.f_bavail * info.f_frsize
        if free < layout.nbytes:
            raise ResourceError(SHM_FOLDER, f"no room for the whiteboard: {layout.nbytes} bytes needed, {free} free "
                                "(a container's --shm-size, or what fills it)")
        try:
            shm = shared_memory.SharedMemory(name=name, create=True, size=layout.nbytes)
        except OSError as exc:
            raise ResourceError(SHM_FOLDER, f"cannot make the whiteboard's segment: {exc.strerror or exc}") from None
        try:
            shm.buf[: layout.nbytes] = bytes(layout.nbytes)
            return cls(shm, layout, owner=True)
        except BaseException:
            shm.close()
            shm.unlink()
            raise

    @classmethod
    def attach(cls, name: str, layout: L.Layout | None = None) -> "Whiteboard":
        """Attach to an existing segment (planner side; never unlinks it)."""
        shm = _attach_untracked(name)
        return cls(shm, layout or L.Layout(), owner=False)

    def close(self) -> None:
        """Drop the views, close the mapping, and unlink the segment if this side created it
        (SIGINT and SIGTERM held back meanwhile, so that a handler raising cannot leave the
        segment mapped-out but not unlinked)."""
        with signals_deferred():
            self._close()

    def _close(self) -> None:
        for attr in ("words", "fifo_ring", "status", "pc_magic", "pc_heartbeat", "fifo_write",
                     "program_periods", "records_sent", "retransmits", "plan_us", "plan_blocks", "fifo_read",
                     "dsp_heartbeat"):
            self.__dict__.pop(attr, None)
        try:
            self.shm.close()
        except BufferError:  # pragma: no cover - a view escaped; the unlink below still happens
            pass
        if self.owner:
            try:
                self.shm.unlink()
            except FileNotFoundError:
                pass

    def __enter__(self) -> "Whiteboard":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _attach_untracked(name: str) -> shared_memory.SharedMemory:
    """Attach without registering with the resource tracker: only the creator owns the segment.

    A spawned child shares its parent's tracker, whose registry is a set; registering again and
    unregistering would drop the owner's entry, and a process with a tracker of its own would
    have it unlink the owner's segment at exit. Python 3.13 has ``track=False`` for this.
    """
    try:
        return shared_memory.SharedMemory(name=name, create=False, track=False)  # type: ignore[call-arg]
    except TypeError:  # Python < 3.13
        pass
    original = resource_tracker.register

    def register(res_name, rtype):
        if rtype != "shared_memory":
            original(res_name, rtype)

    resource_tracker.register = register
    try:
        return shared_memory.SharedMemory(name=name, create=False)
    finally:
        resource_tracker.register = original


def leftover_segments() -> list[str]:
    """Names of cnc-twin segments present in /dev/shm (for tests and diagnostics)."""
    try:
        return sorted(n for n in os.listdir("/dev/shm") if n.startswith(NAME_PREFIX))
    except FileNotFoundError:  # pragma: no cover - not Linux
        return []


def creator_pid(name: str) -> int | None:
    """The pid of the process that created segment ``name`` (:meth:`Whiteboard.create` puts it
    in the name), or None when the name carries none."""
    if not name.startswith(NAME_PREFIX):
        return None
    try:
        return int(name[len(NAME_PREFIX):].split("_")[0])
    except ValueError:
        return None


def leaked_segments(names: Iterable[str]) -> set[str]:
    """The segments among ``names`` that are leaks: created by this process, or by one that has
    exited (nobody is left to unlink them), or of unknown origin.

    A segment of another live process (a second run or test session on the same machine) is that
    process's business, not a leak of this one.
    """
    out = set()
    for name in names:
        pid = creator_pid(name)
        if pid is None or pid == os.getpid() or not os.path.exists(f"/proc/{pid}"):
            out.add(name)
    return out
