"""Results kept on disk between processes, keyed by everything they are made from: a G-code
program's preparation (:mod:`cnc_twin.scenario.program_cache`), a path's feed plan
(:mod:`cnc_twin.planner.feed`). A second run of the same program, and every run of a sweep of
it, loads them in milliseconds instead of making them again.

A key is a SHA-256 over the code (every module of the package, and the versions of numpy, scipy,
numba and mujoco, whose arithmetic the results depend on) and what the caller names. What is
loaded is exactly what was stored (a pickle), so a run from the cache is the same, bit for bit.

Where: ``KIND`` folders (``programs``, ``plans``) in the folder ``CNC_TWIN_CACHE`` names, else in
``$XDG_CACHE_HOME/cnc-twin`` (by default ``~/.cache/cnc-twin``); ``CNC_TWIN_CACHE=off`` keeps
nothing. The folders are the user's own (made private; a folder someone else owns is not used:
an entry is a pickle, loaded as code is). Entries larger than :data:`MAX_ENTRY_BYTES` are not
kept; past :data:`MAX_BYTES` in a kind the least recently used go. A damaged or unreadable entry
is a miss, made again.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

VARIABLE = "CNC_TWIN_CACHE"
MAX_ENTRY_BYTES = 64 << 20
"""an entry kept only up to this size pickled (a CAM program of some 100 000 lines prepared)"""
MAX_BYTES = 512 << 20
"""a kind's entries' size at most: the least recently used go beyond it"""
_code_digest: str | None = None


def folder(kind: str) -> Path | None:
    """The folder of the entries of ``kind`` (made, private), or None: switched off, or not the
    user's own."""
    named = os.environ.get(VARIABLE, "")
    if named.lower() in ("off", "0", "no", "false"):
        return None
    if named:
        place = Path(named) / kind
    else:
        base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
        place = Path(base) / "cnc-twin" / kind
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


def key(parts: tuple, files: tuple[Path | None, ...]) -> str:
    """The entry's name: SHA-256 (hex) of the code, the pickled ``parts`` (plain values: the
    program's section, axes, home...) and each of ``files`` (path and bytes; None: no file)."""
    digest = hashlib.sha256(code_digest().encode())
    digest.update(pickle.dumps(parts, protocol=4))
    for path in files:
        digest.update(b"\0" if path is None else str(Path(path).resolve()).encode() + b"\0" + Path(path).read_bytes())
    return digest.hexdigest()


def cached(kind: str, name: Callable[[], str], make: Callable[[], tuple[object, bool]]):
    """The object of ``kind`` stored under ``name()`` (its :func:`key`, worked out only when the
    cache is on) if there is one, else the one ``make()`` returns with whether it may be kept,
    stored if so."""
    place = folder(kind)
    if place is None:
        return make()[0]
    entry = place / f"{name()}.pickle"
    found = _load(entry)
    if found is not _MISSING:
        return found
    made, keep = make()
    if keep:
        _store(place, entry, made)
    return made


_MISSING = object()


def load(kind: str, name: str):
    """The object of ``kind`` stored under ``name``, or None (none, or the cache is off)."""
    place = folder(kind)
    found = _MISSING if place is None else _load(place / f"{name}.pickle")
    return None if found is _MISSING else found


def store(kind: str, name: str, value) -> None:
    """Keep ``value`` under ``name`` (nothing if the cache is off)."""
    place = folder(kind)
    if place is not None:
        _store(place, place / f"{name}.pickle", value)


def _load(entry: Path):
    try:
        with open(entry, "rb") as stored:
            found = pickle.load(stored)
        os.utime(entry)  # recently used
        return found
    except FileNotFoundError:
        return _MISSING
    except Exception:  # damaged, cut short, from another version of a library: made again
        entry.unlink(missing_ok=True)
        return _MISSING


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


TRIM_EVERY = 5.0
"""[s] a process trims a folder at most this often (a long program's plans are many small entries:
listing the folder at each would cost more than keeping them)"""
_trimmed: dict[Path, float] = {}


def _trim(place: Path) -> None:
    """The least recently used entries of ``place`` removed beyond :data:`MAX_BYTES`."""
    now = time.monotonic()
    if now - _trimmed.get(place, -TRIM_EVERY) < TRIM_EVERY:
        return
    _trimmed[place] = now
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
