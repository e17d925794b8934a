"""Feed paths prepared ahead (:class:`~cnc_twin.gcode.paths_ahead.PathsAhead`): while the reader
reads on, a helper process fits and blends the feed paths it has closed, and the operations are
handed out in program order as they are ready.

A long CAM program's load is half reading (Python) and half fitting its runs of lines
(:mod:`cnc_twin.gcode.line_fit`); on two cores the two overlap when the fits run in a process of
their own (a thread waits for the interpreter's lock the reader holds: tried, slower). Each path
is prepared by the same function as in the reader's process, on the same data: the operations are
the same, bit for bit, in the same order. At most :data:`LOOKAHEAD` paths wait to be handed out
(the memory stays a few paths'); an error is raised where it would be without the helper: a
path's when its turn comes, the reader's after every operation made before it.

The helper is a plain subprocess, ``python -m cnc_twin.gcode.paths_ahead`` (no multiprocessing:
user scripts need no ``__main__`` guard), in a session of its own (a terminal's Ctrl-C reaches
the reader, which ends it). It reads length-prefixed pickles ``(job, args)`` from its stdin in a
thread of its own (a long request never waits on a long answer), prepares them in order, and
writes ``(ok, result or exception)`` back; EOF on its stdin ends it. Started only for programs
long enough to repay its start (:data:`HELPER_LINES`, a second of the other core); a helper
that cannot be started or dies is replaced by preparing in the reader's process, from the
requests it has not answered: nothing is lost.
"""

from __future__ import annotations

import os
import pickle
import select
import subprocess
import sys
from collections import deque
from collections.abc import Callable, Iterator

from cnc_twin.core.child_process import end_process
from cnc_twin.core.helpers import module_command
from cnc_twin.core.messages import framed, read_message, read_payload

LOOKAHEAD = 8
"""requests (each up to a feed path's ``PATH_ELEMENTS`` lines, :mod:`~cnc_twin.gcode.toolpath`) sent
to the helper that may wait to be handed out: enough to keep reading while the helper starts"""
HELPER_LINES = 150_000
"""program lines from which a load prepares its paths in the helper"""


def _jobs() -> dict[str, Callable[..., list]]:
    """What the helper may be asked to do, by name (imported where asked: the helper's process
    loads the fits' modules while the reader's still reads)."""
    from cnc_twin.gcode.feed_paths import gathered_feed_paths
    from cnc_twin.gcode.line_fit import tool_axis_paths

    return {"feed_paths": gathered_feed_paths, "tool_axis_paths": tool_axis_paths}


class _Waiting:
    """A request sent to the helper: its job and arguments (kept to be prepared here if the
    helper dies before it answers)."""

    __slots__ = ("job", "args")

    def __init__(self, job: str, args: tuple):
        self.job, self.args = job, args


class PathsAhead:
    """Operations in program order: :meth:`~PathsAhead.add` one made now, :meth:`~PathsAhead.prepare`
    those a job makes (a list, in order), in the helper when there is one; :meth:`~PathsAhead.ready`
    hands out those at the front that are made, :meth:`~PathsAhead.drain` all;
    :meth:`~PathsAhead.close` ends the helper.

    ``helper``: prepare in a helper process (else each job at once, here)."""

    def __init__(self, helper: bool, lookahead: int = LOOKAHEAD):
        self.lookahead = lookahead
        """requests that may wait before :meth:`ready` waits for the first of them"""
        self.queue: deque = deque()  # operations, and _Waiting requests in the order sent
        self.waiting = 0  # requests in the queue
        self.failed = False
        """a path's preparation raised (handed on by :meth:`ready` or :meth:`drain`)"""
        self.answered = 0
        """requests the helper answered (the others were prepared here)"""
        # started now: its imports (a second and more) pass while the first paths are read
        self._helper = _Helper.start() if helper else None
        self._sent = False  # a request sent since the helper was last asked for answers
        self.fresh = False
        """something was added or sent since :meth:`ready` last handed out all it could (until
        then, asking again hands out nothing: the reader asks only when this is set)"""

    def add(self, operation) -> None:
        """Queue ``operation``, made now."""
        self.queue.append(operation)
        self.fresh = True

    def prepare(self, job: str, *args) -> None:
        """Queue the operations the job ``job`` makes of ``args``: sent to the helper when there
        is one, else made here, now."""
        self.fresh = True
        if self._helper is not None and self._helper.send(job, args):
            self.queue.append(_Waiting(job, args))
            self.waiting += 1
            self._sent = True
            return
        self._lost_helper()
        self.queue.extend(self._made_here(job, args))

    def ready(self) -> Iterator:
        """The operations at the front that are made, and while more than :attr:`lookahead`
        requests wait, the first of them (waiting for it). The helper's answers are looked for
        once a request has been sent since they last were (not at every call: the reader asks
        at every line)."""
        queue = self.queue
        while queue:
            head = queue[0]
            if head.__class__ is _Waiting:
                if self.waiting <= self.lookahead and not (self._sent and self._helper_has_answered()):
                    self._sent = self.fresh = False
                    return
                yield from self._result(queue.popleft())
            else:
                yield queue.popleft()
        self.fresh = False

    def drain(self) -> Iterator:
        """Every operation left, in order (waiting for those being made)."""
        queue = self.queue
        while queue:
            head = queue.popleft()
            if head.__class__ is _Waiting:
                yield from self._result(head)
            else:
                yield head

    def close(self) -> None:
        """End the helper, if one was started (what it still prepares is dropped)."""
        helper, self._helper = self._helper, None
        if helper is not None:
            helper.close()

    def _helper_has_answered(self) -> bool:
        return self._helper is None or self._helper.answered()

    def _result(self, request: _Waiting) -> list:
        self.waiting -= 1
        answer = None if self._helper is None else self._helper.receive()
        if answer is None:  # no helper (any more): prepared here, from what was sent
            self._lost_helper()
            return self._made_here(request.job, request.args)
        ok, value = answer
        self.answered += 1
        if not ok:
            self.failed = True
            raise value
        return value

    def _made_here(self, job: str, args: tuple) -> list:
        try:
            return _jobs()[job](*args)
        except BaseException:
            self.failed = True
            raise

    def _lost_helper(self) -> None:
        if self._helper is not None:
            self._helper.close()
            self._helper = None


