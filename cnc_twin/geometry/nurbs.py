"""NURBS curves: validated construction, points and derivatives, curvature, arc length.

A NURBS curve of degree ``p`` with control points ``P_i`` (shape ``(n, d)``), weights ``w_i > 0``
and a clamped knot vector ``U`` (``n + p + 1`` knots) is the projection of the polynomial
B-spline ``A(u) = sum_i N_i,p(u) [w_i P_i, w_i]`` in homogeneous coordinates. ``A`` is evaluated
with scipy's B-spline machinery; the rational derivatives follow from the quotient rule::

    C   = A / w
    C'  = (A' - w' C) / w
    C'' = (A'' - 2 w' C' - w'' C) / w
    C'''= (A''' - 3 w' C'' - 3 w'' C' - w''' C) / w

For the DSP's per-period work, :class:`SpanEvaluator` holds each knot span's power-basis
coefficients of ``A``, ``A'`` and ``A''`` in one block, so a point with its first two
derivatives costs one small matrix product (:mod:`cnc_twin.geometry.span_eval`, compiled).

Units are whatever the control points are in (the twin uses metres).
"""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np

_GAUSS_NODES, _GAUSS_WEIGHTS = np.polynomial.legendre.leggauss(16)


def gauss_length(d1, knots, t0: float, t1: float, pieces: int = 1) -> float:
    """``integral |d1(t)| dt`` from ``t0`` to ``t1`` (t0 <= t1): 16-point Gauss-Legendre on each
    knot span inside, each span cut into ``pieces`` equal parts. ``d1`` maps parameters (m,) to
    first derivatives (m, d)."""
    return float(gauss_lengths(d1, knots, np.array([t0]), np.array([t1]), pieces)[0])


def gauss_lengths(d1, knots, t0: np.ndarray, t1: np.ndarray, pieces: int = 1) -> np.ndarray:
    """:func:`gauss_length` of each ``(t0[i], t1[i])`` (shape (n,) each), the derivatives of all
    taken in one call of ``d1`` (a curve's hundreds of stretches: one evaluation, not hundreds)."""
    unique = np.unique(knots)
    nodes, halves = [], []
    for a, b in zip(t0.tolist(), t1.tolist()):
        inside = unique[np.searchsorted(unique, a, side="right"):np.searchsorted(unique, b, side="left")]
        breaks = np.concatenate([[a], inside, [b]])
        if pieces > 1:
            breaks = np.unique(np.concatenate([np.linspace(lo, hi, pieces + 1)
                                               for lo, hi in zip(breaks[:-1], breaks[1:])]))
        lo, hi = breaks[:-1], breaks[1:]
        keep = hi > lo
        mid, half = 0.5 * (lo + hi)[keep], 0.5 * (hi - lo)[keep]
        nodes.append((mid[:, None] + half[:, None] * _GAUSS_NODES[None, :]).ravel())
        halves.append(half)
    out = np.zeros(len(halves))
    every = np.concatenate(nodes) if nodes else np.empty(0)
    if every.size == 0:
        return out
    speed = np.linalg.norm(d1(every), axis=1).reshape(-1, len(_GAUSS_NODES))
    start = 0
    for i, half in enumerate(halves):
        if half.size:
            out[i] = np.sum(half * (speed[start:start + half.size] @ _GAUSS_WEIGHTS))
            start += half.size
    return out


class NurbsError(ValueError):
    """An invalid NURBS definition; ``key`` names the offending part (for scenario messages)."""

    def __init__(self, key: str, message: str):
        self.key = key
        super().__init__(message)


