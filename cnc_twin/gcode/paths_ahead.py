"""Feed paths prepared ahead (:class:`PathsAhead`): while the reader reads on, a worker thread
fits and blends the feed paths it has closed, and the operations are handed out in program order
as they are ready.

A CAM program's time goes half to reading (Python, holding the interpreter's lock) and half to
fitting its runs of lines (:mod:`cnc_twin.gcode.line_fit`: k-d tree queries, compiled distances,
B-spline sums, a sparse solve: mostly outside that lock), so on two cores the two overlap. Each
path is prepared by the same function as before, on its own data: the operations are the same,
bit for bit, in the same order. At most :data:`LOOKAHEAD` paths wait to be handed out (the memory
stays a few paths'); an error is raised where it was before: a path's when its turn comes, the
reader's after every operation made before it has been handed out.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from threading import Lock

LOOKAHEAD = 4
"""paths prepared or being prepared that may wait to be handed out"""

_worker: ThreadPoolExecutor | None = None
_worker_lock = Lock()


def _pool() -> ThreadPoolExecutor:
    """The process's path worker (one thread: with the reader, two cores' work)."""
    global _worker
    with _worker_lock:
        if _worker is None:
            _worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="cnc-twin-paths")
        return _worker


class PathsAhead:
    """Operations in program order: :meth:`add` one made now, :meth:`prepare` those a function
    will make (a list, in order) in the worker; :meth:`ready` hands out the first ones that are
    made, :meth:`drain` all."""

    def __init__(self, lookahead: int = LOOKAHEAD):
        self.lookahead = lookahead
        self.queue: deque = deque()  # operations, and futures of lists of them
        self.waiting = 0  # futures in the queue
        self.failed = False
        """a path's preparation raised (handed on by :meth:`ready` or :meth:`drain`)"""

    def add(self, operation) -> None:
        self.queue.append(operation)

    def prepare(self, make: Callable[..., list], *args) -> None:
        self.queue.append(_pool().submit(make, *args))
        self.waiting += 1

    def ready(self) -> Iterator:
        """The operations at the front that are made, and while more than :attr:`lookahead`
        paths wait, the first of them (waiting for it)."""
        queue = self.queue
        while queue:
            head = queue[0]
            if isinstance(head, Future):
                if not head.done() and self.waiting <= self.lookahead:
                    return
                yield from self._result(queue.popleft())
            else:
                yield queue.popleft()

    def drain(self) -> Iterator:
        """Every operation left, in order (waiting for those being made)."""
        queue = self.queue
        while queue:
            head = queue.popleft()
            if isinstance(head, Future):
                yield from self._result(head)
            else:
                yield head

    def _result(self, future: Future) -> list:
        self.waiting -= 1
        try:
            return future.result()
        except BaseException:
            self.failed = True
            raise
