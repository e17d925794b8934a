"""The payload of each command record (:mod:`cnc_twin.whiteboard.records`) on the wire: one entry
per record type, its code, its encoder and its decoder
(:data:`~cnc_twin.whiteboard.payloads.PAYLOADS`). The framing around a
payload (header, length check, CRC, parts) is :mod:`cnc_twin.whiteboard.codec`'s.

A new record type plugs in here, at one place: its class in ``records``, a :class:`Payload` entry
below with the next free code (and, on the card's side, the item it becomes:
:mod:`cnc_twin.dsp.interpolator`).

Payloads (little-endian; positions in m or rad, absolute machine coordinates):

=====  ===============  ===============================================================  =======
type   record           payload                                                          words
=====  ===============  ===============================================================  =======
1      Move             end position f64 x6; trapezoid t_acc, t_flat [s],                42
                        v_peak [1/s], accel [1/s^2] f64 x4; periods u32
2      Dwell            periods u32                                                      2
3      FeedOverride     fraction f64 (1.0 = programmed feed)                             4
4      ForceSetpoint    force f64 [N]                                                    4
5      Spindle          on u16, pad u16, speed f64 [rad/s]                               6
6      EndOfProgram     -                                                                0
7      DataBlock        opaque program data (u16 words), e.g. a 4 KB block               1..2048
8      CurveGeometry    degree u16, n u16, degree2 u16, n2 u16; held A, B, C f64 x3;     varies
                        knots f64 x (n + degree + 1); weights f64 x n;
                        control points f64 x 3n (X, Y, Z axis space; or, when n2 > 0,
                        tool-tip positions, world frame); if n2 > 0: pivot f64 x3,
                        tool offset f64 x3, then the tool-axis curve's knots,
                        weights and direction control points; then, optionally, program
                        line marks: (u, line) f64 pairs to the record's end
9      CurveBlock       S-curve block: length, v0, vp, v1, a_max, j_max f64 x6           24
10     SurfaceGeometry  degree_u, degree_v, nu, nv u16 x4; lead, tilt [rad]; pivot,      varies
                        tool offset f64 x3 each; knots_u, knots_v, weights (nu nv),
                        control net f64 x 3 nu nv (world frame, m; row-major in u)
11     SurfaceCurve     degree u16, n u16; knots f64 x (n + degree + 1); weights         varies
                        f64 x n; (u, v) control points f64 x 2n: one path section
                        on the last SurfaceGeometry; its CurveBlocks follow
12     ForceControl     on u16, n u16 (profile points); setpoint, ramp_time,             varies
                        seek_speed, standoff, contact_threshold, kp, ki, max_depth,
                        retract_speed, adapt_threshold, adapt_feed, adapt_hold f64
                        x12; profile (path length [m], force [N]) f64 x 2n
13     StepContour      method, kind, clockwise, pad, dda bits, pad u16 x6; start,       42
                        end, centre (X, Y) i32 x6 [counts from power-on]; the step
                        clock's S-curve: length, v0, vp, v1, a_max, j_max f64 x6
14     Mark             number u32 (0 = none): a program mark the trace records          2
15     ChipCommand      op, axis, profile, pad u16 x4; deltas X Y Z, distance i32 x4     32
                        [counts]; speed, creep [counts/s], accel [counts/s^2],
                        jerk [counts/s^3], time [s] f64 x5
16     GeometryPart     whole record's type, part index, part count, pad u16 x4;         5..2048
                        the part's payload words
17     Probe            a Move's payload (end f64 x6, trapezoid f64 x4, periods          48
                        u32), then trip force f64 [N], kind u16 (2 .. 5), pad u16
=====  ===============  ===============================================================  =======

"""

from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from cnc_twin.core.config import AxisCurve, ForceControl, SurfaceDef, UvCurve
from cnc_twin.motion.scurve import SCurve
from cnc_twin.motion.trapezoid import Trapezoid
from cnc_twin.whiteboard.records import (
    MAX_BLOCK_WORDS, ChipCommand, CurveBlock, CurveGeometry, DataBlock, Dwell, EndOfProgram, FeedOverride,
    ForceControlRecord, ForceSetpoint, GeometryPart, Mark, Move, Probe, Record, Spindle, StepContour, SurfaceCurve, SurfaceGeometry,
)

MAX_GEOMETRY_WORDS = 16384
"""the card's geometry memory [16-bit words, 32 KB]: the longest curve or surface payload it joins
from parts (about 800 control points of a 3D curve with weights and knots)"""


class RecordError(ValueError):
    """A record failed a check (sync, length, type, CRC); the DSP rejects it."""


