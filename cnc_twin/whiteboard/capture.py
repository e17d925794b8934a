"""What a PC program wrote to the card, exchange by exchange, kept to be streamed again.

A run whose PC side is someone else's program (``cnc-twin serve``) keeps, for every exchange the
card took, the words that program published into the command FIFO with that answer, the status
period it answered and its ALL_SENT and WAKE_FREE words: the file ``pc_stream.bin`` in the run
directory. ``planner.replay`` (``cnc-twin run --replay``) makes the twin's own planner process
write the same words in answer to the same statuses, so a lockstep run of the same scenario gives
the same trace bit for bit without the PC program: what that program sent, rejected records and
resends included, is what the card gets again.

File (little-endian)::

    magic  b"CNCTPCS1"
    u32    layout words of the whiteboard it was written on
    u32    program length the PC program announced [periods]
    u32    number of exchanges
    then per exchange: u32 answered status period, u16 ALL_SENT, u16 WAKE_FREE, u32 n, n x u16 words
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

MAGIC = b"CNCTPCS1"
BEFORE_FIRST_STATUS = 0xFFFFFFFF
"""the period of an exchange taken before the card had posted any status (words the PC wrote
as it attached)"""
_HEAD = struct.Struct("<8sIII")
_EXCHANGE = struct.Struct("<IHHI")


@dataclass(frozen=True)
class Exchange:
    """One answer of the PC: to the status of ``period``, the FIFO ``words`` it published (uint16,
    possibly none) and the flags it left (ALL_SENT, WAKE_FREE)."""

    period: int
    all_sent: int
    wake_free: int
    words: np.ndarray


@dataclass(frozen=True)
class PcStream:
    """A PC program's whole stream: its exchanges in order, the program length it announced
    [periods] and the whiteboard size it was written for [words]."""

    layout_words: int
    program_periods: int
    exchanges: tuple[Exchange, ...]

    def to_bytes(self) -> bytes:
        parts = [_HEAD.pack(MAGIC, self.layout_words, self.program_periods, len(self.exchanges))]
        for ex in self.exchanges:
            parts.append(_EXCHANGE.pack(ex.period, ex.all_sent, ex.wake_free, len(ex.words)))
            parts.append(np.asarray(ex.words, dtype="<u2").tobytes())
        return b"".join(parts)

    @classmethod
    def from_bytes(cls, data: bytes) -> "PcStream":
        """Parse a stream file's bytes; ValueError saying what is wrong where."""
        if len(data) < _HEAD.size or data[:8] != MAGIC:
            raise ValueError("not a PC stream file (cnc-twin serve's pc_stream.bin)")
        _, words, periods, count = _HEAD.unpack_from(data)
        at, exchanges = _HEAD.size, []
        for i in range(count):
            if at + _EXCHANGE.size > len(data):
                raise ValueError(f"ends inside exchange {i} of {count}")
            period, all_sent, wake_free, n = _EXCHANGE.unpack_from(data, at)
            at += _EXCHANGE.size
            if at + 2 * n > len(data):
                raise ValueError(f"ends inside exchange {i} of {count} ({n} words announced)")
            exchanges.append(Exchange(period, all_sent, wake_free, np.frombuffer(data, "<u2", n, at).copy()))
            at += 2 * n
        if at != len(data):
            raise ValueError(f"{len(data) - at} bytes after the last exchange")
        return cls(words, periods, tuple(exchanges))

    @classmethod
    def read(cls, path: Path) -> "PcStream":
        return cls.from_bytes(Path(path).read_bytes())


class StreamCapture:
    """The card's side: every exchange it took, as it took it (:meth:`~StreamCapture.take` at each FIFO
    snapshot)."""

    def __init__(self):
        self.exchanges: list[Exchange] = []

    def take(self, period: int, all_sent: int, wake_free: int, words: np.ndarray) -> None:
        """Keep one exchange as the card took it (an :class:`Exchange` of these values)."""
        self.exchanges.append(Exchange(period, all_sent, wake_free, words))

    def stream(self, layout_words: int, program_periods: int) -> PcStream:
        return PcStream(layout_words, program_periods, tuple(self.exchanges))
