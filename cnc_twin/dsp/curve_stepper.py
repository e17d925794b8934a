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

One implementation: :func:`start` and :func:`step` are plain functions over the stepper's state
vector, compiled with numba; :class:`CurveStepper` holds that state for the card's Python task,
and the batch kernel (:mod:`cnc_twin.run.period_kernel`) calls :func:`step` on the same vector.
``CurveStepper(..., compiled=False)`` runs the same source uncompiled (numba's ``py_func``), for
debugging; the two agree bit for bit (``tests/test_curve_stepper.py``).

State vector (float64, shape ``(2 + 3 d + 6,)``, ``d`` the points' dimension)::

    [u, |C'(u)|, C'(u) (d), C''(u) (d), point (d), S_u, S_v (3 each: on a surface path, the
     surface tangents at the point, for the tool axis; unused on a curve)]

The path ``ev`` is the tuple of :mod:`cnc_twin.geometry.span_eval` (a curve's or a surface
path's evaluator gives it as ``.path``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from cnc_twin.core.kernel_cache import purge_stale
from cnc_twin.geometry import span_eval
from cnc_twin.geometry.span_eval import NO_SURFACE, WORK, next_break, path_dim, path_evaluate, path_speed

# the stepper calls the span kernels: a change there must recompile it
purge_stale(__file__, [span_eval.__file__])

SECOND_STEP = 1e-3
"""a Newton correction larger than this fraction of the predicted step is followed by more
Newton steps with a refined length (near a cusp of the parametrisation, where ``|C'|`` is small and
changes fast, one step with one Simpson panel leaves a relative feed error of 1e-6 to 1e-5)"""
MAX_NEWTON = 4
"""Newton steps after the first, at most"""
ROUGH_SIMPSON = 2e-3
"""``|C'|`` bending over the step by more than this fraction of its midpoint value (``|s_0 + s_1 -
2 s_mid| / s_mid``) makes one Simpson panel too rough for the length, even when the Newton
correction is small (a slow, tight bend of a degree-5 curve: relative feed error 1.4e-6): one
Newton step more, with the refined length"""


MAX_PANELS = 16
"""most Simpson panels :func:`refined_length` uses on each side of a knot"""

U, SPEED = 0, 1
"""indices of the parameter and the speed ``|C'(u)|`` in the state vector"""


@njit(cache=True)
def simpson_panels(ev, a, b, speed_a, speed_b, n, w):
    """``integral |C'|`` over [a, b] (no knot inside) by Simpson's rule on ``n`` equal panels.
    ``w``: work space of :data:`~cnc_twin.geometry.span_eval.WORK`."""
    width = (b - a) / n
    total = 0.0
    left, speed_left = a, speed_a
    for i in range(n):
        right = b if i == n - 1 else a + (i + 1) * width
        speed_right = speed_b if i == n - 1 else path_speed(ev, right, w)
        total += (right - left) / 6.0 * (speed_left + 4.0 * path_speed(ev, 0.5 * (left + right), w) + speed_right)
        left, speed_left = right, speed_right
    return total


@njit(cache=True)
def refined_length(ev, u, u1, speed_u, speed_u1, w):
    """``integral |C'|`` over [u, u1], split at a knot inside, each side by Simpson's rule on 1, 2,
    4 ... panels until two results agree to 1e-12 (at most :data:`MAX_PANELS`): where ``|C'|`` is
    small and changes fast (a cusp of the parametrisation) one panel is off by 1e-5 of the length."""
    knot = next_break(ev, u)
    total = 0.0
    for side in range(2):
        if knot < u1:
            if side == 0:
                a, b, speed_a, speed_b = u, knot, speed_u, path_speed(ev, knot, w)
            else:
                a, b, speed_a, speed_b = knot, u1, path_speed(ev, knot, w), speed_u1
        elif side == 0:
            a, b, speed_a, speed_b = u, u1, speed_u, speed_u1
        else:
            break
        n = 1
        length = simpson_panels(ev, a, b, speed_a, speed_b, n, w)
        while n < MAX_PANELS:
            n *= 2
            finer = simpson_panels(ev, a, b, speed_a, speed_b, n, w)
            done = abs(finer - length) <= 1e-12 * abs(finer)
            length = finer
            if done:
                break
        total += length
    return total


def state_size(d: int) -> int:
    """Length of the stepper's state vector for points of dimension ``d``."""
    return 2 + 3 * d + 6


def scratch_size(d: int) -> int:
    """Length of the stepper's work space for points of dimension ``d``."""
    return WORK + 3 * d + 6


@njit(cache=True)
def step(ev, correct, ds, state, scratch):
    """Advance ``state`` by arc length ``ds`` [m] (``ds > 0``; clamped at the path's end).
    ``correct``: apply the Newton corrector (False = Taylor predictor only, for comparison);
    ``scratch``: float64 work space of :func:`scratch_size`."""
    d = path_dim(ev)
    hi = ev[3]
    c1 = state[2:2 + d]
    c2 = state[2 + d:2 + 2 * d]
    point = state[2 + 2 * d:2 + 3 * d]
    tangents = state[2 + 3 * d:2 + 3 * d + 6]
    w = scratch[:WORK]
    cp = scratch[WORK:WORK + d]
    c1p = scratch[WORK + d:WORK + 2 * d]
    c2p = scratch[WORK + 2 * d:WORK + 3 * d]
    tangents_p = scratch[WORK + 3 * d:WORK + 3 * d + 6]
    speed = state[SPEED]
    sp2 = speed * speed
    dot12 = 0.0
    for k in range(d):
        dot12 += c1[k] * c2[k]
    du = ds / speed - ds * ds * dot12 / (2.0 * sp2 * sp2)
    u = state[U]
    u_p = u + du
    if u_p >= hi:
        path_evaluate(ev, hi, w, cp, c1p, c2p, tangents_p)
        sq = 0.0
        for k in range(d):
            sq += c1p[k] * c1p[k]
        state[U] = hi
        state[SPEED] = math.sqrt(sq)
        for k in range(d):
            point[k] = cp[k]
            c1[k] = c1p[k]
            c2[k] = c2p[k]
        tangents[:] = tangents_p
        return
    path_evaluate(ev, u_p, w, cp, c1p, c2p, tangents_p)
    sq = 0.0
    for k in range(d):
        sq += c1p[k] * c1p[k]
    speed_p = math.sqrt(sq)
    if correct:
        knot = next_break(ev, u)
        if knot < u_p:
            speed_k = path_speed(ev, knot, w)
            mid1 = path_speed(ev, 0.5 * (u + knot), w)
            mid2 = path_speed(ev, 0.5 * (knot + u_p), w)
            length = ((knot - u) / 6.0 * (speed + 4.0 * mid1 + speed_k)
                      + (u_p - knot) / 6.0 * (speed_k + 4.0 * mid2 + speed_p))
            rough = (abs(speed + speed_k - 2.0 * mid1) > ROUGH_SIMPSON * mid1
                     or abs(speed_k + speed_p - 2.0 * mid2) > ROUGH_SIMPSON * mid2)
        else:
            mid = path_speed(ev, u + 0.5 * du, w)
            length = du / 6.0 * (speed + 4.0 * mid + speed_p)
            rough = abs(speed + speed_p - 2.0 * mid) > ROUGH_SIMPSON * mid
        u_new = min(u_p - (length - ds) / speed_p, hi)
        correction = u_new - u_p
        for i in range(MAX_NEWTON):  # a poor prediction or a rough length: Newton on, refined
            if abs(correction) <= SECOND_STEP * abs(du) and not (rough and i == 0):
                break
            speed_n = path_speed(ev, u_new, w)
            correction = -(refined_length(ev, u, u_new, speed, speed_n, w) - ds) / speed_n
            u_new = min(u_new + correction, hi)
        state[U] = u_new
        path_evaluate(ev, u_new, w, point, c1, c2, tangents)
        sq = 0.0
        for k in range(d):
            sq += c1[k] * c1[k]
        state[SPEED] = math.sqrt(sq)
        return
    state[U] = u_p
    for k in range(d):
        point[k] = cp[k]
    state[SPEED] = speed_p
    for k in range(d):
        c1[k] = c1p[k]
        c2[k] = c2p[k]
    tangents[:] = tangents_p


@njit(cache=True)
def start(ev, u, state, scratch):
    """Set ``state`` to the path's at parameter ``u``."""
    d = path_dim(ev)
    path_evaluate(ev, u, scratch[:WORK], state[2 + 2 * d:2 + 3 * d], state[2:2 + d], state[2 + d:2 + 2 * d],
                  state[2 + 3 * d:2 + 3 * d + 6])
    sq = 0.0
    for k in range(d):
        sq += state[2 + k] * state[2 + k]
    state[U] = u
    state[SPEED] = math.sqrt(sq)


NO_PATH = (np.zeros(1), np.zeros((1, 2, 12)), 0.0, 1.0, 3, *NO_SURFACE)
"""an ``ev`` of the right types that nothing evaluates (kernels compiled with it as a placeholder)"""


def warm_up() -> None:
    """Compile the kernels (or load them from numba's cache) now, not in the run's first curve
    period: a step along the line from (0, 0, 0) to (1, 0, 0), degree 1, with the run's types."""
    blocks = np.zeros((1, 2, 12))
    blocks[0, 0, 3] = blocks[0, 0, 4] = blocks[0, 1, 0] = 1.0  # A = (u, 0, 0, 1), A' = (1, 0, 0, 0)
    ev = (np.zeros(1), blocks, 0.0, 1.0, 3, *NO_SURFACE)
    state, scratch = np.zeros(state_size(3)), np.zeros(scratch_size(3))
    start(ev, 0.0, state, scratch)
    step(ev, True, 0.1, state, scratch)


class CurveStepper:
    """Walks one NURBS curve or surface path by arc length (the card's per-period stepper).

    Parameters
    ----------
    evaluator
        the curve's span evaluator, or a surface path's evaluator (its ``path``, ``dim`` and
        ``domain``).
    u
        start parameter.
    correct
        apply the Newton corrector (False = Taylor predictor only, for comparison).
    compiled
        run :func:`step` compiled (the default) or its Python source (``py_func``).

    Attributes
    ----------
    path
        the path's ``ev`` tuple (:mod:`cnc_twin.geometry.span_eval`).
    state
        the state vector (module docstring), shape ``(2 + 3 d + 6,)``; the batch kernel steps it
        in place, then calls :meth:`sync`.
    scratch
        work space of :func:`scratch_size`.
    u, point
        the parameter and the point [m], shape ``(d,)`` as a list, after the last step.
    u_end
        the path's last parameter.
    compiled
        as given (the batch kernel steps only a compiled stepper's path).
    """

    def __init__(self, evaluator, u: float, *, correct: bool = True, compiled: bool = True):
        self.path = evaluator.path
        d = evaluator.dim
        self.correct = bool(correct)
        self.u_end = float(evaluator.domain[1])
        self.state = np.zeros(state_size(d))
        self.scratch = np.zeros(scratch_size(d))
        self.compiled = compiled
        self._step = step if compiled else step.py_func
        self._point = slice(2 + 2 * d, 2 + 3 * d)
        self._tangents = slice(2 + 3 * d, 2 + 3 * d + 6)
        self._d = d
        (start if compiled else start.py_func)(self.path, float(u), self.state, self.scratch)
        self.sync()

    def sync(self) -> None:
        """Read ``u`` and ``point`` from ``state`` (after the batch kernel stepped it)."""
        self.u = float(self.state[U])
        self.point = self.state[self._point].tolist()

    def tangents(self) -> tuple[list[float], list[float], list[float]]:
        """On a surface path: ``S_u``, ``S_v`` and ``C'`` at the current point (as
        :class:`~cnc_twin.geometry.surface_path.SurfacePathEvaluator` keeps them)."""
        t = self.state[self._tangents].tolist()
        return t[:3], t[3:], self.state[2:2 + self._d].tolist()

    def step(self, ds: float) -> list[float]:
        """Advance by arc length ``ds`` [m] (clamped at the curve's end); returns the new point."""
        if ds <= 0.0:
            return self.point
        self._step(self.path, self.correct, ds, self.state, self.scratch)
        self.sync()
        return self.point
