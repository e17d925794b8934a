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

The Taylor predictor alone leaves a relative feed error of order (ds kappa)^2; one Newton step
squares it. Simpson's error over a step of 0.1-1 mm is ~(h/L)^4 / 2880 of the step, far below
1e-6. Three span evaluations per period (midpoint, predicted point, corrected point).
"""

from __future__ import annotations

import math

from cnc_twin.geometry.nurbs import SpanEvaluator


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
                length = ((knot - u) / 6.0 * (speed + 4.0 * self.ev.speed(0.5 * (u + knot)) + speed_k)
                          + (u_p - knot) / 6.0 * (speed_k + 4.0 * self.ev.speed(0.5 * (knot + u_p)) + speed_p))
            else:
                length = du / 6.0 * (speed + 4.0 * self.ev.speed(u + 0.5 * du) + speed_p)
            u_new = min(u_p - (length - ds) / speed_p, self.u_end)
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
