"""The PC planner as its own OS process: plan, encode, stream records through the whiteboard.

``planner_main`` does one run's work; :func:`serve` runs one run after another in the process
that :mod:`cnc_twin.planner.launch` starts (``python -m cnc_twin.planner.process --serve``). Per DSP status it writes as many records as fit, bounded by

- the free FIFO space,
- the chunk size (the card takes 4 KB per mailbox interrupt),
- the look-ahead: motion queued ahead of execution (0 = no limit): what the card reports as
  queued (``queued_periods``, including the rest of the running move) plus what is in flight;
  the record right after the running one is always sent.

When the DSP reports more rejected records than before, the planner goes back to the DSP's
``expected_seq`` and sends from there again (go-back-N); the DSP flushed the FIFO when it
rejected, so the resent records are next in line.

Injected faults (scenario ``faults:``) act here, on the PC side: a stall (no answer and no
heartbeat for a while), a delay on every answer for a time window, a kill (the process dies as
with SIGKILL), and a bit flip in one record after its CRC was computed.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
import traceback
from dataclasses import dataclass
from multiprocessing.connection import Connection

import numpy as np

from cnc_twin.core.config import (
    AxisConfig, ContourProgram, FaultInjection, MotionChipProgram, NurbsProgram, PointToPoint, SurfaceProgram,
)
from cnc_twin.planner.ptp import dwell_chunk, plan_move, plan_point_to_point
from cnc_twin.motion.segments import DwellSegment, MoveSegment, Segment
from cnc_twin.whiteboard import layout as L
from cnc_twin.whiteboard.block import Whiteboard
from cnc_twin.whiteboard.doorbell import Doorbell
from cnc_twin.whiteboard.ports import PcPort
from cnc_twin.whiteboard.records import (
    CurveBlock, CurveGeometry, Dwell, EndOfProgram, Move, Record, StepContour, encode,
)
from cnc_twin.whiteboard.status import DspState


@dataclass(frozen=True)
class PlannerJob:
    """Everything the planner process needs, as plain picklable data."""

    program: PointToPoint | NurbsProgram | SurfaceProgram | ContourProgram | MotionChipProgram
    axes: tuple[AxisConfig, ...]
    home: tuple[float, ...]
    period: float
    """interpolation period [s]"""
    layout_words: int
    chunk_words: int
    lookahead_periods: int
    """0 = no limit"""
    faults: tuple[FaultInjection, ...] = ()
    lockstep: bool = True
    """plan windows inside the exchange loop (deterministic); False: in a background thread"""
    window: float = 0.05
    """curve length planned per window [m]"""


def segments_to_records(segments: list[Segment]) -> tuple[list[Record], list[int]]:
    """Wire records for planned segments plus end of program, and each record's duration [periods]."""
    records: list[Record] = []
    periods: list[int] = []
    for seg in segments:
        if isinstance(seg, MoveSegment):
            records.append(Move(end=seg.end, profile=seg.profile, periods=seg.periods))
        elif isinstance(seg, DwellSegment):
            records.append(Dwell(periods=seg.periods))
        else:  # pragma: no cover
            raise TypeError(f"cannot stream {type(seg).__name__}")
        periods.append(seg.periods)
    records.append(EndOfProgram())
    periods.append(0)
    return records, periods


def curve_setup(prog: NurbsProgram):
    """``(curve, start pose, axis_path, axis_limits, CurveGeometry record)`` for a curve program.

    Held tool axis: the curve is already in axis space. Varying tool axis: the curve is the tool
    tip's (world frame); ``axis_path(u)`` gives X/Y/Z/A/B through the kinematics, for planning
    against every axis's limits.
    """
    from cnc_twin.geometry.kinematics import HeadGeometry
    from cnc_twin.geometry.nurbs import NurbsCurve

    curve = NurbsCurve(prog.control_points, prog.weights, prog.knots, prog.degree)
    u0 = curve.domain[0]
    if prog.axis_curve is None:
        start = tuple(float(x) for x in curve.point(u0)[0]) + tuple(prog.hold)
        geometry = CurveGeometry(degree=prog.degree, knots=prog.knots, weights=prog.weights,
                                 control_points=prog.control_points, hold=prog.hold)
        return curve, start, None, None, geometry
    ac = prog.axis_curve
    directions = NurbsCurve(ac.control_points, ac.weights, ac.knots, ac.degree)
    head = HeadGeometry(pivot_home=prog.pivot_home, tool_offset=prog.tool_offset, workpiece_origin=(0.0, 0.0, 0.0))

    def axis_path(u):
        return head.axes_from_pose(curve.point(u), directions.point(u))

    start = tuple(float(x) for x in axis_path([u0])[0]) + (prog.hold[2],)
    lim, rot = prog.limits, prog.rotary_limits
    axis_limits = (tuple(lim.axis_velocity) + tuple(rot[0]), tuple(lim.axis_acceleration) + tuple(rot[1]),
                   tuple(lim.axis_jerk) + tuple(rot[2]))
    geometry = CurveGeometry(degree=prog.degree, knots=prog.knots, weights=prog.weights,
                             control_points=prog.control_points, hold=prog.hold,
                             axis=ac,
                             pivot=prog.pivot_home, offset=prog.tool_offset)
    return curve, start, axis_path, axis_limits, geometry


