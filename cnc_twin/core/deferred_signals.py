"""Deferring SIGINT and SIGTERM around a few lines that must not be cut in half.

Python runs a signal's handler in the main thread between two bytecodes; a handler that raises
(``SystemExit`` on a sweep worker's SIGTERM, ``KeyboardInterrupt`` on the default SIGINT) could
otherwise land between creating a shared-memory segment and taking charge of it (seen in CI: a
0-byte segment left between ``shm_open`` and ``ftruncate``), or between closing its mapping and
unlinking it.

Blocking the signal with ``pthread_sigmask`` is not enough: the kernel then hands it to another
thread of the process (numba's, OpenBLAS's), whose C handler still schedules the Python handler
for the main thread. So for the ``with`` body the handlers themselves are swapped for one that
only notes the signal, and the noted signals are raised again, to the real handlers, as it ends.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterable, Iterator

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
"""the signals that stop a run or a worker"""


@contextlib.contextmanager
def signals_deferred(signals: Iterable[int] = STOP_SIGNALS) -> Iterator[None]:
    """Hold back the Python handlers of ``signals`` for the ``with`` body; a signal that came
    meanwhile reaches its handler as the body ends (once per signal number). Outside the main
    thread nothing is swapped: handlers run in the main thread only, so they cannot cut a body
    that runs elsewhere. A signal whose handler Python does not know (set from C) is left as is."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    came: list[int] = []
    previous = {}
    for number in signals:
        handler = signal.getsignal(number)
        if handler is not None:
            previous[number] = signal.signal(number, lambda signum, _frame: came.append(signum))
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
        for number in dict.fromkeys(came):
            signal.raise_signal(number)
