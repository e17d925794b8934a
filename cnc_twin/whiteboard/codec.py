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

Payloads (little-endian; positions in m or rad, absolute machine coordinates):

=====  ===============  =========================================================  ======
type   record           payload                                                    words
=====  ===============  =========================================================  ======
1      Move             end position f64 x6; trapezoid t_acc, t_flat [s],         42
                        v_peak [1/s], accel [1/s^2] f64 x4; periods u32
2      Dwell            periods u32                                                2
3      FeedOverride     fraction f64 (1.0 = programmed feed)                       4
4      ForceSetpoint    force f64 [N]                                              4
5      Spindle          on u16, pad u16, speed f64 [rad/s]                         6
6      EndOfProgram     -                                                          0
7      DataBlock        opaque program data (u16 words), e.g. a 4 KB block         1..2048
8      CurveGeometry    degree u16, n u16, degree2 u16, n2 u16; held A, B, C f64 x3; varies
                        knots f64 x (n + degree + 1); weights f64 x n;
                        control points f64 x 3n (X, Y, Z axis space; or, when n2 > 0,
                        tool-tip positions, world frame); if n2 > 0: pivot f64 x3,
                        tool offset f64 x3, then the tool-axis curve's knots,
                        weights and direction control points; then, optionally, program
                        line marks: (u, line) f64 pairs to the record's end
9      CurveBlock       S-curve block: length, v0, vp, v1, a_max, j_max f64 x6      24
10     SurfaceGeometry  degree_u, degree_v, nu, nv u16 x4; lead, tilt [rad]; pivot,   varies
                        tool offset f64 x3 each; knots_u, knots_v, weights (nu nv),
                        control net f64 x 3 nu nv (world frame, m; row-major in u)
11     SurfaceCurve     degree u16, n u16; knots f64 x (n + degree + 1); weights     varies
                        f64 x n; (u, v) control points f64 x 2n: one path section
                        on the last SurfaceGeometry; its CurveBlocks follow
12     ForceControl     on u16, n u16 (profile points); setpoint, ramp_time,         varies
                        seek_speed, standoff, contact_threshold, kp, ki, max_depth,
                        retract_speed, adapt_threshold, adapt_feed, adapt_hold f64
                        x12; profile (path length [m], force [N]) f64 x 2n
13     StepContour      method, kind, clockwise, pad, dda bits, pad u16 x6; start,   42
                        end, centre (X, Y) i32 x6 [counts from power-on]; the step
                        clock's S-curve: length, v0, vp, v1, a_max, j_max f64 x6
14     Mark             number u32 (0 = none): a program mark the trace records    2
15     ChipCommand      op, axis, profile, pad u16 x4; deltas X Y Z, distance i32 x4 32
                        [counts]; speed, creep [counts/s], accel [counts/s^2],
                        jerk [counts/s^3], time [s] f64 x5
16     GeometryPart     whole record's type, part index, part count, pad u16 x4;   5..2048
                        the part's payload words
=====  ===============  =========================================================  ======

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

from cnc_twin.core.config import AxisCurve, ForceControl, SurfaceDef, UvCurve
from cnc_twin.motion.trapezoid import Trapezoid
from cnc_twin.motion.scurve import SCurve
from cnc_twin.whiteboard.records import (
    MAX_BLOCK_WORDS, ChipCommand, CurveBlock, CurveGeometry, DataBlock, Dwell, EndOfProgram, FeedOverride,
    ForceControlRecord, ForceSetpoint, GeometryPart, Mark, Move, Record, Spindle, StepContour, SurfaceCurve, SurfaceGeometry,
)

