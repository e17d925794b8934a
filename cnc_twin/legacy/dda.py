"""Digital differential analyser (DDA, 数字积分法) interpolation, lines and arcs, in pulses.

Each axis has an integrand register J_v and an accumulator (remainder) register J_r of n bits.
Every iteration (one clock of the old cards) each accumulator adds its integrand; a carry out
of bit n (overflow) is one pulse on that axis, and the accumulator keeps the n low bits::

    J_r += J_v
    if J_r >= 2^n:  J_r -= 2^n;  step the axis     (overflow = step)

Both axes are clocked together, so one iteration may step X, Y, both or neither.

Line to (dx, dy): ``J_vx = |dx|``, ``J_vy = |dy|``, n = bit length of ``max(|dx|, |dy|)`` unless
given (2^n must exceed both, so an iteration carries at most once). After ``k`` iterations an
axis has made ``floor((k |d| + J_r0) / 2^n)`` steps, so after exactly 2^n iterations it has made
``|d|`` steps (with ``J_r0 < 2^n``) and the line ends on target; the end-point judgement is the
iteration counter. Zero-cleared accumulators (``half_load=False``, the textbook form) lag the
ideal point by [0, 1) pulse per axis; half-loaded ones (``J_r0 = 2^(n-1)``) round instead,
within 1/2 pulse per axis. Either way the point is within one pulse of the line.

Arc about the origin (classic DDA circle), split into quadrant pieces like point-by-point
(:mod:`cnc_twin.legacy.quadrants`: same pieces, directions and end validation). The X axis
integrates ``|y|`` and the Y axis integrates ``|x|`` (``dx/dt = -y``, ``dy/dt = x`` for CCW)::

    J_vx = |y|,  J_vy = |x|               (loaded at the start of each piece)
    per iteration, for each axis that still owes steps in the piece:
        J_r += J_v;  overflow -> step in the piece's direction
    a step on X updates J_vy = |x|; a step on Y updates J_vx = |y|   (after the iteration)
    an axis stops when it has made its |dx| (|dy|) steps of the piece   (end-point per axis)

Three changes to the textbook form, documented because they change accuracy:

* The integrand lags by the accumulator remainder, which makes the zero-cleared DDA circle
  spiral outwards (measured on a quarter circle from (R, 0): up to ~1.8 pulses radial error at
  R = 4095 with n = bit length of R). Arcs therefore default to half-loaded accumulators and
  ``GUARD_BITS`` more bits than the radius needs (4x the iterations, a smaller Euler step).
  ``half_load=False, bits=<bit length>`` gives the classic card.
* The DDA has no deviation to pull it back onto the circle, so a piece starting on an axis
  point ``(a, 0)``, which is off the circle by ``delta = a - R`` (``|delta| < 1``), would follow a
  circle of radius a. The inward axis's accumulator is preloaded with ``delta * 2^n`` more
  (clamped at 0) so the integrated position starts on the circle; it may carry at once.
* A piece ending on an axis can leave the axis that moves away from the centre a step short
  when its integrand (the other coordinate) has just reached 0; the card would hang there. Once
  the other axis has finished, a zero integrand is treated as 2^n: the owed steps come out one
  per iteration. (At a piece's start a zero integrand is normal: the other axis is leaving 0.)

With these defaults every lattice point was within one pulse of the circle of radius
sqrt(x0^2 + y0^2) in an exhaustive check (all starts with ``|x0|, |y0| <= 12``, every valid end,
both directions) and on random arcs up to R = 40000; the closest calls are the axis points
themselves (a - R < 1 by construction) and ends accepted one pulse off the circle.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

from cnc_twin.legacy.quadrants import arc_pieces

GUARD_BITS = 2
"""extra accumulator bits for arcs beyond the radius's bit length (see module docstring)"""


def line(dx: int, dy: int, *, bits: int | None = None, half_load: bool = False) -> Iterator[tuple[int, int]]:
    """Per-iteration steps ``(sx, sy)``, each in {-1, 0, +1}, from (0, 0) to ``(dx, dy)`` [pulses].

    Yields exactly ``2^bits`` iterations (none for a zero line). Raises ``ValueError`` when
    ``bits`` is too small to hold ``max(|dx|, |dy|)``.
    """
    dx, dy = int(dx), int(dy)
    vx, vy = abs(dx), abs(dy)
    need = max(vx, vy).bit_length()
    if bits is None:
        bits = need
    if bits < need:
        raise ValueError(f"{bits}-bit registers cannot hold {max(vx, vy)}: need {need} bits")
    if need == 0:
        return iter(())
    return _line_steps(vx, vy, 1 if dx >= 0 else -1, 1 if dy >= 0 else -1, bits, half_load)


def _line_steps(vx: int, vy: int, sx: int, sy: int, bits: int, half_load: bool) -> Iterator[tuple[int, int]]:
    full = 1 << bits
    rx = ry = full >> 1 if half_load else 0
    for _ in range(full):
        rx += vx
        ry += vy
        ox = rx >= full
        oy = ry >= full
        if ox:
            rx -= full
        if oy:
            ry -= full
        yield (sx if ox else 0), (sy if oy else 0)


def arc(x0: int, y0: int, x1: int, y1: int, *, clockwise: bool, bits: int | None = None,
        half_load: bool = True) -> Iterator[tuple[int, int]]:
    """Per-iteration steps ``(sx, sy)``, each in {-1, 0, +1}, along the arc about the origin.

    From ``(x0, y0)`` to ``(x1, y1)`` [pulses]; ``start == end`` is a full circle. ``bits``
    defaults to the bit length of the largest coordinate on the arc plus :data:`GUARD_BITS`.
    Raises ``ValueError`` (when called) for an end off the start's lattice circle or too few bits.
    """
    pieces = arc_pieces(x0, y0, x1, y1, clockwise=clockwise)
    largest = max(max(abs(c) for c in p.start + p.end) for p in pieces)
    need = largest.bit_length()
    if bits is None:
        bits = need + GUARD_BITS
    if bits < need:
        raise ValueError(f"{bits}-bit registers cannot hold the radius {largest}: need {need} bits")
    return _arc_steps(pieces, int(x0) ** 2 + int(y0) ** 2, bits, half_load)


def _arc_steps(pieces, r2: int, bits: int, half_load: bool) -> Iterator[tuple[int, int]]:
    full = 1 << bits
    load = full >> 1 if half_load else 0
    for piece in pieces:
        x, y = piece.start
        sx, sy = piece.direction
        nx, ny = piece.steps
        rx = ry = load
        px, py = piece.start
        if px == 0 or py == 0:
            # On an axis point (+-a, 0) / (0, +-a): the lattice point is off the circle by
            # delta = a - R, |delta| < 1. Preload the inward axis's remainder with delta so the
            # integrated point starts on the circle; the DDA has no deviation to pull it back.
            offset = abs(px + py) * full - math.isqrt(r2 * full * full)
            if piece.inward == 0:
                rx = max(0, load + offset)
            else:
                ry = max(0, load + offset)
        while nx or ny:
            # Integrands hold the coordinates before this iteration's steps (parallel clocking).
            vx, vy = abs(y), abs(x)
            step_x = step_y = 0
            if nx:
                rx += vx if vx or ny else full  # hung axis: see the module docstring
                if rx >= full:
                    rx -= full
                    step_x = sx
            if ny:
                ry += vy if vy or nx else full
                if ry >= full:
                    ry -= full
                    step_y = sy
            if step_x:
                x += step_x
                nx -= 1
            if step_y:
                y += step_y
                ny -= 1
            yield step_x, step_y
