"""Giving freed memory back to the system (glibc's ``malloc_trim``), and how much the process holds.

A long program's load frees most of what it made (its calls, its operations); the C heap keeps
those pages for the process unless asked to return them, and a run of hours then starts holding
a loading's worth of memory it never uses again (the 250-pass raster: 128 of 506 MB). Elsewhere
than glibc (no ``malloc_trim``) this does nothing.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os

_TRIM = None


def return_freed_memory() -> None:
    """Hand the C heap's free pages back to the system (a no-op where glibc is not the C
    library). No garbage collection: a full one costs 0.1 s with the twin's modules loaded, and
    a long program's reading leaves nothing large in reference cycles (the interpreter lets go of
    the program's text when its reading ends: :meth:`cnc_twin.gcode.flow.Flow.release`)."""
    global _TRIM
    if _TRIM is None:
        try:
            _TRIM = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").malloc_trim
        except (OSError, AttributeError):
            _TRIM = False
    if _TRIM:
        _TRIM(0)


def resident_bytes() -> int | None:
    """The process's resident memory now [bytes] (Linux's ``/proc/self/statm``); None elsewhere."""
    try:
        with open("/proc/self/statm", "rb") as statm:
            return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, IndexError, ValueError, AttributeError):
        return None
