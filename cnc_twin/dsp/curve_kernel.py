"""The NURBS curve stepper, compiled: one call per interpolation period, on curves and surface paths.

:class:`~cnc_twin.dsp.curve_stepper.CurveStepper` on a
:class:`~cnc_twin.geometry.nurbs.SpanEvaluator` or a
:class:`~cnc_twin.geometry.surface_path.SurfacePathEvaluator` is the reference (plain Python, two
to four path evaluations per period). :class:`CompiledCurveStepper` runs the same predictor and
corrector, with the same evaluation (:mod:`cnc_twin.dsp.span_kernel`), in a numba kernel: the
same IEEE operations in the same order (Simpson, Newton), no fast-math, so the two agree bit for
bit (``tests/test_curve_kernel.py``, ``tests/test_surface_kernel.py``).

State vector (float64, shape ``(2 + 3 d + 6,)``, ``d`` the points' dimension)::

    [u, |C'(u)|, C'(u) (d), C''(u) (d), point (d), S_u, S_v (3 each: on a surface path, the
     surface tangents at the point, for the tool axis; unused on a curve)]
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from cnc_twin.core.kernel_cache import purge_stale
from cnc_twin.dsp import curve_stepper, span_kernel
from cnc_twin.dsp.curve_stepper import MAX_NEWTON, MAX_PANELS, ROUGH_SIMPSON, SECOND_STEP
from cnc_twin.dsp.span_kernel import NO_SURFACE, WORK, next_break, path_dim, path_evaluate, path_speed
from cnc_twin.geometry.nurbs import SpanEvaluator
from cnc_twin.geometry.surface_path import SurfacePathEvaluator

# the stepper's constants are compiled in as constants, and it calls the span kernels: a change
# there must recompile these kernels
purge_stale(__file__, [curve_stepper.__file__, span_kernel.__file__])

U, SPEED = 0, 1
"""indices of the parameter and the speed ``|C'(u)|`` in the state vector"""


@njit(cache=True)
def _simpson_panels(ev, a, b, speed_a, speed_b, n, w):
    """As :func:`cnc_twin.dsp.curve_stepper.simpson_panels`."""
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
def _refined_length(ev, u, u1, speed_u, speed_u1, w):
    """As :func:`cnc_twin.dsp.curve_stepper.refined_length`."""
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
        length = _simpson_panels(ev, a, b, speed_a, speed_b, n, w)
        while n < MAX_PANELS:
            n *= 2
            finer = _simpson_panels(ev, a, b, speed_a, speed_b, n, w)
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
    """Advance ``state`` by arc length ``ds`` [m] (``ds > 0``), as :meth:`CurveStepper.step`.
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
            correction = -(_refined_length(ev, u, u_new, speed, speed_n, w) - ds) / speed_n
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
    """The state at parameter ``u``, as :class:`CurveStepper`'s constructor."""
    d = path_dim(ev)
    path_evaluate(ev, u, scratch[:WORK], state[2 + 2 * d:2 + 3 * d], state[2:2 + d], state[2 + d:2 + 2 * d],
                  state[2 + 3 * d:2 + 3 * d + 6])
    sq = 0.0
    for k in range(d):
        sq += state[2 + k] * state[2 + k]
    state[U] = u
    state[SPEED] = math.sqrt(sq)


def path_args(evaluator: SpanEvaluator | SurfacePathEvaluator) -> tuple:
    """The ``ev`` tuple of :mod:`cnc_twin.dsp.span_kernel` for a curve's or a surface path's evaluator."""
    if isinstance(evaluator, SurfacePathEvaluator):
        uv, sf = evaluator.uv, evaluator.surface
        surface = (sf.starts_u, sf.starts_v, np.ascontiguousarray(sf.patches), sf.degree_u, sf.degree_v,
                   np.array([*sf.domain_u, *sf.domain_v], dtype=np.float64))
    else:
        uv, surface = evaluator, NO_SURFACE
    return (uv.starts, np.ascontiguousarray(uv.blocks), float(uv.domain[0]), float(uv.domain[1]), uv.dim, *surface)


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


class CompiledCurveStepper:
    """Walks one NURBS curve or surface path by arc length, compiled; the interface of
    :class:`~cnc_twin.dsp.curve_stepper.CurveStepper` (``u``, ``point``, ``u_end``, :meth:`step`).

    Parameters
    ----------
    evaluator : the curve's span evaluator, or a surface path's evaluator.
    u : start parameter.
    correct : apply the Newton corrector (False = Taylor predictor only, for comparison).
    """

    def __init__(self, evaluator: SpanEvaluator | SurfacePathEvaluator, u: float, *, correct: bool = True):
        self._args = path_args(evaluator)
        d = 3 if isinstance(evaluator, SurfacePathEvaluator) else evaluator.dim
        self.correct = bool(correct)
        self.u_end = float(evaluator.domain[1])
        self._state = np.zeros(state_size(d))
        self._scratch = np.zeros(scratch_size(d))
        self._point = slice(2 + 2 * d, 2 + 3 * d)
        self._tangents = slice(2 + 3 * d, 2 + 3 * d + 6)
        self._d = d
        start(self._args, float(u), self._state, self._scratch)
        self.u = float(self._state[U])
        self.point = self._state[self._point].tolist()

    def tangents(self) -> tuple[list[float], list[float], list[float]]:
        """On a surface path: ``S_u``, ``S_v`` and ``C'`` at the current point (as
        :class:`~cnc_twin.geometry.surface_path.SurfacePathEvaluator` keeps them)."""
        t = self._state[self._tangents].tolist()
        return t[:3], t[3:], self._state[2:2 + self._d].tolist()

    def step(self, ds: float) -> list[float]:
        """Advance by arc length ``ds`` [m] (clamped at the curve's end); returns the new point."""
        if ds <= 0.0:
            return self.point
        state = self._state
        step(self._args, self.correct, ds, state, self._scratch)
        self.u = float(state[U])
        self.point = state[self._point].tolist()
        return self.point
