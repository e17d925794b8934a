"""Keeping numba's on-disk cache honest across modules.

numba's ``cache=True`` checks only the source file of the kernel it compiled: when a kernel calls
a compiled function of another module (the period batch calls the curve stepper and the servo
ticks), a change there leaves the caller's cached machine code in use, silently running the old
code. :func:`purge_stale` keeps a fingerprint of those other modules' sources beside the cache and
removes the caller's cached kernels when it changes, before any of them is loaded.
"""

from __future__ import annotations

import hashlib
from pathlib import Path


def fingerprint(files: list[str | Path]) -> str:
    """SHA-256 over the files' names and bytes, hex."""
    digest = hashlib.sha256()
    for file in files:
        path = Path(file)
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def purge_stale(module_file: str | Path, dependencies: list[str | Path]) -> bool:
    """Remove the numba cache files of ``module_file``'s kernels (``__pycache__/<stem>.*.nbi|nbc``)
    if the sources of ``dependencies`` changed since they were cached; record the new fingerprint.
    Returns True if anything was removed. A cache folder that cannot be written is left alone
    (numba then caches elsewhere or not at all)."""
    module = Path(module_file)
    cache = module.parent / "__pycache__"
    stamp = cache / f"{module.stem}.deps"
    current = fingerprint(dependencies)
    try:
        if stamp.read_text() == current:
            return False
    except OSError:
        pass
    removed = False
    try:
        for cached in list(cache.glob(f"{module.stem}.*.nbi")) + list(cache.glob(f"{module.stem}.*.nbc")):
            cached.unlink()
            removed = True
        cache.mkdir(exist_ok=True)
        stamp.write_text(current)
    except OSError:
        pass
    return removed
