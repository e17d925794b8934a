"""A G-code program prepared once: its conversion (reading, fitting, the machine steps) kept on
disk, keyed by everything it is made from, so that a second run of the same program, and every
run of a sweep of it, loads it in milliseconds instead of preparing it again (the bundled CAM
raster: 4408 lines read and fitted in about three seconds).

The key is a SHA-256 over: the code (every module of the package, and the versions of numpy,
scipy, numba and mujoco, whose arithmetic the preparation uses); the scenario's program section;
the axes; the compiled machine model (MuJoCo's binary form: the head's geometry, the workpiece);
where the machine stands at home; the program file's and the tool table's bytes and paths. A
program that opened subroutine files or probes (read again at run time) is not kept. What is
loaded is exactly what was stored (a pickle), so a run from the cache is the same, bit for bit
(``tests/test_program_cache.py``).

Where: the folder ``CNC_TWIN_CACHE`` names, else ``$XDG_CACHE_HOME/cnc-twin/programs`` (by default
``~/.cache/cnc-twin/programs``); ``CNC_TWIN_CACHE=off`` keeps nothing. The folder is the user's
own (made private; a folder someone else owns is not used: an entry is a pickle, loaded as code
is). Entries larger than :data:`MAX_ENTRY_BYTES` are not kept; past :data:`MAX_BYTES` in all the
least recently used go. A damaged or unreadable entry is a miss, made again.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import tempfile
from collections.abc import Callable
from pathlib import Path

VARIABLE = "CNC_TWIN_CACHE"
MAX_ENTRY_BYTES = 64 << 20
"""a prepared program kept only up to this size pickled (a CAM program of some 100 000 lines)"""
MAX_BYTES = 512 << 20
"""the cache's size at most: the least recently used entries go beyond it"""
_code_digest: str | None = None


def folder() -> Path | None:
    """The cache's folder (made, private), or None: switched off, or not the user's own."""
    named = os.environ.get(VARIABLE, "")
    if named.lower() in ("off", "0", "no", "false"):
        return None
    if named:
        place = Path(named)
    else:
        base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
        place = Path(base) / "cnc-twin" / "programs"
    try:
        place.mkdir(parents=True, exist_ok=True, mode=0o700)
        if place.stat().st_uid != os.getuid():
            return None
    except OSError:
        return None
    return place


def code_digest() -> str:
    """SHA-256 (hex) of the package's modules and the versions of the libraries a preparation's
    figures depend on (once per process)."""
    global _code_digest
    if _code_digest is None:
        from importlib.metadata import version

        digest = hashlib.sha256()
        package = Path(__file__).resolve().parents[1]
        for module in sorted(package.rglob("*.py")):
            digest.update(str(module.relative_to(package)).encode())
            digest.update(module.read_bytes())
        for name in ("numpy", "scipy", "numba", "mujoco"):
            digest.update(f"{name} {version(name)}".encode())
        _code_digest = digest.hexdigest()
    return _code_digest


def model_digest(model) -> str:
    """SHA-256 (hex) of a compiled MuJoCo model, in MuJoCo's binary form."""
    import mujoco
    import numpy as np

    buffer = np.empty(mujoco.mj_sizeModel(model), np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return hashlib.sha256(buffer).hexdigest()


def key(parts: tuple, files: tuple[Path | None, ...]) -> str:
    """The entry's name: SHA-256 (hex) of the code, the pickled ``parts`` (plain values: the
    program's section, axes, home...) and each of ``files`` (path and bytes; None: no file)."""
    digest = hashlib.sha256(code_digest().encode())
    digest.update(pickle.dumps(parts, protocol=4))
    for path in files:
        digest.update(b"\0" if path is None else str(Path(path).resolve()).encode() + b"\0" + Path(path).read_bytes())
    return digest.hexdigest()


def cached(name: Callable[[], str], make: Callable[[], tuple[object, bool]]):
    """The object stored under ``name()`` (its :func:`key`, worked out only when the cache is on)
    if there is one, else the one ``make()`` returns with whether it may be kept, stored if so."""
    place = folder()
    if place is None:
        return make()[0]
    entry = place / f"{name()}.pickle"
    try:
        with open(entry, "rb") as stored:
            found = pickle.load(stored)
        os.utime(entry)  # recently used
        return found
    except FileNotFoundError:
        pass
    except Exception:  # damaged, cut short, from another version of a library: made again
        entry.unlink(missing_ok=True)
    made, keep = make()
    if keep:
        _store(place, entry, made)
    return made


def _store(place: Path, entry: Path, value) -> None:
    """``value`` pickled into ``entry`` (written aside, then renamed: a reader never sees half of
    it), unless too large; then the cache trimmed to :data:`MAX_BYTES`. A cache that cannot be
    written is no failure of the load."""
    try:
        data = pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception:  # something in it does not pickle: not kept
        return
    if len(data) > MAX_ENTRY_BYTES:
        return
    try:
        handle, staged = tempfile.mkstemp(dir=place, prefix=".entry-")
        with os.fdopen(handle, "wb") as out:
            out.write(data)
        os.replace(staged, entry)
        _trim(place)
    except OSError:
        return


def _trim(place: Path) -> None:
    entries = []
    for path in place.glob("*.pickle"):
        try:
            status = path.stat()
        except OSError:
            continue
        entries.append((status.st_mtime, status.st_size, path))
    total = sum(size for _, size, _ in entries)
    for _, size, path in sorted(entries):
        if total <= MAX_BYTES:
            break
        path.unlink(missing_ok=True)
        total -= size
