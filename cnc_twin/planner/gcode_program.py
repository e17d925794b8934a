"""The G-code program's plan: its steps in order, records handed out in chunks.

Per step (:class:`~cnc_twin.core.gcode_config.GcodeProgram`)::

    GcodeMove     Mark line, Move (a synchronised trapezoid, the feed capping X/Y/Z, or A/B/C alone)
    GcodePath     Mark line, CurveGeometry (with the program line of each part of the curve, which
                  the card shows in the trace's ``mark`` as it runs them), its CurveBlocks planned
                  window by window (rest to rest)
    GcodePause    Mark line, Dwell
    GcodeSpindle  Mark line, Spindle
    GcodeProbe    Mark line, Probe (a trapezoid at the probe's feed), the last record of its chunk:
                  the next chunk waits for the card's answer (:meth:`GcodePlan.answer`), and the
                  steps after it are the program read again with the answers so far
                  (``GcodeProgram.after_probe``), from where the card stopped
    GcodeForce    on (M100): the next GcodePath's approach Move ends ``standoff`` above its start
                  along the tool axis, and a ForceControl on follows its CurveGeometry (the card
                  seeks contact, ramps, then runs the blocks); off (M101): Mark line, ForceControl
                  off (ramp down, retract to ``standoff`` above the last path's end: the next
                  move starts there)

then Dwell (settle), EndOfProgram.
"""

from __future__ import annotations

import dataclasses
import math

from cnc_twin.core.config import AxisConfig
from cnc_twin.core.gcode_config import (GcodeForce, GcodeMove, GcodePath, GcodePause, GcodeProbe, GcodeProgram,
                                        GcodeSpindle, ProbeAnswer)
from cnc_twin.geometry.kinematics import tool_axis
from cnc_twin.planner.ptp import dwell_chunk, plan_move
from cnc_twin.whiteboard.records import CurveBlock, EndOfProgram, ForceControlRecord, Mark, Move, Probe, Spindle


def _standoff(pose: tuple[float, ...], distance: float) -> tuple[float, ...]:
    """``pose`` (X, Y, Z [m], A, B, C [rad]) moved ``distance`` [m] up its tool axis."""
    n = tool_axis(pose[3], pose[4])
    return (*(p + distance * k for p, k in zip(pose[:3], n)), *pose[3:])


def _move_records(here: tuple[float, ...], step: GcodeMove, axes, period: float):
    """``([Move], [periods])`` of a G-code move (the feed caps X/Y/Z, or A/B/C when only they turn)."""
    if step.rotary_only and step.feed is not None:
        # plan_move caps only X/Y/Z by the feed: give the rotary axes' own cap through their limits
        axes = tuple(dataclasses.replace(a, max_velocity=min(a.max_velocity, step.feed)) if a.rotary else a
                     for a in axes)
        seg = plan_move(here, step.end, axes, feed=None, period=period)
    else:
        seg = plan_move(here, step.end, axes, feed=step.feed, period=period)
    if seg is None:
        return [], []
    return [Move(end=seg.end, profile=seg.profile, periods=seg.periods)], [seg.periods]


def _probe_records(here: tuple[float, ...], step: GcodeProbe, axes, period: float):
    """``([Probe], [periods])``: the probing move as a trapezoid at its feed along the tool axis."""
    seg = plan_move(here, step.end, axes, feed=step.feed, period=period)
    if seg is None:  # refused at load: a probe goes somewhere
        raise ValueError(f"line {step.line}: a probing move of no length")
    return [Probe(end=seg.end, profile=seg.profile, periods=seg.periods, trip_force=step.trip_force,
                  kind=step.kind)], [seg.periods]


def _end_pose(curve, axis_path, hold: tuple[float, ...]) -> tuple[float, ...]:
    """The six axes at a path's end: the curve's point with the held A, B, C, or (a varying tool
    axis) X, Y, Z, A, B through the kinematics with C held."""
    u1 = curve.domain[1]
    if axis_path is None:
        return (*curve.point(u1)[0].tolist(), *hold)
    return (*(float(x) for x in axis_path([u1])[0]), hold[2])


def feed_caps(prog: GcodeProgram, axes: tuple[AxisConfig, ...]) -> list[tuple[int, float, float, int]]:
    """The feed paths whose programmed feed is more than X/Y/Z's velocity limits allow anywhere
    along them (:func:`~cnc_twin.planner.feed.curve_feed_cap`): ``(line, feed [m/s], cap [m/s], axis)`` each."""
    from cnc_twin.planner.feed import curve_feed_cap

    out = []
    for path in prog.paths:
        capped = curve_feed_cap(path.curve, axes)
        if capped is not None:
            out.append((path.line, path.curve.limits.feed, *capped))
    return out


