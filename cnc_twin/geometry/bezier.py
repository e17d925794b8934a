"""Rational Bezier pieces: a NURBS cut into its pieces, raised to a common degree, and pieces
joined back into one NURBS (the G-code program kind joins lines, arcs, blends and NURBS blocks of
one path run into the one curve the card interpolates).

A piece is an array of homogeneous control points, shape ``(degree + 1, 4)``: ``(w x, w y, w z, w)``
(points in any length unit, the same for every piece of one curve). Cutting and raising act on the
homogeneous points, so the pieces are the exact curve, weights and all (The NURBS Book, A5.1 knot
insertion and the Bezier degree elevation of section 5.5).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


def homogeneous(points, weights) -> np.ndarray:
    """``(n, 4)`` homogeneous points of ``points`` ``(n, 3)`` with ``weights`` ``(n,)``."""
    P = np.asarray(points, dtype=np.float64)
    W = np.asarray(weights, dtype=np.float64)
    return np.hstack([P * W[:, None], W[:, None]])


@njit(cache=True, nogil=True)
def _insert_knots(Pw, knots, inner, times, degree):  # pragma: no cover - compiled
    """``Pw`` ((n, 4) homogeneous) on ``knots`` with each of ``inner`` inserted ``times`` times
    more, by Boehm's insertion one knot at a time (The NURBS Book A5.1 with r = 1), in place on
    arrays made room for: each new point ``alpha * P[i] + (1 - alpha) * P[i - 1]`` computed as
    numpy computes it on the rows (no fused multiply-add), so the pieces are its bits."""
    n, m, p = Pw.shape[0], knots.shape[0], degree
    total = 0
    for j in range(inner.shape[0]):
        total += times[j]
    out = np.empty((n + total, Pw.shape[1]))
    out[:n] = Pw
    U = np.empty(m + total)
    U[:m] = knots
    for j in range(inner.shape[0]):
        u = inner[j]
        for _ in range(times[j]):
            k = np.searchsorted(U[:m], u, side="right") - 1  # U[k] <= u < U[k + 1]
            for i in range(n - 1, k - 1, -1):  # the points from k on move up one
                out[i + 1] = out[i]
            for i in range(k, k - p, -1):  # from the top down: out[i - 1] is still the old point
                alpha = (u - U[i]) / (U[i + p] - U[i])
                for c in range(out.shape[1]):
                    out[i, c] = alpha * out[i, c] + (1.0 - alpha) * out[i - 1, c]
            for i in range(m - 1, k, -1):
                U[i + 1] = U[i]
            U[k + 1] = u
            n += 1
            m += 1
    return out


def bezier_pieces(points, weights, knots, degree: int) -> list[np.ndarray]:
    """A clamped NURBS cut at its interior knots into rational Bezier pieces, in order, each
    ``(degree + 1, 4)`` homogeneous; one per knot span of non-zero length (see :func:`knot_spans`)."""
    Pw = homogeneous(points, weights)
    U = np.asarray(knots, dtype=np.float64)
    p = int(degree)
    inner = np.unique(U[p + 1:len(U) - p - 1])
    times = np.array([p - int(np.count_nonzero(U == u)) for u in inner], dtype=np.int64)
    Pw = _insert_knots(Pw, U, inner, np.maximum(times, 0), p)
    return [Pw[i * p:i * p + p + 1].copy() for i in range(len(Pw) // p) if i * p + p < len(Pw)]


def knot_spans(knots, degree: int) -> list[float]:
    """The non-zero knot spans of a clamped knot vector: the parameter span of each piece
    :func:`bezier_pieces` gives (joined with these spans, the curve keeps its own parametrisation,
    so its parametric continuity at the cuts)."""
    U = np.unique(np.asarray(knots, dtype=np.float64))
    return np.diff(U).tolist()


def end_speed(piece: np.ndarray, at_end: bool) -> float:
    """``|dC/dt|`` of a rational Bezier piece at ``t = 0`` (or 1) on its own ``t in [0, 1]``:
    ``p (w1 / w0) |P1 - P0|`` (0 when the first two points coincide)."""
    q = piece[::-1] if at_end else piece
    p = len(piece) - 1
    a, b = q[0][:3] / q[0][3], q[1][:3] / q[1][3]
    return p * float(q[1][3] / q[0][3]) * float(np.linalg.norm(b - a))


def elevate(piece: np.ndarray, degree: int) -> np.ndarray:
    """The same Bezier piece written with degree ``degree`` (>= its own)."""
    Q = piece
    while len(Q) - 1 < degree:
        n = len(Q) - 1
        up = np.empty((n + 2, Q.shape[1]))
        up[0], up[-1] = Q[0], Q[-1]
        for i in range(1, n + 1):
            a = i / (n + 1)
            up[i] = a * Q[i - 1] + (1.0 - a) * Q[i]
        Q = up
    return Q


def piece_points(piece: np.ndarray, t) -> np.ndarray:
    """Points (k, 3) of a rational Bezier piece (homogeneous, (degree + 1, 4)) at parameters
    ``t`` in [0, 1], shape (k,): Bernstein basis, then the division by the weight."""
    p = len(piece) - 1
    basis = np.array([[math.comb(p, i) * ti ** i * (1 - ti) ** (p - i) for i in range(p + 1)] for ti in t])
    h = basis @ piece
    return h[:, :3] / h[:, 3:4]


def piece_length(piece: np.ndarray, samples: int = 16) -> float:
    """Length of a rational Bezier piece [its points' unit], by a polyline of ``samples`` chords
    (a parameter span for the joined curve: close to the length keeps the parameter speed near
    one across joins, which the card's stepper and the feed planner like)."""
    xyz = piece_points(piece, np.linspace(0.0, 1.0, samples + 1))
    return float(np.sum(np.linalg.norm(np.diff(xyz, axis=0), axis=1)))


def join(pieces: list[np.ndarray], spans: list[float]) -> tuple[int, list[float], list[float], list[list[float]]]:
    """One clamped NURBS ``(degree, knots, weights, control_points)`` through ``pieces`` in order,
    each raised to the highest degree among them and given the parameter span ``spans[i]`` (> 0).

    Consecutive pieces must share their joining point (the caller's job); the joined knot vector
    repeats each interior knot ``degree`` times, so the curve is exactly the pieces.
    """
    p = max(len(q) - 1 for q in pieces)
    raised = [elevate(q, p) for q in pieces]
    # a piece's end and the next's start are the same point but may carry different weights
    # (homogeneous scale): scale each piece so its first weight equals the previous piece's last
    rows = [raised[0]]
    for q in raised[1:]:
        rows.append(q[1:] * (rows[-1][-1, 3] / q[0, 3]))
    Pw = np.vstack(rows)
    u = np.concatenate([[0.0], np.cumsum(spans)])
    knots = [0.0] * (p + 1) + [float(x) for x in u[1:-1] for _ in range(p)] + [float(u[-1])] * (p + 1)
    weights = Pw[:, 3]
    points = Pw[:, :3] / weights[:, None]
    return p, knots, weights.tolist(), points.tolist()
