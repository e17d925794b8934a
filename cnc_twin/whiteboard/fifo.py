"""The command FIFO: a ring of 16-bit words in the PC half, written by the PC, read by the DSP.

Indices count words ever written / consumed, modulo 2^32; the ring position is ``index %
capacity``. The writer copies a record's words (wrapping at the ring's end if needed) and only
then publishes the new write index; the reader never reads past the published index, so it never
sees a partly written record. ``free = capacity - (write - read)``.

The reader takes a :meth:`~FifoReader.snapshot` of the write index while the DSP owns the bus
and consumes only up to it, record by record as the card needs them; records the PC writes
afterwards become visible at the next exchange. In lockstep this makes what the DSP sees, and
the fill it reports, independent of process timing.

Who writes what: the PC writes the ring words and ``PC_FIFO_WRITE``; the DSP writes
``DSP_FIFO_READ``.
"""

from __future__ import annotations

import numpy as np

from cnc_twin.whiteboard.codec import HEADER_WORDS, RecordError, record_length

_U32 = 1 << 32


class FifoWriter:
    """PC side.

    Parameters
    ----------
    ring : the FIFO's words, a uint16 view into the whiteboard.
    write_index, read_index : 1-element uint32 views of PC_FIFO_WRITE and DSP_FIFO_READ.
    """

    def __init__(self, ring: np.ndarray, write_index: np.ndarray, read_index: np.ndarray):
        self.ring = ring
        self.capacity = len(ring)
        self._write = write_index
        self._read = read_index

    def free(self) -> int:
        """Words that can be written now."""
        return self.capacity - ((int(self._write[0]) - int(self._read[0])) % _U32)

    def write(self, words: np.ndarray) -> None:
        """Append one or more whole records' words; the caller checked :meth:`free`."""
        n = len(words)
        if n > self.free():
            raise OverflowError(f"{n} words do not fit in {self.free()} free FIFO words")
        index = int(self._write[0])
        pos = index % self.capacity
        first = min(n, self.capacity - pos)
        self.ring[pos:pos + first] = words[:first]
        if first < n:
            self.ring[: n - first] = words[first:]
        self._write[0] = (index + n) % _U32  # published last


class FifoReader:
    """DSP side: pops whole records up to the last snapshot, or flushes after a framing error."""

    def __init__(self, ring: np.ndarray, write_index: np.ndarray, read_index: np.ndarray):
        self.ring = ring
        self.capacity = len(ring)
        self._write = write_index
        self._read = read_index
        self._limit = int(read_index[0])

    def snapshot(self) -> None:
        """Take the published write index as the limit of what may be consumed (DSP owns the bus)."""
        self._limit = int(self._write[0])

    @property
    def limit(self) -> int:
        """The write index of the last snapshot (mod 2^32)."""
        return self._limit

    def published_since(self, limit: int) -> np.ndarray:
        """The words published from write index ``limit`` to the last snapshot (a copy)."""
        n = (self._limit - limit) % _U32
        return self._take(limit % self.capacity, n) if n else np.zeros(0, np.uint16)

    def fill(self) -> int:
        """Words published up to the snapshot and not yet consumed."""
        return (self._limit - int(self._read[0])) % _U32

    def free(self) -> int:
        """Free words as of the snapshot (what the PC's :meth:`FifoWriter.free` was when it answered,
        plus what the card has consumed since)."""
        return self.capacity - self.fill()

    def _take(self, pos: int, n: int) -> np.ndarray:
        end = pos + n
        if end <= self.capacity:
            return self.ring[pos:end].copy()
        return np.concatenate((self.ring[pos:], self.ring[: end - self.capacity]))

    def pop(self) -> np.ndarray | None:
        """The next whole record's words (consumed), or None when nothing is left to the snapshot.

        Raises
        ------
        RecordError
            If a header is malformed or claims more words than were published; the FIFO is
            then flushed to the snapshot so the stream can resynchronise.
        """
        available = self.fill()
        if available == 0:
            return None
        read = int(self._read[0])
        pos = read % self.capacity
        try:
            if available < HEADER_WORDS:
                raise RecordError(f"{available} stray words at the end of the FIFO")
            total = record_length(self._take(pos, 3))
            if total > available:
                raise RecordError(f"record of {total} words, only {available} published")
        except RecordError:
            self.flush()
            raise
        words = self._take(pos, total)
        self._read[0] = (read + total) % _U32
        return words

    def pop_records(self) -> list[np.ndarray]:
        """Every whole record up to the snapshot, consumed (bulk transfers, benchmarks)."""
        out = []
        while (words := self.pop()) is not None:
            out.append(words)
        return out

    def flush(self) -> None:
        """Drop everything published up to the snapshot."""
        self._read[0] = self._limit
