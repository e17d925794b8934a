"""The PC side of the cnc-twin card, for your own PC program: attach, stream records, read status.

Written against the documented protocol only (docs/pc-software.md): it imports nothing of the
twin. Addresses, codes and payload layouts come from ``cnct_layout.py`` beside it, generated from
the twin's own layout definition. Copy both files into your project, or put this folder on
``sys.path``. Python 3.9+, standard library only.

A session, against ``cnc-twin serve SCENARIO`` (which prints ``attach: FOLDER``)::

    from cnct_client import Card, Streamer, move, end_of_program

    with Card(folder) as card:
        stream = Streamer(card)
        stream.add(move(end=(0.01, 0, 0, 0, 0, 0), t_acc=0.1, t_flat=0.2, v_peak=2.5, accel=25.0, periods=80))
        stream.add(end_of_program())
        stream.complete = True
        card.attach(program_periods=80)
        last = stream.run()        # answers every status until the card finishes or faults
        print(last["state"], last["fault"])

Units: positions in m (linear axes) or rad (rotary), absolute machine coordinates, axis order
X Y Z A B C; times in s; durations of motion in interpolation periods.
"""

from __future__ import annotations

import binascii
import mmap
import os
import select
import struct
import time
from dataclasses import dataclass, field
from pathlib import Path

import cnct_layout as W

WAKE_INTERVAL = 0.002
"""[s] the longest a waiting PC sleeps before it advances its heartbeat and looks again"""
_U32 = 1 << 32


class CardGone(RuntimeError):
    """The card's side ended (the twin's process exited) while this PC program waited for it."""


# --- records ---------------------------------------------------------------------------------

def _format(name: str) -> struct.Struct:
    fields = W.PAYLOAD_FIELDS[name]
    return struct.Struct("<" + "".join(f"{count if count > 1 else ''}{code}" for _, code, count in fields))


_MOVE, _PROBE_TAIL, _DWELL = _format("move"), _format("probe_tail"), _format("dwell")
_FRACTION, _NEWTONS, _SPINDLE, _MARK = _format("fraction"), _format("newtons"), _format("spindle"), _format("mark")
_CURVE_HEAD, _CURVE_BLOCK, _PART_HEAD = _format("curve_head"), _format("curve_block"), _format("part_head")
_HEADER = struct.Struct("<HHHI")


@dataclass(frozen=True)
class Record:
    """One command record before it is numbered: its type code, payload bytes and the motion it
    holds [interpolation periods] (what the look-ahead counts; 0 for records without motion)."""

    type: int
    payload: bytes
    periods: int = 0
    in_parts: bool = False
    """a curve or surface, sent as GeometryPart records when longer than one record or chunk"""


def move(end, t_acc: float, t_flat: float, v_peak: float, accel: float, periods: int) -> Record:
    """A synchronised move to ``end`` (6 axes) along a normalised trapezoid s: 0 -> 1: accelerate
    at ``accel`` [1/s^2] for ``t_acc`` [s], cruise at ``v_peak`` [1/s] for ``t_flat`` [s],
    decelerate for ``t_acc``; ``periods`` interpolation periods long in all."""
    return Record(W.TYPE_MOVE, _MOVE.pack(*end, t_acc, t_flat, v_peak, accel, periods), periods)


def dwell(periods: int) -> Record:
    return Record(W.TYPE_DWELL, _DWELL.pack(periods), periods)


def feed_override(fraction: float) -> Record:
    """Scale the programmed feed (1.0 = as programmed)."""
    return Record(W.TYPE_FEED_OVERRIDE, _FRACTION.pack(fraction))


def force_setpoint(newtons: float) -> Record:
    return Record(W.TYPE_FORCE_SETPOINT, _NEWTONS.pack(newtons))


def spindle(on: bool, speed: float) -> Record:
    """The polishing spindle on or off, at ``speed`` [rad/s]."""
    return Record(W.TYPE_SPINDLE, _SPINDLE.pack(1 if on else 0, 0, speed))


def mark(number: int) -> Record:
    """A program mark the card's trace records (0 = none)."""
    return Record(W.TYPE_MARK, _MARK.pack(number))


def end_of_program() -> Record:
    return Record(W.TYPE_END_OF_PROGRAM, b"")