def turn_limited_time(c) -> float:
    """[s] roughly how long a joined feed path (a curve program ``c``) takes when its turns slow
    it, read off its control polygon (which follows a curve of Bezier pieces closely): where the
    polygon turns by ``theta`` between edges of length ``l`` the radius is about ``l / theta``;
    there the normal acceleration allows ``sqrt(a_n r)`` and the normal jerk, its curvature
    building up over ``l``, about ``(j_n r l)^(1/3)``; each edge runs at the feed or the slower
    of its two ends. A raster's corners blended within G64 P0.01, or a dense 3D polyline, run far
    below F on the card (an estimate at the feed would time the run out); a 50 mm radius at
    3 m/min runs at F."""
    points = [c.control_points[0]]
    for q in c.control_points[1:]:  # the pieces' shared ends are repeated: one of each
        if q != points[-1]:
            points.append(q)
    lim = c.limits
    edges = [math.dist(p, q) for p, q in zip(points, points[1:])]
    at_vertex = [lim.feed]  # the speed each vertex allows (the ends: the feed, ramps counted elsewhere)
    for j in range(1, len(points) - 1):
        d_in = [x1 - x0 for x0, x1 in zip(points[j - 1], points[j])]
        d_out = [x1 - x0 for x0, x1 in zip(points[j], points[j + 1])]
        cos = sum(x * y for x, y in zip(d_in, d_out)) / (edges[j - 1] * edges[j])
        theta = math.acos(max(-1.0, min(1.0, cos)))
        if theta < 1e-9:
            at_vertex.append(lim.feed)
            continue
        l = 0.5 * (edges[j - 1] + edges[j])
        r = l / theta
        at_vertex.append(min(lim.feed, math.sqrt(lim.normal_acceleration * r), (lim.normal_jerk * r * l) ** (1 / 3)))
    at_vertex.append(lim.feed)
    # the card's ramps between them are jerk-limited: over an edge the speed gains at most what
    # the tangential jerk gives in the time the edge takes (forward, then backward for braking)
    a, j = lim.tangential_acceleration, lim.tangential_jerk
    for order in (range(1, len(at_vertex)), range(len(at_vertex) - 2, -1, -1)):
        for k in order:
            prev = k - 1 if order.step == 1 else k + 1
            v0, length = max(at_vertex[prev], 1e-6), edges[min(k, prev)]
            t = length / v0
            at_vertex[k] = min(at_vertex[k], v0 + min(0.5 * j * t * t, a * t))
    return sum(2.0 * l / max(v0 + v1, 1e-6) for l, v0, v1 in zip(edges, at_vertex, at_vertex[1:]))


def move_starts(prog: GcodeProgram, home: tuple[float, ...]) -> list[tuple[GcodeMove, tuple[float, ...]]]:
    """Each coordinated move of the program with the six axes where it starts [m | rad] (after
    the step before it: a move's end, or a path's end pose)."""
    from cnc_twin.planner.curve_program import curve_setup

    here, out = tuple(home), []
    for step in prog.steps:
        if isinstance(step, GcodeMove):
            out.append((step, here))
            here = step.end
        elif isinstance(step, GcodePath):
            curve, _, axis_path, _, _ = curve_setup(step.curve)
            here = _end_pose(curve, axis_path, step.curve.hold)
    return out


