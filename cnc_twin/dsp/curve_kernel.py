"""The NURBS curve stepper, compiled: one call per interpolation period.

:class:`~cnc_twin.dsp.curve_stepper.CurveStepper` on a
:class:`~cnc_twin.geometry.nurbs.SpanEvaluator` is the reference (plain Python, two to four span
evaluations per period). :class:`CompiledCurveStepper` runs the same predictor and corrector,
with the same span evaluation, in a numba kernel: the same IEEE operations in the same order (the
span's rows summed as ``((b0 + x b1) + x^2 b2) + ...``, the quotient rule, Simpson, Newton), no
fast-math, so the two agree bit for bit (``tests/test_curve_kernel.py``).

State vector (float64, shape ``(2 + 3 d,)``)::

    [u, |C'(u)|, C'(u) (d), C''(u) (d), point (d)]

Surface paths (a (u, v) curve on a surface) keep the Python stepper: their evaluator composes
the surface's and the curve's.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from cnc_twin.core.kernel_cache import purge_stale
from cnc_twin.dsp import curve_stepper
from cnc_twin.dsp.curve_stepper import MAX_NEWTON, MAX_PANELS, ROUGH_SIMPSON, SECOND_STEP
from cnc_twin.geometry.nurbs import SpanEvaluator

# the stepper's constants are compiled in as constants: a change there must recompile these kernels
purge_stale(__file__, [curve_stepper.__file__])

U, SPEED = 0, 1
"""indices of the parameter and the speed ``|C'(u)|`` in the state vector"""


@njit(cache=True)
def bisect_right(values, x):
    """``bisect.bisect_right`` on a sorted float64 array."""
    lo, hi = 0, values.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        if x < values[mid]:
            hi = mid
        else:
            lo = mid + 1
    return lo


@njit(cache=True)
def _homogeneous(starts, blocks, lo, hi, u, ncols, out):
    """``out[:ncols]`` = the span block's rows at ``u`` (clamped to ``[lo, hi]``), summed in order."""
    if u < lo:
        u = lo
    elif u > hi:
        u = hi
    i = bisect_right(starts, u) - 1
    x = u - starts[i]
    block = blocks[i]
    for c in range(ncols):
        out[c] = block[0, c]
    power = 1.0
    for j in range(1, block.shape[0]):
        power = power * x
        for c in range(ncols):
            out[c] = out[c] + power * block[j, c]


@njit(cache=True)
def _speed(starts, blocks, lo, hi, d, u, h):
    """``|C'(u)|``, as :meth:`SpanEvaluator.speed`."""
    _homogeneous(starts, blocks, lo, hi, u, 2 * (d + 1), h)
    w, w1 = h[d], h[2 * d + 1]
    inv = 1.0 / w
    total = 0.0
    for k in range(d):
        v = (h[d + 1 + k] - w1 * h[k] * inv) * inv
        total += v * v
    return math.sqrt(total)


@njit(cache=True)
def evaluate_span(starts, blocks, lo, hi, d, u, h, c, c1, c2):
    """``C, C', C''`` at ``u`` into ``c, c1, c2``, as :meth:`SpanEvaluator.evaluate`."""
    n = d + 1
    _homogeneous(starts, blocks, lo, hi, u, 3 * n, h)
    w, w1, w2 = h[d], h[n + d], h[2 * n + d]
    inv = 1.0 / w
    for k in range(d):
        c[k] = h[k] * inv
    for k in range(d):
        c1[k] = (h[n + k] - w1 * c[k]) * inv
    for k in range(d):
        c2[k] = (h[2 * n + k] - 2.0 * w1 * c1[k] - w2 * c[k]) * inv


@njit(cache=True)
def _next_break(starts, hi, u):
    """The first span start after ``u``; the domain's end if none."""
    i = bisect_right(starts, u)
    return starts[i] if i < starts.shape[0] else hi


