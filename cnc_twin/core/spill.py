"""Arrays a long run needs only at its end, kept on disk meanwhile
(:class:`~cnc_twin.core.spill.StoredArray`): a CAM program's programmed paths (what the run is
measured against when it is over) would otherwise hold 24 bytes per line through the whole run
(120 MB for 5 000 000 lines).

An array of :data:`SPILL_BYTES` or more is written to the process's spill file, an unlinked
temporary file (nothing is left on disk whatever ends the process), and read back whole each
time it is asked for; a smaller one is held as it is. Pickled (a sweep's worker, a copy), a
stored array carries its values: the spill file is this process's alone.
"""

from __future__ import annotations

import os
import tempfile
import threading

import numpy as np

SPILL_BYTES = 1 << 16
"""arrays this large or larger go to the spill file (a short program's stay in memory)"""


class _SpillFile:
    """The process's spill file: arrays appended, read back by their offset."""

    def __init__(self):
        self.file = tempfile.TemporaryFile(prefix="cnc-twin-spill-")
        self.end = 0
        self.lock = threading.Lock()
        self.pid = os.getpid()

    def put(self, array: np.ndarray) -> int:
        data = np.ascontiguousarray(array).view(np.uint8).reshape(-1)
        with self.lock:
            offset = self.end
            written = 0
            while written < len(data):
                written += os.pwrite(self.file.fileno(), data[written:], offset + written)
            self.end += len(data)
        return offset

    def get(self, offset: int, shape: tuple[int, ...], dtype: np.dtype) -> np.ndarray:
        out = np.empty(shape, dtype)
        view = out.view(np.uint8).reshape(-1)
        read = 0
        while read < len(view):
            got = os.preadv(self.file.fileno(), [view[read:]], offset + read)
            if got <= 0:
                raise OSError("the spill file ended early")
            read += got
        return out


_spill: _SpillFile | None = None
_spill_lock = threading.Lock()


def _spill_file() -> _SpillFile:
    """This process's spill file (a forked child makes its own)."""
    global _spill
    with _spill_lock:
        if _spill is None or _spill.pid != os.getpid():
            _spill = _SpillFile()
        return _spill


class StoredArray:
    """An array kept in the spill file when large (else held); :meth:`~StoredArray.array` gives it
    back (read from the file each time, or the held array itself: not to be written into)."""

    __slots__ = ("shape", "dtype", "_held", "_file", "_offset")

    def __init__(self, array: np.ndarray, *, spill_bytes: int = SPILL_BYTES):
        array = np.asarray(array)
        self.shape, self.dtype = array.shape, array.dtype
        self._held: np.ndarray | None = None
        self._file: _SpillFile | None = None
        self._offset = 0
        if array.nbytes >= spill_bytes and array.dtype != object:
            self._file = _spill_file()
            self._offset = self._file.put(array)
        else:
            self._held = array

    @property
    def spilled(self) -> bool:
        return self._file is not None

    def array(self) -> np.ndarray:
        """The array: read from the spill file (a new copy each time) or the held one itself."""
        if self._held is not None:
            return self._held
        assert self._file is not None
        return self._file.get(self._offset, self.shape, self.dtype)

    def __reduce__(self):
        return (_held, (self.array(),))


def _held(array: np.ndarray) -> StoredArray:
    """A stored array unpickled: held in memory in its new process."""
    return StoredArray(array, spill_bytes=np.iinfo(np.int64).max)
