"""Consecutive feed elements -> feed paths (:class:`~cnc_twin.gcode.path_ops.FeedPath`): a new
path where the feed, the held axes or the control mode change, and at corners that are not
blended; under G64 P runs of gently turning lines fitted as curves
(:mod:`~cnc_twin.gcode.line_fit`); corners between lines blended (``_blend_corners``).

A program's G1 lines come as :class:`~cnc_twin.gcode.path_ops.LineChain` (their points in one
array): their turns are found for the whole chain at once, and a line becomes an
:class:`~cnc_twin.gcode.path_ops.Element` only where it stays a line (a fitted run of them is
its two half lines and its curve). Element for element the paths are those made from one
Element per line, bit for bit: each chain turn is the same arithmetic on the same numbers
(``tests/test_program_streaming.py`` checks)."""

from __future__ import annotations

import math

import numpy as np

from cnc_twin.gcode.line_fit import FIT_CORNER, MIN_SEGMENTS, fit_lines
from cnc_twin.gcode.path_ops import Element, FeedPath, LineChain, line_element
from cnc_twin.geometry.bezier import homogeneous

TANGENT_ANGLE = 1e-4
"""[rad] a join turning less than this is tangent: the path runs through it without a blend"""
BLEND_MAX_ANGLE = math.radians(120.0)
"""[rad] a corner turning more than this is not blended (a reversal): the path stops there"""


def chain_turns(points: np.ndarray) -> list[float]:
    """[rad] the turn at each inner vertex of the lines through ``points`` ((n + 1, 3) mm):
    :func:`element_turn` of each two consecutive line elements, computed for all of them at once with the
    same operations (a line's direction: its difference over its length, zero when that is 1e-12
    or less; the turn: acos of the dot product, sums left to right, clipped to [-1, 1])."""
    d = points[1:] - points[:-1]
    norm = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2])
    unit = np.zeros_like(d)
    long = norm > 1e-12
    unit[long] = d[long] / norm[long, None]
    c = unit[:-1, 0] * unit[1:, 0] + unit[:-1, 1] * unit[1:, 1] + unit[:-1, 2] * unit[1:, 2]
    return [math.acos(-1.0 if x < -1.0 else (1.0 if x > 1.0 else x)) for x in c.tolist()]


class OpenChain:
    """The G1 lines of an open feed path since its last other element, in Python floats as the
    reader gathers them (:class:`~cnc_twin.gcode.path_ops.LineChain` once the path closes:
    :func:`gathered_feed_paths`)."""

    def __init__(self, start: list[float], end: list[float], line: int):
        self.points, self.lines = [start[:3], end[:3]], [line]

    def add(self, end: list[float], line: int) -> None:
        self.points.append(end[:3])
        self.lines.append(line)

    def closed(self) -> LineChain:
        points = np.array(self.points)
        return LineChain(points, self.lines, chain_turns(points))


def _first_line(chain: LineChain) -> Element:
    return line_element(chain.points[0], chain.points[1], chain.lines[0])


def _last_line(chain: LineChain) -> Element:
    return line_element(chain.points[-2], chain.points[-1], chain.lines[-1])


def gathered_feed_paths(path: list[tuple[Element | OpenChain, tuple]], default_blend: float) -> list[FeedPath]:
    """:func:`feed_paths` of a path as the reader gathered it: its chains of lines still open
    (closed here: where the path is prepared, in a helper process for a long program)."""
    return feed_paths([(item.closed() if isinstance(item, OpenChain) else item, m) for item, m in path], default_blend)


def feed_paths(path: list[tuple[Element | LineChain, tuple]], default_blend: float) -> list[FeedPath]:
    """Consecutive feed elements and chains of lines, each with its modes ``(feed, held A B C,
    control)``, as feed paths: a new path where the modes change, and at corners that are not
    blended (``_joins``)."""
    out: list[FeedPath] = []
    run: list[Element | LineChain] = []
    modes = None
    for item, m in path:
        if isinstance(item, LineChain):
            for piece in _joined_pieces(item, m[2]):
                first = _first_line(piece)
                if run and (m != modes or not _joins(_end_of(run[-1]), first, m[2])):
                    out.append(_finish(run, modes, default_blend))
                    run = []
                run.append(piece)
                modes = m
            continue
        if run and (m != modes or not _joins(_end_of(run[-1]), item, m[2])):
            out.append(_finish(run, modes, default_blend))
            run = []
        run.append(item)
        modes = m
    if run:
        out.append(_finish(run, modes, default_blend))
    return out


def _end_of(item: Element | LineChain) -> Element:
    return _last_line(item) if isinstance(item, LineChain) else item


def _joined_pieces(chain: LineChain, control: tuple) -> list[LineChain]:
    """``chain`` cut where two of its lines do not join (``_joins``: more than
    :data:`BLEND_MAX_ANGLE`, or any corner outside G64)."""
    turns = chain.turns
    blends = control[0] == "CANON_CONTINUOUS"
    cuts = [k + 1 for k, turn in enumerate(turns)
            if not (turn <= TANGENT_ANGLE or (blends and turn <= BLEND_MAX_ANGLE))]
    if not cuts:
        return [chain]
    bounds = [0, *cuts, len(chain.lines)]
    return [chain.part(a, b) for a, b in zip(bounds, bounds[1:])]


