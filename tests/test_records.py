"""Whiteboard records and FIFO: round trips, every single-bit flip caught, wrap-around, framing."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnc_twin.motion.trapezoid import Trapezoid
from cnc_twin.motion.scurve import SCurve
from cnc_twin.whiteboard.codec import MAX_RECORD_WORDS, RecordError, crc16, decode, encode
from cnc_twin.whiteboard.fifo import FifoReader, FifoWriter
from cnc_twin.whiteboard.layout import Layout
from cnc_twin.whiteboard.records import (
    DataBlock, Dwell, EndOfProgram, FeedOverride, ForceSetpoint, Mark, Move, Probe, Spindle, StepContour,
)

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
seqs = st.integers(min_value=0, max_value=2**32 - 1)
i32 = st.integers(-2**31, 2**31 - 1)

moves = st.builds(
    Move,
    end=st.tuples(finite, finite, finite, finite, finite, finite),
    profile=st.builds(Trapezoid, finite, finite, finite, finite),
    periods=st.integers(0, 2**32 - 1),
)
records = st.one_of(
    moves,
    st.builds(Probe, end=st.tuples(finite, finite, finite, finite, finite, finite),
              profile=st.builds(Trapezoid, finite, finite, finite, finite), periods=st.integers(0, 2**32 - 1),
              trip_force=finite, kind=st.sampled_from([2, 3, 4, 5])),
    st.builds(Dwell, periods=st.integers(0, 2**32 - 1)),
    st.builds(FeedOverride, fraction=finite),
    st.builds(ForceSetpoint, newtons=finite),
    st.builds(Spindle, on=st.booleans(), speed=finite),
    st.just(EndOfProgram()),
    st.builds(Mark, number=st.integers(0, 2**32 - 1)),
    st.builds(
        StepContour, method=st.sampled_from([1, 2]), kind=st.sampled_from([1, 2]),
        start=st.tuples(i32, i32), end=st.tuples(i32, i32), center=st.tuples(i32, i32), clockwise=st.booleans(),
        profile=st.builds(lambda length, v: SCurve.plan(length, 0.0, 0.0, v_max=v, a_max=2.0, j_max=50.0),
                          st.floats(1e-6, 1.0), st.floats(1e-3, 0.5)),
        dda_bits=st.integers(0, 30)),
)


def test_crc16_check_value():
    assert crc16(b"123456789") == 0x29B1  # CRC-16/CCITT-FALSE


@given(records, seqs)
def test_encode_decode_round_trip(record, seq):
    words = encode(record, seq)
    assert words.dtype == np.dtype("<u2") and len(words) <= MAX_RECORD_WORDS
    assert decode(words) == (seq, record)


def assert_flip_caught(words: np.ndarray, bit: int) -> None:
    """Flip one bit of an encoded record; decoding must reject it."""
    bad = words.copy()
    bad[bit // 16] ^= np.uint16(1 << (bit % 16))
    with pytest.raises(RecordError):
        decode(bad)


@settings(max_examples=300)
@given(records, seqs, st.data())
def test_every_single_bit_flip_is_caught(record, seq, data):
    words = encode(record, seq)
    assert_flip_caught(words, data.draw(st.integers(0, 16 * len(words) - 1)))


def test_every_bit_of_a_move_record_exhaustively():
    words = encode(Move(end=(0.1, -0.2, 0.0, 0.5, -0.5, math.pi), profile=Trapezoid(0.1, 0.2, 3.0, 30.0),
                        periods=400), 7)
    for bit in range(16 * len(words)):
        assert_flip_caught(words, bit)


def _fifo(capacity: int):
    ring = np.zeros(capacity, dtype="<u2")
    w = np.zeros(1, dtype="<u4")
    r = np.zeros(1, dtype="<u4")
    return FifoWriter(ring, w, r), FifoReader(ring, w, r), w, r


def test_fifo_wraps_around_the_ring_and_keeps_records_whole():
    writer, reader, _, _ = _fifo(100)
    sent = []
    for seq in range(1, 40):
        rec = FeedOverride(fraction=seq / 10)
        words = encode(rec, seq)
        if writer.free() < len(words):
            reader.snapshot()
            got = [decode(w) for w in reader.pop_records()]
            assert got == sent
            sent = []
        writer.write(words)
        sent.append((seq, rec))
    reader.snapshot()
    assert [decode(w) for w in reader.pop_records()] == sent
    assert reader.fill() == 0 and writer.free() == 100


def test_fifo_indices_wrap_at_32_bits():
    writer, reader, w, r = _fifo(64)
    w[0] = r[0] = 2**32 - 5
    words = encode(Dwell(periods=3), 1)
    writer.write(words)
    assert int(w[0]) == (2**32 - 5 + len(words)) % 2**32
    reader.snapshot()
    assert decode(reader.pop_records()[0]) == (1, Dwell(periods=3))


def test_fifo_refuses_to_overfill():
    writer, _, _, _ = _fifo(16)
    with pytest.raises(OverflowError):
        writer.write(encode(Move(end=(0,) * 6, profile=Trapezoid(0, 0, 0, 0), periods=1), 1))


def test_fifo_flushes_on_garbage_so_the_stream_can_resync():
    writer, reader, _, _ = _fifo(128)
    writer.write(np.array([0x1234, 5, 7, 0, 0, 0], dtype="<u2"))  # bad sync byte
    reader.snapshot()
    with pytest.raises(RecordError):
        reader.pop_records()
    assert reader.fill() == 0
    writer.write(encode(EndOfProgram(), 1))
    assert reader.pop() is None  # not visible before the next snapshot (the next exchange)
    reader.snapshot()
    assert decode(reader.pop_records()[0]) == (1, EndOfProgram())


def test_layout_default_map_matches_the_card():
    lay = Layout()
    assert lay.words == 8192 and lay.nbytes == 16384
    assert (lay.mailbox_to_dsp, lay.mailbox_to_pc) == (0x1FFE, 0x1FFF)
    assert lay.fifo_base + lay.fifo_words == 0x1000 == lay.dsp_control
    with pytest.raises(ValueError):
        Layout(words=3000)


blocks = st.builds(lambda xs: DataBlock(words=np.array(xs, dtype="<u2")),
                   st.lists(st.integers(0, 0xFFFF), min_size=1, max_size=300))


@given(blocks, seqs)
def test_data_block_round_trip(block, seq):
    got_seq, got = decode(encode(block, seq))
    assert got_seq == seq and got == block


@settings(max_examples=200)
@given(blocks, seqs, st.data())
def test_every_single_bit_flip_in_a_variable_length_block_is_caught(block, seq, data):
    words = encode(block, seq)
    assert_flip_caught(words, data.draw(st.integers(0, 16 * len(words) - 1)))


def test_data_block_size_limits():
    with pytest.raises(ValueError):
        encode(DataBlock(words=np.zeros(0, dtype="<u2")), 1)
    with pytest.raises(ValueError):
        encode(DataBlock(words=np.zeros(2049, dtype="<u2")), 1)


def test_status_struct_has_the_numpy_layout():
    from cnc_twin.whiteboard.status import STATUS_DTYPE, STATUS_STRUCT

    assert STATUS_STRUCT.size == STATUS_DTYPE.itemsize
    values = (7, 1, 0, 100, 12, 11, 11, 0, 3, 2, 480, 0.007, 0.5, 19.5,
              1.0, 2.0, 3.0, 4.0, 5.0, 6.0, -1, -2, -3, -4, -5, -6, 10, -20, 30, -40, 50, -2048,
              0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 1, 2, 4, 8, 0, 3, 365000, -25000, 0, 0, 0, -7,
              2, 1, 11, 12, 13, -14, 15, 16, 0.25, 0.5, -0.75, 1.0, 1.25, 1.5)
    rec = np.frombuffer(STATUS_STRUCT.pack(*values), dtype=STATUS_DTYPE)[0]
    assert rec["period"] == 7 and rec["queued_periods"] == 480 and rec["pad_force"] == 19.5
    assert list(rec["actual"]) == [-1, -2, -3, -4, -5, -6] and rec["dac"][-1] == -2048
    assert rec["following_error"][5] == 0.6 and rec["command"][0] == 1.0
    assert list(rec["events"]) == [1, 2, 4, 8, 0, 3] and list(rec["index_latch"]) == [365000, -25000, 0, 0, 0, -7]
    assert rec["probes"] == 2 and rec["probe_tripped"] == 1 and list(rec["probe_latch"]) == [11, 12, 13, -14, 15, 16]
    assert list(rec["probe_stop"]) == [0.25, 0.5, -0.75, 1.0, 1.25, 1.5]


def test_curve_records_round_trip_and_every_bit_flip_is_caught():
    from cnc_twin.whiteboard.records import CurveBlock, CurveGeometry

    geometry = CurveGeometry(degree=2, knots=(0, 0, 0, 0.5, 1, 1, 1), weights=(1, 0.7, 1.2, 1),
                             control_points=((0.0, 0.1, -0.2), (0.1, 0.2, -0.2), (0.2, 0.1, -0.2), (0.3, 0.0, -0.2)),
                             hold=(0.1, -0.2, 0.0))
    from cnc_twin.motion.scurve import SCurve

    block = CurveBlock(SCurve(0.05, 0.0, 0.1, 0.02, 2.0, 50.0))
    for record in (geometry, block):
        words = encode(record, 9)
        seq, got = decode(words)
        assert seq == 9
        if isinstance(record, CurveBlock):
            assert got.profile.length == record.profile.length and got.profile.j_max == record.profile.j_max
        else:
            assert got.knots == tuple(map(float, record.knots)) and got.control_points == record.control_points
        for bit in range(0, 16 * len(words), 3):
            assert_flip_caught(words, bit)


def test_curve_geometry_with_a_tool_axis_curve_round_trips():
    from cnc_twin.whiteboard.records import CurveGeometry

    from cnc_twin.core.config import AxisCurve

    axis = AxisCurve(1, (0.0, 0.0, 1.0, 1.0), (1.0, 1.0), ((0.0, 0.0, 1.0), (0.3, -0.2, 1.0)))
    rec = CurveGeometry(degree=1, knots=(0, 0, 1, 1), weights=(1, 1), control_points=((0, 0, 0.1), (0.1, 0, 0.1)),
                        hold=(0.0, 0.0, 0.5), axis=axis, pivot=(0.0, 0.0, 0.6), offset=(0.0, 0.0, -0.25))
    words = encode(rec, 3)
    _, got = decode(words)
    assert got.axis == AxisCurve(1, (0.0, 0.0, 1.0, 1.0), (1.0, 1.0), ((0.0, 0.0, 1.0), (0.3, -0.2, 1.0)))
    assert got.pivot == (0.0, 0.0, 0.6) and got.offset == (0.0, 0.0, -0.25) and got.hold == (0.0, 0.0, 0.5)
    for bit in range(0, 16 * len(words), 5):
        assert_flip_caught(words, bit)


def _long_curve(n: int):
    from cnc_twin.whiteboard.records import CurveGeometry

    points = tuple((1e-4 * i, 1e-3 * math.sin(i / 7), -0.2) for i in range(n))
    knots = (0.0,) * 4 + tuple(float(k) for k in range(1, n - 3)) + (float(n - 3),) * 4
    return CurveGeometry(degree=3, knots=knots, weights=tuple(1.0 + (i % 3) / 10 for i in range(n)),
                         control_points=points, hold=(0.0, 0.1, 0.0))


def test_a_curve_longer_than_one_record_goes_in_parts_and_is_joined_whole():
    from cnc_twin.whiteboard.codec import GeometryJoiner, split
    from cnc_twin.whiteboard.records import GeometryPart

    curve = _long_curve(666)  # the scroll's size: 13 340 payload words
    with pytest.raises(ValueError, match="exceeds one record"):
        encode(curve, 1)
    parts = split(curve, 2048)  # the default chunk per exchange: 2048 words
    assert len(parts) == 7 and all(isinstance(p, GeometryPart) for p in parts)
    joiner = GeometryJoiner()
    got = None
    for seq, part in enumerate(parts, start=5):
        words = encode(part, seq)
        assert len(words) <= 2048
        for bit in range(0, 16 * len(words), 97):
            assert_flip_caught(words, bit)
        assert got is None
        decoded_seq, decoded = decode(words)
        assert decoded_seq == seq and decoded == part
        got = joiner.add(decoded)
        assert joiner.joining == (got is None)
    assert got == curve
    small = _long_curve(20)
    assert split(small) == [small]


def test_geometry_parts_out_of_order_or_beyond_the_cards_memory_are_rejected():
    from cnc_twin.whiteboard.codec import MAX_GEOMETRY_WORDS, GeometryJoiner, payload_words, split

    parts = split(_long_curve(300))
    joiner = GeometryJoiner()
    assert joiner.add(parts[0]) is None
    with pytest.raises(RecordError, match="out of order"):
        joiner.add(parts[2])
    assert joiner.add(parts[1]) is None  # what was joined stays: the resent part goes on from there
    assert joiner.add(parts[2]) == _long_curve(300)
    with pytest.raises(ValueError, match="geometry memory"):
        payload_words(_long_curve(850))
    assert payload_words(_long_curve(800)) <= MAX_GEOMETRY_WORDS
