"""Runs of G1 lines as one smooth curve: CAM's dense segments fitted within G64 P.

A run is consecutive lines of one feed path (same feed, held axes and G64 P) that each turn less
than :data:`FIT_CORNER` from the last, at least :data:`MIN_SEGMENTS` of them. Its points, from
the middle of its first line to the middle of its last, are fitted with a cubic B-spline
(:func:`cnc_twin.geometry.fit.fit_polyline`) within ``FIT_SHARE`` of P, both ways: every
programmed point to the curve and the curve to every programmed segment. The curve leaves the
first half line and joins the last one along them, at unit parameter speed and without
curvature, so the corners at the run's ends (turns above :data:`FIT_CORNER`) stay corners for
the usual blend, between half lines. A run the fit cannot follow within P (it turns too sharply
for its tolerance) stays lines.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cnc_twin.gcode.path_ops import Operation, ToolAxisPath, Traverse
from cnc_twin.geometry.bezier import bezier_pieces, knot_spans
from cnc_twin.geometry.fit import DEGREE, Fit, FitError, chord_parameters, fit_polyline
from cnc_twin.geometry.kinematics import tool_axis

FIT_CORNER = math.radians(30.0)
"""a turn between two lines above this is a corner (blended, or a stop), never fitted across"""
MIN_SEGMENTS = 3
"""lines in a run, at least, for a fit (two lines are one corner: the blend serves them)"""
FIT_SHARE = 0.9
"""the fit's tolerance as a share of P: the rest is margin for the measured check"""


@dataclass(frozen=True)
class FittedRun:
    """A run of lines as: the first half line ``(start, middle)``, the fitted curve's rational
    Bezier pieces (homogeneous, each (4, 4)) with their parameter spans and program lines, and the
    last half line ``(middle, end)``; ``fit``: the fit and its measured deviation [mm]."""

    head: tuple[np.ndarray, np.ndarray]
    pieces: list[np.ndarray]
    spans: list[float]
    piece_lines: list[int]
    tail: tuple[np.ndarray, np.ndarray]
    fit: Fit


def turn_angle(d0: np.ndarray, d1: np.ndarray) -> float:
    """Angle [rad] between unit directions ``d0`` and ``d1``."""
    return math.acos(float(np.clip(np.dot(d0, d1), -1.0, 1.0)))


def fit_lines(points: np.ndarray, lines: list[int], tolerance: float) -> FittedRun | None:
    """The run of lines through ``points`` ((n + 1, 3) mm; line k from point k to k + 1, program
    line ``lines[k]``) fitted within ``FIT_SHARE * tolerance`` [mm]; None when the fit cannot
    follow it within that."""
    pts = np.asarray(points, dtype=np.float64)
    first, last = 0.5 * (pts[0] + pts[1]), 0.5 * (pts[-2] + pts[-1])
    t0 = (pts[1] - pts[0]) / np.linalg.norm(pts[1] - pts[0])
    t1 = (pts[-1] - pts[-2]) / np.linalg.norm(pts[-1] - pts[-2])
    data = np.vstack([first, pts[1:-1], last])
    try:
        fit = fit_polyline(data, FIT_SHARE * tolerance, start_tangent=t0, end_tangent=t1)
    except FitError:
        return None
    pieces = bezier_pieces(fit.points, np.ones(len(fit.points)), fit.knots, DEGREE)
    spans = knot_spans(fit.knots, DEGREE)
    # the fitted points' segment k lies on line k (the first and last only in half)
    return FittedRun((pts[0], first), pieces, spans, _span_lines(fit, data, lines), (last, pts[-1]), fit)


def _span_lines(fit: Fit, data: np.ndarray, lines: list[int]) -> list[int]:
    """The program line each knot span of ``fit`` starts on: segment k of the fitted points
    ``data`` is program line ``lines[k]``."""
    u = chord_parameters(data)  # the fit's own parameter at the points
    index = np.clip(np.searchsorted(u, np.unique(fit.knots)[:-1], side="right") - 1, 0, len(lines) - 1)
    return [lines[int(k)] for k in index]


@dataclass(frozen=True)
class FittedToolAxisRun:
    """A run of G1 lines that also turn the head (A / B), fitted whole: the tip curve and the
    tool-axis curve on the same ``knots`` (cubic, ``points`` and ``axis_points`` (n, 3)), with
    the program line of each knot span (``span_lines``, increasing ``(u, line)``)."""

    knots: np.ndarray
    points: np.ndarray
    axis_points: np.ndarray
    span_lines: list[tuple[float, int]]
    fit: Fit


