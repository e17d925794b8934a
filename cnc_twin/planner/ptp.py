"""Point-to-point planning: each move becomes one synchronised trapezoid segment.

For a move with per-axis displacement ``d_i``, the normalised profile limits are::

    v_s = min( min_i v_max_i / |d_i| ,  feed / |d_xyz| )      [1/s]
    a_s = min_i a_max_i / |d_i|                                [1/s^2]

so every axis stays within its own velocity and acceleration limits, the tool's X/Y/Z speed
within ``feed``, and all axes start and arrive together. Durations are rounded up to whole
interpolation periods.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from cnc_twin.core.axes import LINEAR_AXES
from cnc_twin.motion.trapezoid import Trapezoid
from cnc_twin.motion.segments import DwellSegment, MoveSegment, Segment
from cnc_twin.core.config import AxisConfig, PointToPoint
from cnc_twin.whiteboard.records import Dwell, Move, Record


def plan_point_to_point(
    program: PointToPoint, axes: Sequence[AxisConfig], *, start: Sequence[float], period: float
) -> list[Segment]:
    """Plan every move and dwell of ``program`` from ``start`` [m | rad].

    Parameters
    ----------
    program : the scenario's point-to-point program (SI).
    axes : the six axis configurations, in axis order.
    start : position of each axis when the program starts, shape ``(6,)``.
    period : interpolation period [s].

    Returns
    -------
    list of segments, ending with a dwell of ``program.settle`` so the run records settling.
    """
    segments: list[Segment] = []
    end = tuple(float(p) for p in start)
    for move, (begin, end) in zip(program.moves, move_ends(program, start)):
        segment = plan_move(begin, end, axes, feed=move.feed, period=period)
        if segment is not None:
            segments.append(segment)
        if move.dwell > 0:
            segments.append(DwellSegment(position=end, periods=dwell_periods(move.dwell, period)))
    if program.settle > 0:
        segments.append(DwellSegment(position=end, periods=dwell_periods(program.settle, period)))
    return segments


def move_ends(program: PointToPoint, start: Sequence[float]) -> list[tuple[tuple[float, ...], tuple[float, ...]]]:
    """``(from, to)`` of each move [m | rad], shape ``(6,)`` each: an axis a move leaves out stays
    where it is."""
    here, ends = tuple(float(p) for p in start), []
    for move in program.moves:
        target = tuple(here[i] if t is None else t for i, t in enumerate(move.targets))
        ends.append((here, target))
        here = target
    return ends


def axis_scales(start: tuple[float, ...], end: tuple[float, ...], axes: Sequence[AxisConfig]
                ) -> tuple[float, float, float, int]:
    """What the axes allow a move: ``(v_s [1/s], a_s [1/s^2], |d_xyz| [m], the axis that sets v_s)``
    (see the module docstring; v_s infinite and the axis -1 when nothing moves)."""
    v_s, a_s, xyz_sq, slowest = math.inf, math.inf, 0.0, -1
    for i, (cfg, p0, p1) in enumerate(zip(axes, start, end)):
        d = abs(p1 - p0)
        if d == 0.0:
            continue
        if cfg.max_velocity / d < v_s:
            v_s, slowest = cfg.max_velocity / d, i
        a_s = min(a_s, cfg.max_acceleration / d)
        if cfg.name in LINEAR_AXES:
            xyz_sq += d * d
    return v_s, a_s, math.sqrt(xyz_sq), slowest


def plan_move(
    start: tuple[float, ...], end: tuple[float, ...], axes: Sequence[AxisConfig], *, feed: float | None, period: float
) -> MoveSegment | None:
    """One synchronised move, or ``None`` when nothing moves."""
    v_s, a_s, xyz, _ = axis_scales(start, end, axes)
    if math.isinf(v_s):
        return None
    if feed is not None and xyz > 0.0:
        v_s = min(v_s, feed / xyz)
    profile, periods = Trapezoid.fastest(v_s, a_s).quantised(period)
    return MoveSegment(start=start, end=end, profile=profile, periods=periods)


def dwell_periods(seconds: float, period: float) -> int:
    """Whole interpolation periods of a dwell of ``seconds`` (at least one)."""
    return max(1, math.ceil(seconds / period - 1e-9))


def move_chunk(start: tuple[float, ...], end: tuple[float, ...], axes: Sequence[AxisConfig], *,
               feed: float | None = None, period: float) -> tuple[list[Record], list[int]]:
    """A planned move as ``([Move], [periods])``, or ``([], [])`` when nothing moves."""
    seg = plan_move(tuple(start), tuple(end), axes, feed=feed, period=period)
    if seg is None:
        return [], []
    return [Move(end=seg.end, profile=seg.profile, periods=seg.periods)], [seg.periods]


def dwell_chunk(seconds: float, period: float) -> tuple[list[Record], list[int]]:
    """A dwell as ``([Dwell], [periods])``, or ``([], [])`` for none (``seconds <= 0``)."""
    if seconds <= 0:
        return [], []
    n = dwell_periods(seconds, period)
    return [Dwell(periods=n)], [n]