FIELDS = {
    "move": (("end", "d", 6), ("t_acc", "d", 1), ("t_flat", "d", 1), ("v_peak", "d", 1), ("accel", "d", 1),
             ("periods", "I", 1)),
    "probe_tail": (("trip_force", "d", 1), ("kind", "H", 1), ("pad", "H", 1)),
    "dwell": (("periods", "I", 1),),
    "fraction": (("fraction", "d", 1),),
    "newtons": (("newtons", "d", 1),),
    "spindle": (("on", "H", 1), ("pad", "H", 1), ("speed", "d", 1)),
    "chip": (("op", "H", 1), ("axis", "H", 1), ("profile", "H", 1), ("pad", "H", 1), ("deltas", "i", 3),
             ("distance", "i", 1), ("speed", "d", 1), ("creep", "d", 1), ("accel", "d", 1), ("jerk", "d", 1),
             ("time", "d", 1)),
    "step_contour": (("method", "H", 1), ("kind", "H", 1), ("clockwise", "H", 1), ("pad", "H", 1),
                     ("dda_bits", "H", 1), ("pad2", "H", 1), ("start", "i", 2), ("end", "i", 2), ("centre", "i", 2),
                     ("length", "d", 1), ("v0", "d", 1), ("vp", "d", 1), ("v1", "d", 1), ("a_max", "d", 1),
                     ("j_max", "d", 1)),
    "mark": (("number", "I", 1),),
    "curve_head": (("degree", "H", 1), ("n", "H", 1), ("degree2", "H", 1), ("n2", "H", 1), ("held", "d", 3)),
    "curve_block": (("length", "d", 1), ("v0", "d", 1), ("vp", "d", 1), ("v1", "d", 1), ("a_max", "d", 1),
                    ("j_max", "d", 1)),
    "part_head": (("type", "H", 1), ("index", "H", 1), ("count", "H", 1), ("pad", "H", 1)),
}
"""The fixed payloads and payload heads, field by field: ``(name, struct code, count)``, packed
little-endian without padding. The one definition of these layouts: the structs below are built
from it, and so are the client libraries' (``cnc_twin.whiteboard.client_files``)."""


def _struct(name: str) -> struct.Struct:
    return struct.Struct("<" + "".join(f"{count if count > 1 else ''}{code}" for _, code, count in FIELDS[name]))


_MOVE = _struct("move")
_PROBE_TAIL = _struct("probe_tail")
"""what a Probe adds to a Move's payload: trip force, kind, pad"""
_DWELL = _struct("dwell")
_F64 = _struct("fraction")
_SPINDLE = _struct("spindle")
_CHIP = _struct("chip")
_STEP_CONTOUR = _struct("step_contour")
_MARK = _struct("mark")
_CURVE_HEAD = _struct("curve_head")
_CURVE_BLOCK = _struct("curve_block")
PART_HEAD = _struct("part_head")
"""a geometry part's head: the whole record's type, part index, part count, pad"""
PART_HEAD_WORDS = PART_HEAD.size // 2
_SURFACE_HEAD = struct.Struct("<HHHH8d")
_UV_HEAD = struct.Struct("<HH")
_FORCE_HEAD = struct.Struct("<HH12d")
_FORCE_FIELDS = ("setpoint", "ramp_time", "seek_speed", "standoff", "contact_threshold", "kp", "ki", "max_depth",
                 "retract_speed", "adapt_threshold", "adapt_feed", "adapt_hold")


@dataclass(frozen=True)
class Payload:
    """One record type on the wire.

    ``code``: its type byte (header word 0's low byte); ``kind``: the record class; ``encode``:
    record -> payload bytes (ValueError when it cannot be sent); ``decode``: ``(payload bytes,
    payload words (uint16 view))`` -> record (RecordError on a malformed payload); ``words``: the
    fixed payload length [words], or None for a variable one (1 .. MAX_BLOCK_WORDS); ``in_parts``:
    a payload longer than one record may go as GeometryPart records
    (:func:`~cnc_twin.whiteboard.codec.split`).
    """

    code: int
    kind: type
    encode: Callable[[Record], bytes]
    decode: Callable[[bytes, np.ndarray], Record]
    words: int | None
    in_parts: bool = False


def _checked_size(body: bytes, what: str, limit: int = MAX_BLOCK_WORDS) -> bytes:
    if len(body) // 2 > limit:
        where = "one record" if limit == MAX_BLOCK_WORDS else "the card's geometry memory"
        raise ValueError(f"{what} exceeds {where} ({len(body) // 2} of {limit} words)")
    return body


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


def _encode_curve(record: CurveGeometry) -> bytes:
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


def decode_curve(payload: bytes, _words=None) -> CurveGeometry:
    """A CurveGeometry record from its payload bytes (RecordError on a malformed one)."""
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


