"""Starting the planner process, and keeping one warm between runs.

The planner is a plain subprocess, ``python -m cnc_twin.planner.process --serve WAIT_FD RING_FD``
(not multiprocessing's spawn, so user scripts need no ``__main__`` guard). It imports its
modules once, then serves runs one after another: for each it reads ``(shared-memory name, job)``
from its stdin (a length-prefixed pickle), plans and streams that run, and writes one status
byte to its stdout when the run is over. EOF on its stdin makes it exit.

A :class:`~cnc_twin.run.twin.Twin` without a pool starts one planner per run and closes it
afterwards: nothing is left running. With a :class:`PlannerPool` (a sweep's worker keeps one) the
planner that served a clean run is kept for the next: a run then waits a few milliseconds for its
planner instead of the interpreter start and the imports (0.2 s for point-to-point, 0.6 s once
scipy's splines are needed for curves), and the CPU those cost is not spent again.

A planner is reused only when its run ended cleanly: a lockstep run (a real-time planner may
still be planning in its thread) without injected planner faults, reported over within
``DONE_TIMEOUT`` with status 0. Anything else and it is closed (EOF, then SIGTERM, then
SIGKILL).
"""

from __future__ import annotations

import os
import pickle
import select
import struct
import weakref

from cnc_twin.core.child_process import end_process
from cnc_twin.core.helpers import start_helper
from cnc_twin.whiteboard.doorbell import PipeDoorbells

DONE_TIMEOUT = 2.0
"""how long the DSP side waits, after the shutdown word, for the planner to finish its run [s]"""

_HEADER = struct.Struct("<I")
"""a job message: its pickle's length, then the pickle"""

SINGLE_THREAD_MATH = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
"""the planner's linear algebra is tiny: a BLAS thread pool only costs start-up CPU (numpy's
import takes 0.24 s of CPU with OpenBLAS's threads on two cores, 0.09 s with one)"""


class PlannerProcess:
    """One planner subprocess in serve mode, with its doorbell pipes.

    ``popen`` is the :class:`subprocess.Popen` or :class:`~cnc_twin.core.helpers.ForkedHelper` (its ``pid``
    and ``poll()`` tell liveness).
    """

    capture = False
    """the card does not keep this planner's stream (it plans it again from the scenario)"""

    def __init__(self):
        self.bells = PipeDoorbells()
        env = dict(os.environ)
        for name in SINGLE_THREAD_MATH:
            env.setdefault(name, "1")
        wait_fd, ring_fd = self.bells.pc_fds()
        self.popen = start_helper("cnc_twin.planner.process", ["--serve", str(wait_fd), str(ring_fd)],
                                  pass_fds=(wait_fd, ring_fd), env=env)
        self.bells.release_pc_ends()
        self.owner = os.getpid()
        self.runs = 0
        self.reusable = True
        """False once a run did not end cleanly (the process is then closed, not kept)"""

    @property
    def pid(self) -> int:
        return self.popen.pid

    def alive(self) -> bool:
        return self.popen.poll() is None

    def submit(self, shm_name: str, job) -> None:
        """Hand the planner its next run. A planner that died at once is noticed by the DSP's
        ``wait_ready`` (process exited before it attached)."""
        # Stale rings from the last run are harmless (waiters re-check the mailbox) but are
        # drained so the first wait of this run sleeps for real.
        self.bells.wait_pc.drain()
        payload = pickle.dumps((shm_name, job))
        try:
            self.popen.stdin.write(_HEADER.pack(len(payload)) + payload)
            self.popen.stdin.flush()
        except (BrokenPipeError, OSError):
            self.reusable = False
        self.runs += 1

    def finish(self, timeout: float = DONE_TIMEOUT) -> bool:
        """After the shutdown word: wait for the run-over byte; True when the planner can serve
        another run (it answered in time with status 0)."""
        out = self.popen.stdout
        ready, _, _ = select.select([out], [], [], timeout)
        if not ready:
            self.reusable = False
            return False
        status = os.read(out.fileno(), 1)
        if status != b"\x00":
            self.reusable = False
        return self.reusable and self.alive()

    def failure(self, timeout: float = 2.0) -> str | None:
        """Why the planner's run failed, as it reported it (the exception's type and message, one
        line), or None if it did not say within ``timeout`` [s] (killed, hung, or not failed).
        Call after a planner fault only: it reads the run's status byte, so the process is not
        kept for another run."""
        self.reusable = False
        out = self.popen.stdout
        ready, _, _ = select.select([out], [], [], timeout)
        if not ready or os.read(out.fileno(), 1) != b"\x01":
            return None
        size = int.from_bytes(_read_exactly(out.fileno(), 2), "little")
        return _read_exactly(out.fileno(), size).decode("utf-8", "replace") or None

    def close(self) -> None:
        """End the process: EOF on its stdin, then SIGTERM, then SIGKILL; release the pipes."""
        end_process(self.popen, grace=2.0, term_grace=1.0)
        self.popen.stdout.close()
        self.bells.close()


def _close_idle(idle: list[PlannerProcess]) -> None:
    """Close the planners in ``idle`` (those this process started) and empty it."""
    planners = list(idle)
    idle.clear()
    for planner in planners:
        if planner.owner == os.getpid():
            planner.close()


class PlannerPool:
    """Keeps the planner of a clean run for the next run in this process (at most ``size`` idle).

    Use as a context manager, or call :meth:`close`; a pool collected or still open at
    interpreter exit closes its planners then. Give it to :meth:`cnc_twin.run.twin.Twin.run` (``planners=``) or
    :func:`cnc_twin.run.twin.run_scenario`.
    """

    def __init__(self, size: int = 1):
        self.size = size
        self._idle: list[PlannerProcess] = []
        self.started = 0
        """planner processes this pool started (runs minus this are the reuses)"""
        # at close(), when the pool is collected, or at interpreter exit, whichever comes first
        self._finalizer = weakref.finalize(self, _close_idle, self._idle)

    def prestart(self) -> None:
        """Start a planner now, if none is idle, so that its start-up runs alongside the
        caller's (imports, loading the scenario, building the twin)."""
        if not any(p.alive() and p.owner == os.getpid() for p in self._idle):
            self.started += 1
            self._idle.append(PlannerProcess())

    def acquire(self) -> PlannerProcess:
        """An idle planner of this process that is still alive, or a new one."""
        while self._idle:
            planner = self._idle.pop()
            if planner.alive() and planner.owner == os.getpid():
                return planner
            if planner.owner == os.getpid():
                planner.close()
        self.started += 1
        return PlannerProcess()

    def release(self, planner: PlannerProcess) -> None:
        """Keep ``planner`` if its run ended cleanly and there is room; close it otherwise."""
        if planner.reusable and planner.alive() and len(self._idle) < self.size:
            self._idle.append(planner)
        else:
            planner.close()

    def idle_pids(self) -> set[int]:
        """Process ids of the planners this pool keeps idle."""
        return {planner.pid for planner in self._idle}

    def close(self) -> None:
        """Close the idle planners (a pool can be used again after; it starts new ones)."""
        _close_idle(self._idle)

    def __enter__(self) -> "PlannerPool":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _read_exactly(fd: int, n: int, timeout: float = 1.0) -> bytes:
    """Up to ``n`` bytes from ``fd``, fewer if it ends or stays silent for ``timeout`` [s]."""
    data = b""
    while len(data) < n:
        ready, _, _ = select.select([fd], [], [], timeout)
        chunk = os.read(fd, n - len(data)) if ready else b""
        if not chunk:
            break
        data += chunk
    return data
