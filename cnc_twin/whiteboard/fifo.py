"""The command FIFO: a ring of 16-bit words in the PC half, written by the PC, read by the DSP.

Indices count words ever written / consumed, modulo 2^32; the ring position is ``index %
capacity``. The writer copies a record's words (wrapping at the ring's end if needed) and only
then publishes the new write index; the reader never reads past the published index, so it never
sees a partly written record. ``fill = write - read``; ``free = capacity - fill``.

Who writes what: the PC writes the ring words and ``PC_FIFO_WRITE``; the DSP writes
``DSP_FIFO_READ``.
"""

from __future__ import annotations

import numpy as np

from cnc_twin.whiteboard.records import HEADER_WORDS, RecordError, record_length

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
    """DSP side: pops whole records' words, or flushes everything after a framing error."""

    def __init__(self, ring: np.ndarray, write_index: np.ndarray, read_index: np.ndarray):
        self.ring = ring
        self.capacity = len(ring)
        self._write = write_index
        self._read = read_index

    def fill(self) -> int:
        """Words written and not yet consumed."""
        return (int(self._write[0]) - int(self._read[0])) % _U32

    def _take(self, pos: int, n: int) -> np.ndarray:
        end = pos + n
        if end <= self.capacity:
            return self.ring[pos:end].copy()
        return np.concatenate((self.ring[pos:], self.ring[: end - self.capacity]))

    def pop_records(self) -> list[np.ndarray]:
        """Every whole record published so far, as word arrays, consuming them.

        Raises
        ------
        RecordError
            If a header is malformed or claims more words than were published; the FIFO is
            then flushed (everything published is consumed) so the stream can resynchronise.
        """
        out = []
        read = int(self._read[0])
        available = self.fill()
        while available >= HEADER_WORDS:
            pos = read % self.capacity
            try:
                total = record_length(self._take(pos, 3))
                if total > available:
                    raise RecordError(f"record of {total} words, only {available} published")
            except RecordError:
                self.flush()
                raise
            out.append(self._take(pos, total))
            read = (read + total) % _U32
            available -= total
            self._read[0] = read
        if available:
            self.flush()
            raise RecordError(f"{available} stray words at the end of the FIFO")
        return out

    def flush(self) -> None:
        """Drop everything published so far."""
        self._read[0] = int(self._write[0])
