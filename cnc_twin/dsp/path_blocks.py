"""What the interpolator runs on curve and surface paths: one class per record kind, built when the
record is accepted (the card decodes ahead) and run when it reaches the head of the queue
(:class:`~cnc_twin.dsp.interpolator.SegmentInterpolator`); and the rule the running segment's
time scale follows.

- :class:`Curve` (from a CurveGeometry record): ``stepper``, the curve's arc-length stepper
  (:class:`~cnc_twin.dsp.curve_stepper.CurveStepper`; its ``point`` [m], shape ``(3,)``, and
  parameter ``u``); ``hold``, the held A, B, C [rad], shape ``(3,)``; ``axis``, the tool-axis
  curve's span evaluator (None when A and B are held), with ``pivot`` and ``offset``, the head
  geometry [m], shape ``(3,)`` each; ``start`` and ``end``, the machine positions at the
  curve's ends (X, Y, Z [m], A, B, C [rad]), shape ``(6,)``, with ``start_axis`` and
  ``end_axis``, the tool axis there (world frame, unit), shape ``(3,)``. ``pose(point, u)`` is the machine position
  for the tip at ``point``: X, Y, Z = ``point`` and the held A, B, C, or the head's inverse
  kinematics for the tool axis at ``u`` (C held).
- :class:`Surface` (from a SurfaceGeometry record): ``evaluator``, the surface's span evaluator;
  ``lead`` and ``tilt`` of the tool axis [rad]; ``pivot`` and ``offset``, the head geometry [m],
  shape ``(3,)`` each. Shared by the sections that follow it.
- :class:`SurfaceRun` (from a SurfaceCurve record, one section of a surface path): ``surface``
  (the :class:`Surface`); ``evaluator``, the surface-path evaluator of the (u, v) curve on it
  (:mod:`cnc_twin.geometry.surface_path`); ``stepper``, its arc-length stepper (compiled
  or Python, as for a curve); ``c_hold``, the held C [rad];
  ``start`` and ``end``, the machine positions at the section's ends, shape ``(6,)``, with
  ``start_axis`` and ``end_axis``, the tool axis there (world frame, unit), shape ``(3,)``;
  ``axis``, the tool axis of the last pose, shape ``(3,)``. ``pose(point, u)``: the tool
  axis is the surface normal at the stepper's point with lead and tilt, and the head's
  inverse kinematics solve X, Y, Z [m], A, B [rad]; C is held.
- :class:`ForceWait` (from a ForceControlRecord): force control switching on (seek, ramp up) at
  the following section's (or curve's) start or off (ramp down, retract) at the last one's end.
  ``record``; ``on``; ``base``, the section's pose there, shape ``(6,)``; ``axis``, the tool
  axis there, shape ``(3,)``; ``clear_pose``, ``base`` moved ``standoff`` [m] up the tool axis
  (where the tool is while force control is off), shape ``(6,)``.
- :class:`Block` (from a CurveBlock record): ``profile``, the block's S-curve
  (:class:`~cnc_twin.motion.scurve.SCurve`: duration [s], length [m], speeds [m/s]);
  ``curve``, the :class:`Curve` or :class:`SurfaceRun` it runs on; ``periods``, its duration
  in interpolation periods (rounded up).

:func:`slew` moves the time scale ``lambda`` (the running segment's clock rate, 1 = as
programmed) toward its target as fast as the acceleration limit allows, with the margin
:data:`SLEW_MARGIN` for the discrete step (see :mod:`cnc_twin.dsp.interpolator`).

How the interpolator runs them. Surfaces (SurfaceGeometry, then SurfaceCurve sections with their CurveBlocks): each section is a
(u, v) curve on the surface, stepped like a curve (:mod:`cnc_twin.geometry.surface_path`); the
pose's tool axis is the surface normal with lead and tilt, and the kinematics solve X/Y/Z/A/B.
ForceControl records wait at the head of the queue until the force loop
(:mod:`cnc_twin.dsp.force`) has made contact and ramped up (on) or ramped down and retracted
(off); in between the loop's ``depth`` is added along the tool axis every period and its feed
factor scales the path's speed. Spindle records put C in speed mode: its angle advances by the
ramped speed each period, on top of every C setpoint.
"""

from __future__ import annotations

import bisect
import math

from cnc_twin.dsp.curve_stepper import CurveStepper
from cnc_twin.dsp.feed_slew import stop_distance
from cnc_twin.geometry.kinematics import pose_to_axes, tool_axis
from cnc_twin.geometry.nurbs import NurbsCurve
from cnc_twin.geometry.surface import NurbsSurface, SurfaceSpanEvaluator
from cnc_twin.geometry.surface_path import SurfacePathEvaluator, tool_axis_at
from cnc_twin.whiteboard.records import CurveBlock, CurveGeometry, ForceControlRecord, SurfaceCurve, SurfaceGeometry

SLEW_MARGIN = 0.9
"""fraction of the acceleration limit the time-scale slew (and the stops it plans for) may use"""