class Program:
    """A job planned once; its length announced up front and its records handed out in chunks.

    Point-to-point: all moves are planned here, one chunk. Curves: the curve, its kinematics and
    the approach move are set up here; :meth:`chunks` then yields the approach and the curve,
    the S-curve blocks window by window (:func:`cnc_twin.planner.feed.plan_feed_windows`), and
    settle and end of program. Surface, contour and motion-chip programs have their own plan
    objects (``estimated_periods`` and ``chunks()``), kept in ``plan``.
    """

    def __init__(self, job: PlannerJob):
        self.job = job
        self.segments: list[Segment] | None = None
        self.plan = None
        if isinstance(job.program, MotionChipProgram):
            from cnc_twin.planner.chip_program import ChipPlan

            self.plan = ChipPlan(job.program, job.period)
        elif isinstance(job.program, ContourProgram):
            from cnc_twin.planner.contour_program import ContourPlan

            self.plan = ContourPlan(job.program, job.axes, job.home, job.period)
        elif isinstance(job.program, SurfaceProgram):
            from cnc_twin.planner.surface_program import SurfacePlan

            self.plan = SurfacePlan(job.program, job.axes, job.home, job.period)
        elif isinstance(job.program, NurbsProgram):
            self.curve, start, self.axis_path, self.axis_limits, self.geometry = curve_setup(job.program)
            self.approach = plan_move(tuple(job.home), start, job.axes, feed=job.program.approach_feed,
                                      period=job.period)
        else:
            self.segments = plan_point_to_point(job.program, job.axes, start=job.home, period=job.period)

    @property
    def estimated_periods(self) -> int:
        """Program length [periods]: exact for moves, estimated (1.2x the curve at feed) for curves."""
        import math

        if self.plan is not None:
            return self.plan.estimated_periods
        if self.segments is not None:
            return sum(seg.periods for seg in self.segments)
        prog, period = self.job.program, self.job.period
        curve_time = 1.2 * self.curve.arc_length() / prog.limits.feed
        return (self.approach.periods if self.approach else 0) + math.ceil((curve_time + prog.settle) / period)

    def chunks(self):
        """Successive ``(records, periods)`` chunks, planned as they are asked for."""
        if self.plan is not None:
            yield from self.plan.chunks()
            return
        if self.segments is not None:
            yield segments_to_records(self.segments)
            return
        import math

        from cnc_twin.planner.feed import plan_feed_windows

        job, prog, approach = self.job, self.job.program, self.approach
        records: list[Record] = []
        periods: list[int] = []
        if approach is not None:
            records.append(Move(end=approach.end, profile=approach.profile, periods=approach.periods))
            periods.append(approach.periods)
        records.append(self.geometry)
        periods.append(0)
        yield records, periods
        for blocks in plan_feed_windows(self.curve, prog.limits, period=job.period, window=job.window,
                                        axis_path=self.axis_path, axis_limits=self.axis_limits):
            yield ([CurveBlock(b) for b in blocks], [math.ceil(b.duration / job.period) for b in blocks])
        tail, tail_periods = dwell_chunk(prog.settle, job.period)
        yield tail + [EndOfProgram()], tail_periods + [0]


def build_program(job: PlannerJob) -> tuple[list[Record], list[int], int]:
    """The whole program at once: records, their durations [periods], motion blocks."""
    records: list[Record] = []
    periods: list[int] = []
    for chunk, chunk_periods in Program(job).chunks():
        records += chunk
        periods += chunk_periods
    return records, periods, sum(isinstance(r, (Move, CurveBlock, StepContour)) for r in records)


