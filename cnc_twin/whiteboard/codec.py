"""The wire format of the command records (:mod:`cnc_twin.whiteboard.records`) in the FIFO.

A record is a header, its payload and a CRC-16 trailer, in 16-bit little-endian words::

    w0        0xA5 << 8 | type          sync byte and record type
    w1        n                         payload length [words]
    w2        ~n & 0xFFFF               length check: a flipped length bit never goes unseen
    w3, w4    seq (u32, low word first) sequence number, +1 per record
    w5 ..     payload (n words)
    w5+n      CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) over the bytes of w0 .. w4+n

CRC-16 detects every single-bit and every burst error of up to 16 bits over the span it covers;
the sync byte, the length check and the fixed payload length of each type make the span itself
certain, so every single-bit flip anywhere in a record is detected.

The payload of each record type, its code and its length: :mod:`cnc_twin.whiteboard.payloads`.

DataBlock, CurveGeometry, GeometryPart and the surface records have variable length: their span is fixed by the
length and its complement (a single flipped bit in either makes them disagree), so the CRC-16 guarantee holds.

A curve or surface whose payload exceeds one record (``MAX_BLOCK_WORDS``) goes in parts
(:func:`split`): consecutive GeometryPart records, each checked by its own CRC, whose payloads
joined are the whole record's payload. The card joins them in sequence order
(:class:`GeometryJoiner`) up to its geometry memory, ``MAX_GEOMETRY_WORDS``, and decodes the whole
record when the last part arrives. Parts are accepted one by one like any record, so a rejected
part is resent from where it failed and the parts already joined stay.
"""

from __future__ import annotations

import binascii
import struct

import numpy as np

from cnc_twin.whiteboard.payloads import (
    BY_CODE, BY_KIND, MAX_GEOMETRY_WORDS, PART_HEAD_WORDS, RecordError, decode_curve, decode_surface,
)
from cnc_twin.whiteboard.records import MAX_BLOCK_WORDS, CurveGeometry, GeometryPart, Record, SurfaceGeometry

__all__ = ["MAX_GEOMETRY_WORDS", "MAX_RECORD_WORDS", "RecordError", "GeometryJoiner", "crc16", "decode", "encode",
           "payload_words", "record_length", "split"]

