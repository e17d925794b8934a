"""Stopping a local sweep on SIGINT or SIGTERM: the main process's side and the workers' side.

The main process holds a :class:`SweepStop` (the CLI sets it from SIGINT and SIGTERM through
:class:`~cnc_twin.run.signals.SignalGuard`); once it
is set, no new case is handed out and SIGINT is passed on to the pool's workers, which told the
main process their pids through a pipe when they started (:func:`init_worker`). A worker takes
SIGINT, from the main process or from the terminal (Ctrl-C reaches the whole process group), as
"stop": the case it runs stops at the twin's next interpolation period as ``cnc-twin run`` does,
and a case it is handed afterwards returns at once; both come back with status ``interrupted``.
The planner ignores SIGINT and ends with its run; the workers then leave as the pool shuts down,
closing their planners on the way out. SIGTERM in a worker (the pool ending it, or a SIGTERM to
the whole group) stops the case running at its next period, and the worker leaves once the run
has cleaned up; an idle worker leaves at once. Only the first SIGTERM raises: later ones (the
main process repeats it, :meth:`SweepStop.end_workers`) would cut the clean-up short.

Why a signal and not a flag that a thread in the worker watches: a run gives up the GIL only for
the microseconds of each compiled servo call and takes it straight back, so such a thread waits
up to a whole run (seconds) before it can set the flag; a signal handler runs in the worker's
main thread between two periods.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import time
import threading
from collections.abc import Iterator
from typing import Any

_stopped = False
"""in a worker: SIGINT or SIGTERM came; cases from now on are not run"""
_running: Any = None
"""in a worker: the twin of the case running now (a SIGINT asks it to stop)"""
_terminated = False
"""in a worker: SIGTERM came; the worker leaves once the case running has cleaned up"""
_exiting = False
"""in a worker: SIGTERM raised SystemExit already (later ones leave the clean-up alone)"""


class SweepStop:
    """The main process's stop: its reason, and the workers to pass it on to.

    ``reason`` is None until :meth:`request_stop` (``"SIGINT"`` or ``"SIGTERM"`` from a signal:
    the CLI hands it to :meth:`cnc_twin.run.signals.SignalGuard.stopping`, as it hands a twin).
    Give :attr:`worker_args` to each pool as the ``initargs`` of :func:`init_worker`.
    """

    def __init__(self):
        self.reason: str | None = None
        # workers write their pids here at start-up; only the main process reads
        self._pids_in, self._pids_out = multiprocessing.Pipe(duplex=False)
        self._workers: set[int] = set()
        self._told: set[int] = set()

    @property
    def worker_args(self) -> tuple[Any, ...]:
        """The pool's ``initargs`` for :func:`init_worker`: the write end of the workers' pid pipe."""
        return (self._pids_out,)

    def request_stop(self, reason: str) -> None:
        """Stop the sweep (the first reason is kept). Safe in a signal handler: it only notes
        the reason; :meth:`pass_on`, from the sweep's loop, tells the workers."""
        if self.reason is None:
            self.reason = reason

    def pass_on(self) -> None:
        """Once stopped, send SIGINT to every worker that registered and was not told yet."""
        if self.reason is None:
            return
        while self._pids_in.poll():
            self._workers.add(int(self._pids_in.recv_bytes()))
        for pid in self._workers - self._told:
            self._told.add(pid)
            try:
                os.kill(pid, signal.SIGINT)
            except ProcessLookupError:  # it left already (a broken pool)
                pass

    def end_workers(self, grace: float = 10.0) -> None:
        """End every worker that registered, after a pool broke, so that its shutdown does not
        wait on a worker left waiting for work (Python 3.13.0 did, seen here: the sweep never
        returned). SIGTERM, again every 0.2 s while one lives (a worker still cleaning up a case
        when the first came takes the next), SIGKILL after ``grace`` [s]."""
        while self._pids_in.poll():
            self._workers.add(int(self._pids_in.recv_bytes()))
        deadline = time.monotonic() + grace
        living = {pid for pid in self._workers if _alive(pid)}
        while living:
            late = time.monotonic() >= deadline
            for pid in living:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL if late else signal.SIGTERM)
            if late:
                return
            time.sleep(0.2)
            living = {pid for pid in living if _alive(pid)}

    def forget_workers(self) -> None:
        """After a pool has shut down (its workers joined): their pids may be reused, so none
        of them is signalled again."""
        while self._pids_in.poll():
            self._pids_in.recv_bytes()
        self._workers.clear()
        self._told.clear()

    def close(self) -> None:
        """Close the pid pipe (no pool may start after this)."""
        self._pids_in.close()
        self._pids_out.close()


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (an exited child not yet reaped counts as gone)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as stat:
            return stat.read().rsplit(b")", 1)[1].split()[0] != b"Z"
    except (OSError, IndexError):
        return False