@njit(cache=True)
def _simpson_panels(starts, blocks, lo, hi, d, a, b, speed_a, speed_b, n, h):
    """As :func:`cnc_twin.dsp.curve_stepper.simpson_panels`."""
    w = (b - a) / n
    total = 0.0
    left, speed_left = a, speed_a
    for i in range(n):
        right = b if i == n - 1 else a + (i + 1) * w
        speed_right = speed_b if i == n - 1 else _speed(starts, blocks, lo, hi, d, right, h)
        total += (right - left) / 6.0 * (speed_left + 4.0 * _speed(starts, blocks, lo, hi, d, 0.5 * (left + right), h)
                                         + speed_right)
        left, speed_left = right, speed_right
    return total


@njit(cache=True)
def _refined_length(starts, blocks, lo, hi, d, u, u1, speed_u, speed_u1, h):
    """As :func:`cnc_twin.dsp.curve_stepper.refined_length`."""
    knot = _next_break(starts, hi, u)
    total = 0.0
    for side in range(2):
        if knot < u1:
            if side == 0:
                a, b, speed_a, speed_b = u, knot, speed_u, _speed(starts, blocks, lo, hi, d, knot, h)
            else:
                a, b, speed_a, speed_b = knot, u1, _speed(starts, blocks, lo, hi, d, knot, h), speed_u1
        elif side == 0:
            a, b, speed_a, speed_b = u, u1, speed_u, speed_u1
        else:
            break
        n = 1
        length = _simpson_panels(starts, blocks, lo, hi, d, a, b, speed_a, speed_b, n, h)
        while n < MAX_PANELS:
            n *= 2
            finer = _simpson_panels(starts, blocks, lo, hi, d, a, b, speed_a, speed_b, n, h)
            done = abs(finer - length) <= 1e-12 * abs(finer)
            length = finer
            if done:
                break
        total += length
    return total


@njit(cache=True)
def step(starts, blocks, lo, hi, d, correct, ds, state, scratch):
    """Advance ``state`` by arc length ``ds`` [m] (``ds > 0``), as :meth:`CurveStepper.step`.
    ``scratch``: float64 work space of at least ``3 (d + 1) + 3 d``."""
    c1 = state[2:2 + d]
    c2 = state[2 + d:2 + 2 * d]
    point = state[2 + 2 * d:2 + 3 * d]
    h = scratch[:3 * (d + 1)]
    cp = scratch[3 * (d + 1):3 * (d + 1) + d]
    c1p = scratch[3 * (d + 1) + d:3 * (d + 1) + 2 * d]
    c2p = scratch[3 * (d + 1) + 2 * d:3 * (d + 1) + 3 * d]
    speed = state[SPEED]
    sp2 = speed * speed
    dot12 = 0.0
    for k in range(d):
        dot12 += c1[k] * c2[k]
    du = ds / speed - ds * ds * dot12 / (2.0 * sp2 * sp2)
    u = state[U]
    u_p = u + du
    if u_p >= hi:
        evaluate_span(starts, blocks, lo, hi, d, hi, h, cp, c1p, c2p)
        sq = 0.0
        for k in range(d):
            sq += c1p[k] * c1p[k]
        state[U] = hi
        state[SPEED] = math.sqrt(sq)
        for k in range(d):
            point[k] = cp[k]
            c1[k] = c1p[k]
            c2[k] = c2p[k]
        return
    evaluate_span(starts, blocks, lo, hi, d, u_p, h, cp, c1p, c2p)
    sq = 0.0
    for k in range(d):
        sq += c1p[k] * c1p[k]
    speed_p = math.sqrt(sq)
    if correct:
        knot = _next_break(starts, hi, u)
        if knot < u_p:
            speed_k = _speed(starts, blocks, lo, hi, d, knot, h)
            mid1 = _speed(starts, blocks, lo, hi, d, 0.5 * (u + knot), h)
            mid2 = _speed(starts, blocks, lo, hi, d, 0.5 * (knot + u_p), h)
            length = ((knot - u) / 6.0 * (speed + 4.0 * mid1 + speed_k)
                      + (u_p - knot) / 6.0 * (speed_k + 4.0 * mid2 + speed_p))
            rough = (abs(speed + speed_k - 2.0 * mid1) > ROUGH_SIMPSON * mid1
                     or abs(speed_k + speed_p - 2.0 * mid2) > ROUGH_SIMPSON * mid2)
        else:
            mid = _speed(starts, blocks, lo, hi, d, u + 0.5 * du, h)
            length = du / 6.0 * (speed + 4.0 * mid + speed_p)
            rough = abs(speed + speed_p - 2.0 * mid) > ROUGH_SIMPSON * mid
        u_new = min(u_p - (length - ds) / speed_p, hi)
        correction = u_new - u_p
        for i in range(MAX_NEWTON):  # a poor prediction or a rough length: Newton on, refined
            if abs(correction) <= SECOND_STEP * abs(du) and not (rough and i == 0):
                break
            speed_n = _speed(starts, blocks, lo, hi, d, u_new, h)
            correction = -(_refined_length(starts, blocks, lo, hi, d, u, u_new, speed, speed_n, h) - ds) / speed_n
            u_new = min(u_new + correction, hi)
        state[U] = u_new
        evaluate_span(starts, blocks, lo, hi, d, u_new, h, point, c1, c2)
        sq = 0.0
        for k in range(d):
            sq += c1[k] * c1[k]
        state[SPEED] = math.sqrt(sq)
        return
    else:
        state[U] = u_p
        for k in range(d):
            point[k] = cp[k]
    state[SPEED] = speed_p
    for k in range(d):
        c1[k] = c1p[k]
        c2[k] = c2p[k]