SYNC = 0xA5
HEADER_WORDS = 5
TRAILER_WORDS = 1
OVERHEAD_WORDS = HEADER_WORDS + TRAILER_WORDS


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE of ``data`` (check value of b"123456789" is 0x29B1)."""
    return binascii.crc_hqx(data, 0xFFFF)


_MOVE = struct.Struct("<6d4dI")
_DWELL = struct.Struct("<I")
_F64 = struct.Struct("<d")
_SPINDLE = struct.Struct("<HHd")
_HEADER = struct.Struct("<HHHI")

_TYPE_OF = {Move: 1, Dwell: 2, FeedOverride: 3, ForceSetpoint: 4, Spindle: 5, EndOfProgram: 6, DataBlock: 7,
            CurveGeometry: 8, CurveBlock: 9, SurfaceGeometry: 10, SurfaceCurve: 11, ForceControlRecord: 12,
            StepContour: 13, Mark: 14, ChipCommand: 15, GeometryPart: 16}
_CHIP = struct.Struct("<4H4i5d")
_STEP_CONTOUR = struct.Struct("<6H6i6d")
_MARK = struct.Struct("<I")
_CURVE_HEAD = struct.Struct("<HHHH3d")
_CURVE_BLOCK = struct.Struct("<6d")
_PAYLOAD_WORDS = {1: _MOVE.size // 2, 2: _DWELL.size // 2, 3: 4, 4: 4, 5: _SPINDLE.size // 2, 6: 0,
                  9: _CURVE_BLOCK.size // 2, 13: _STEP_CONTOUR.size // 2, 14: _MARK.size // 2,
                  15: _CHIP.size // 2}
_DATA_BLOCK = 7
_CURVE_GEOMETRY = 8
_SURFACE, _SURFACE_CURVE, _FORCE = 10, 11, 12
_GEOMETRY_PART = 16
_VARIABLE = {_DATA_BLOCK, _CURVE_GEOMETRY, _SURFACE, _SURFACE_CURVE, _FORCE, _GEOMETRY_PART}
_PART_HEAD = struct.Struct("<HHHH")
_PART_HEAD_WORDS = _PART_HEAD.size // 2
_SURFACE_HEAD = struct.Struct("<HHHH8d")
_UV_HEAD = struct.Struct("<HH")
_FORCE_HEAD = struct.Struct("<HH12d")
_FORCE_FIELDS = ("setpoint", "ramp_time", "seek_speed", "standoff", "contact_threshold", "kp", "ki", "max_depth",
                 "retract_speed", "adapt_threshold", "adapt_feed", "adapt_hold")
MAX_RECORD_WORDS = OVERHEAD_WORDS + MAX_BLOCK_WORDS
MAX_GEOMETRY_WORDS = 16384
"""the card's geometry memory [16-bit words, 32 KB]: the longest curve or surface payload it joins
from parts (about 800 control points of a 3D curve with weights and knots)"""


class RecordError(ValueError):
    """A record failed a check (sync, length, type, CRC); the DSP rejects it."""


def _payload(record: Record) -> bytes:
    if isinstance(record, Move):
        p = record.profile
        return _MOVE.pack(*record.end, p.t_acc, p.t_flat, p.v_peak, p.accel, record.periods)
    if isinstance(record, Dwell):
        return _DWELL.pack(record.periods)
    if isinstance(record, FeedOverride):
        return _F64.pack(record.fraction)
    if isinstance(record, ForceSetpoint):
        return _F64.pack(record.newtons)
    if isinstance(record, Spindle):
        return _SPINDLE.pack(1 if record.on else 0, 0, record.speed)
    if isinstance(record, EndOfProgram):
        return b""
    if isinstance(record, DataBlock):
        if not 1 <= len(record.words) <= MAX_BLOCK_WORDS:
            raise ValueError(f"a data block holds 1..{MAX_BLOCK_WORDS} words, got {len(record.words)}")
        return np.ascontiguousarray(record.words, dtype="<u2").tobytes()
    if isinstance(record, CurveGeometry):
        n = len(record.control_points)
        parts = [np.asarray(record.knots, "<f8"), np.asarray(record.weights, "<f8"),
                 np.asarray(record.control_points, "<f8").ravel()]
        degree2 = n2 = 0
        if record.axis is not None:
            ac = record.axis
            degree2, n2 = ac.degree, len(ac.control_points)
            parts += [np.asarray(record.pivot, "<f8"), np.asarray(record.offset, "<f8"),
                      np.asarray(ac.knots, "<f8"), np.asarray(ac.weights, "<f8"),
                      np.asarray(ac.control_points, "<f8").ravel()]
        if record.lines:  # after everything else: the count follows from the record's length
            parts.append(np.asarray(record.lines, "<f8").ravel())
        body = _CURVE_HEAD.pack(record.degree, n, degree2, n2, *record.hold) + np.concatenate(parts).tobytes()
        return _checked_size(body, f"curve of {n} control points", MAX_GEOMETRY_WORDS)
    if isinstance(record, CurveBlock):
        p = record.profile
        return _CURVE_BLOCK.pack(p.length, p.v0, p.vp, p.v1, p.a_max, p.j_max)
    if isinstance(record, SurfaceGeometry):
        s = record.surface
        nu, nv = len(s.control_net), len(s.control_net[0])
        body = _SURFACE_HEAD.pack(s.degree_u, s.degree_v, nu, nv, record.lead, record.tilt,
                                  *record.pivot, *record.offset) + np.concatenate([
            np.asarray(s.knots_u, "<f8"), np.asarray(s.knots_v, "<f8"),
            np.asarray(s.weights, "<f8").ravel(), np.asarray(s.control_net, "<f8").ravel()]).tobytes()
        return _checked_size(body, f"surface of {nu} x {nv} control points", MAX_GEOMETRY_WORDS)
    if isinstance(record, SurfaceCurve):
        c = record.curve
        body = _UV_HEAD.pack(c.degree, len(c.control_points)) + np.concatenate([
            np.asarray(c.knots, "<f8"), np.asarray(c.weights, "<f8"),
            np.asarray(c.control_points, "<f8").ravel()]).tobytes()
        return _checked_size(body, f"path section of {len(c.control_points)} control points")
    if isinstance(record, ForceControlRecord):
        f = record.params
        body = _FORCE_HEAD.pack(1 if record.on else 0, len(f.profile), *(getattr(f, k) for k in _FORCE_FIELDS))
        if f.profile:
            body += np.asarray(f.profile, "<f8").ravel().tobytes()
        return _checked_size(body, f"force profile of {len(f.profile)} points")
    if isinstance(record, StepContour):
        p = record.profile
        return _STEP_CONTOUR.pack(record.method, record.kind, 1 if record.clockwise else 0, 0, record.dda_bits, 0,
                                  *record.start, *record.end, *record.center,
                                  p.length, p.v0, p.vp, p.v1, p.a_max, p.j_max)
    if isinstance(record, Mark):
        return _MARK.pack(record.number)
    if isinstance(record, GeometryPart):
        return _PART_HEAD.pack(record.kind, record.index, record.count, 0) + np.ascontiguousarray(
            record.words, dtype="<u2").tobytes()
    if isinstance(record, ChipCommand):
        return _CHIP.pack(record.op, record.axis, record.profile, 0, *record.deltas, record.distance,
                          record.speed, record.creep, record.accel, record.jerk, record.time)
    raise TypeError(f"not a record: {record!r}")


def _checked_size(body: bytes, what: str, limit: int = MAX_BLOCK_WORDS) -> bytes:
    if len(body) // 2 > limit:
        where = "one record" if limit == MAX_BLOCK_WORDS else "the card's geometry memory"
        raise ValueError(f"{what} exceeds {where} ({len(body) // 2} of {limit} words)")
    return body


def payload_words(record: Record) -> int:
    """Length of the record's payload [words]; for a curve or surface, checked against the card's
    geometry memory (ValueError beyond it)."""
    return len(_payload(record)) // 2


def split(record: Record, record_words: int = MAX_RECORD_WORDS) -> list[Record]:
    """``[record]`` when it fits one record of ``record_words`` words (header and CRC included),
    else the GeometryPart records that carry it, in order. Only a CurveGeometry or SurfaceGeometry
    is split; ValueError if it exceeds the card's geometry memory."""
    if not isinstance(record, (CurveGeometry, SurfaceGeometry)):  # the rest are packed once, by encode
        return [record]
    payload = _payload(record)
    capacity = min(record_words, MAX_RECORD_WORDS) - OVERHEAD_WORDS
    if len(payload) // 2 <= capacity:
        return [record]
    words = np.frombuffer(payload, dtype="<u2")
    piece = capacity - _PART_HEAD_WORDS
    if piece < 1:
        raise ValueError(f"records of {record_words} words cannot carry a geometry part")
    count = -(-len(words) // piece)
    if count > 0xFFFF:
        raise ValueError(f"{len(words)} words need more than 65535 parts")
    kind = _TYPE_OF[type(record)]
    return [GeometryPart(kind=kind, index=i, count=count, words=words[i * piece:(i + 1) * piece].copy())
            for i in range(count)]


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
        if part.kind not in (_CURVE_GEOMETRY, _SURFACE):
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
        return _decode_curve(payload) if part.kind == _CURVE_GEOMETRY else _decode_surface(payload)


def encode(record: Record, seq: int) -> np.ndarray:
    """The record's words, shape ``(OVERHEAD_WORDS + n,)``, dtype uint16. ValueError when the
    payload exceeds one record (a long curve or surface goes in parts: :func:`split`)."""
    payload = _payload(record)
    n = len(payload) // 2
    if n > MAX_BLOCK_WORDS:
        raise ValueError(f"{type(record).__name__} of {n} words exceeds one record ({MAX_BLOCK_WORDS} words): "
                         "send it in parts (codec.split)")
    body = _HEADER.pack(SYNC << 8 | _TYPE_OF[type(record)], n, ~n & 0xFFFF, seq & 0xFFFFFFFF) + payload
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
    kind = w0 & 0xFF
    if kind in _VARIABLE:
        if not 1 <= n <= MAX_BLOCK_WORDS:
            raise RecordError(f"variable record of {n} words")
        return OVERHEAD_WORDS + n
    expected = _PAYLOAD_WORDS.get(kind)
    if expected is None:
        raise RecordError(f"unknown record type {kind}")
    if n != expected:
        raise RecordError(f"record type {w0 & 0xFF} has {expected} payload words, header says {n}")
    return OVERHEAD_WORDS + n


def _head(head: struct.Struct, payload: bytes, what: str) -> tuple:
    """The fixed header of a variable record's payload."""
    if len(payload) < head.size:
        raise RecordError(f"{what} record shorter than its header")
    return head.unpack_from(payload)


def _f64s(payload: bytes, offset: int, expected: int, what: str) -> np.ndarray:
    """The float64 values after a variable record's header; exactly ``expected`` of them."""
    values = np.frombuffer(payload, dtype="<f8", offset=offset)
    if len(values) != expected:
        raise RecordError(f"{what} record of {len(values)} values, expected {expected}")
    return values


def _decode_curve(payload: bytes) -> CurveGeometry:
    degree, n, degree2, n2, *hold = _head(_CURVE_HEAD, payload, "curve")
    n_knots, n_knots2 = n + degree + 1, (n2 + degree2 + 1 if n2 else 0)
    expected = n_knots + 4 * n + (6 + n_knots2 + 4 * n2 if n2 else 0)
    values = np.frombuffer(payload, dtype="<f8", offset=_CURVE_HEAD.size)
    extra = len(values) - expected  # program line marks, (u, line) pairs
    if extra < 0 or extra % 2:
        raise RecordError(f"curve record of {len(values)} values, expected {expected} plus (u, line) pairs")

    def take(count: int) -> np.ndarray:
        nonlocal values
        out, values = values[:count], values[count:]
        return out

    knots, weights = tuple(take(n_knots).tolist()), tuple(take(n).tolist())
    points = tuple(tuple(p) for p in take(3 * n).reshape(n, 3).tolist())
    axis, pivot, offset = None, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    if n2:
        pivot, offset = tuple(take(3).tolist()), tuple(take(3).tolist())
        axis = AxisCurve(degree=degree2, knots=tuple(take(n_knots2).tolist()), weights=tuple(take(n2).tolist()),
                         control_points=tuple(tuple(p) for p in take(3 * n2).reshape(n2, 3).tolist()))
    lines = tuple((u, int(line)) for u, line in take(extra).reshape(-1, 2).tolist())
    return CurveGeometry(degree=degree, knots=knots, weights=weights, control_points=points, hold=tuple(hold),
                         axis=axis, pivot=pivot, offset=offset, lines=lines)


def _decode_surface(payload: bytes) -> SurfaceGeometry:
    du, dv, nu, nv, lead, tilt, *geo = _head(_SURFACE_HEAD, payload, "surface")
    ku, kv = nu + du + 1, nv + dv + 1
    values = _f64s(payload, _SURFACE_HEAD.size, ku + kv + 4 * nu * nv, "surface")
    w = values[ku + kv:ku + kv + nu * nv].reshape(nu, nv)
    net = values[ku + kv + nu * nv:].reshape(nu, nv, 3)
    surface = SurfaceDef(degree_u=du, degree_v=dv, knots_u=tuple(values[:ku].tolist()),
                         knots_v=tuple(values[ku:ku + kv].tolist()), weights=tuple(tuple(r) for r in w.tolist()),
                         control_net=tuple(tuple(tuple(p) for p in row) for row in net.tolist()))
    return SurfaceGeometry(surface=surface, lead=lead, tilt=tilt, pivot=tuple(geo[:3]), offset=tuple(geo[3:]))


def _decode_surface_curve(payload: bytes) -> SurfaceCurve:
    degree, n = _head(_UV_HEAD, payload, "path section")
    k = n + degree + 1
    values = _f64s(payload, _UV_HEAD.size, k + 3 * n, "path section")
    return SurfaceCurve(UvCurve(degree=degree, knots=tuple(values[:k].tolist()),
                                weights=tuple(values[k:k + n].tolist()),
                                control_points=tuple(tuple(p) for p in values[k + n:].reshape(n, 2).tolist())))


def _decode_force(payload: bytes) -> ForceControlRecord:
    on, n, *fields = _head(_FORCE_HEAD, payload, "force")
    profile = _f64s(payload, _FORCE_HEAD.size, 2 * n, "force").reshape(n, 2)
    params = ForceControl(profile=tuple(tuple(p) for p in profile.tolist()), **dict(zip(_FORCE_FIELDS, fields)))
    return ForceControlRecord(on=bool(on), params=params)


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
    kind = int(words[0]) & 0xFF
    seq = struct.unpack_from("<I", body, 6)[0]
    payload = body[2 * HEADER_WORDS:]
    if kind == 1:
        v = _MOVE.unpack(payload)
        record: Record = Move(end=tuple(v[:6]), profile=Trapezoid(*v[6:10]), periods=v[10])
    elif kind == 2:
        record = Dwell(periods=_DWELL.unpack(payload)[0])
    elif kind == 3:
        record = FeedOverride(fraction=_F64.unpack(payload)[0])
    elif kind == 4:
        record = ForceSetpoint(newtons=_F64.unpack(payload)[0])
    elif kind == 5:
        on, _pad, speed = _SPINDLE.unpack(payload)
        record = Spindle(on=bool(on), speed=speed)
    elif kind == _DATA_BLOCK:
        record = DataBlock(words=words[HEADER_WORDS:-1])
    elif kind == _CURVE_GEOMETRY:
        record = _decode_curve(bytes(payload))
    elif kind == 9:
        record = CurveBlock(SCurve(*_CURVE_BLOCK.unpack(payload)))
    elif kind == 13:
        v = _STEP_CONTOUR.unpack(payload)
        record = StepContour(method=v[0], kind=v[1], clockwise=bool(v[2]), dda_bits=v[4], start=v[6:8],
                             end=v[8:10], center=v[10:12], profile=SCurve(*v[12:18]))
    elif kind == 14:
        record = Mark(number=_MARK.unpack(payload)[0])
    elif kind == 15:
        v = _CHIP.unpack(payload)
        record = ChipCommand(op=v[0], axis=v[1], profile=v[2], deltas=v[4:7], distance=v[7], speed=v[8], creep=v[9], accel=v[10],
                             jerk=v[11], time=v[12])
    elif kind == _SURFACE:
        record = _decode_surface(bytes(payload))
    elif kind == _SURFACE_CURVE:
        record = _decode_surface_curve(bytes(payload))
    elif kind == _FORCE:
        record = _decode_force(bytes(payload))
    elif kind == _GEOMETRY_PART:
        head, index, count, _pad = _head(_PART_HEAD, payload, "geometry part")
        if not index < count or len(payload) == _PART_HEAD.size:
            raise RecordError(f"geometry part {index} of {count} with {len(payload) // 2 - _PART_HEAD_WORDS} words")
        record = GeometryPart(kind=head, index=index, count=count,
                              words=words[HEADER_WORDS + _PART_HEAD_WORDS:-1].copy())
    else:
        record = EndOfProgram()
    return seq, record
