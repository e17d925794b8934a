"""Split a circular arc about the origin into quadrant pieces, for the step interpolators.

Both the point-by-point and the DDA arc interpolators step each axis in one fixed direction
inside a quadrant, and count the steps each axis still owes to the end of the piece (their
end-point judgement). This module finds those pieces and gives the direction table.

Circle: ``R2 = x0^2 + y0^2`` (the start is on it, so the deviation starts at 0). An arc
crosses an axis at the lattice point ``(+-a, 0)`` / ``(0, +-a)`` with::

    a = ceil(sqrt(R2 - 1))      (a = 1 when R2 = 1)

which is where point-by-point comparison itself reaches the axis (from the row/column one pulse
off the axis it steps onto the axis once ``1 + c^2 >= R2``), and ``R - 1 < a < R + 1``.

End validation (the end must be a lattice neighbour of the circle), with ``F = x1^2 + y1^2 - R2``
and ``m = max(|x1|, |y1|)``::

    -(2 m + 1) <= F <= 2 m - 2

i.e. stepping the larger coordinate by one pulse towards the circle crosses or reaches it. It
implies ``R - 1 <= |end| < R + 1`` and, with the ``a`` above, that no axis ever has to step
against its quadrant direction inside the last piece.

Quadrants. A point on an axis belongs to the quadrant the motion *leaves* it into, so the start
picks the first piece; the end is placed in the quadrant the motion *arrives* from::

    CCW leaving (= CW arriving):  I x>0,y>=0   II x<=0,y>0   III x<0,y<=0   IV x>=0,y<0
    CW  leaving (= CCW arriving): I x>=0,y>0   II x<0,y>=0   III x<=0,y<0   IV x>0,y<=0

Pieces: from the start's quadrant, go to that quadrant's axis point and on to the next
quadrant, until the end's quadrant is reached with the end ahead of the current position (on
the first visit only if the end is strictly ahead of the start: cross(start, end) > 0 for CCW,
< 0 for CW). start == end is a full circle (4 pieces from an axis point, 5 otherwise).

Direction table (per-step signs of X and Y, and the axis stepped when ``F >= 0``, i.e. on or
outside the circle: the one moving towards the centre; ``F < 0`` steps the other)::

                 CCW                     CW
    quadrant     dir(x,y)  F>=0 steps    dir(x,y)  F>=0 steps   piece ends at (CCW | CW)
    I            (-1,+1)   X             (+1,-1)   Y            (0, a)  | (a, 0)
    II           (-1,-1)   Y             (+1,+1)   X            (-a, 0) | (0, a)
    III          (+1,-1)   X             (-1,+1)   Y            (0, -a) | (-a, 0)
    IV           (+1,+1)   Y             (-1,-1)   X            (a, 0)  | (0, -a)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

_CCW_DIR = ((-1, 1), (-1, -1), (1, -1), (1, 1))
_CW_DIR = ((1, -1), (1, 1), (-1, 1), (-1, -1))
# Index of the axis (0 = X, 1 = Y) stepped when F >= 0: the inward one.
_CCW_INWARD = (0, 1, 0, 1)
_CW_INWARD = (1, 0, 1, 0)


@dataclass(frozen=True)
class Piece:
    """One quadrant's part of an arc, all in pulses.

    ``start``/``end`` are lattice points; ``direction`` the (x, y) step signs inside the piece;
    ``inward`` the axis index (0 = X, 1 = Y) stepped when the deviation is >= 0.
    """

    quadrant: int
    start: tuple[int, int]
    end: tuple[int, int]
    direction: tuple[int, int]
    inward: int

    @property
    def steps(self) -> tuple[int, int]:
        """Steps each axis makes in this piece: ``(|dx|, |dy|)``."""
        return abs(self.end[0] - self.start[0]), abs(self.end[1] - self.start[1])


def axis_radius(r2: int) -> int:
    """``a = ceil(sqrt(r2 - 1))`` (1 when ``r2 == 1``): where the arc crosses an axis [pulses]."""
    if r2 <= 2:
        return 1
    return math.isqrt(r2 - 2) + 1  # ceil(sqrt(n)) == isqrt(n - 1) + 1 for n >= 1


def end_is_on_circle(r2: int, x: int, y: int) -> bool:
    """True when ``(x, y)`` is a lattice neighbour of the circle ``x^2 + y^2 = r2`` (see module doc)."""
    m = max(abs(x), abs(y))
    f = x * x + y * y - r2
    return -(2 * m + 1) <= f <= 2 * m - 2


def _quadrant_leaving(x: int, y: int, ccw: bool) -> int:
    if not ccw:
        return _quadrant_arriving(x, y, True)
    if x > 0 and y >= 0:
        return 0
    if x <= 0 and y > 0:
        return 1
    if x < 0 and y <= 0:
        return 2
    return 3


def _quadrant_arriving(x: int, y: int, ccw: bool) -> int:
    if not ccw:
        return _quadrant_leaving(x, y, True)
    if x >= 0 and y > 0:
        return 0
    if x < 0 and y >= 0:
        return 1
    if x <= 0 and y < 0:
        return 2
    return 3


def _axis_point(quadrant: int, a: int, ccw: bool) -> tuple[int, int]:
    if ccw:
        return ((0, a), (-a, 0), (0, -a), (a, 0))[quadrant]
    return ((a, 0), (0, a), (-a, 0), (0, -a))[quadrant]


def arc_pieces(x0: int, y0: int, x1: int, y1: int, *, clockwise: bool) -> list[Piece]:
    """Quadrant pieces of the arc about the origin from ``(x0, y0)`` to ``(x1, y1)``.

    Raises ``ValueError`` for a zero radius or an end that is not on the start's lattice circle.
    """
    x0, y0, x1, y1 = int(x0), int(y0), int(x1), int(y1)
    r2 = x0 * x0 + y0 * y0
    if r2 == 0:
        raise ValueError("arc start is the centre: radius 0")
    if not end_is_on_circle(r2, x1, y1):
        raise ValueError(
            f"arc end ({x1}, {y1}) is not on the lattice circle of the start ({x0}, {y0}): "
            f"r0^2 = {r2}, r1^2 = {x1 * x1 + y1 * y1}")
    ccw = not clockwise
    a = axis_radius(r2)
    dirs, inward = (_CCW_DIR, _CCW_INWARD) if ccw else (_CW_DIR, _CW_INWARD)
    cross = x0 * y1 - y0 * x1
    ahead = cross > 0 if ccw else cross < 0
    q = _quadrant_leaving(x0, y0, ccw)
    q_end = _quadrant_arriving(x1, y1, ccw)
    step_q = 1 if ccw else -1
    pieces: list[Piece] = []
    current = (x0, y0)
    while True:
        # Stop in the end's quadrant; on the first visit only if the end lies ahead of the start.
        if q == q_end and (pieces or ahead):
            pieces.append(Piece(q, current, (x1, y1), dirs[q], inward[q]))
            return pieces
        nxt = _axis_point(q, a, ccw)
        pieces.append(Piece(q, current, nxt, dirs[q], inward[q]))
        current = nxt
        q = (q + step_q) % 4