class GcodePlan:
    """A G-code program, planned step by step as :meth:`~GcodePlan.chunks` is asked (``window`` [m]
    of curve per feed-planning window)."""

    def __init__(self, prog: GcodeProgram, axes: tuple[AxisConfig, ...], home: tuple[float, ...], period: float,
                 *, window: float):
        self.prog, self.axes, self.home, self.period, self.window = prog, axes, tuple(home), period, window
        self.answers: list[tuple[GcodeProbe, ProbeAnswer]] = []
        """each probe run so far with the card's answer (:meth:`answer`)"""

    def answer(self, answer: ProbeAnswer) -> None:
        """The card's answer to the probe :meth:`chunks` last handed out; the chunks after it are
        planned from it (asked for only once it is given)."""
        step = self._probing
        if step is None:
            raise RuntimeError("a probe answer with no probe running")
        self.answers.append((step, answer))
        self._probing = None

    _probing: GcodeProbe | None = None

    @property
    def estimated_periods(self) -> int:
        """Program length [periods], estimated: moves at their planned time, feed paths at 1.5x
        their length at feed or as their turns slow them (:func:`turn_limited_time`), whichever
        is longer, pauses, the settle."""
        from cnc_twin.planner.curve_program import curve_setup

        T, here, total = self.period, self.home, 0.0
        for step in self.prog.steps:
            if isinstance(step, GcodeMove):
                total += sum(_move_records(here, step, self.axes, T)[1]) * T
                here = step.end
            elif isinstance(step, GcodePath):
                c = step.curve
                length = sum(math.dist(p, q) for p, q in zip(c.control_points, c.control_points[1:]))
                total += max(1.5 * length / c.limits.feed, turn_limited_time(c)) + 0.05
                curve, _, axis_path, _, _ = curve_setup(c)
                here = _end_pose(curve, axis_path, c.hold)
            elif isinstance(step, GcodePause):
                total += step.seconds + T
            elif isinstance(step, GcodeProbe):  # its whole length (it stops short when it trips)
                total += sum(_probe_records(here, step, self.axes, T)[1]) * T
                here = step.end
            elif isinstance(step, GcodeForce) and step.control is not None:
                f = step.control  # seek from the standoff (twice: slack for a gap), ramps, retract
                total += 2.0 * f.standoff / f.seek_speed + 2.0 * f.ramp_time + f.standoff / f.retract_speed
        return math.ceil((total + self.prog.settle) / T)

    def chunks(self):
        """Successive ``(records, periods)`` chunks, planned as they are asked for."""
        from cnc_twin.planner.curve_program import curve_setup
        from cnc_twin.planner.feed import plan_feed_windows, plan_key

        T = self.period
        here = self.home
        force_on = None  # the ForceControl of an M100 waiting for the next path's start
        force = None  # the one in effect (for M101's record)
        steps, k = list(self.prog.steps), 0
        while k < len(steps):
            step = steps[k]
            k += 1
            mark = Mark(step.line)
            if isinstance(step, GcodeProbe):
                records, periods = _probe_records(here, step, self.axes, T)
                self._probing = step
                yield [mark] + records, [0] + periods
                if self._probing is not None:  # asked for more before the card answered
                    raise RuntimeError(f"line {step.line}: the program after a probe was asked for before its answer")
                here = self.answers[-1][1].stop
                steps, k = list(self.prog.after_probe(self.answers)), 0
            elif isinstance(step, GcodeMove):
                records, periods = _move_records(here, step, self.axes, T)
                yield [mark] + records, [0] + periods
                here = step.end
            elif isinstance(step, GcodePath):
                curve, start, axis_path, axis_limits, geometry = curve_setup(step.curve)
                records, periods = [mark], [0]
                if force_on is not None:  # the seek starts the standoff above the path's start
                    start = _standoff(start, force_on.standoff)
                if any(abs(a - b) > 1e-12 for a, b in zip(start, here)):  # a path never starts off the tool
                    seg = plan_move(here, start, self.axes, feed=step.curve.limits.feed, period=T)
                    if seg is not None:
                        records.append(Move(end=seg.end, profile=seg.profile, periods=seg.periods))
                        periods.append(seg.periods)
                records.append(dataclasses.replace(geometry, lines=step.lines))
                periods.append(0)
                if force_on is not None:
                    records.append(ForceControlRecord(on=True, params=force_on))
                    periods.append(0)
                    force, force_on = force_on, None
                yield records, periods
                # a varying tool axis: planned against every axis after the kinematics, as a curve
                # program; kept for a later run in the same planner process (a sweep's next gains)
                for blocks in plan_feed_windows(curve, step.curve.limits, period=T, window=self.window,
                                                axis_path=axis_path, axis_limits=axis_limits,
                                                key=plan_key(step.curve, T, self.window)):
                    yield [CurveBlock(b) for b in blocks], [math.ceil(b.duration / T) for b in blocks]
                here = _end_pose(curve, axis_path, step.curve.hold)
            elif isinstance(step, GcodePause):
                records, periods = dwell_chunk(max(step.seconds, T), T)
                yield [mark] + records, [0] + periods
            elif isinstance(step, GcodeSpindle):
                yield [mark, Spindle(on=step.speed != 0.0, speed=step.speed)], [0, 0]
            elif isinstance(step, GcodeForce):
                if step.control is not None:
                    force_on = step.control
                elif force is not None:  # retracted: the next move starts the standoff above
                    yield [mark, ForceControlRecord(on=False, params=force)], [0, 0]
                    here = _standoff(here, force.standoff)
                    force = None
        settle = dwell_chunk(self.prog.settle, T)
        yield settle[0] + [EndOfProgram()], settle[1] + [0]