SYNC = 0xA5
HEADER_WORDS = 5
TRAILER_WORDS = 1
OVERHEAD_WORDS = HEADER_WORDS + TRAILER_WORDS


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE of ``data`` (check value of b"123456789" is 0x29B1)."""
    return binascii.crc_hqx(data, 0xFFFF)


_HEADER = struct.Struct("<HHHI")
MAX_RECORD_WORDS = OVERHEAD_WORDS + MAX_BLOCK_WORDS


def _payload(record: Record) -> bytes:
    entry = BY_KIND.get(type(record))
    if entry is None:
        raise TypeError(f"not a record: {record!r}")
    return entry.encode(record)


def payload_words(record: Record) -> int:
    """Length of the record's payload [words]; for a curve or surface, checked against the card's
    geometry memory (ValueError beyond it)."""
    return len(_payload(record)) // 2


def split(record: Record, record_words: int = MAX_RECORD_WORDS) -> list[Record]:
    """``[record]`` when it fits one record of ``record_words`` words (header and CRC included),
    else the GeometryPart records that carry it, in order. Only a CurveGeometry or SurfaceGeometry
    is split; ValueError if it exceeds the card's geometry memory."""
    if not BY_KIND[type(record)].in_parts:  # the rest are packed once, by encode
        return [record]
    payload = _payload(record)
    capacity = min(record_words, MAX_RECORD_WORDS) - OVERHEAD_WORDS
    if len(payload) // 2 <= capacity:
        return [record]
    words = np.frombuffer(payload, dtype="<u2")
    piece = capacity - PART_HEAD_WORDS
    if piece < 1:
        raise ValueError(f"records of {record_words} words cannot carry a geometry part")
    count = -(-len(words) // piece)
    if count > 0xFFFF:
        raise ValueError(f"{len(words)} words need more than 65535 parts")
    kind = BY_KIND[type(record)].code
    return [GeometryPart(kind=kind, index=i, count=count, words=words[i * piece:(i + 1) * piece].copy())
            for i in range(count)]


_JOINED = {BY_KIND[CurveGeometry].code: decode_curve, BY_KIND[SurfaceGeometry].code: decode_surface}
"""the records that come in parts, by type code: their decoders"""


class GeometryJoiner:
    """The card's side of :func:`split`: joins GeometryPart records in order.

    :meth:`add` returns the whole record when its last part arrives, else None. A part out of
    order, of another record, or one that would overflow ``MAX_GEOMETRY_WORDS`` raises RecordError
    (the card rejects it like a record with a bad CRC) and the parts joined so far stay.
    """

    def __init__(self) -> None:
        self._parts: list[np.ndarray] = []
        self._kind = self._count = 0

    @property
    def joining(self) -> bool:
        """Parts received, the last one not yet."""
        return bool(self._parts)

    def add(self, part: GeometryPart) -> CurveGeometry | SurfaceGeometry | None:
        """Join ``part``: the whole record once it is the last, else None (see the class)."""
        if part.kind not in _JOINED:
            raise RecordError(f"geometry part of record type {part.kind}")
        if part.index != len(self._parts) or (self._parts and (part.kind, part.count) != (self._kind, self._count)):
            raise RecordError(f"geometry part {part.index + 1} of {part.count} out of order "
                              f"({len(self._parts)} of {self._count or part.count} joined)")
        if sum(map(len, self._parts)) + len(part.words) > MAX_GEOMETRY_WORDS:
            raise RecordError(f"geometry beyond the card's memory of {MAX_GEOMETRY_WORDS} words")
        self._parts.append(np.ascontiguousarray(part.words, dtype="<u2"))
        self._kind, self._count = part.kind, part.count
        if len(self._parts) < part.count:
            return None
        payload = np.concatenate(self._parts).tobytes()
        self._parts, self._kind, self._count = [], 0, 0
        return _JOINED[part.kind](payload)


def encode(record: Record, seq: int) -> np.ndarray:
    """The record's words, shape ``(OVERHEAD_WORDS + n,)``, dtype uint16. ValueError when the
    payload exceeds one record (a long curve or surface goes in parts: :func:`split`)."""
    payload = _payload(record)
    n = len(payload) // 2
    if n > MAX_BLOCK_WORDS:
        raise ValueError(f"{type(record).__name__} of {n} words exceeds one record ({MAX_BLOCK_WORDS} words): "
                         "send it in parts (codec.split)")
    body = _HEADER.pack(SYNC << 8 | BY_KIND[type(record)].code, n, ~n & 0xFFFF, seq & 0xFFFFFFFF) + payload
    return np.frombuffer(body + struct.pack("<H", crc16(body)), dtype="<u2").copy()


def record_length(header: np.ndarray) -> int:
    """Total words of the record whose first three words are ``header``; checks sync and length.

    Raises
    ------
    RecordError
        If the sync byte, the type or the length check is wrong.
    """
    w0, n, n_check = int(header[0]), int(header[1]), int(header[2])
    if w0 >> 8 != SYNC:
        raise RecordError(f"bad sync byte 0x{w0 >> 8:02X}")
    if n_check != (~n & 0xFFFF):
        raise RecordError("length check failed")
    entry = BY_CODE.get(w0 & 0xFF)
    if entry is None:
        raise RecordError(f"unknown record type {w0 & 0xFF}")
    if entry.words is None:
        if not 1 <= n <= MAX_BLOCK_WORDS:
            raise RecordError(f"variable record of {n} words")
    elif n != entry.words:
        raise RecordError(f"record type {w0 & 0xFF} has {entry.words} payload words, header says {n}")
    return OVERHEAD_WORDS + n


def decode(words: np.ndarray) -> tuple[int, Record]:
    """``(seq, record)`` from a whole record's words.

    Raises
    ------
    RecordError
        On any failed check; nothing in a rejected record is used.
    """
    if len(words) < OVERHEAD_WORDS:
        raise RecordError("record shorter than its header")
    total = record_length(words[:3])
    if len(words) != total:
        raise RecordError(f"record is {len(words)} words, header says {total}")
    words = np.ascontiguousarray(words, dtype="<u2")
    body = memoryview(words).cast("B")[:-2]  # no copy: the CRC runs over the words in place
    if crc16(body) != int(words[-1]):
        raise RecordError("CRC mismatch")
    entry = BY_CODE[int(words[0]) & 0xFF]
    seq = struct.unpack_from("<I", body, 6)[0]
    payload = body[2 * HEADER_WORDS:]
    return seq, entry.decode(payload if entry.words is not None else bytes(payload), words[HEADER_WORDS:-1])