def curve_geometry(degree: int, knots, weights, points, held=(0.0, 0.0, 0.0)) -> Record:
    """A NURBS path in axis space for the CurveBlock records that follow: ``points`` (n x 3, X Y Z
    [m]), ``weights`` (n), ``knots`` (n + degree + 1); A, B, C held at ``held`` [rad]."""
    points = [tuple(map(float, p)) for p in points]
    n = len(points)
    if len(weights) != n or len(knots) != n + degree + 1:
        raise ValueError(f"a curve of {n} points needs {n} weights and {n + degree + 1} knots")
    values = [*map(float, knots), *map(float, weights), *(c for p in points for c in p)]
    payload = _CURVE_HEAD.pack(degree, n, 0, 0, *held) + struct.pack(f"<{len(values)}d", *values)
    if len(payload) // 2 > W.MAX_GEOMETRY_WORDS:
        raise ValueError(f"a curve of {len(payload) // 2} words is more than the card's geometry memory")
    return Record(W.TYPE_CURVE_GEOMETRY, payload, 0, in_parts=True)


def curve_block(length: float, v0: float, vp: float, v1: float, a_max: float, j_max: float, periods: int) -> Record:
    """One S-curve block along the last curve: ``length`` [m] from speed ``v0`` through at most
    ``vp`` to ``v1`` [m/s], within ``a_max`` [m/s^2] and ``j_max`` [m/s^3]; ``periods``: how long
    the card takes for it (what the look-ahead counts)."""
    return Record(W.TYPE_CURVE_BLOCK, _CURVE_BLOCK.pack(length, v0, vp, v1, a_max, j_max), periods)


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF): b"123456789" gives 0x29B1."""
    return binascii.crc_hqx(data, 0xFFFF)


def encode(record_type: int, payload: bytes, seq: int) -> bytes:
    """A record on the wire: header (sync and type, length, its complement, sequence), payload, CRC."""
    n = len(payload) // 2
    body = _HEADER.pack(W.SYNC << 8 | record_type, n, ~n & 0xFFFF, seq & 0xFFFFFFFF) + payload
    return body + struct.pack("<H", crc16(body))


def parts(record: Record, record_words: int) -> list[tuple[int, bytes]]:
    """``(type, payload)`` of each record that carries ``record``: itself when it fits one record of
    ``record_words`` words (header and CRC included), else GeometryPart records in order."""
    capacity = min(record_words, W.HEADER_WORDS + W.TRAILER_WORDS + W.MAX_PAYLOAD_WORDS) \
        - W.HEADER_WORDS - W.TRAILER_WORDS
    if not record.in_parts or len(record.payload) // 2 <= capacity:
        return [(record.type, record.payload)]
    step = 2 * (capacity - W.PART_HEAD_WORDS)
    pieces = [record.payload[i:i + step] for i in range(0, len(record.payload), step)]
    return [(W.TYPE_GEOMETRY_PART, _PART_HEAD.pack(record.type, i, len(pieces), 0) + piece)
            for i, piece in enumerate(pieces)]


# --- the whiteboard --------------------------------------------------------------------------

class Card:
    """The card's whiteboard, opened from the attach folder ``cnc-twin serve`` printed.

    Maps the shared memory (``folder/whiteboard``) and opens the two doorbells (``to_pc``, read;
    ``to_dsp``, write), waiting up to ``timeout`` [s] for the folder to be made (a PC program may
    start together with ``cnc-twin serve``). Nothing is written before :meth:`attach`.

    ``spin_polls``: mailbox polls before sleeping on the doorbell. None by default: the PC answers
    status k while the card runs period k, so it has a whole period, and a spinning PC takes a
    core from the card; a PC that must answer within microseconds spins (a few hundred polls).
    """

    def __init__(self, folder, *, timeout: float = 30.0, spin_polls: int = 0):
        folder = Path(folder)
        deadline = time.monotonic() + timeout
        while not (folder / "to_pc").exists():  # made last: the folder is whole once it is there
            if time.monotonic() > deadline:
                raise FileNotFoundError(f"{folder}: no attach folder of a served run within {timeout:g} s")
            time.sleep(0.05)
        fd = os.open(folder / "whiteboard", os.O_RDWR)
        try:
            self.memory = mmap.mmap(fd, 0)
        finally:
            os.close(fd)
        self.words = len(self.memory) // 2
        self.area = W.areas(self.words)
        self.word = memoryview(self.memory).cast("H")
        self._wake = os.open(folder / "to_pc", os.O_RDONLY | os.O_NONBLOCK)
        self._ring = os.open(folder / "to_dsp", os.O_WRONLY | os.O_NONBLOCK)
        self._poll = select.poll()
        self._poll.register(self._wake, select.POLLIN | select.POLLHUP)
        self._last_seen = 0
        self.spin_polls = spin_polls
        dsp = self.area["dsp_control"]
        self._shutdown = dsp + W.DSP_SHUTDOWN
        self._holda = dsp + W.DSP_HOLDA
        self._read_index = 2 * (dsp + W.DSP_FIFO_READ)
        self._status = struct.Struct(W.STATUS_FORMAT)

    # 32- and 64-bit fields: aligned, one store each
    def _u32(self, word: int) -> int:
        return struct.unpack_from("<I", self.memory, 2 * word)[0]

    def _set_u32(self, word: int, value: int) -> None:
        struct.pack_into("<I", self.memory, 2 * word, value & 0xFFFFFFFF)

    def attach(self, program_periods: int = 0) -> None:
        """Say the PC is here and ready: the program's length [periods] (0: unknown; the card then
        runs until the program ends, at most the scenario's ``max_time`` or an hour simulated),
        the layout version, the magic word, then READY. The card's clock starts on it."""
        self._set_u32(W.PC_PROGRAM_PERIODS, program_periods)
        self.word[W.PC_VERSION] = W.VERSION
        self._set_u32(W.PC_MAGIC, W.MAGIC)
        self.word[W.PC_STATE] = W.PC_STATE_READY

    def beat(self) -> None:
        """Advance the heartbeat: the card counts a PC whose heartbeat stops as lost."""
        self._set_u32(W.PC_HEARTBEAT, self._u32(W.PC_HEARTBEAT) + 1)

    def wait_status(self) -> dict | None:
        """Block until the card posts a status; the status (a dict of its fields, per-axis ones as
        tuples), or None when the run is over (the card's shutdown word). CardGone if the twin's
        process ended meanwhile."""
        mailbox = self.area["mailbox_to_pc"]
        for _ in range(self.spin_polls):
            if self.word[mailbox] != self._last_seen:
                break
        while self.word[mailbox] == self._last_seen and not self.word[self._shutdown]:
            self.beat()
            for _fd, event in self._poll.poll(WAKE_INTERVAL * 1000):
                if event & select.POLLIN:
                    self._drain()
                elif event & select.POLLHUP:
                    raise CardGone("the card's doorbell closed: the twin's run ended")
        if self.word[self._shutdown]:
            return None
        self._last_seen = self.word[mailbox]
        self.beat()
        return self.read_status()

    def end_state(self) -> tuple[int, int] | None:
        """Once the run is over (:meth:`wait_status` returned None): ``(state, fault)`` the card's
        run ended with (DSP_STATE_*, FAULT_*); None before."""
        if not self.word[self._shutdown]:
            return None
        dsp = self.area["dsp_control"]
        return int(self.word[dsp + W.DSP_END_STATE]), int(self.word[dsp + W.DSP_END_FAULT])

    def _drain(self) -> None:
        try:
            while os.read(self._wake, 4096):
                pass
        except BlockingIOError:
            pass

    def read_status(self) -> dict:
        values = self._status.unpack_from(self.memory, 2 * self.area["status_base"])
        out, at = {}, 0
        for name, count in W.STATUS_FIELDS:
            out[name] = values[at] if count == 1 else tuple(values[at:at + count])
            at += count
        return out

    def begin(self) -> None:
        """Take the bus: HOLD, then wait for the card's grant (normally already given with the status)."""
        self.word[W.PC_HOLD] = 1
        while not self.word[self._holda]:
            os.sched_yield()

    def end(self, *, all_sent: bool = False, wake_free: int = 0) -> None:
        """Give the bus back and acknowledge the status: ALL_SENT (the whole program is in the FIFO:
        the card may stop exchanging) and WAKE_FREE (no exchange before the FIFO has that many free
        words), HOLD low, the time, the mailbox, a ring."""
        self.word[W.PC_ALL_SENT] = 1 if all_sent else 0
        self.word[W.PC_WAKE_FREE] = wake_free
        self.word[W.PC_HOLD] = 0
        struct.pack_into("<Q", self.memory, 2 * W.PC_ACK_TIME, time.perf_counter_ns())
        self.word[self.area["mailbox_to_dsp"]] = self._last_seen
        try:
            os.write(self._ring, b"\x01")
        except BlockingIOError:  # a full pipe: the card has wake-ups pending
            pass
        except BrokenPipeError:
            raise CardGone("the card's doorbell closed: the twin's run ended") from None

    def set_state(self, state: int) -> None:
        self.word[W.PC_STATE] = state

    # the command FIFO: the PC writes, the card reads
    def fifo_free(self) -> int:
        written = self._u32(W.PC_FIFO_WRITE)
        read = struct.unpack_from("<I", self.memory, self._read_index)[0]
        return self.area["fifo_words"] - (written - read) % _U32

    def fifo_write(self, data: bytes) -> None:
        """Copy whole records (``data``, bytes) into the ring, then publish the write index."""
        base, capacity = self.area["fifo_base"], self.area["fifo_words"]
        index = self._u32(W.PC_FIFO_WRITE)
        n = len(data) // 2
        at = index % capacity
        first = min(n, capacity - at)
        self.memory[2 * (base + at):2 * (base + at + first)] = data[:2 * first]
        if first < n:
            self.memory[2 * base:2 * (base + n - first)] = data[2 * first:]
        self._set_u32(W.PC_FIFO_WRITE, (index + n) % _U32)  # published after the data

    def close(self) -> None:
        for fd in (self._wake, self._ring):
            try:
                os.close(fd)
            except OSError:
                pass
        self.word.release()
        self.memory.close()

    def __enter__(self) -> "Card":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


