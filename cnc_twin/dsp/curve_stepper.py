"""NURBS direct interpolation: advance the curve parameter by a given arc length each period.

Inputs per period: the arc length to travel, ``ds = s(t + T) - s(t)`` from the feed profile [m].
Output: the new parameter ``u`` and the point ``C(u)`` [m].

Algorithm (``C1 = C'(u)``, ``C2 = C''(u)`` kept from the previous period)::

    predictor (2nd-order Taylor of u(s)):
        du  = ds / |C1| - ds^2 (C1 . C2) / (2 |C1|^4)
        u_p = u + du
    corrector (one Newton step on  L(u, u') - ds = 0,  dL/du' = |C'(u')|):
        L     = du / 6 (|C'(u)| + 4 |C'(u + du/2)| + |C'(u_p)|)        Simpson, split at a knot
                                                                      inside [u, u_p] (|C'| may
                                                                      have a kink there)
        u_new = u_p - (L - ds) / |C'(u_p)|
        point, C1, C2 = C(u_new), C'(u_new), C''(u_new)     # the next step starts from here

    while the last correction > SECOND_STEP |du| (a poor prediction, near a cusp of the
    parametrisation; at most MAX_NEWTON times), and once when |C'| bends over the step by more
    than ROUGH_SIMPSON (one Simpson panel is too rough there): Newton again from u_new, the
    length by Simpson on as many panels as it takes (refined_length)

The Taylor predictor alone leaves a relative feed error of order (ds kappa)^2; one Newton step
squares it. Simpson's error over a step of 0.1-1 mm is ~(h/L)^4 / 2880 of the step, far below
1e-6. Three span evaluations per period (midpoint, predicted point, corrected point).
"""

from __future__ import annotations

import math

from cnc_twin.geometry.nurbs import SpanEvaluator

SECOND_STEP = 1e-3
"""a Newton correction larger than this fraction of the predicted step is followed by more
Newton steps with a refined length (near a cusp of the parametrisation, where |C'| is small and
changes fast, one step with one Simpson panel leaves a relative feed error of 1e-6 to 1e-5)"""
MAX_NEWTON = 4
"""Newton steps after the first, at most"""
ROUGH_SIMPSON = 2e-3
"""|C'| bending over the step by more than this fraction of its midpoint value (``|s_0 + s_1 -
2 s_mid| / s_mid``) makes one Simpson panel too rough for the length, even when the Newton
correction is small (a slow, tight bend of a degree-5 curve: relative feed error 1.4e-6): one
Newton step more, with the refined length"""