@contextlib.contextmanager
def sigint_held() -> Iterator[None]:
    """Around starting a child (a pool's worker: ``pool.submit`` may start one; a worker's
    planner): SIGINT is blocked in this thread, and so in the child, which inherits the mask;
    Python still takes a SIGINT for this process meanwhile through another thread, or once the
    block ends. Without this, a Ctrl-C during a child's start-up (imports, about a second) kills
    it with a KeyboardInterrupt traceback. A worker unblocks SIGINT in :func:`init_worker`, once
    it stops the worker's cases; a planner keeps it blocked (it ignores SIGINT anyway)."""
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def init_worker(pids) -> None:
    """Pool initializer, in each worker: from now on SIGINT stops this worker's cases (one that
    came during its start-up, held back by :func:`sigint_held`, arrives now); then the worker's
    pid goes to the main process (``pids``: the write end from :attr:`SweepStop.worker_args`)."""
    signal.signal(signal.SIGINT, _on_sigint)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    pids.send_bytes(str(os.getpid()).encode())  # one short write: workers' pids never interleave
    pids.close()


def exit_on_sigterm() -> None:
    """In a worker's main thread: SIGTERM (a pool shutting down after another worker died, or a
    SIGTERM to the whole process group) exits the case through the twin's clean-up (planner
    reaped, shared memory unlinked) instead of killing the worker, and no further case runs."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _on_sigterm)


def _on_sigterm(signum, _frame) -> None:
    global _stopped, _terminated, _exiting
    _stopped = _terminated = True
    if _running is not None:
        # A case runs: it stops at its next period and cleans up (planner reaped, segment
        # unlinked); :func:`stoppable` then leaves the worker. Raising here instead would cut
        # that clean-up short when the next SIGTERM (the pool's, then :meth:`SweepStop.end_workers`
        # every 0.2 s) lands inside it, and leave the segment behind (seen in CI).
        _running.request_stop("SIGTERM")
        return
    if _exiting:  # already leaving: a second SystemExit would cut the atexit clean-up short
        return
    _exiting = True
    raise SystemExit(128 + signum)


def _on_sigint(_signum, _frame) -> None:
    global _stopped
    _stopped = True
    if _running is not None:
        _running.request_stop("SIGINT")


def stop_requested() -> bool:
    """In a worker: whether SIGINT or SIGTERM came (no further case should run)."""
    return _stopped


@contextlib.contextmanager
def stoppable(twin) -> Iterator[None]:
    """In a worker, around ``twin.run()``: a SIGINT, before or during the run, asks the twin to
    stop at its next period (its result is then ``interrupted``)."""
    global _running, _exiting
    _running = twin
    try:
        if _stopped:  # came between the check before the case and now
            twin.request_stop("SIGINT")
        yield
    finally:
        _running = None
    if _terminated:  # SIGTERM came during the case: the run has cleaned up, now leave
        _exiting = True
        raise SystemExit(128 + signal.SIGTERM)
