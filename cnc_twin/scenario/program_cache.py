"""A G-code program prepared once: its conversion (reading, fitting, the machine steps) kept on
disk (:mod:`cnc_twin.core.disk_cache`, kind ``programs``), keyed by everything it is made from,
so that a second run of the same program, and every run of a sweep of it, loads it in
milliseconds instead of preparing it again (the bundled CAM raster: 4408 lines read and fitted in
about three seconds).

The key is a SHA-256 over: the code; the scenario's program section; the axes; the compiled
machine model (MuJoCo's binary form: the head's geometry, the workpiece); where the machine
stands at home; the program file's and the tool table's bytes and paths. A program that opened
subroutine files or probes (read again at run time) is not kept. A run from the cache is the
same, bit for bit (``tests/test_program_cache.py``).
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from pathlib import Path

from cnc_twin.core import disk_cache

VARIABLE = disk_cache.VARIABLE
KIND = "programs"


def model_digest(model) -> str:
    """SHA-256 (hex) of a compiled MuJoCo model, in MuJoCo's binary form."""
    import mujoco
    import numpy as np

    buffer = np.empty(mujoco.mj_sizeModel(model), np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return hashlib.sha256(buffer).hexdigest()


def key(parts: tuple, files: tuple[Path | None, ...]) -> str:
    """An entry's name (:func:`cnc_twin.core.disk_cache.key`)."""
    return disk_cache.key(parts, files)


def cached(name: Callable[[], str], make: Callable[[], tuple[object, bool]]):
    """The prepared program stored under ``name()``, else ``make()``'s (kept if it may be)."""
    return disk_cache.cached(KIND, name, make)


def folder() -> Path | None:
    """Where prepared programs are kept (None: not kept)."""
    return disk_cache.folder(KIND)