class Feeder:
    """Moves planned chunks into the streamer: in the exchange loop (lockstep) or from a thread.

    Lockstep plans the next chunk only when fewer than ``BACKLOG`` records wait unsent, a decision
    that depends on the exchange sequence alone, so the stream is the same on every run.
    """

    BACKLOG = 8

    def __init__(self, job: PlannerJob, streamer: "Streamer"):
        self.streamer = streamer
        started = time.perf_counter()
        self.program = Program(job)
        self.plan_seconds = time.perf_counter() - started
        self.chunks = self.program.chunks()
        self.blocks = 0
        self._lock = threading.Lock()
        self._ready: list[tuple[list[Record], list[int]]] = []
        self._done = False
        self._error: BaseException | None = None
        self.threaded = not job.lockstep
        if self.threaded:
            threading.Thread(target=self._run, name="planner-windows", daemon=True).start()

    def _next(self) -> tuple[list[Record], list[int]] | None:
        started = time.perf_counter()
        try:
            chunk = next(self.chunks)
        except StopIteration:
            return None
        finally:
            self.plan_seconds += time.perf_counter() - started
        self.blocks += sum(isinstance(r, (Move, CurveBlock)) for r in chunk[0])
        return chunk

    def _run(self) -> None:
        try:
            while (chunk := self._next()) is not None:
                with self._lock:
                    self._ready.append(chunk)
        except BaseException as exc:  # reported from the exchange loop
            self._error = exc
        self._done = True

    def top_up(self) -> None:
        """Hand planned records to the streamer (planning one chunk now, in lockstep mode)."""
        if self.threaded:
            if self._error is not None:
                raise self._error
            with self._lock:
                ready, self._ready = self._ready, []
            for chunk in ready:
                self.streamer.add(*chunk)
            if self._done and not self._ready:
                self.streamer.complete = True
            return
        while not self.streamer.complete and self.streamer.backlog < self.BACKLOG:
            chunk = self._next()
            if chunk is None:
                self.streamer.complete = True
            else:
                self.streamer.add(*chunk)


class Streamer:
    """Which records go out in answer to a status. Sequence numbers start at 1.

    Records are added as they are planned (:meth:`add`); ``complete`` is set after the last.

    Parameters
    ----------
    chunk_words, lookahead_periods : limits per exchange (0 look-ahead = none).
    """

    def __init__(self, *, chunk_words: int, lookahead_periods: int):
        self.encoded: list[np.ndarray] = []
        self.cumulative: list[int] = [0]
        self.chunk_words = chunk_words
        self.lookahead_periods = lookahead_periods
        self.next_index = 0
        self.complete = False
        self._rejected_seen = 0
        self.retransmitted = 0

    def add(self, records: list[Record], periods: list[int]) -> None:
        for record, n in zip(records, periods):
            self.encoded.append(encode(record, len(self.encoded) + 1))
            self.cumulative.append(self.cumulative[-1] + n)

    @property
    def backlog(self) -> int:
        """Records planned and not yet sent."""
        return len(self.encoded) - self.next_index

    @property
    def all_sent(self) -> bool:
        return self.complete and self.next_index >= len(self.encoded)

    def answer(self, status: np.ndarray, port: PcPort, *, corrupt=None) -> int:
        """Write records for one exchange; returns how many were written."""
        st = status[0]
        rejected = int(st["records_rejected"])
        if rejected != self._rejected_seen:
            self._rejected_seen = rejected
            resend_from = int(st["expected_seq"]) - 1
            self.retransmitted += max(0, self.next_index - resend_from)
            self.next_index = resend_from
        # Motion queued on the card, as it reported, plus what is in flight (sent, not yet accepted).
        # The record after the running one always goes, whatever the look-ahead: a card holding
        # because it ran dry does not drain its queue, and must not wait for itself.
        accepted = int(st["expected_seq"]) - 1
        executed = int(st["last_seq_executed"])
        on_card = int(st["queued_periods"])
        budget = self.chunk_words
        written = 0
        fifo = port.fifo
        free = fifo.free()
        while self.next_index < len(self.encoded):
            queued = on_card + (self.cumulative[self.next_index] - self.cumulative[accepted])
            if (self.lookahead_periods and queued >= self.lookahead_periods and self.next_index > executed + 1
                    and int(st["state"]) != DspState.FEED_HOLD):  # a card holding for data gets data
                break
            words = self.encoded[self.next_index]
            if len(words) > budget or len(words) > free:
                break
            if corrupt is not None:
                words = corrupt(words)
            fifo.write(words)
            budget -= len(words)
            free -= len(words)
            self.next_index += 1
            written += 1
        return written


