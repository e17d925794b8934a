"""The planner's side of a surface polishing program: the record sequence and its feed plans.

Records, in order::

    Move          home -> standoff above the first section's start, tool along its axis
    Spindle on    + Dwell while the spindle runs up
    SurfaceGeometry
    for each section:
        SurfaceCurve
        ForceControl on          (before the first section only: seek, ramp up)
        CurveBlock ...           the section's S-curve feed plan, window by window
    ForceControl off             ramp down, retract to the standoff
    Spindle off   + Dwell while it runs down
    Move          Z up to its home position, then Move every axis home
    Dwell (settle), EndOfProgram

Each section is planned against every axis's limits after the kinematics (X/Y/Z/A/B along the
surface normal with lead and tilt), exactly as a curve with a varying tool axis.
"""

from __future__ import annotations

import math

import numpy as np

from cnc_twin.core.config import AxisConfig, SurfaceProgram
from cnc_twin.geometry.kinematics import HeadGeometry
from cnc_twin.geometry.nurbs import NurbsCurve
from cnc_twin.geometry.surface import NurbsSurface
from cnc_twin.geometry.surface_path import SurfacePath
from cnc_twin.planner.ptp import dwell_chunk, move_chunk, plan_move
from cnc_twin.whiteboard.records import (
    CurveBlock, Dwell, EndOfProgram, ForceControlRecord, Move, Record, Spindle, SurfaceCurve, SurfaceGeometry,
)


def build_surface(prog: SurfaceProgram) -> NurbsSurface:
    """The program's surface, as a NURBS surface."""
    return NurbsSurface.from_def(prog.surface)


def section_paths(prog: SurfaceProgram, surface: NurbsSurface | None = None) -> list[SurfacePath]:
    """The program's sections as :class:`~cnc_twin.geometry.surface_path.SurfacePath` objects."""
    surface = build_surface(prog) if surface is None else surface
    return [SurfacePath(surface, NurbsCurve(c.control_points, c.weights, c.knots, c.degree)) for c in prog.sections]


def head_of(prog: SurfaceProgram) -> HeadGeometry:
    """The head's geometry of the program (its pivot's home and tool offset), the workpiece at
    the origin."""
    return HeadGeometry(pivot_home=prog.pivot_home, tool_offset=prog.tool_offset, workpiece_origin=(0.0, 0.0, 0.0))


def section_poses(prog: SurfaceProgram, path: SurfacePath, t: np.ndarray) -> np.ndarray:
    """X/Y/Z/A/B along a section at parameters ``t``, shape (m, 5)."""
    return head_of(prog).axes_from_pose(path.point(t), path.axes(t, prog.lead, prog.tilt))


def approach_pose(prog: SurfaceProgram, path: SurfacePath, home: tuple[float, ...]) -> tuple[float, ...]:
    """All six axes standoff above the first section's start, tool along its axis."""
    t0 = path.domain[0]
    axis = path.axes([t0], prog.lead, prog.tilt)
    tip = path.point([t0]) + prog.force.standoff * axis
    return tuple(float(x) for x in head_of(prog).axes_from_pose(tip, axis)[0]) + (home[5],)


def spindle_periods(prog: SurfaceProgram, period: float) -> int:
    """Periods for the spindle to reach speed (or stop) at its acceleration, plus 10 %."""
    return max(1, math.ceil(1.1 * prog.spindle_speed / prog.spindle_acceleration / period))


class SurfacePlan:
    """A surface program set up once (sections, approach), its records handed out in chunks."""

    def __init__(self, prog: SurfaceProgram, axes: tuple[AxisConfig, ...], home: tuple[float, ...], period: float):
        self.prog, self.axes, self.home, self.period = prog, axes, tuple(home), period
        self.surface = build_surface(prog)
        self.paths = section_paths(prog, self.surface)
        self.start = approach_pose(prog, self.paths[0], self.home)
        self.approach = plan_move(self.home, self.start, axes, feed=prog.approach_feed, period=period)

    @property
    def estimated_periods(self) -> int:
        p, T = self.prog, self.period
        f = p.force
        path_time = 1.3 * p.path_length / p.limits.feed
        contact = (f.standoff / f.seek_speed + f.ramp_time) * 2.0 + f.standoff / f.retract_speed
        moves = (self.approach.periods if self.approach else 0) + 2 * spindle_periods(p, T)
        return moves + math.ceil((path_time + contact + 2.0 + p.settle) / T)

    def chunks(self):
        """Successive ``(records, periods)`` chunks, planned as they are asked for."""
        from cnc_twin.planner.feed import plan_feed_windows, plan_key

        prog, T = self.prog, self.period
        first: list[Record] = []
        periods: list[int] = []
        if self.approach is not None:
            first.append(Move(end=self.approach.end, profile=self.approach.profile, periods=self.approach.periods))
            periods.append(self.approach.periods)
        spin = spindle_periods(prog, T)
        first += [Spindle(on=True, speed=prog.spindle_speed), Dwell(periods=spin)]
        periods += [0, spin]
        first.append(SurfaceGeometry(surface=prog.surface, lead=prog.lead, tilt=prog.tilt,
                                     pivot=prog.pivot_home, offset=prog.tool_offset))
        periods.append(0)
        yield first, periods
        axis_limits = tuple(tuple(getattr(c, k) for c in self.axes[:5])
                            for k in ("max_velocity", "max_acceleration", "max_jerk"))
        for i, (section, path) in enumerate(zip(prog.sections, self.paths)):
            head: list[Record] = [SurfaceCurve(section)]
            if i == 0:
                head.append(ForceControlRecord(on=True, params=prog.force))
            yield head, [0] * len(head)

            def axis_path(t, path=path):
                return section_poses(prog, path, t)

            # everything the section's plan depends on: a sweep of the force loop's or the servo's
            # gains replays it from the planner process's last runs
            key = plan_key(prog.surface, section, prog.limits, T, 0.05, prog.lead, prog.tilt, prog.pivot_home,
                           prog.tool_offset, axis_limits)
            for blocks in plan_feed_windows(path, prog.limits, period=T, window=0.05,
                                            axis_path=axis_path, axis_limits=axis_limits, key=key):
                yield [CurveBlock(b) for b in blocks], [math.ceil(b.duration / T) for b in blocks]
        tail: list[Record] = [ForceControlRecord(on=False, params=prog.force),
                              Spindle(on=False, speed=0.0), Dwell(periods=spin)]
        tail_periods = [0, 0, spin]
        # from the clear pose above the last section's end: Z up to home, then every axis home
        last = self.paths[-1]
        t1 = last.domain[1]
        axis = last.axes([t1], prog.lead, prog.tilt)
        clear = head_of(prog).axes_from_pose(last.point([t1]) + prog.force.standoff * axis, axis)[0]
        here = tuple(float(x) for x in clear) + (self.home[5],)
        up = (here[0], here[1], self.home[2], here[3], here[4], here[5])
        for chunk in (move_chunk(here, up, self.axes, period=T), move_chunk(up, self.home, self.axes, period=T),
                      dwell_chunk(prog.settle, T)):
            tail += chunk[0]
            tail_periods += chunk[1]
        yield tail + [EndOfProgram()], tail_periods + [0]
