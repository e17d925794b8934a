"""A polyline (CAM's dense G1 points) fitted with a C2 cubic B-spline within a tolerance.

The parameter is the polyline's arc length (chord length through the points), so the fitted
curve runs at about unit parameter speed, as the card's stepper wants it. For a fixed knot
vector the control points solve a least-squares problem, one coordinate at a time::

    minimise  sum_i |C(u_i) - D_i|^2  +  lam sum_j |P_(j-1) - 2 P_j + P_(j+1)|^2

with the end points fixed (``P_0 = D_0``, ``P_(n-1) = D_last``) and, when given, the end
tangents: ``P_1`` and ``P_2`` on the line along ``t_0`` so that the curve leaves at unit
parameter speed with no curvature (the same at the end): joined to a line there, it is C2. The small smoothing term ``lam`` keeps spans with few points well determined.

The tolerance is checked, not assumed: after each solve :func:`deviation` measures both ways,
every programmed point's distance to the curve and every curve sample's distance to the
programmed polyline (its points *and* segments), and each span where either exceeds the
tolerance gets a knot at its middle; then the solve runs again. A tool axis per point (5-axis
programs) is fitted with the same knots and basis, and its angle from the programmed axis (at the
points and the segments' middles) is held to its own tolerance the same way.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline
from scipy.sparse import diags, vstack
from scipy.sparse.linalg import spsolve

from cnc_twin.geometry.polyline import point_to_polyline

DEGREE = 3
POINTS_PER_SPAN = 64
"""programmed points per span of the first fit"""
SMOOTHING = 1e-6
"""``lam`` relative to the mean weight of a control point in the data term"""
MAX_REFITS = 40
SAMPLES_PER_TOLERANCE = 0.5
"""curve samples per tolerance of length in the check: the sampled polyline's own sagitta stays far
below the tolerance"""
MAX_SAMPLES = 2_000_000


class FitError(ValueError):
    """The points cannot be fitted: fewer than two distinct points, or no fit within the tolerance
    (a span beyond it that holds too few points to split: the polyline turns too sharply for a
    smooth curve within the tolerance of its segments)."""


@dataclass(frozen=True)
class Fit:
    """A fitted cubic: clamped ``knots`` (arc length along the polyline), ``points`` (n, 3) and,
    for a tool axis, ``axis_points`` (n, 3) on the same knots (not unit: normalise the evaluated
    axis)."""

    knots: np.ndarray
    points: np.ndarray
    axis_points: np.ndarray | None
    deviation: float
    """largest distance between the curve and the programmed polyline, both ways, as measured"""
    axis_deviation: float
    """largest angle between the fitted and the programmed tool axis [rad]; 0 without one"""
    refits: int
    """knot insertion rounds after the first fit"""

    @property
    def spans(self) -> int:
        return len(np.unique(self.knots)) - 1

    def curve(self) -> BSpline:
        return BSpline(self.knots, self.points, DEGREE)


def chord_parameters(points: np.ndarray) -> np.ndarray:
    """Cumulative chord length through ``points`` (m, 3), starting at 0; shape (m,)."""
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])


def _initial_knots(u: np.ndarray, spans_at_least: int) -> np.ndarray:
    spans = max(spans_at_least, (len(u) - 1) // POINTS_PER_SPAN)
    inner = u[np.linspace(0, len(u) - 1, spans + 1).round().astype(int)[1:-1]]
    return np.concatenate([[u[0]] * (DEGREE + 1), inner, [u[-1]] * (DEGREE + 1)])


def _solve(u: np.ndarray, data: np.ndarray, knots: np.ndarray, tangents: tuple) -> np.ndarray:
    """Control points (n, 3) of the least-squares fit on ``knots`` (see the module docstring)."""
    n = len(knots) - DEGREE - 1
    basis = BSpline.design_matrix(u, knots, DEGREE).tocsc()
    fixed = {0: data[0], n - 1: data[-1]}
    t0, t1 = tangents
    # a given end tangent: unit speed along it and no curvature there (the derivative curve's
    # first two control points equal), so the curve joins a line there with C2 continuity
    if t0 is not None:
        fixed[1] = data[0] + np.asarray(t0) * (knots[DEGREE + 1] - knots[DEGREE]) / 3.0
        fixed[2] = fixed[1] + np.asarray(t0) * (knots[DEGREE + 2] - knots[DEGREE]) / 3.0
    if t1 is not None:
        fixed[n - 2] = data[-1] - np.asarray(t1) * (knots[n] - knots[n - 1]) / 3.0
        fixed[n - 3] = fixed[n - 2] - np.asarray(t1) * (knots[n] - knots[n - 2]) / 3.0
    free = [j for j in range(n) if j not in fixed]
    known = np.zeros((n, data.shape[1]))
    for j, p in fixed.items():
        known[j] = p
    if not free:
        return known
    second = diags([1.0, -2.0, 1.0], [0, 1, 2], shape=(max(n - 2, 0), n), format="csc")
    weight = basis.multiply(basis).sum() / n
    lam = SMOOTHING * weight
    a = vstack([basis, math.sqrt(lam) * second]).tocsc()
    rhs = np.vstack([data, np.zeros((second.shape[0], data.shape[1]))]) - a @ known
    af = a[:, free]
    normal = (af.T @ af).tocsc()
    solution = spsolve(normal, af.T @ rhs)
    known[free] = solution.reshape(len(free), -1)
    return known


def deviation(knots: np.ndarray, points: np.ndarray, data: np.ndarray, u: np.ndarray, tolerance: float
              ) -> tuple[float, np.ndarray]:
    """The largest distance between the cubic (``knots``, ``points``) and the polyline ``data``
    both ways, and the parameters where it exceeds ``tolerance`` (shape (k,))."""
    curve = BSpline(knots, points, DEGREE)
    length = u[-1] - u[0]
    count = int(min(MAX_SAMPLES, max(8 * (len(np.unique(knots)) - 1), math.ceil(SAMPLES_PER_TOLERANCE * length / tolerance))))
    s = np.union1d(np.linspace(u[0], u[-1], count + 1), u)
    samples = curve(s)
    to_curve = point_to_polyline(data, samples)  # each programmed point to the curve
    to_poly = point_to_polyline(samples, data)  # the curve to the programmed points and segments
    worst = float(max(to_curve.max(), to_poly.max()))
    bad = np.concatenate([u[to_curve > tolerance], s[to_poly > tolerance]])
    return worst, bad


def _axis_deviation(knots: np.ndarray, axis_points: np.ndarray, axes: np.ndarray, u: np.ndarray, tolerance: float
                    ) -> tuple[float, np.ndarray]:
    """Largest angle [rad] between the fitted axis and the programmed one, at the points and at the
    segments' middles (the programmed axis there: the normalised mean of its ends), and the
    parameters where it exceeds ``tolerance``."""
    mid = 0.5 * (axes[1:] + axes[:-1])
    want = np.vstack([axes, mid / np.linalg.norm(mid, axis=1, keepdims=True)])
    at = np.concatenate([u, 0.5 * (u[1:] + u[:-1])])
    got = BSpline(knots, axis_points, DEGREE)(at)
    got /= np.linalg.norm(got, axis=1, keepdims=True)
    angle = np.arccos(np.clip(np.sum(got * want, axis=1), -1.0, 1.0))
    return float(angle.max()), at[angle > tolerance]


def _split(knots: np.ndarray, where: np.ndarray, u: np.ndarray) -> np.ndarray | None:
    """``knots`` with a knot in every span holding one of the parameters ``where``: at the middle
    one of the programmed points' parameters ``u`` inside the span, so every span keeps points
    of its own, at least on its ends (the least-squares problem stays well posed). None when no
    such span has a point inside left to split at."""
    breaks = np.unique(knots)
    spans = np.unique(np.clip(np.searchsorted(breaks, where, side="right") - 1, 0, len(breaks) - 2))
    added = []
    for k in spans:
        inside = u[(u > breaks[k]) & (u < breaks[k + 1])]
        if len(inside):  # at the middle point inside (a knot at a programmed point: each side keeps it)
            added.append(float(inside[len(inside) // 2]))
    if not added:
        return None
    return np.sort(np.concatenate([knots, added]))


def fit_polyline(points, tolerance: float, *, axes=None, axis_tolerance: float | None = None,
                 start_tangent=None, end_tangent=None) -> Fit:
    """Fit ``points`` (m, 3) with a cubic B-spline within ``tolerance`` (same units); ``axes`` (m,
    3): a unit tool axis per point, fitted within ``axis_tolerance`` [rad]; ``start_tangent`` /
    ``end_tangent``: unit directions the curve must leave and arrive along (its neighbours'), with
    no curvature there.

    Raises
    ------
    FitError
        Fewer than two distinct points, or the tolerance not met after MAX_REFITS rounds.
    """
    data = np.asarray(points, dtype=np.float64)
    keep = np.concatenate([[True], np.linalg.norm(np.diff(data, axis=0), axis=1) > 0.0])
    data = data[keep]
    if len(data) < 2:
        raise FitError("fewer than two distinct points to fit")
    axis_data = None
    if axes is not None:
        axis_data = np.asarray(axes, dtype=np.float64)[keep]
        axis_data = axis_data / np.linalg.norm(axis_data, axis=1, keepdims=True)
        if axis_tolerance is None:
            raise FitError("a tool axis needs its tolerance")
    u = chord_parameters(data)
    # with end tangents, three control points are fixed at each such end: at least one free
    ends = (start_tangent is not None) + (end_tangent is not None)
    knots = _initial_knots(u, 1 + 2 * ends)
    for refit in range(MAX_REFITS + 1):
        ctrl = _solve(u, data, knots, (start_tangent, end_tangent))
        worst, bad = deviation(knots, ctrl, data, u, tolerance)
        axis_ctrl, axis_worst = None, 0.0
        if axis_data is not None:
            axis_ctrl = _solve(u, axis_data, knots, (None, None))
            axis_worst, axis_bad = _axis_deviation(knots, axis_ctrl, axis_data, u, axis_tolerance)
            bad = np.concatenate([bad, axis_bad])
        if not len(bad):
            return Fit(knots, ctrl, axis_ctrl, worst, axis_worst, refit)
        split = _split(knots, bad, u)
        if split is None:
            raise FitError(f"no fit within {tolerance:g}: the spans beyond it hold too few points to split "
                           f"(largest deviation {worst:g})")
        knots = split
    raise FitError(f"no fit within {tolerance:g} after {MAX_REFITS} knot insertions (largest deviation {worst:g})")