# --- streaming -------------------------------------------------------------------------------

@dataclass
class Streamer:
    """Which records go out in answer to each status: as many as the FIFO's free words, the chunk
    (``chunk_bytes`` per exchange; a longer record goes alone) and the look-ahead allow, numbered
    from 1; go-back-N when the card reports a rejected record (it resends from the card's expected
    sequence number). Add records any time (:meth:`add`); set ``complete`` after the last.

    ``lookahead_periods``: motion kept queued on the card ahead of execution [periods]; 0 = no
    limit. The record after the running one always goes, and a card in FEED_HOLD always gets
    records. ``fifo_interrupt``: when the next record does not fit, ask for no exchange before the
    FIFO has room for it (WAKE_FREE). ``corrupt(seq, data) -> data``: a hook that may change a
    record's bytes as it is written (to test a program's handling of rejects). ``solo``: see below.
    """

    card: Card
    chunk_bytes: int = 4096
    lookahead_periods: int = 0
    fifo_interrupt: bool = True
    corrupt: object = None
    solo: bool = True
    """raise ALL_SENT once the whole program is in the FIFO (the card then stops exchanging until it
    needs a resend); False: the card keeps posting a status every period"""
    complete: bool = False
    encoded: list = field(default_factory=list)
    cumulative: list = field(default_factory=lambda: [0])
    next_index: int = 0
    retransmitted: int = 0
    _rejected_seen: int = 0

    def add(self, record: Record) -> None:
        for i, (kind, payload) in enumerate(pieces := parts(record, self.chunk_bytes // 2)):
            self.encoded.append(encode(kind, payload, len(self.encoded) + 1))
            self.cumulative.append(self.cumulative[-1] + (record.periods if i == len(pieces) - 1 else 0))

    @property
    def all_sent(self) -> bool:
        return self.complete and self.next_index >= len(self.encoded)

    def answer(self, status: dict) -> int:
        """Write this exchange's records (between :meth:`Card.begin` and :meth:`Card.end`); how many.
        Leaves ``wake_free`` for :meth:`Card.end`."""
        if status["records_rejected"] != self._rejected_seen:  # go back to what the card expects
            self._rejected_seen = status["records_rejected"]
            resend_from = status["expected_seq"] - 1
            self.retransmitted += max(0, self.next_index - resend_from)
            self.next_index = resend_from
        accepted, executed = status["expected_seq"] - 1, status["last_seq_executed"]
        budget, written, free = self.chunk_bytes // 2, 0, self.card.fifo_free()
        self.wake_free = 0
        while self.next_index < len(self.encoded):
            queued = status["queued_periods"] + self.cumulative[self.next_index] - self.cumulative[accepted]
            if (self.lookahead_periods and queued >= self.lookahead_periods and self.next_index > executed + 1
                    and status["state"] != W.DSP_STATE_FEED_HOLD):
                break
            data = self.encoded[self.next_index]
            if len(data) // 2 > free:  # the FIFO must drain first
                self.wake_free = len(data) // 2
                break
            if len(data) // 2 > budget and written:  # a record longer than the chunk goes alone
                break
            if self.corrupt is not None:
                data = self.corrupt(self.next_index + 1, data)
            self.card.fifo_write(data)
            budget -= len(data) // 2
            free -= len(data) // 2
            self.next_index += 1
            written += 1
        return written

    def exchange(self, status: dict) -> int:
        """One whole exchange: take the bus, write, give it back with the flags."""
        self.card.begin()
        written = self.answer(status)
        self.card._set_u32(W.PC_RECORDS_SENT, self.next_index)
        self.card._set_u32(W.PC_RETRANSMITS, self.retransmitted)
        self.card.end(all_sent=self.solo and self.all_sent, wake_free=self.wake_free if self.fifo_interrupt else 0)
        self.card.set_state(W.PC_STATE_STREAMING)
        return written

    def run(self, on_status=None) -> dict | None:
        """Answer every status until the run is over (the card's shutdown word; then
        :meth:`Card.end_state` says how it ended): the last status seen. ``on_status(status)`` is
        called with each first (add records there)."""
        last = None
        while (status := self.card.wait_status()) is not None:
            last = status
            if on_status is not None:
                on_status(status)
            self.exchange(status)
        self.card.set_state(W.PC_STATE_DONE)
        return last