@njit(cache=True)
def start(starts, blocks, lo, hi, d, u, state, scratch):
    """The state at parameter ``u``, as :class:`CurveStepper`'s constructor."""
    h = scratch[:3 * (d + 1)]
    evaluate_span(starts, blocks, lo, hi, d, u, h, state[2 + 2 * d:2 + 3 * d], state[2:2 + d], state[2 + d:2 + 2 * d])
    sq = 0.0
    for k in range(d):
        sq += state[2 + k] * state[2 + k]
    state[U] = u
    state[SPEED] = math.sqrt(sq)


def warm_up() -> None:
    """Compile the kernels (or load them from numba's cache) now, not in the run's first curve
    period: a step along the line from (0, 0, 0) to (1, 0, 0), degree 1, with the run's types."""
    blocks = np.zeros((1, 2, 12))
    blocks[0, 0, 3] = blocks[0, 0, 4] = blocks[0, 1, 0] = 1.0  # A = (u, 0, 0, 1), A' = (1, 0, 0, 0)
    state, scratch = np.zeros(11), np.zeros(21)
    start(np.zeros(1), blocks, 0.0, 1.0, 3, 0.0, state, scratch)
    step(np.zeros(1), blocks, 0.0, 1.0, 3, True, 0.1, state, scratch)


class CompiledCurveStepper:
    """Walks one NURBS curve by arc length, compiled; the interface of
    :class:`~cnc_twin.dsp.curve_stepper.CurveStepper` (``u``, ``point``, ``u_end``, :meth:`step`).

    Parameters
    ----------
    evaluator : the curve's span evaluator (its ``starts`` and ``blocks`` are used).
    u : start parameter.
    correct : apply the Newton corrector (False = Taylor predictor only, for comparison).
    """

    def __init__(self, evaluator: SpanEvaluator, u: float, *, correct: bool = True):
        d = evaluator.dim
        self._args = (evaluator.starts, np.ascontiguousarray(evaluator.blocks), float(evaluator.domain[0]),
                      float(evaluator.domain[1]), d)
        self.correct = bool(correct)
        self.u_end = float(evaluator.domain[1])
        self._state = np.zeros(2 + 3 * d)
        self._scratch = np.zeros(3 * (d + 1) + 3 * d)
        self._point = slice(2 + 2 * d, 2 + 3 * d)
        start(*self._args, float(u), self._state, self._scratch)
        self.u = float(self._state[U])
        self.point = self._state[self._point].tolist()

    def step(self, ds: float) -> list[float]:
        """Advance by arc length ``ds`` [m] (clamped at the curve's end); returns the new point."""
        if ds <= 0.0:
            return self.point
        state = self._state
        step(*self._args, self.correct, ds, state, self._scratch)
        self.u = float(state[U])
        self.point = state[self._point].tolist()
        return self.point