def element_turn(a: Element, b: Element) -> float:
    """Angle [rad] the path turns from ``a``'s end to ``b``'s start (kept on ``b`` with ``a``: the
    joins, the fit runs and the blends each ask for it)."""
    kept = b.__dict__.get("_turn_from")
    if kept is not None and kept[0] is a:
        return kept[1]
    c = float(np.dot(a.direction(True), b.direction(False)))
    c = -1.0 if c < -1.0 else (1.0 if c > 1.0 else c)  # np.clip's result (NaN kept), without its cost on a scalar
    turn = math.acos(c)
    b.__dict__["_turn_from"] = (a, turn)
    return turn


def _joins(a: Element, b: Element, control: tuple) -> bool:
    """``b`` continues ``a``'s path: tangent, or (in G64) a line-line corner that can be blended."""
    turn = element_turn(a, b)
    if turn <= TANGENT_ANGLE:
        return True
    return control[0] == "CANON_CONTINUOUS" and a.kind == b.kind == "line" and turn <= BLEND_MAX_ANGLE


def _finish(run: list[Element | LineChain], modes: tuple, default_blend: float) -> FeedPath:
    feed, hold, control = modes
    tolerance = control[1] or default_blend
    p = control[1] if control[0] == "CANON_CONTINUOUS" and control[1] > 0.0 else None
    programmed = list(run)
    if p is not None:  # G64 P: runs of gently turning lines (CAM's) as fitted curves
        elements = _fit_runs(run, p)
    else:
        elements = [e for item in run for e in _elements(item)]
    return FeedPath(_blend_corners(elements, tolerance), feed, hold, elements[0].line, p, programmed)


def _elements(item: Element | LineChain) -> list[Element]:
    """An element as it is, a chain as its lines."""
    if not isinstance(item, LineChain):
        return [item]
    p = item.points
    return [line_element(p[k], p[k + 1], line) for k, line in enumerate(item.lines)]


def _fit_runs(run: list[Element | LineChain], tolerance: float) -> list[Element]:
    """Each run of :data:`~cnc_twin.gcode.line_fit.MIN_SEGMENTS` or more lines turning less than
    :data:`~cnc_twin.gcode.line_fit.FIT_CORNER` at each point, as its first half line, one fitted
    curve and its last half line (:func:`~cnc_twin.gcode.line_fit.fit_lines`); the rest as it is.
    A path's lines are its chains' (two chains never follow each other in one path)."""
    out: list[Element] = []
    for item in run:
        if not isinstance(item, LineChain):
            out.append(item)
            continue
        turns, count = item.turns, len(item.lines)
        k = 0
        while k < count:
            j = k
            while j + 1 < count and turns[j] < FIT_CORNER:
                j += 1
            fitted = None
            if j - k + 1 >= MIN_SEGMENTS:
                fitted = fit_lines(item.points[k:j + 2], item.lines[k:j + 1], tolerance)
            if fitted is None:
                out += _elements(item.part(k, j + 1))
            else:
                out.append(line_element(*fitted.head, item.lines[k]))
                out.append(Element(fitted.pieces, item.lines[k], "fit", spans=fitted.spans,
                                   piece_lines=fitted.piece_lines, deviation=fitted.fit.deviation))
                out.append(line_element(*fitted.tail, item.lines[j]))
            k = j + 1
    return out


def _blend_corners(run: list[Element], tolerance: float) -> list[Element]:
    """Each corner between two lines replaced by a cubic Bezier ``(P0, C, C, P3)`` that leaves the
    incoming line at ``P0`` and joins the outgoing one at ``P3``, both ``d`` from the corner ``C``.

    The blend is tangent to both lines with zero curvature where it meets them (its second
    derivative at each end lies along the line), so feed and acceleration stay continuous. Its
    farthest point from the corner is ``d sin(theta / 2) / 4`` (``theta``: the turn), which the
    tolerance bounds; ``d`` is also at most half of either line, so blends never overlap.
    """
    lines = [e.start.copy() for e in run] + [run[-1].end.copy()]
    cuts = [0.0] * (len(run) + 1)  # how far each corner's blend reaches along its lines
    for k in range(1, len(run)):
        a, b = run[k - 1], run[k]
        turn = element_turn(a, b)
        if turn > TANGENT_ANGLE:
            la, lb = a.length, b.length
            cuts[k] = min(4.0 * tolerance / math.sin(0.5 * turn), 0.5 * la, 0.5 * lb)
    out: list[Element] = []
    for k, e in enumerate(run):
        if e.kind != "line" or (cuts[k] == 0.0 and cuts[k + 1] == 0.0):
            out.append(e)
        else:
            s, t = lines[k], lines[k + 1]
            u = (t - s) / np.linalg.norm(t - s)
            p0, p1 = s + cuts[k] * u, t - cuts[k + 1] * u
            if np.linalg.norm(p1 - p0) > 1e-9:
                out.append(line_element(p0, p1, e.line))
        if k + 1 < len(run) and cuts[k + 1] > 0.0:
            corner = lines[k + 1]
            d_in, d_out = run[k].direction(True), run[k + 1].direction(False)
            p0, p3 = corner - cuts[k + 1] * d_in, corner + cuts[k + 1] * d_out
            out.append(Element([homogeneous([p0, corner, corner, p3], [1.0] * 4)], run[k + 1].line, "blend"))
    return out
