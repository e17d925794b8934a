"""The NURBS curve program's plan: the approach move and a settle dwell, the curve's geometry
record, then its S-curve feed blocks window by window (:func:`cnc_twin.planner.feed.plan_feed_windows`),
and the settle dwell after the curve."""

from __future__ import annotations

import math

from cnc_twin.core.config import AxisConfig, NurbsProgram
from cnc_twin.planner.feed import plan_feed_windows, plan_key, sample_limits, traverse_time
from cnc_twin.planner.ptp import dwell_chunk, plan_move
from cnc_twin.whiteboard.records import CurveBlock, CurveGeometry, EndOfProgram, Move, Record


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


class CurvePlan:
    """A curve program: the curve, its kinematics and the approach move set up at once; the feed
    blocks planned window by window as :meth:`~CurvePlan.chunks` is asked (``window`` [m] of curve
    each)."""

    def __init__(self, prog: NurbsProgram, axes: tuple[AxisConfig, ...], home: tuple[float, ...], period: float,
                 *, window: float):
        self.prog, self.period, self.window = prog, period, window
        self.curve, start, self.axis_path, self.axis_limits, self.geometry = curve_setup(prog)
        self.approach = plan_move(tuple(home), start, axes, feed=prog.approach_feed, period=period)
        # sampled here, before the planner reports ready: the windows then plan on the samples in
        # the planning thread, which never holds the interpreter long while the card waits for an answer.
        # The plan depends on the program, the period and the window alone (the axes' limits are
        # the program's): a sweep of the servo's gains replays it in a pooled planner
        self.key = plan_key(prog, period, window)
        self.samples = sample_limits(self.curve, prog.limits, period=period, axis_path=self.axis_path,
                                     axis_limits=self.axis_limits, key=self.key)

    @property
    def estimated_periods(self) -> int:
        """Program length [periods], estimated: the approach, 1.2x the curve's time at its feed
        limit with the acceleration budget (a curve with many sharp corners takes several times its
        length at feed), the settle."""
        prog, period = self.prog, self.period
        curve_time = 1.2 * traverse_time(self.samples)
        approach = self.approach.periods + math.ceil(prog.settle / period) if self.approach else 0
        return approach + math.ceil((curve_time + prog.settle) / period)

    def chunks(self):
        """Successive ``(records, periods)`` chunks, planned as they are asked for."""
        prog, period, approach = self.prog, self.period, self.approach
        records: list[Record] = []
        periods: list[int] = []
        if approach is not None:
            # the approach, then the settle: the curve starts with the axes at rest on its start
            # (the approach's following error decays first), not one period after a long move
            records.append(Move(end=approach.end, profile=approach.profile, periods=approach.periods))
            periods.append(approach.periods)
            settle, settle_periods = dwell_chunk(prog.settle, period)
            records += settle
            periods += settle_periods
        records.append(self.geometry)
        periods.append(0)
        yield records, periods
        for blocks in plan_feed_windows(self.curve, prog.limits, period=period, window=self.window,
                                        axis_path=self.axis_path, axis_limits=self.axis_limits, samples=self.samples,
                                        key=self.key):
            yield ([CurveBlock(b) for b in blocks], [math.ceil(b.duration / period) for b in blocks])
        tail, tail_periods = dwell_chunk(prog.settle, period)
        yield tail + [EndOfProgram()], tail_periods + [0]