def _encode_surface(record: SurfaceGeometry) -> bytes:
    s = record.surface
    nu, nv = len(s.control_net), len(s.control_net[0])
    body = _SURFACE_HEAD.pack(s.degree_u, s.degree_v, nu, nv, record.lead, record.tilt,
                              *record.pivot, *record.offset) + np.concatenate([
        np.asarray(s.knots_u, "<f8"), np.asarray(s.knots_v, "<f8"),
        np.asarray(s.weights, "<f8").ravel(), np.asarray(s.control_net, "<f8").ravel()]).tobytes()
    return _checked_size(body, f"surface of {nu} x {nv} control points", MAX_GEOMETRY_WORDS)


def decode_surface(payload: bytes, _words=None) -> SurfaceGeometry:
    """A SurfaceGeometry record from its payload bytes (RecordError on a malformed one)."""
    du, dv, nu, nv, lead, tilt, *geo = _head(_SURFACE_HEAD, payload, "surface")
    ku, kv = nu + du + 1, nv + dv + 1
    values = _f64s(payload, _SURFACE_HEAD.size, ku + kv + 4 * nu * nv, "surface")
    w = values[ku + kv:ku + kv + nu * nv].reshape(nu, nv)
    net = values[ku + kv + nu * nv:].reshape(nu, nv, 3)
    surface = SurfaceDef(degree_u=du, degree_v=dv, knots_u=tuple(values[:ku].tolist()),
                         knots_v=tuple(values[ku:ku + kv].tolist()), weights=tuple(tuple(r) for r in w.tolist()),
                         control_net=tuple(tuple(tuple(p) for p in row) for row in net.tolist()))
    return SurfaceGeometry(surface=surface, lead=lead, tilt=tilt, pivot=tuple(geo[:3]), offset=tuple(geo[3:]))


def _encode_surface_curve(record: SurfaceCurve) -> bytes:
    c = record.curve
    body = _UV_HEAD.pack(c.degree, len(c.control_points)) + np.concatenate([
        np.asarray(c.knots, "<f8"), np.asarray(c.weights, "<f8"),
        np.asarray(c.control_points, "<f8").ravel()]).tobytes()
    return _checked_size(body, f"path section of {len(c.control_points)} control points")


def _decode_surface_curve(payload: bytes, _words=None) -> SurfaceCurve:
    degree, n = _head(_UV_HEAD, payload, "path section")
    k = n + degree + 1
    values = _f64s(payload, _UV_HEAD.size, k + 3 * n, "path section")
    return SurfaceCurve(UvCurve(degree=degree, knots=tuple(values[:k].tolist()),
                                weights=tuple(values[k:k + n].tolist()),
                                control_points=tuple(tuple(p) for p in values[k + n:].reshape(n, 2).tolist())))


def _encode_force(record: ForceControlRecord) -> bytes:
    f = record.params
    body = _FORCE_HEAD.pack(1 if record.on else 0, len(f.profile), *(getattr(f, k) for k in _FORCE_FIELDS))
    if f.profile:
        body += np.asarray(f.profile, "<f8").ravel().tobytes()
    return _checked_size(body, f"force profile of {len(f.profile)} points")


def _decode_force(payload: bytes, _words=None) -> ForceControlRecord:
    on, n, *fields = _head(_FORCE_HEAD, payload, "force")
    profile = _f64s(payload, _FORCE_HEAD.size, 2 * n, "force").reshape(n, 2)
    params = ForceControl(profile=tuple(tuple(p) for p in profile.tolist()), **dict(zip(_FORCE_FIELDS, fields)))
    return ForceControlRecord(on=bool(on), params=params)


def _encode_data(record: DataBlock) -> bytes:
    if not 1 <= len(record.words) <= MAX_BLOCK_WORDS:
        raise ValueError(f"a data block holds 1..{MAX_BLOCK_WORDS} words, got {len(record.words)}")
    return np.ascontiguousarray(record.words, dtype="<u2").tobytes()


def _encode_move(record: Move) -> bytes:
    p = record.profile
    return _MOVE.pack(*record.end, p.t_acc, p.t_flat, p.v_peak, p.accel, record.periods)


def _decode_move(payload: bytes, _words) -> Move:
    v = _MOVE.unpack(payload)
    return Move(end=tuple(v[:6]), profile=Trapezoid(*v[6:10]), periods=v[10])


def _encode_probe(record: Probe) -> bytes:
    return _encode_move(record) + _PROBE_TAIL.pack(record.trip_force, record.kind, 0)


def _decode_probe(payload: bytes, _words) -> Probe:
    move = _decode_move(payload[:_MOVE.size], None)
    trip_force, kind, _ = _PROBE_TAIL.unpack(payload[_MOVE.size:])
    return Probe(end=move.end, profile=move.profile, periods=move.periods, trip_force=trip_force, kind=kind)


