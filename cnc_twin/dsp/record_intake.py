"""The card accepting records: what each record type becomes when the card decodes it, ahead of
running it (:class:`~cnc_twin.dsp.record_intake.RecordIntake`, the accepting half of
:class:`~cnc_twin.dsp.interpolator.SegmentInterpolator`).

A move becomes a :class:`~cnc_twin.motion.segments.MoveSegment` from the programmed position (a
probing move a :class:`~cnc_twin.dsp.probe.ProbeSegment`); a
curve or a surface section is built at once (the card decodes ahead) into a
:class:`~cnc_twin.dsp.path_blocks.Curve` or :class:`~cnc_twin.dsp.path_blocks.SurfaceRun`, and
its CurveBlocks into :class:`~cnc_twin.dsp.path_blocks.Block` items; a force-control record
becomes a :class:`~cnc_twin.dsp.path_blocks.ForceWait` at its path's end; a step contour a
:class:`~cnc_twin.dsp.step_interpolator.StepRun`; everything else (modal records, marks, the
end of the program, chip commands) waits in the queue as it is. :data:`ACCEPT` holds one handler
per record type: a new record type plugs in there. :data:`MODAL`: what a modal record changes
when it reaches the queue's head.
"""

from __future__ import annotations

import math

from cnc_twin.dsp.path_blocks import Block, Curve, ForceWait, Surface, SurfaceRun, stop_reserve
from cnc_twin.dsp.probe import ProbeSegment
from cnc_twin.dsp.step_interpolator import StepRun
from cnc_twin.motion.segments import MoveSegment
from cnc_twin.whiteboard.records import (
    CurveBlock, CurveGeometry, Dwell, EndOfProgram, FeedOverride, ForceControlRecord, ForceSetpoint, Mark, Move, Probe, Record,
    Spindle, StepContour, SurfaceCurve, SurfaceGeometry,
)


class RecordIntake:
    """Queues accepted records (:meth:`~RecordIntake.push`). Works on the interpolator's own state:
    ``queue``, ``programmed``, ``queued_path``, ``path_open`` and the queued periods."""

    def push(self, seq: int, record: Record) -> None:
        """Queue an accepted record; moves start from the programmed position."""
        ACCEPT.get(type(record), RecordIntake._accept_as_is)(self, seq, record)

    def _accept_move(self, seq: int, record: Move) -> None:
        segment = MoveSegment(start=self.programmed, end=tuple(record.end), profile=record.profile,
                              periods=record.periods)
        self.programmed = segment.end
        self.queue.append((seq, segment))
        self._queued_periods += record.periods

    def _accept_probe(self, seq: int, record: Probe) -> None:
        # the next move starts where the probe stops: the card sets ``programmed`` then (the
        # planner sends nothing more before it has the probe's result)
        segment = ProbeSegment(start=self.programmed, end=tuple(record.end), profile=record.profile,
                               periods=record.periods, trip_force=record.trip_force, kind=record.kind)
        self.programmed = segment.end
        self.queue.append((seq, segment))
        self._queued_periods += record.periods

    def _accept_dwell(self, seq: int, record: Dwell) -> None:  # holds wherever the axes are when it starts
        self.queue.append((seq, record))
        self._queued_periods += record.periods

    def _accept_curve(self, seq: int, record: CurveGeometry) -> None:
        # built when accepted (the card decodes ahead), run when it reaches the queue's head
        self._pending_curve = Curve(record, self.compiled)
        self.programmed = self._pending_curve.end
        self.queue.append((seq, self._pending_curve))

    def _accept_surface(self, seq: int, record: SurfaceGeometry) -> None:
        self._surface = Surface(record)
        self.queue.append((seq, record))
        self.path_open = False

    def _accept_section(self, seq: int, record: SurfaceCurve) -> None:
        self._pending_curve = SurfaceRun(self._surface, record, self.programmed[5], self.compiled)
        self.programmed = self._pending_curve.end
        self.queue.append((seq, self._pending_curve))

    def _accept_force(self, seq: int, record: ForceControlRecord) -> None:
        wait = ForceWait(record, self._pending_curve)
        if not record.on:
            self.programmed = wait.clear_pose
        self.queue.append((seq, wait))
        self.path_open = False

    def _accept_steps(self, seq: int, record: StepContour) -> None:
        run = StepRun(record, self.counts_of(self.programmed))
        run.periods = math.ceil(record.profile.duration / self.period)
        self.programmed = (*self._position_of(run.end)[:2], *self.programmed[2:])
        self.queue.append((seq, run))
        self._queued_periods += run.periods
        self.path_open = False

    def _accept_block(self, seq: int, record: CurveBlock) -> None:
        block = Block(record, self._pending_curve, self.period)
        self.queue.append((seq, block))
        self._queued_periods += block.periods
        self.queued_path += block.profile.length
        self.path_open = block.profile.v1 > 0.0
        self._arrivals += 1
        self._stop_reserve = stop_reserve(block.profile, self.period)

    def _accept_as_is(self, seq: int, record: Record) -> None:
        self.queue.append((seq, record))
        self.path_open = False


ACCEPT = {Move: RecordIntake._accept_move, Dwell: RecordIntake._accept_dwell, CurveGeometry: RecordIntake._accept_curve,
          SurfaceGeometry: RecordIntake._accept_surface, SurfaceCurve: RecordIntake._accept_section,
          ForceControlRecord: RecordIntake._accept_force, StepContour: RecordIntake._accept_steps,
          CurveBlock: RecordIntake._accept_block, Probe: RecordIntake._accept_probe}
"""what each record type becomes in the queue; any other waits there as it is (modal records,
marks, the end of the program, chip commands)"""


def _feed_override(interp: RecordIntake, record: FeedOverride) -> None:
    interp.override_target = max(0.0, record.fraction)


def _force_setpoint(interp: RecordIntake, record: ForceSetpoint) -> None:
    interp.force_setpoint = record.newtons


def _spindle(interp: RecordIntake, record: Spindle) -> None:
    interp.spindle_on, interp.spindle_speed = record.on, record.speed


def _mark(interp: RecordIntake, record: Mark) -> None:
    interp.mark = record.number


def _end_of_program(interp: RecordIntake, _record: EndOfProgram) -> None:
    interp.finished = True


MODAL = {FeedOverride: _feed_override, ForceSetpoint: _force_setpoint, Spindle: _spindle, Mark: _mark,
         EndOfProgram: _end_of_program}
"""what a modal record changes when it reaches the queue's head (in program order)"""