class CurveStepper:
    """Walks one NURBS curve by arc length.

    Parameters
    ----------
    evaluator : the curve's span evaluator.
    u : start parameter.
    correct : apply the Newton corrector (False = Taylor predictor only, for comparison).
    """

    def __init__(self, evaluator: SpanEvaluator, u: float, *, correct: bool = True):
        self.ev = evaluator
        self.correct = correct
        self.u = u
        c, c1, c2 = evaluator.evaluate(u)
        self.point = c
        self._c1, self._c2 = c1, c2
        self._speed = math.sqrt(sum(x * x for x in c1))
        self.u_end = evaluator.domain[1]

    def step(self, ds: float) -> list[float]:
        """Advance by arc length ``ds`` [m] (clamped at the curve's end); returns the new point."""
        if ds <= 0.0:
            return self.point
        c1, c2, speed = self._c1, self._c2, self._speed
        sp2 = speed * speed
        dot12 = 0.0
        for a, b in zip(c1, c2):
            dot12 += a * b
        du = ds / speed - ds * ds * dot12 / (2.0 * sp2 * sp2)
        u = self.u
        u_p = u + du
        if u_p >= self.u_end:
            c, c1n, c2n = self.ev.evaluate(self.u_end)
            self.u, self.point = self.u_end, c
            self._c1, self._c2 = c1n, c2n
            self._speed = math.sqrt(sum(x * x for x in c1n))
            return c
        cp, c1p, c2p = self.ev.evaluate(u_p)
        sq = 0.0
        for x in c1p:
            sq += x * x
        speed_p = math.sqrt(sq)
        if self.correct:
            knot = self.ev.next_break(u)
            if knot < u_p:
                speed_k = self.ev.speed(knot)
                mid1 = self.ev.speed(0.5 * (u + knot))
                mid2 = self.ev.speed(0.5 * (knot + u_p))
                length = ((knot - u) / 6.0 * (speed + 4.0 * mid1 + speed_k)
                          + (u_p - knot) / 6.0 * (speed_k + 4.0 * mid2 + speed_p))
                rough = (abs(speed + speed_k - 2.0 * mid1) > ROUGH_SIMPSON * mid1
                         or abs(speed_k + speed_p - 2.0 * mid2) > ROUGH_SIMPSON * mid2)
            else:
                mid = self.ev.speed(u + 0.5 * du)
                length = du / 6.0 * (speed + 4.0 * mid + speed_p)
                rough = abs(speed + speed_p - 2.0 * mid) > ROUGH_SIMPSON * mid
            u_new = min(u_p - (length - ds) / speed_p, self.u_end)
            correction = u_new - u_p
            for i in range(MAX_NEWTON):  # a poor prediction or a rough length: Newton on, refined
                if abs(correction) <= SECOND_STEP * abs(du) and not (rough and i == 0):
                    break
                speed_n = self.ev.speed(u_new)
                correction = -(refined_length(self.ev, u, u_new, speed, speed_n) - ds) / speed_n
                u_new = min(u_new + correction, self.u_end)
            # the point and the next step's derivatives at the corrected parameter itself: kept
            # from u_p instead, the next step's predictor and Simpson rule start from the wrong
            # place (a relative feed error up to 3e-4 after a knot where C'' jumps, degree 2)
            point, c1p, c2p = self.ev.evaluate(u_new)
            sq = 0.0
            for x in c1p:
                sq += x * x
            speed_p = math.sqrt(sq)
        else:
            u_new, point = u_p, cp
        self.u = u_new
        self.point = point
        self._c1, self._c2, self._speed = c1p, c2p, speed_p
        return point


MAX_PANELS = 16
"""most Simpson panels :func:`refined_length` uses on each side of a knot"""


def simpson_panels(ev: SpanEvaluator, a: float, b: float, speed_a: float, speed_b: float, n: int) -> float:
    """``integral |C'|`` over [a, b] (no knot inside) by Simpson's rule on ``n`` equal panels."""
    h = (b - a) / n
    total = 0.0
    left, speed_left = a, speed_a
    for i in range(n):
        right = b if i == n - 1 else a + (i + 1) * h
        speed_right = speed_b if i == n - 1 else ev.speed(right)
        total += (right - left) / 6.0 * (speed_left + 4.0 * ev.speed(0.5 * (left + right)) + speed_right)
        left, speed_left = right, speed_right
    return total


def refined_length(ev: SpanEvaluator, u: float, u1: float, speed_u: float, speed_u1: float) -> float:
    """``integral |C'|`` over [u, u1], split at a knot inside, each side by Simpson's rule on 1, 2,
    4 ... panels until two results agree to 1e-12 (at most :data:`MAX_PANELS`): where |C'| is
    small and changes fast (a cusp of the parametrisation) one panel is off by 1e-5 of the length."""
    knot = ev.next_break(u)
    pieces = ((u, knot, speed_u, ev.speed(knot)), (knot, u1, ev.speed(knot), speed_u1)) if knot < u1 else \
        ((u, u1, speed_u, speed_u1),)
    total = 0.0
    for a, b, speed_a, speed_b in pieces:
        n = 1
        length = simpson_panels(ev, a, b, speed_a, speed_b, n)
        while n < MAX_PANELS:
            n *= 2
            finer = simpson_panels(ev, a, b, speed_a, speed_b, n)
            done = abs(finer - length) <= 1e-12 * abs(finer)
            length = finer
            if done:
                break
        total += length
    return total
