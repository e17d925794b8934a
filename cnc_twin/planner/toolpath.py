"""Polishing tool paths in a surface's (u, v) space: raster (zig-zag) and spiral.

Both are built in *scaled* parameter coordinates ``x = u L_u``, ``y = v L_v``, where ``L_u`` and
``L_v`` are the surface's mean ``|S_u|`` and ``|S_v|``, so distances there are close to distances
on the surface; the result is scaled back (NURBS are affine invariant).

Raster along u (``direction="u"``): passes of constant v, alternately towards +u and -u, joined by
semicircles, as one rational quadratic NURBS (lines with their middle control point, each
quarter circle with weights 1, sqrt(2)/2, 1; double knots at the joints, knot spacing equal to
the pieces' scaled lengths). The passes are spaced evenly so that the largest distance between
neighbouring passes on the surface, ``max |S_v| dv``, does not exceed the step-over. ``margin``
keeps the passes that far (on the surface, approximately) from the surface's edges; the turns
bulge half a step-over beyond the passes.

Spiral: an Archimedean spiral ``r = r0 + step_over theta / (2 pi)`` about the parameter domain's
centre (scaled coordinates), out to the largest radius that keeps ``margin`` from the edges;
interpolated by cubic B-splines through 16 points per turn.

A path is cut into sections of at most ``MAX_SECTION_LENGTH`` and one whiteboard record (at the
end of a raster pass, or along the spiral); the card runs each section from rest to rest.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import make_interp_spline

from cnc_twin.core.config import UvCurve
from cnc_twin.geometry.surface import NurbsSurface, parameter_scales

MAX_SECTION_POINTS = 110
"""control points per section: a (u, v) curve of 110 points is ~1800 words, within one record"""
MAX_SECTION_LENGTH = 0.3
"""path length per section [m, scaled coordinates]: the planner samples a whole section before its
first window, which must stay well inside the card's planner-heartbeat timeout"""
_W = math.sqrt(0.5)


class ToolpathError(ValueError):
    """The path cannot be laid out as asked; ``key`` names the scenario key to change."""

    def __init__(self, key: str, message: str):
        self.key = key
        super().__init__(message)


def _bezier_pieces_to_nurbs(pieces: list[tuple[np.ndarray, np.ndarray]], scale: np.ndarray) -> UvCurve:
    """Quadratic rational Bezier pieces ``(3 points, 3 weights)`` in scaled coordinates -> one NURBS
    in (u, v) with double knots at the joints."""
    points = [pieces[0][0][0]]
    weights = [pieces[0][1][0]]
    knots = [0.0, 0.0, 0.0]
    t = 0.0
    for ctrl, w in pieces:
        points += [ctrl[1], ctrl[2]]
        weights += [w[1], w[2]]
        # the piece's length (scaled) as its parameter span: a line's exact, an arc's pi r / 2
        chord = float(np.linalg.norm(ctrl[2] - ctrl[0]))
        t += chord if w[1] == 1.0 else chord * math.pi / (2.0 * math.sqrt(2.0))
        knots += [t, t]
    knots[-2:] = [t, t]
    knots.append(t)
    uv = np.asarray(points) / scale
    return UvCurve(degree=2, knots=tuple(knots), weights=tuple(float(x) for x in weights),
                   control_points=tuple((float(a), float(b)) for a, b in uv))


def _line(p: np.ndarray, q: np.ndarray):
    return np.array([p, 0.5 * (p + q), q]), (1.0, 1.0, 1.0)


def _quarter(p: np.ndarray, corner: np.ndarray, q: np.ndarray):
    return np.array([p, corner, q]), (1.0, _W, 1.0)


def _pass_positions(surface: NurbsSurface, u_range, v_range, step_over: float, *, swap: bool) -> np.ndarray:
    """Pass parameters from ``v_range[0]`` to ``v_range[1]``: each gap as wide as the step-over
    allows where the passes are furthest apart on the surface (``max_u |S_v| dv``), then all
    gaps scaled by one factor so the last pass lands on the range's end."""
    us = np.linspace(*u_range, 64)
    lo, hi = v_range
    if hi <= lo:
        return np.array([lo])

    def widest(v: float) -> float:
        vv = np.full_like(us, v)
        d = surface.derivatives(vv, us, 1)[(1, 0)] if swap else surface.derivatives(us, vv, 1)[(0, 1)]
        return float(np.max(np.linalg.norm(d, axis=1)))

    gaps, v = [], lo
    while v < hi:
        here = widest(v)
        dv = step_over / max(here, widest(min(hi, v + 0.5 * step_over / here)))  # and half-way to the next pass
        gaps.append(dv)
        v += dv
    gaps = np.asarray(gaps) * (hi - lo) / np.sum(gaps)  # shrink the gaps evenly: none widens
    return lo + np.concatenate([[0.0], np.cumsum(gaps)])