def _encode_step_contour(record: StepContour) -> bytes:
    p = record.profile
    return _STEP_CONTOUR.pack(record.method, record.kind, 1 if record.clockwise else 0, 0, record.dda_bits, 0,
                              *record.start, *record.end, *record.center, p.length, p.v0, p.vp, p.v1, p.a_max, p.j_max)


def _decode_step_contour(payload: bytes, _words) -> StepContour:
    v = _STEP_CONTOUR.unpack(payload)
    return StepContour(method=v[0], kind=v[1], clockwise=bool(v[2]), dda_bits=v[4], start=v[6:8], end=v[8:10],
                       center=v[10:12], profile=SCurve(*v[12:18]))


def _encode_chip(record: ChipCommand) -> bytes:
    return _CHIP.pack(record.op, record.axis, record.profile, 0, *record.deltas, record.distance, record.speed,
                      record.creep, record.accel, record.jerk, record.time)


def _decode_chip(payload: bytes, _words) -> ChipCommand:
    v = _CHIP.unpack(payload)
    return ChipCommand(op=v[0], axis=v[1], profile=v[2], deltas=v[4:7], distance=v[7], speed=v[8], creep=v[9],
                       accel=v[10], jerk=v[11], time=v[12])


def _encode_part(record: GeometryPart) -> bytes:
    return PART_HEAD.pack(record.kind, record.index, record.count, 0) + np.ascontiguousarray(
        record.words, dtype="<u2").tobytes()


def _decode_part(payload: bytes, words: np.ndarray) -> GeometryPart:
    head, index, count, _pad = _head(PART_HEAD, payload, "geometry part")
    if not index < count or len(payload) == PART_HEAD.size:
        raise RecordError(f"geometry part {index} of {count} with {len(payload) // 2 - PART_HEAD_WORDS} words")
    return GeometryPart(kind=head, index=index, count=count, words=words[PART_HEAD_WORDS:].copy())


def _decode_spindle(payload: bytes, _words) -> Spindle:
    on, _pad, speed = _SPINDLE.unpack(payload)
    return Spindle(on=bool(on), speed=speed)


PAYLOADS = (
    Payload(1, Move, _encode_move, _decode_move, _MOVE.size // 2),
    Payload(2, Dwell, lambda r: _DWELL.pack(r.periods), lambda p, _: Dwell(periods=_DWELL.unpack(p)[0]),
            _DWELL.size // 2),
    Payload(3, FeedOverride, lambda r: _F64.pack(r.fraction), lambda p, _: FeedOverride(fraction=_F64.unpack(p)[0]), 4),
    Payload(4, ForceSetpoint, lambda r: _F64.pack(r.newtons), lambda p, _: ForceSetpoint(newtons=_F64.unpack(p)[0]),
            4),
    Payload(5, Spindle, lambda r: _SPINDLE.pack(1 if r.on else 0, 0, r.speed), _decode_spindle, _SPINDLE.size // 2),
    Payload(6, EndOfProgram, lambda r: b"", lambda p, _: EndOfProgram(), 0),
    Payload(7, DataBlock, _encode_data, lambda p, words: DataBlock(words=words), None),
    Payload(8, CurveGeometry, _encode_curve, decode_curve, None, in_parts=True),
    Payload(9, CurveBlock, lambda r: _CURVE_BLOCK.pack(r.profile.length, r.profile.v0, r.profile.vp, r.profile.v1,
                                                       r.profile.a_max, r.profile.j_max),
            lambda p, _: CurveBlock(SCurve(*_CURVE_BLOCK.unpack(p))), _CURVE_BLOCK.size // 2),
    Payload(10, SurfaceGeometry, _encode_surface, decode_surface, None, in_parts=True),
    Payload(11, SurfaceCurve, _encode_surface_curve, _decode_surface_curve, None),
    Payload(12, ForceControlRecord, _encode_force, _decode_force, None),
    Payload(13, StepContour, _encode_step_contour, _decode_step_contour, _STEP_CONTOUR.size // 2),
    Payload(14, Mark, lambda r: _MARK.pack(r.number), lambda p, _: Mark(number=_MARK.unpack(p)[0]), _MARK.size // 2),
    Payload(15, ChipCommand, _encode_chip, _decode_chip, _CHIP.size // 2),
    Payload(16, GeometryPart, _encode_part, _decode_part, None),
    Payload(17, Probe, _encode_probe, _decode_probe, (_MOVE.size + _PROBE_TAIL.size) // 2),
)
"""every record type on the wire, by code"""
BY_KIND = {p.kind: p for p in PAYLOADS}
"""the entry of a record's class"""
BY_CODE = {p.code: p for p in PAYLOADS}
"""the entry of a type code"""
