"""What the planner process is asked to do (:class:`~cnc_twin.planner.job.PlannerJob`) and the plan
of each program kind.

:data:`PLANS` is the one place a program kind's planner plugs in: :func:`plan_for` returns an object with
``estimated_periods`` (the program's length, announced to the card up front) and ``chunks()``
(successive ``(records, durations [periods])``, planned as they are asked for).
"""

from __future__ import annotations

from dataclasses import dataclass

from cnc_twin.core.config import (
    AxisConfig, ContourProgram, FaultInjection, GcodeProgram, MotionChipProgram, NurbsProgram, PointToPoint,
    SurfaceProgram,
)
from cnc_twin.motion.segments import DwellSegment, MoveSegment, Segment
from cnc_twin.planner.ptp import plan_point_to_point
from cnc_twin.whiteboard.capture import PcStream
from cnc_twin.whiteboard.records import Dwell, EndOfProgram, Move, Record


@dataclass(frozen=True)
class PlannerJob:
    """Everything the planner process needs, as plain picklable data."""

    program: PointToPoint | NurbsProgram | SurfaceProgram | ContourProgram | MotionChipProgram | GcodeProgram
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
    fifo_interrupt: bool = True
    """ask the card for the next exchange only once the next record fits (see the whiteboard's WAKE_FREE)"""
    window: float = 0.05
    """curve length planned per window [m]"""
    replay: PcStream | None = None
    """a PC program's recorded stream to write again instead of planning ``program``
    (:mod:`cnc_twin.planner.replay`)"""


_RECORD_OF = {
    MoveSegment: lambda seg: Move(end=seg.end, profile=seg.profile, periods=seg.periods),
    DwellSegment: lambda seg: Dwell(periods=seg.periods),
}
"""the wire record of each kind of planned segment"""


def segments_to_records(segments: list[Segment]) -> tuple[list[Record], list[int]]:
    """Wire records for planned segments plus end of program, and each record's duration [periods]."""
    records: list[Record] = [_RECORD_OF[type(seg)](seg) for seg in segments]
    periods: list[int] = [seg.periods for seg in segments]
    records.append(EndOfProgram())
    periods.append(0)
    return records, periods


class PointsPlan:
    """Point-to-point: every move and dwell planned at once, one chunk."""

    def __init__(self, job: PlannerJob):
        self.segments = plan_point_to_point(job.program, job.axes, start=job.home, period=job.period)

    @property
    def estimated_periods(self) -> int:
        """Program length [periods], exact."""
        return sum(seg.periods for seg in self.segments)

    def chunks(self):
        """The whole program as one ``(records, periods)`` chunk."""
        yield segments_to_records(self.segments)


def _chip_plan(job: PlannerJob):
    from cnc_twin.planner.chip_program import ChipPlan

    return ChipPlan(job.program, job.period)


def _contour_plan(job: PlannerJob):
    from cnc_twin.planner.contour_program import ContourPlan

    return ContourPlan(job.program, job.axes, job.home, job.period)


def _surface_plan(job: PlannerJob):
    from cnc_twin.planner.surface_program import SurfacePlan

    return SurfacePlan(job.program, job.axes, job.home, job.period)


def _gcode_plan(job: PlannerJob):
    from cnc_twin.planner.gcode_program import GcodePlan

    return GcodePlan(job.program, job.axes, job.home, job.period, window=job.window)


def _curve_plan(job: PlannerJob):
    from cnc_twin.planner.curve_program import CurvePlan

    return CurvePlan(job.program, job.axes, job.home, job.period, window=job.window)


PLANS = {PointToPoint: PointsPlan, MotionChipProgram: _chip_plan, ContourProgram: _contour_plan,
         SurfaceProgram: _surface_plan, GcodeProgram: _gcode_plan, NurbsProgram: _curve_plan}
"""the plan of each program kind, from the job (each imports its planner when asked: the process
loads only its own); a new kind plugs in here"""


def plan_for(job: PlannerJob):
    """The plan of ``job``'s program, by its kind (:data:`PLANS`)."""
    return PLANS[type(job.program)](job)


def build_program(job: PlannerJob) -> tuple[list[Record], list[int], int]:
    """The whole program at once: records, their durations [periods], motion blocks."""
    records: list[Record] = []
    periods: list[int] = []
    for chunk, chunk_periods in plan_for(job).chunks():
        records += chunk
        periods += chunk_periods
    return records, periods, sum(r.motion_block for r in records)
