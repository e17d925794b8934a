"""What the planner process is asked to do (:class:`PlannerJob`) and the plan of each program kind.

:func:`plan_for` is the one place a program kind's planner plugs in: it returns an object with
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
from cnc_twin.whiteboard.records import CurveBlock, Dwell, EndOfProgram, Move, Record, StepContour


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


def plan_for(job: PlannerJob):
    """The plan of ``job``'s program, by its kind (imported here: the process loads only its own)."""
    prog = job.program
    if isinstance(prog, MotionChipProgram):
        from cnc_twin.planner.chip_program import ChipPlan

        return ChipPlan(prog, job.period)
    if isinstance(prog, ContourProgram):
        from cnc_twin.planner.contour_program import ContourPlan

        return ContourPlan(prog, job.axes, job.home, job.period)
    if isinstance(prog, SurfaceProgram):
        from cnc_twin.planner.surface_program import SurfacePlan

        return SurfacePlan(prog, job.axes, job.home, job.period)
    if isinstance(prog, GcodeProgram):
        from cnc_twin.planner.gcode_program import GcodePlan

        return GcodePlan(prog, job.axes, job.home, job.period, window=job.window)
    if isinstance(prog, NurbsProgram):
        from cnc_twin.planner.curve_program import CurvePlan

        return CurvePlan(prog, job.axes, job.home, job.period, window=job.window)
    return PointsPlan(job)


def build_program(job: PlannerJob) -> tuple[list[Record], list[int], int]:
    """The whole program at once: records, their durations [periods], motion blocks."""
    records: list[Record] = []
    periods: list[int] = []
    for chunk, chunk_periods in plan_for(job).chunks():
        records += chunk
        periods += chunk_periods
    return records, periods, sum(isinstance(r, (Move, CurveBlock, StepContour)) for r in records)
