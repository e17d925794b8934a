"""A monotonic clock for compiled (numba) kernels: libc's ``clock_gettime(CLOCK_MONOTONIC)``.

The same clock as ``time.perf_counter_ns()`` on Linux, about 30 ns per call, so a kernel can time
a part of its work (the interpolation inside a batch of periods) the way the Python task times
it. :data:`AVAILABLE` is False where libc or the symbol cannot be found; :func:`monotonic_ns`
then returns 0 and callers keep no samples.
"""

from __future__ import annotations

import ctypes.util

import numpy as np
from numba import njit, types

CLOCK_MONOTONIC = 1
"""Linux's clock id"""

#: whether libc's ``clock_gettime`` was found (else :func:`monotonic_ns` returns 0)
AVAILABLE = False
try:
    import llvmlite.binding as _llvm

    _libc = ctypes.util.find_library("c")
    if _libc is not None:
        _llvm.load_library_permanently(_libc)
        AVAILABLE = _llvm.address_of_symbol("clock_gettime") is not None
except (ImportError, RuntimeError, OSError):  # pragma: no cover - llvmlite is numba's dependency
    AVAILABLE = False

if AVAILABLE:
    _clock_gettime = types.ExternalFunction("clock_gettime", types.int32(types.int32, types.voidptr))

    @njit(cache=True)
    def monotonic_ns(timespec):  # pragma: no cover - compiled
        """Nanoseconds of ``CLOCK_MONOTONIC``; ``timespec``: int64 work array of 2."""
        _clock_gettime(CLOCK_MONOTONIC, timespec.ctypes.data)
        return timespec[0] * 1_000_000_000 + timespec[1]
else:  # pragma: no cover
    @njit(cache=True)
    def monotonic_ns(timespec):
        return 0


def timespec() -> np.ndarray:
    """A work array for :func:`monotonic_ns`."""
    return np.zeros(2, dtype=np.int64)