class FaultSchedule:
    """The PC-side injected faults, each triggered by the simulated time of a status."""

    def __init__(self, faults: tuple[FaultInjection, ...]):
        self.faults = list(faults)
        self._fired: set[int] = set()

    def before_answer(self, sim_time: float) -> None:
        """Stall, delay or die, as scheduled for this status's time."""
        for i, f in enumerate(self.faults):
            if f.kind == "planner_kill" and sim_time >= f.at:
                os.kill(os.getpid(), signal.SIGKILL)
            if f.kind == "planner_stall" and sim_time >= f.at and i not in self._fired:
                self._fired.add(i)
                time.sleep(f.duration)
            if f.kind == "planner_delay" and sim_time >= f.at:
                since = sim_time - f.at
                if (since % f.every if f.every > 0 else since) < f.duration:
                    time.sleep(f.delay)

    @property
    def idle(self) -> bool:
        """Nothing scheduled is still to happen (faults need the status stream to keep going)."""
        return len(self._fired) == len(self.faults) and not any(
            f.kind in ("planner_kill", "planner_delay") for f in self.faults)

    def corrupter(self, sim_time: float):
        """A function flipping the scheduled bit in the next record, or None."""
        for i, f in enumerate(self.faults):
            if f.kind == "record_bitflip" and sim_time >= f.at and i not in self._fired:
                def flip(words: np.ndarray, i=i, bit=f.bit) -> np.ndarray:
                    self._fired.add(i)
                    out = words.copy()
                    b = bit % (16 * len(out))
                    out[b // 16] ^= np.uint16(1 << (b % 16))
                    return out
                return flip
        return None


def planner_main(shm_name: str, job: PlannerJob, wait_dsp: Connection | int, ring_dsp: Connection | int) -> None:
    """Process entry point: attach, plan, announce, then answer every DSP status until the end.

    ``wait_dsp`` / ``ring_dsp`` are the planner's ends of the mailbox doorbells.
    """
    # Ctrl-C reaches the whole process group; the DSP side decides how the run ends.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    wb = Whiteboard.attach(shm_name, L.Layout(job.layout_words))
    port = PcPort(wb, wait_dsp=Doorbell(wait_dsp), ring_dsp=Doorbell(ring_dsp))
    try:
        streamer = Streamer(chunk_words=job.chunk_words, lookahead_periods=job.lookahead_periods)
        feeder = Feeder(job, streamer)
        faults = FaultSchedule(job.faults)
        # The first chunks are planned before the card is told the planner is ready, as a PC fills
        # the card's buffer before cycle start: the run's clock does not wait for them. Lockstep
        # plans the same chunks as at the first status (the backlog rule sees the same counts).
        feeder.top_up()
        port.announce(program_periods=feeder.program.estimated_periods)
        while True:
            status = port.wait_status()
            if status is None:
                break
            st = status[0]
            sim_time = float(st["sim_time"])
            faults.before_answer(sim_time)
            feeder.top_up()
            wb.plan_us[0] = min(int(feeder.plan_seconds * 1e6), 0xFFFFFFFF)
            wb.plan_blocks[0] = feeder.blocks
            port.begin()
            before = streamer.retransmitted
            streamer.answer(status, port, corrupt=faults.corrupter(sim_time))
            wb.records_sent[0] = streamer.next_index
            wb.retransmits[0] = wb.retransmits[0] + (streamer.retransmitted - before)
            port.set_all_sent(streamer.all_sent and faults.idle)
            port.end()
            port.set_state(L.PcState.STREAMING)
            if int(st["state"]) in (DspState.FINISHED, DspState.FAULT):
                break
        port.set_state(L.PcState.DONE)
    except BaseException:
        port.set_state(L.PcState.ERROR)
        traceback.print_exc(file=sys.stderr)
        raise
    finally:
        del port
        wb.close()


def serve(wait_fd: int, ring_fd: int) -> int:
    """Serve runs until EOF on stdin: read ``(shm name, job)`` (a 4-byte little-endian length,
    then the pickle), run it, write one status byte (0 done, 1 failed) to the original stdout.
    A failed run ends the process (its traceback is on stderr). See :mod:`cnc_twin.planner.launch`."""
    import pickle
    import struct

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the group; the DSP side decides
    # The status bytes get a private descriptor; anything printed goes to stderr, not into them.
    status_fd = os.dup(1)
    os.dup2(2, 1)
    stdin = sys.stdin.buffer
    while True:
        header = stdin.read(4)
        if len(header) < 4:
            return 0
        payload = stdin.read(struct.unpack("<I", header)[0])
        shm_name, job = pickle.loads(payload)
        Doorbell(wait_fd).drain()  # rings left over from the last run
        try:
            planner_main(shm_name, job, wait_fd, ring_fd)
        except BaseException:
            os.write(status_fd, b"\x01")
            return 1
        os.write(status_fd, b"\x00")


def main(argv: list[str] | None = None) -> int:
    """``python -m cnc_twin.planner.process --serve WAIT_FD RING_FD``: serve runs whose jobs come
    on stdin (:func:`serve`), started by :class:`cnc_twin.planner.launch.PlannerProcess`.

    Started as a plain subprocess (not multiprocessing's spawn), so the user's main script is
    never imported again in here: scripts need no ``if __name__ == "__main__"`` guard.
    """
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 3 or args[0] != "--serve":
        print("usage: python -m cnc_twin.planner.process --serve WAIT_FD RING_FD", file=sys.stderr)
        return 2
    return serve(int(args[1]), int(args[2]))


if __name__ == "__main__":
    raise SystemExit(main())