class NurbsCurve:
    """A clamped NURBS curve.

    Parameters
    ----------
    control_points : shape ``(n, d)``, d = 2 or 3.
    weights : shape ``(n,)``, all > 0; None for a non-rational B-spline (all 1).
    knots : shape ``(n + degree + 1,)``, non-decreasing, first and last ``degree + 1`` equal.
    degree : >= 1.

    Raises
    ------
    NurbsError
        With ``key`` one of ``degree``, ``control_points``, ``weights``, ``knots``.
    """

    def __init__(self, control_points, weights, knots, degree: int):
        p = int(degree)
        P = np.asarray(control_points, dtype=np.float64)
        if p < 1:
            raise NurbsError("degree", f"degree must be >= 1, got {degree}")
        if P.ndim != 2 or P.shape[1] not in (2, 3):
            raise NurbsError("control_points", f"expected a list of 2-D or 3-D points, got shape {P.shape}")
        n = P.shape[0]
        if n < p + 1:
            raise NurbsError("control_points", f"degree {p} needs at least {p + 1} control points, got {n}")
        W = np.ones(n) if weights is None else np.asarray(weights, dtype=np.float64)
        if W.shape != (n,):
            raise NurbsError("weights", f"expected {n} weights (one per control point), got {W.size}")
        if not np.all(np.isfinite(P)):
            raise NurbsError("control_points", "control points must be finite")
        if not np.all(np.isfinite(W)) or np.any(W <= 0):
            raise NurbsError("weights", "weights must be finite and > 0")
        U = np.asarray(knots, dtype=np.float64)
        if U.shape != (n + p + 1,):
            raise NurbsError("knots", f"expected n + degree + 1 = {n + p + 1} knots, got {U.size}")
        if not np.all(np.isfinite(U)) or np.any(np.diff(U) < 0):
            raise NurbsError("knots", "knots must be finite and non-decreasing")
        if np.any(U[: p + 1] != U[0]) or np.any(U[-(p + 1):] != U[-1]):
            raise NurbsError("knots", f"knot vector must be clamped: first and last {p + 1} knots equal")
        if not U[-1] > U[0]:
            raise NurbsError("knots", "knot vector spans no parameter range")
        interior = U[p + 1:n]
        if interior.size and np.max(np.unique(interior, return_counts=True)[1]) > p:
            raise NurbsError("knots", f"an interior knot repeats more than degree = {p} times")
        self.degree = p
        self.control_points = P
        self.weights = W
        self.knots = U
        self.dim = P.shape[1]
        homogeneous = np.hstack([P * W[:, None], W[:, None]])
        # Derivatives through __call__(u, nu=k): it differentiates the polynomial piece of the
        # span holding u, so repeated interior knots (exact conics) are fine; .derivative() is not.
        from scipy.interpolate import BSpline  # here: importing scipy.interpolate takes 0.4 s

        self._spline = BSpline(U, homogeneous, p, extrapolate=False)

    @property
    def domain(self) -> tuple[float, float]:
        """Parameter range ``(u_start, u_end)``."""
        return float(self.knots[0]), float(self.knots[-1])

    def _homogeneous(self, u: np.ndarray, order: int) -> list[np.ndarray]:
        u = np.clip(u, *self.domain)
        out = []
        for k in range(order + 1):
            if k <= self.degree:
                out.append(self._spline(u, nu=k))
            else:
                out.append(np.zeros(u.shape + (self.dim + 1,)))
        return out

    def derivatives(self, u, order: int = 2) -> list[np.ndarray]:
        """``[C, C', ..., C^(order)]`` at parameters ``u`` (shape ``(m,)``), each ``(m, d)``; order <= 3."""
        if order > 3:
            raise ValueError("derivatives up to third order")
        u = np.atleast_1d(np.asarray(u, dtype=np.float64))
        H = self._homogeneous(u, order)
        A = [h[:, :-1] for h in H]
        w = [h[:, -1:] for h in H]
        C = [A[0] / w[0]]
        if order >= 1:
            C.append((A[1] - w[1] * C[0]) / w[0])
        if order >= 2:
            C.append((A[2] - 2 * w[1] * C[1] - w[2] * C[0]) / w[0])
        if order >= 3:
            C.append((A[3] - 3 * w[1] * C[2] - 3 * w[2] * C[1] - w[3] * C[0]) / w[0])
        return C

    def point(self, u) -> np.ndarray:
        """Points at ``u``, shape ``(m, d)``."""
        return self.derivatives(u, 0)[0]

    def curvature(self, u) -> np.ndarray:
        """Curvature ``|C' x C''| / |C'|^3`` at ``u``, shape ``(m,)`` [1/unit]."""
        _, d1, d2 = self.derivatives(u, 2)
        if self.dim == 2:
            cross = np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
        else:
            cross = np.linalg.norm(np.cross(d1, d2), axis=1)
        speed = np.linalg.norm(d1, axis=1)
        return cross / speed**3

    def arc_length(self, u0: float | None = None, u1: float | None = None) -> float:
        """Length between parameters (whole curve by default): 16-point Gauss-Legendre per knot span."""
        a, b = self.domain
        u0 = a if u0 is None else float(u0)
        u1 = b if u1 is None else float(u1)
        if u1 < u0:
            return -self.arc_length(u1, u0)
        return gauss_length(lambda u: self.derivatives(u, 1)[1], self.knots, u0, u1)

    def arc_lengths(self, u0: np.ndarray, u1: np.ndarray) -> np.ndarray:
        """:meth:`arc_length` of each ``(u0[i], u1[i])`` (``u0 <= u1``), in one evaluation."""
        return gauss_lengths(lambda u: self.derivatives(u, 1)[1], self.knots, np.asarray(u0, np.float64),
                             np.asarray(u1, np.float64))

    def span_evaluator(self) -> "SpanEvaluator":
        return SpanEvaluator(self)