def raster(surface: NurbsSurface, *, step_over: float, margin: float, direction: str = "u") -> list[UvCurve]:
    """Zig-zag passes along ``direction`` ("u" or "v"); see the module docstring. Lengths in m."""
    lu, lv, _, _ = parameter_scales(surface)
    (u0, u1), (v0, v1) = surface.domain_u, surface.domain_v
    if direction == "v":  # lay out in swapped coordinates, swap back at the end
        (u0, u1), (v0, v1), lu, lv = (v0, v1), (u0, u1), lv, lu
    x_lo, x_hi = u0 * lu + margin, u1 * lu - margin
    y_lo, y_hi = v0 * lv + margin, v1 * lv - margin
    if not (x_hi > x_lo and y_hi >= y_lo):
        raise ToolpathError("margin", f"a margin of {margin * 1e3:g} mm leaves no area to polish on this surface")
    ys = _pass_positions(surface, (x_lo / lu, x_hi / lu), (y_lo / lv, y_hi / lv), step_over, swap=direction == "v") * lv
    r_max = 0.5 * float(np.max(np.diff(ys))) if len(ys) > 1 else 0.0
    if x_hi + r_max > u1 * lu + 1e-12 or x_lo - r_max < u0 * lu - 1e-12:
        raise ToolpathError("margin", f"the raster's turns (radius up to {r_max * 1e3:.3g} mm) leave the surface: "
                            f"the margin must be at least half the step-over")
    scale = np.array([lu, lv])
    sections: list[UvCurve] = []
    pieces: list = []
    n_points = 1
    length = 0.0
    for i, y in enumerate(ys):
        a, b = (x_lo, x_hi) if i % 2 == 0 else (x_hi, x_lo)
        pieces.append(_line(np.array([a, y]), np.array([b, y])))
        n_points += 2
        length += x_hi - x_lo
        if i == len(ys) - 1:
            break
        if n_points + 6 > MAX_SECTION_POINTS or length + (x_hi - x_lo) > MAX_SECTION_LENGTH:
            sections.append(_bezier_pieces_to_nurbs(pieces, scale))
            pieces, n_points, length = [], 1, 0.0
        side = 1.0 if i % 2 == 0 else -1.0
        r = 0.5 * (ys[i + 1] - y)
        mid = np.array([b + side * r, y + r])
        pieces.append(_quarter(np.array([b, y]), np.array([b + side * r, y]), mid))
        pieces.append(_quarter(mid, np.array([b + side * r, y + 2 * r]), np.array([b, y + 2 * r])))
        n_points += 4
    sections.append(_bezier_pieces_to_nurbs(pieces, scale))
    if direction == "v":
        sections = [UvCurve(c.degree, c.knots, c.weights, tuple((b, a) for a, b in c.control_points))
                    for c in sections]
    return sections


def spiral(surface: NurbsSurface, *, step_over: float, margin: float, points_per_turn: int = 16) -> list[UvCurve]:
    """An outward Archimedean spiral about the domain's centre; see the module docstring."""
    lu, lv, su_max, sv_max = parameter_scales(surface)
    (u0, u1), (v0, v1) = surface.domain_u, surface.domain_v
    cx, cy = 0.5 * (u0 + u1) * lu, 0.5 * (v0 + v1) * lv
    # radial spacing on the surface at most the step-over, whichever way the spiral runs
    pitch = step_over * min(lu / su_max, lv / sv_max)
    r_max = min(0.5 * (u1 - u0) * lu, 0.5 * (v1 - v0) * lv) - margin
    r0 = pitch
    if r_max <= r0:
        raise ToolpathError("margin", f"a margin of {margin * 1e3:g} mm leaves no room for a spiral")
    theta_end = 2.0 * math.pi * (r_max - r0) / pitch
    n = max(8, math.ceil(theta_end / (2.0 * math.pi) * points_per_turn))
    theta = np.linspace(0.0, theta_end, n + 1)
    r = r0 + pitch * theta / (2.0 * math.pi)
    xy = np.column_stack([cx + r * np.cos(theta), cy + r * np.sin(theta)])
    sections = []
    total = float(np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1)))
    # even sections (none too short for a cubic), within one record and MAX_SECTION_LENGTH
    n_sections = max(math.ceil(n / (MAX_SECTION_POINTS - 3)), math.ceil(total / MAX_SECTION_LENGTH))
    bounds = np.linspace(0, n, n_sections + 1).round().astype(int)
    for start, stop in zip(bounds[:-1], bounds[1:]):
        chunk = xy[start:stop + 1]
        seg = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(chunk, axis=0), axis=1))])
        spline = make_interp_spline(seg, chunk, k=3)
        sections.append(UvCurve(degree=3, knots=tuple(float(k) for k in spline.t),
                                weights=(1.0,) * len(spline.c),
                                control_points=tuple((float(a) / lu, float(b) / lv) for a, b in spline.c)))
    return sections