class Curve:
    """A curve ready to run: its stepper, and either the held A, B, C or the tool-axis curve with
    the head geometry for the per-period kinematics (tip + axis -> X, Y, Z, A, B)."""

    def __init__(self, record: CurveGeometry, compiled: bool = True):
        curve = NurbsCurve(record.control_points, record.weights, record.knots, record.degree)
        self.stepper = CurveStepper(curve.span_evaluator(), curve.domain[0], compiled=compiled)
        self.hold = tuple(record.hold)
        self.line_us = [u for u, _ in record.lines]
        """where the curve's program lines start [u], increasing; empty: no line marks"""
        self.line_numbers = [line for _, line in record.lines]
        self.axis = None
        if record.axis is not None:
            ac = record.axis
            self.axis = NurbsCurve(ac.control_points, ac.weights, ac.knots, ac.degree).span_evaluator()
            self.pivot, self.offset = tuple(record.pivot), tuple(record.offset)
        t0, t1 = curve.domain
        self.start = self.pose(curve.point(t0)[0].tolist(), t0)
        self.end = self.pose(curve.point(t1)[0].tolist(), t1)
        self.start_axis, self.end_axis = self.tool_axis(t0), self.tool_axis(t1)
        """the tool axis at the ends (world frame, unit), for the force loop's seek and retract"""

    def line_at(self, u: float) -> int:
        """The program line the curve runs at parameter ``u`` (``line_us`` not empty)."""
        return self.line_numbers[max(bisect.bisect_right(self.line_us, u) - 1, 0)]

    def tool_axis(self, u: float) -> tuple[float, float, float]:
        """Unit tool axis (world frame) at parameter ``u``: the held A / B's, or the axis curve's."""
        if self.axis is None:
            return tool_axis(self.hold[0], self.hold[1])
        n = self.axis.evaluate(u)[0]
        norm = math.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
        return (n[0] / norm, n[1] / norm, n[2] / norm)

    def pose(self, point: list[float], u: float) -> tuple[float, ...]:
        """Machine position (X, Y, Z, A, B, C) for the tip at ``point`` and parameter ``u``."""
        if self.axis is None:
            return (point[0], point[1], point[2], *self.hold)
        x, y, z, a, b = pose_to_axes(point, self.axis.evaluate(u)[0], self.pivot, self.offset)
        return (x, y, z, a, b, self.hold[2])


class Surface:
    """The surface of the following path sections, ready for per-period evaluation."""

    def __init__(self, record: SurfaceGeometry):
        self.evaluator: SurfaceSpanEvaluator = NurbsSurface.from_def(record.surface).span_evaluator()
        self.lead, self.tilt = record.lead, record.tilt
        self.pivot, self.offset = tuple(record.pivot), tuple(record.offset)


class SurfaceRun:
    """One path section on a surface: its stepper, the tool axis along the surface normal (with
    lead and tilt), the kinematics per period. ``axis`` is the tool axis of the last pose."""

    def __init__(self, surface: Surface, section: SurfaceCurve, c_hold: float, compiled: bool = True):
        c = section.curve
        uv = NurbsCurve(c.control_points, c.weights, c.knots, c.degree)
        self.surface = surface
        self.evaluator = SurfacePathEvaluator(surface.evaluator, uv.span_evaluator())
        self.c_hold = c_hold
        t0, t1 = uv.domain
        ev = self.evaluator
        self.end = self._pose(ev.evaluate(t1)[0], ev.last_su, ev.last_sv, ev.last_c1)
        self.end_axis = self.axis
        # the stepper keeps the tangents of the point it last evaluated: the tool axis of its pose
        self.stepper = CurveStepper(ev, t0, compiled=compiled)
        self.start = self.pose(self.stepper.point, t0)
        self.start_axis = self.axis

    def pose(self, point: list[float], u: float) -> tuple[float, ...]:
        """Machine position for the tip at ``point``, with the tool axis at the stepper's point."""
        return self._pose(point, *self.stepper.tangents())

    def _pose(self, point, su, sv, c1) -> tuple[float, ...]:
        sf = self.surface
        self.axis = tool_axis_at(su, sv, c1, sf.lead, sf.tilt)
        return (*pose_to_axes(point, self.axis, sf.pivot, sf.offset), self.c_hold)


class ForceWait:
    """Force control switching on (seek, ramp) or off (ramp down, retract) at the start or end pose
    of a surface section or a curve (a G-code path); the queue waits until it is done."""

    def __init__(self, record: ForceControlRecord, run: SurfaceRun | Curve):
        self.record = record
        self.on = record.on
        self.base = run.start if record.on else run.end
        self.axis = run.start_axis if record.on else run.end_axis
        standoff = record.params.standoff
        # where the tool is when force control is off: standoff above the section's pose
        self.clear_pose = tuple(p + standoff * n for p, n in zip(self.base[:3], self.axis)) + self.base[3:]


class Block:
    """A queued curve block: the S-curve and the curve (or surface section) it runs on."""

    def __init__(self, record: CurveBlock, curve: "Curve | SurfaceRun", period: float):
        self.profile = record.profile
        self.curve = curve
        self.periods = math.ceil(self.profile.duration / period)


def slew(lam: float, target: float, v: float, a: float, a_lim: float, dt: float) -> float:
    """Move the time scale toward ``target`` as fast as ``|a lam^2 + v lam'| <= a_lim`` allows."""
    if v <= 1e-12:
        return target
    if lam > target:
        return max(target, lam - SLEW_MARGIN * (a_lim + a * lam * lam) / v * dt)
    return min(target, lam + SLEW_MARGIN * (a_lim - a * lam * lam) / v * dt)


def stop_reserve(profile, period: float) -> float:
    """Queued path [m] the card keeps on an open curve: twice the distance a starved hold needs to
    stop from the block's peak speed ``vp``, so the hold never latches while records still wait
    in the FIFO."""
    return 2.0 * stop_distance(profile.vp, 0.0, SLEW_MARGIN * profile.a_max, SLEW_MARGIN * profile.j_max, period)