def fit_tool_axis_lines(points: np.ndarray, axes: np.ndarray, lines: list[int], tolerance: float,
                        axis_tolerance: float) -> FittedToolAxisRun | None:
    """The run through ``points`` ((n + 1, 3) mm) with the unit tool ``axes`` there ((n + 1, 3);
    line k from point k to k + 1 is program line ``lines[k]``) fitted within ``FIT_SHARE *
    tolerance`` [mm] and ``axis_tolerance`` [rad], from its first point to its last (it starts and
    ends at rest); None when the fit cannot follow it."""
    pts = np.asarray(points, dtype=np.float64)
    try:
        fit = fit_polyline(pts, FIT_SHARE * tolerance, axes=axes, axis_tolerance=axis_tolerance)
    except FitError:
        return None
    span_lines: list[tuple[float, int]] = []  # (u, line) where the line changes
    for start, line in zip(np.unique(fit.knots)[:-1], _span_lines(fit, pts, lines)):
        if not span_lines or span_lines[-1][1] != line:
            span_lines.append((float(start), line))
    return FittedToolAxisRun(fit.knots, fit.points, fit.axis_points, span_lines, fit)


def tool_axis_paths(moves: list[tuple], axis_tolerance: float) -> list[Operation]:
    """G1 moves turning the head, in order: each run of :data:`~cnc_twin.gcode.line_fit.MIN_SEGMENTS`
    or more (same feed and G64 P, each turning the tip less than :data:`~cnc_twin.gcode.line_fit.FIT_CORNER`)
    fitted whole (:func:`~cnc_twin.gcode.line_fit.fit_tool_axis_lines`); the others, and a run the
    fit cannot follow, as coordinated moves of the axes, one per line."""
    out: list[Operation] = []
    k = 0
    while k < len(moves):
        j = k
        while j + 1 < len(moves) and moves[j + 1][3] == moves[k][3] and _tip_turn(moves[j], moves[j + 1]) < FIT_CORNER:
            j += 1
        run = moves[k:j + 1]
        fitted = None
        if len(run) >= MIN_SEGMENTS:
            points = np.array([m[0] for m in run] + [run[-1][1]])
            axes = np.array([tool_axis(math.radians(p[3]), math.radians(p[4])) for p in points])
            lines, tolerance = [m[2] for m in run], run[0][3][1][1]
            fitted = fit_tool_axis_lines(points[:, :3], axes, lines, tolerance, axis_tolerance)
        if fitted is None:
            out += [Traverse(tuple(float(x) for x in end), feed, line) for _, end, line, (feed, _) in run]
        else:
            out.append(_tool_axis_path(fitted, points[:, :3], axes, lines, run[0][3][0], float(run[0][0][5]),
                                       tolerance, axis_tolerance))
        k = j + 1
    return out


def _tool_axis_path(fitted: FittedToolAxisRun, points, axes, lines, feed, c, tolerance, axis_tolerance) -> ToolAxisPath:
    return ToolAxisPath(fitted.knots, fitted.points, fitted.axis_points, feed, c, lines[0], fitted.span_lines,
                        tolerance, fitted.fit.deviation, fitted.fit.axis_deviation, points, axes, lines, axis_tolerance)


def _cut_point(points: np.ndarray) -> int:
    """Where to cut a run in two: in its middle half, at the programmed point where it turns most
    (a tight turn is slow anyway: the stop between the halves costs least there)."""
    d = np.diff(points, axis=0)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    turns = np.arccos(np.clip(np.sum(d[1:] * d[:-1], axis=1), -1.0, 1.0))  # at points 1 .. m - 2
    lo, hi = len(points) // 4, 3 * len(points) // 4
    return lo + int(np.argmax(turns[lo - 1:hi - 1])) if hi - lo > 1 else len(points) // 2


def split_tool_axis_path(path: ToolAxisPath) -> list[ToolAxisPath]:
    """``path`` cut at a programmed point (``_cut_point``) into two, each fitted again (a card
    whose memory cannot hold the whole curve runs them one after the other, rest to rest); a half
    the fit cannot follow any more raises :class:`~cnc_twin.geometry.fit.FitError`."""
    middle = _cut_point(path.program_points)
    if min(middle, len(path.program_points) - 1 - middle) < MIN_SEGMENTS:
        raise FitError("too short to cut")
    out = []
    for first, last in ((0, middle), (middle, len(path.program_points) - 1)):  # points first..last
        points, axes = path.program_points[first:last + 1], path.program_axes[first:last + 1]
        lines = path.program_lines[first:last]
        fitted = fit_tool_axis_lines(points, axes, lines, path.tolerance, path.axis_tolerance)
        if fitted is None:
            raise FitError("a half of the run cannot be fitted within the tolerance")
        out.append(_tool_axis_path(fitted, points, axes, lines, path.feed, path.c, path.tolerance, path.axis_tolerance))
    return out


def _tip_turn(a: tuple, b: tuple) -> float:
    """Angle [rad] the tip's path turns between two moves ``(start, end, ...)``."""
    da, db = a[1][:3] - a[0][:3], b[1][:3] - b[0][:3]
    return turn_angle(da / np.linalg.norm(da), db / np.linalg.norm(db))
