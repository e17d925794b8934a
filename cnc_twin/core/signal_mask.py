"""Holding signals back around a few lines that must not be cut in half.

Python runs a signal's handler between two bytecodes of the main thread; a handler that raises
(SystemExit from a sweep worker's SIGTERM, KeyboardInterrupt from the default SIGINT) could
otherwise land between creating a shared-memory segment and taking charge of it, or between
closing its mapping and unlinking it, and leave the segment in /dev/shm. With the signals
blocked for the thread, a signal that comes meanwhile is kept pending by the kernel and handled
as the block ends.
"""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Iterable, Iterator

STOP_SIGNALS = frozenset({signal.SIGINT, signal.SIGTERM})
"""the signals that stop a run or a worker"""


@contextlib.contextmanager
def signals_held(signals: Iterable[int] = STOP_SIGNALS) -> Iterator[None]:
    """Block ``signals`` in this thread for the ``with`` body; they arrive once it ends. A child
    started inside inherits the mask (see :func:`cnc_twin.studies.sweep_stop.sigint_held`)."""
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, set(signals))
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)
