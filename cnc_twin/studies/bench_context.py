"""What a benchmark's figures were measured on: kept with them, since a figure without its
machine, date and versions cannot be compared with another.

The documentation's performance page renders the figures the benchmarks write into ``docs/data/``
together with this record (``docs/_ext/bench_figures.py``).
"""

from __future__ import annotations

import os
import platform
from datetime import datetime, timezone
from importlib import metadata
from typing import Any

#: the distributions whose versions a figure depends on (the twin's own and its numeric stack)
MEASURED_WITH = ("cnc-twin", "mujoco", "numpy", "numba", "scipy", "pyarrow", "rerun-sdk")


def _cpu_model() -> str:
    """The processor's name as Linux reports it (``/proc/cpuinfo``), else the platform's."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as info:
            for line in info:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _version(distribution: str) -> str:
    try:
        return metadata.version(distribution)
    except metadata.PackageNotFoundError:
        return "not installed"


def measurement_context(command: list[str]) -> dict[str, Any]:
    """The record kept beside a benchmark's figures, measured by ``command`` (the command line,
    e.g. ``["cnc-twin", "bench", "--repeat", "3"]``): ``date_utc`` (ISO 8601, to the second),
    ``command`` (one string), ``machine`` (``cpu``: the processor's name; ``cores``: the logical
    CPUs this process may use; ``system``: the platform string; ``load_1min``: the load average
    when the figures were written), ``python`` (its version) and
    ``versions`` (distribution -> version, for each of :data:`MEASURED_WITH`)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return {
        "date_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "command": " ".join(command),
        "machine": {"cpu": _cpu_model(), "cores": cores, "system": platform.platform(),
                    # how busy the machine was (other work beside the benchmark slows it)
                    "load_1min": round(os.getloadavg()[0], 2) if hasattr(os, "getloadavg") else None},
        "python": platform.python_version(),
        "versions": {name: _version(name) for name in MEASURED_WITH},
    }