class _Helper:
    """The helper subprocess and its two pipes (see the module docstring)."""

    def __init__(self, popen: subprocess.Popen):
        self.popen = popen
        self.out = popen.stdout.fileno()

    @classmethod
    def start(cls) -> _Helper | None:
        """A new helper, or None when one cannot be started (no process to spare)."""
        try:
            popen = subprocess.Popen(module_command("cnc_twin.gcode.paths_ahead"), stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, close_fds=True,
                                     start_new_session=True)
        except OSError:
            return None
        return cls(popen)

    def send(self, job: str, args: tuple) -> bool:
        """Send a request; False when the helper is gone."""
        data = framed((job, args))
        try:
            self.popen.stdin.write(data)
            self.popen.stdin.flush()
        except OSError:
            return False
        return True

    def answered(self) -> bool:
        """An answer (or the helper's end) can be read without waiting."""
        return bool(select.select([self.out], [], [], 0.0)[0])

    def receive(self) -> tuple | None:
        """The next answer ``(ok, value)``, waiting for it; None when the helper ended first."""
        try:
            return read_message(self.out)
        except OSError:
            return None

    def close(self) -> None:
        end_process(self.popen, grace=0.5, term_grace=1.0)
        self.popen.stdout.close()


def _serve() -> None:
    """The helper's loop: requests from stdin (read in a thread), answers to stdout, in order."""
    import queue
    import threading

    requests: queue.SimpleQueue = queue.SimpleQueue()
    stdin, stdout = sys.stdin.buffer.fileno(), sys.stdout.buffer.fileno()

    def read_requests() -> None:
        while (payload := read_payload(stdin)) is not None:
            requests.put(payload)
        requests.put(None)

    def write_answers() -> None:
        while (data := answers.get()) is not None:
            view = memoryview(data)
            while view:
                view = view[os.write(stdout, view):]

    answers: queue.SimpleQueue = queue.SimpleQueue()
    threading.Thread(target=read_requests, daemon=True).start()
    # the answers go out while the next request is prepared: the reader picks them up when it
    # next sends one, and a full pipe must not hold the fits up until then
    writer = threading.Thread(target=write_answers)
    writer.start()
    jobs = _jobs()
    while (payload := requests.get()) is not None:
        job, args = pickle.loads(payload)
        try:
            answer = (True, jobs[job](*args))
        except Exception as exc:  # the reader raises it where the path's turn comes
            answer = (False, exc)
        try:
            data = framed(answer)
        except Exception as exc:  # an exception that does not pickle: its type and words
            data = framed((False, RuntimeError(f"{type(answer[1]).__name__}: {exc}")))
        answers.put(data)
    answers.put(None)
    writer.join()


if __name__ == "__main__":
    _serve()
    os._exit(0)  # every answer written: no teardown for the reader's process to wait for
