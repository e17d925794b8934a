"""Point-by-point comparison interpolation (逐点比较法), lines and circular arcs, in pulses.

Every step is one pulse on exactly one axis, chosen by the sign of a deviation F that says on
which side of the ideal path the current lattice point lies. Each step is the four-beat cycle
of the old cards: deviation judgement, feed one step on X or Y, compute the new deviation,
end-point judgement (a step counter that runs down to zero).

Line from (0, 0) to (dx, dy), worked in the first quadrant with ``xe = |dx|``, ``ye = |dy|``
and the steps mapped back by the signs of dx and dy (symmetry)::

    F = ye * x - xe * y          (> 0: below the line, < 0: above, 0: on it)
    n = xe + ye                  (end-point counter)
    repeat n times:
        F > 0, or F == 0 and xe <  ye :  step Y,  F -= xe
        F < 0, or F == 0 and xe >= ye :  step X,  F += ye

On the line (F == 0) the step goes along the major axis, so lines on an axis need no special
case. F stays within [-xe, ye], so the lattice point is at most ``max(xe, ye) / hypot(xe, ye)
<= 1`` pulse from the line, and neither axis ever passes its end coordinate (at x == xe,
F = xe (ye - y) >= 0 steps Y; at y == ye, F = ye (x - xe) <= 0 steps X).

Arc about the origin from (x0, y0) to (x1, y1), split into quadrant pieces
(:mod:`cnc_twin.legacy.quadrants`, which also has the direction table per quadrant, CW/CCW)::

    F = x^2 + y^2 - R2,  R2 = x0^2 + y0^2            (F = 0 at the start)
    per piece, nx, ny = steps each axis owes to the piece's end:
        while nx + ny > 0:
            if ny == 0 or (nx > 0 and F >= 0 if X is the inward axis else F < 0):
                x += sx;  F += 2 x_old sx + 1;  nx -= 1         (i.e. F += 2x+1 or -2x+1)
            else:
                y += sy;  F += 2 y_old sy + 1;  ny -= 1

F >= 0 (on or outside) steps the axis that moves towards the centre, F < 0 the other.
The per-axis counters are the end-point judgement: once one axis has made its steps the other
finishes alone, so the arc ends exactly on the piece's end, and a full circle on its start.
Every lattice point is within one pulse of the circle of radius sqrt(R2).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator

import numpy as np

from cnc_twin.legacy.quadrants import arc_pieces


def line(dx: int, dy: int) -> Iterator[tuple[int, int]]:
    """Unit steps ``(sx, sy)`` (one of them +-1, the other 0) from (0, 0) to ``(dx, dy)`` [pulses]."""
    dx, dy = int(dx), int(dy)
    sx = 1 if dx >= 0 else -1
    sy = 1 if dy >= 0 else -1
    xe, ye = abs(dx), abs(dy)
    x_major = xe >= ye
    f = 0
    for _ in range(xe + ye):
        if f > 0 or (f == 0 and not x_major):
            f -= xe
            yield 0, sy
        else:
            f += ye
            yield sx, 0


def arc(x0: int, y0: int, x1: int, y1: int, *, clockwise: bool) -> Iterator[tuple[int, int]]:
    """Unit steps along the arc about the origin from ``(x0, y0)`` to ``(x1, y1)`` [pulses].

    ``start == end`` is a full circle. Raises ``ValueError`` (when called, before any step) if
    the end is not on the start's lattice circle; see :func:`cnc_twin.legacy.quadrants.arc_pieces`.
    """
    pieces = arc_pieces(x0, y0, x1, y1, clockwise=clockwise)
    return _arc_steps(pieces, int(x0) ** 2 + int(y0) ** 2)


def _arc_steps(pieces, r2: int) -> Iterator[tuple[int, int]]:
    for piece in pieces:
        x, y = piece.start
        sx, sy = piece.direction
        nx, ny = piece.steps
        f = x * x + y * y - r2  # 0 at the start; an axis point (+-a, 0) may be off by < 2a
        x_inward = piece.inward == 0
        while nx or ny:
            if ny == 0 or (nx and (f >= 0) == x_inward):
                f += 2 * x * sx + 1
                x += sx
                nx -= 1
                yield sx, 0
            else:
                f += 2 * y * sy + 1
                y += sy
                ny -= 1
                yield 0, sy


def trace(steps: Iterable[tuple[int, int]], start: tuple[int, int] = (0, 0)) -> np.ndarray:
    """Lattice points visited by ``steps`` from ``start``: int64 array of shape (n + 1, 2)."""
    # fromiter over the flattened pairs: no list of tuples (a DDA circle has ~10^6 iterations)
    moves = np.fromiter((c for step in steps for c in step), dtype=np.int64).reshape(-1, 2)
    out = np.empty((len(moves) + 1, 2), dtype=np.int64)
    out[0] = start
    np.cumsum(moves, axis=0, out=out[1:])
    out[1:] += out[0]
    return out