class SpanEvaluator:
    """A curve's spans as the card evaluates them, one point per call (:mod:`cnc_twin.geometry.span_eval`).

    Each knot span ``[u_i, u_i+1)`` stores the power-basis coefficients of ``A``, ``A'``, ``A''``
    in the local variable ``x = u - u_i`` as one ``(p + 1, 3 (d + 1))`` block, taken exactly from
    the B-spline's right-hand Taylor coefficients at ``u_i``. One evaluation = one powers vector,
    the block's rows summed in order, the quotient rule: done by the compiled functions of
    :mod:`~cnc_twin.geometry.span_eval` (imported at the first evaluation, so that a process
    that only plans never loads numba), which the card's stepper calls on :attr:`path`.
    """

    def __init__(self, curve: NurbsCurve):
        p, d = curve.degree, curve.dim
        self.degree, self.dim = p, d
        self.domain = curve.domain
        starts = [float(k) for k in np.unique(curve.knots)[:-1]]
        hom = curve._spline
        blocks = []
        for s in starts:
            # right-hand Taylor coefficients at the span start (the spline evaluates a knot in the
            # span to its right)
            taylor = np.array([hom(s, nu=j) / math.factorial(j) for j in range(p + 1)])  # (p+1, d+1)
            block = np.zeros((p + 1, 3 * (d + 1)))
            block[:, : d + 1] = taylor
            for j in range(p):  # A' coefficients
                block[j, d + 1: 2 * (d + 1)] = (j + 1) * taylor[j + 1]
            for j in range(p - 1):  # A'' coefficients
                block[j, 2 * (d + 1):] = (j + 1) * (j + 2) * taylor[j + 2]
            blocks.append(block)
        self.blocks = np.ascontiguousarray(np.array(blocks))
        """the spans' coefficient blocks, shape ``(spans, p + 1, 3 (d + 1))``"""
        self.starts = np.array(starts)
        """the spans' first parameters (distinct knots but the last), shape ``(spans,)``"""

    @cached_property
    def path(self) -> tuple:
        """The curve as :mod:`~cnc_twin.geometry.span_eval`'s ``ev`` tuple (made once: every
        evaluation passes it)."""
        from cnc_twin.geometry.span_eval import NO_SURFACE

        return (self.starts, self.blocks, float(self.domain[0]), float(self.domain[1]), self.dim, *NO_SURFACE)

    def next_break(self, u: float) -> float:
        """The first span boundary (distinct knot) after ``u``; the domain's end if none."""
        from cnc_twin.geometry.span_eval import next_break

        return float(next_break(self.path, u))

    def speed(self, u: float) -> float:
        """``|C'(u)|`` (first derivative only: half the work of :meth:`evaluate`)."""
        from cnc_twin.geometry.span_eval import WORK, path_speed

        return float(path_speed(self.path, u, np.zeros(WORK)))

    def evaluate(self, u: float) -> tuple[list[float], list[float], list[float]]:
        """``(C, C', C'')`` at scalar ``u`` (clamped to the domain) as plain float lists of length d."""
        from cnc_twin.geometry.span_eval import WORK, path_evaluate

        c, c1, c2 = np.zeros(self.dim), np.zeros(self.dim), np.zeros(self.dim)
        path_evaluate(self.path, float(u), np.zeros(WORK), c, c1, c2, np.zeros(6))
        return c.tolist(), c1.tolist(), c2.tolist()
