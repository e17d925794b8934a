"""Where a command's time goes: named marks on the machine's monotonic clock, written as they come
to the file the environment variable ``CNC_TWIN_PHASES`` names (nothing otherwise).

The start-up benchmark (:mod:`cnc_twin.studies.bench_startup`) starts ``cnc-twin`` with it set,
notes the monotonic time before it starts the process and after the process ends, and reads the
marks in between: the interpreter's start, the imports, the load, the kernels, the planner, the
run, each file written. ``CLOCK_MONOTONIC`` is one clock for every process of the machine, so the
marks of a child line up with the times its parent took.
"""

from __future__ import annotations

import os
import time

VARIABLE = "CNC_TWIN_PHASES"


def mark(name: str) -> None:
    """Note that the phase ``name`` ended now (a line ``<monotonic seconds> <name>``), if asked to."""
    path = os.environ.get(VARIABLE)  # read each time: a warm server's command takes its client's environment
    if path:
        with open(path, "a", encoding="utf-8") as out:
            out.write(f"{time.monotonic():.6f} {name}\n")


def read_marks(path) -> list[tuple[float, str]]:
    """The marks written to ``path``, in order: ``(monotonic seconds, name)``."""
    marks = []
    with open(path, encoding="utf-8") as lines:
        for line in lines:
            stamp, _, name = line.rstrip("\n").partition(" ")
            marks.append((float(stamp), name))
    return marks
