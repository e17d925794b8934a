"""Planar contours of straight lines and circular arcs (G01 / G02 / G03), in SI metres.

A contour is a sequence of :data:`Element` s in one plane, points are ``(x, y)`` in m. An arc
runs from ``start`` to ``end`` about ``center`` in the given direction; its radius is
``|start - center|`` and its sweep is the angle from start to end in that direction, in
``(0, 2 pi]``. ``end == start`` (exactly equal tuples) is a full circle (sweep ``2 pi``).

Every element has an exact rational quadratic NURBS (:func:`element_nurbs`) on ``[0, 1]`` so a
contour can be handed to the NURBS interpolator. An arc is cut into at most-quarter-circle
pieces, each the textbook rational Bezier arc::

    P0 = c + r e(t0),  P1 = c + r / cos(h) e(t0 + h),  P2 = c + r e(t0 + 2 h),
    weights (1, cos h, 1),  h = half the piece sweep (signed by the direction)

:func:`contour_distance` gives the exact shortest distance of many points to a contour, and
:func:`check_contour` rejects contours that are degenerate or do not join up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

TWO_PI = 2.0 * math.pi
JOIN_TOLERANCE = 1e-12  # [m] largest gap between consecutive elements that still counts as joined
RADIUS_ABS_TOLERANCE = 1e-9  # [m] start/end radius mismatch allowed on an arc ...
RADIUS_REL_TOLERANCE = 1e-9  # ... plus this fraction of the larger radius
_POINT_CHUNK = 1 << 20  # [entries] bound on a (points x elements) work array in contour_distance


@dataclass(frozen=True)
class Line:
    """Straight segment (G01) from ``start`` to ``end``, both ``(x, y)`` in m."""

    start: tuple[float, float]
    end: tuple[float, float]


@dataclass(frozen=True)
class Arc:
    """Circular arc (G02 clockwise / G03 counter-clockwise) about ``center``; points in m.

    ``end == start`` (exactly equal tuples) means a full circle.
    """

    start: tuple[float, float]
    end: tuple[float, float]
    center: tuple[float, float]
    clockwise: bool


#: one element of a contour: a :class:`Line` or an :class:`Arc`
Element = Line | Arc


def _check_type(el) -> None:
    if not isinstance(el, (Line, Arc)):
        raise TypeError(f"contour element must be a Line or an Arc, got {type(el).__name__}")


def _radius(arc: Arc) -> float:
    """Arc radius [m]: the distance of the start point from the centre."""
    return math.hypot(arc.start[0] - arc.center[0], arc.start[1] - arc.center[1])


def _start_angle(arc: Arc) -> float:
    """Polar angle [rad] of the start point about the centre, in (-pi, pi]."""
    return math.atan2(arc.start[1] - arc.center[1], arc.start[0] - arc.center[0])


def arc_sweep(arc: Arc) -> float:
    """Sweep angle [rad] of ``arc`` in its own direction, in ``(0, 2 pi]`` (full circle: ``2 pi``)."""
    if tuple(arc.start) == tuple(arc.end):
        return TWO_PI
    a0 = _start_angle(arc)
    a1 = math.atan2(arc.end[1] - arc.center[1], arc.end[0] - arc.center[0])
    sweep = ((a0 - a1) if arc.clockwise else (a1 - a0)) % TWO_PI
    # Distinct end points at the same polar angle only happen with mismatched radii (which
    # check_contour rejects); read them as a full turn so the sweep stays in (0, 2 pi].
    return sweep if sweep > 0.0 else TWO_PI


def element_length(el: Element) -> float:
    """Exact length [m] of a line or an arc (``radius * sweep``)."""
    _check_type(el)
    if isinstance(el, Line):
        return math.hypot(el.end[0] - el.start[0], el.end[1] - el.start[1])
    return _radius(el) * arc_sweep(el)


def elements_length(elements) -> float:
    """Total length [m] of a sequence of elements."""
    return math.fsum(element_length(el) for el in elements)


def _line_nurbs(line: Line):
    """Degree-2 NURBS of a segment: uniform speed because the middle point is the midpoint."""
    (x0, y0), (x1, y1) = line.start, line.end
    mid = (0.5 * (x0 + x1), 0.5 * (y0 + y1))
    points = [(float(x0), float(y0)), (float(mid[0]), float(mid[1])), (float(x1), float(y1))]
    return 2, [0.0, 0.0, 0.0, 1.0, 1.0, 1.0], [1.0, 1.0, 1.0], points


def _arc_nurbs(arc: Arc):
    """Rational quadratic NURBS of an arc: ``n`` equal pieces of at most a quarter turn each."""
    sweep = arc_sweep(arc)
    # The -1e-9 keeps a sweep of exactly k quarter turns (up to rounding) at k pieces.
    n = max(1, math.ceil(sweep / (math.pi / 2.0) - 1e-9))
    half = 0.5 * sweep / n  # [rad] half a piece's sweep, unsigned
    sign = -1.0 if arc.clockwise else 1.0
    cx, cy = float(arc.center[0]), float(arc.center[1])
    r, a0 = _radius(arc), _start_angle(arc)
    r_mid = r / math.cos(half)  # the end tangents of a piece meet this far out on its bisector

    points = [(float(arc.start[0]), float(arc.start[1]))]
    weights = [1.0]
    for i in range(n):
        t_mid = a0 + sign * (2 * i + 1) * half
        points.append((cx + r_mid * math.cos(t_mid), cy + r_mid * math.sin(t_mid)))
        weights.append(math.cos(half))
        if i < n - 1:
            t_end = a0 + sign * (2 * i + 2) * half
            points.append((cx + r * math.cos(t_end), cy + r * math.sin(t_end)))
        else:  # the given end point exactly, so consecutive elements still join bit for bit
            points.append((float(arc.end[0]), float(arc.end[1])))
        weights.append(1.0)

    interior = [k / n for k in range(1, n) for _ in range(2)]  # double knots: C1 joins
    knots = [0.0] * 3 + interior + [1.0] * 3
    return 2, knots, weights, points


def element_nurbs(el: Element) -> tuple[int, list[float], list[float], list[tuple[float, float]]]:
    """Exact NURBS ``(degree, knots, weights, control_points)`` of an element on ``u in [0, 1]``.

    Degree 2 for both kinds. A line has 3 control points (6 knots); an arc cut into ``n`` pieces
    has ``2 n + 1`` control points and ``2 n + 4`` knots. Control points are ``(x, y)`` in m.
    """
    _check_type(el)
    return _line_nurbs(el) if isinstance(el, Line) else _arc_nurbs(el)


def _line_distances(p: np.ndarray, lines: list[Line]) -> np.ndarray:
    """Distances [m] of points ``p`` (m, 2) to each segment: shape (m, k)."""
    a = np.array([ln.start for ln in lines], dtype=float)  # (k, 2)
    ab = np.array([ln.end for ln in lines], dtype=float) - a
    len2 = np.einsum("kd,kd->k", ab, ab)
    ap = p[:, None, :] - a[None, :, :]  # (m, k, 2)
    # Projection parameter clipped to the segment; a zero-length line is just its start point.
    t = np.divide(np.einsum("mkd,kd->mk", ap, ab), len2, out=np.zeros(ap.shape[:2]), where=len2 > 0)
    t = np.clip(t, 0.0, 1.0)
    d = ap - t[..., None] * ab
    return np.hypot(d[..., 0], d[..., 1])


def _arc_distances(p: np.ndarray, arcs: list[Arc]) -> np.ndarray:
    """Distances [m] of points ``p`` (m, 2) to each arc: shape (m, k)."""
    c = np.array([a.center for a in arcs], dtype=float)  # (k, 2)
    s = np.array([a.start for a in arcs], dtype=float)
    e = np.array([a.end for a in arcs], dtype=float)
    r = np.array([_radius(a) for a in arcs])
    a0 = np.array([_start_angle(a) for a in arcs])
    sweep = np.array([arc_sweep(a) for a in arcs])
    cw = np.array([a.clockwise for a in arcs])

    cp = p[:, None, :] - c[None, :, :]  # (m, k, 2)
    phi = np.arctan2(cp[..., 1], cp[..., 0])
    # Angle travelled from the start to the point's polar angle, in the arc's own direction; it
    # lies in [0, 2 pi], so a full circle (sweep 2 pi) holds every point without a special case.
    rel = np.where(cw, a0 - phi, phi - a0) % TWO_PI
    inside = rel <= sweep
    radial = np.abs(np.hypot(cp[..., 0], cp[..., 1]) - r)
    # Outside the angular extent the nearest arc point is an end point (the distance to a
    # circle point grows monotonically with the angle away from the point's polar angle).
    ds = p[:, None, :] - s[None, :, :]
    de = p[:, None, :] - e[None, :, :]
    ends = np.minimum(np.hypot(ds[..., 0], ds[..., 1]), np.hypot(de[..., 0], de[..., 1]))
    return np.where(inside, radial, ends)


def contour_distance(points, elements) -> np.ndarray:
    """Shortest distance [m] of each point to the union of ``elements``.

    ``points``: shape (m, 2) in m. Returns shape (m,). Exact (no sampling); with no elements
    every distance is ``inf`` (the distance to the empty set).
    """
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"points must have shape (m, 2), got {p.shape}")
    for el in elements:
        _check_type(el)
    lines = [el for el in elements if isinstance(el, Line)]
    arcs = [el for el in elements if isinstance(el, Arc)]
    out = np.full(len(p), np.inf)
    # Points in chunks so the (points x elements) work arrays stay bounded for long contours.
    step = max(1, _POINT_CHUNK // max(1, len(lines) + len(arcs)))
    for lo in range(0, len(p), step):
        chunk = p[lo:lo + step]
        if lines:
            out[lo:lo + step] = np.minimum(out[lo:lo + step], _line_distances(chunk, lines).min(axis=1))
        if arcs:
            out[lo:lo + step] = np.minimum(out[lo:lo + step], _arc_distances(chunk, arcs).min(axis=1))
    return out


def _mm(point) -> str:
    return f"({point[0] * 1e3:.6g}, {point[1] * 1e3:.6g}) mm"


def _check_element(i: int, el: Element) -> None:
    """Raise ValueError if element ``i`` is degenerate on its own."""
    coords = [*el.start, *el.end] + ([*el.center] if isinstance(el, Arc) else [])
    if not all(math.isfinite(v) for v in coords):
        raise ValueError(f"element {i}: coordinates must be finite, got {el}")
    if isinstance(el, Line):
        if tuple(el.start) == tuple(el.end):
            raise ValueError(f"element {i}: zero-length line at {_mm(el.start)}")
        return
    r0 = _radius(el)
    r1 = math.hypot(el.end[0] - el.center[0], el.end[1] - el.center[1])
    if r0 == 0.0:
        raise ValueError(f"element {i}: arc radius is zero (start {_mm(el.start)} is its centre)")
    if abs(r0 - r1) > RADIUS_ABS_TOLERANCE + RADIUS_REL_TOLERANCE * max(r0, r1):
        raise ValueError(f"element {i}: arc start radius {r0 * 1e3:.12g} mm and end radius "
                         f"{r1 * 1e3:.12g} mm differ")


def check_contour(elements) -> None:
    """Raise ValueError (message names the element index) unless ``elements`` is a valid contour.

    Rejected: non-finite coordinates, zero-length lines, zero-radius arcs, arcs whose start and
    end radii differ by more than 1e-9 m + 1e-9 relative, and consecutive elements that do not
    join (element i's start more than 1e-12 m from element i-1's end). An empty sequence passes.
    """
    prev_end = None
    for i, el in enumerate(elements):
        _check_type(el)
        _check_element(i, el)
        if prev_end is not None:
            gap = math.hypot(el.start[0] - prev_end[0], el.start[1] - prev_end[1])
            if gap > JOIN_TOLERANCE:
                raise ValueError(f"element {i} starts at {_mm(el.start)} but element {i - 1} ends at "
                                 f"{_mm(prev_end)}: they do not join (gap {gap * 1e3:.6g} mm)")
        prev_end = el.end
