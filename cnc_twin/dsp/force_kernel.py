"""The force loop's TRACK period, compiled, for the period batch (:mod:`cnc_twin.run.period_kernel`).

:meth:`~cnc_twin.dsp.force.ForceController.update` in TRACK is the reference: the programmed
force at the path length so far, the PI step with its clamp and anti-windup, the feed adaptation.
:func:`track` does the same IEEE operations in the same order on a state vector, so the depth and
the force setpoint of every period are the same bit for bit (``tests/test_polish_batch.py``). The
other states (seek, ramps, retract) and a frozen loop stay with the reference.

Parameters (float64, shape ``(N_PARAMS,)``) and state (float64, shape ``(N_STATE,)``)::

    params: kp [m/N], ki [m/(N s)], lo = -standoff [m], hi = max_depth [m], adapt_threshold,
            adapt_feed, adapt_hold [s], setpoint [N], period [s]
    state:  integral [m], depth [m], target [N], feed_factor, calm [s], t [s]
"""

from __future__ import annotations

import numpy as np
from numba import njit

from cnc_twin.dsp.force import ForceController
from cnc_twin.dsp.span_kernel import bisect_right

KP, KI, LO, HI, ADAPT_THRESHOLD, ADAPT_FEED, ADAPT_HOLD, SETPOINT, PERIOD = range(9)
N_PARAMS = 9
INTEGRAL, DEPTH, TARGET, FEED_FACTOR, CALM, T = range(6)
N_STATE = 6


@njit(cache=True)
def setpoint_at(params, xs, fs, path_s):
    """The programmed force at path length ``path_s`` [m] (N), as :meth:`ForceController.setpoint_at`;
    ``xs``, ``fs``: the profile's path lengths and forces (empty: the constant setpoint)."""
    n = xs.shape[0]
    if n == 0:
        return params[SETPOINT]
    i = bisect_right(xs, path_s)
    if i == 0:
        return fs[0]
    if i == n:
        return fs[n - 1]
    x0, x1 = xs[i - 1], xs[i]
    return fs[i - 1] + (fs[i] - fs[i - 1]) * (path_s - x0) / (x1 - x0)


@njit(cache=True)
def track(params, xs, fs, measured, path_s, state):
    """One TRACK period on ``state`` (in place), as :meth:`ForceController.update`: ``measured`` the
    load cell [N], ``path_s`` the path length so far [m]."""
    period = params[PERIOD]
    state[T] += period
    target = setpoint_at(params, xs, fs, path_s)
    state[TARGET] = target
    error = target - measured
    # ForceController._pi
    lo, hi = params[LO], params[HI]
    integral = state[INTEGRAL] + params[KI] * error * period
    depth = integral + params[KP] * error
    if depth > hi or depth < lo:
        depth = min(hi, max(lo, depth))
        if (depth >= hi and error > 0.0) or (depth <= lo and error < 0.0):
            integral = state[INTEGRAL]  # anti-windup
    state[INTEGRAL] = min(hi, max(lo, integral))
    state[DEPTH] = depth
    # ForceController._adapt
    limit = params[ADAPT_THRESHOLD] * abs(target)
    if limit <= 0.0:
        return
    if abs(error) > limit:
        state[FEED_FACTOR] = params[ADAPT_FEED]
        state[CALM] = 0.0
    elif state[FEED_FACTOR] < 1.0:
        state[CALM] = state[CALM] + period if abs(error) < 0.5 * limit else 0.0
        if state[CALM] >= params[ADAPT_HOLD]:
            state[FEED_FACTOR] = 1.0


def arrays_of(force: ForceController) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(params, xs, fs, state)`` of a running controller (its parameters set by ``start``)."""
    p = force._p
    params = np.zeros(N_PARAMS)
    if p is not None:
        params[:] = (p.kp, p.ki, -p.standoff, p.max_depth, p.adapt_threshold, p.adapt_feed, p.adapt_hold, p.setpoint,
                     force.period)
    else:
        params[PERIOD] = force.period
    state = np.array([force._integral, force.depth, force.target, force.feed_factor, force._calm, force._t])
    return (params, np.array(force._profile_s, dtype=np.float64), np.array(force._profile_f, dtype=np.float64),
            state)


def store(force: ForceController, state: np.ndarray) -> None:
    """Leave the controller as the reference would after the periods run on ``state``."""
    force._integral, force.depth, force.target, force.feed_factor, force._calm, force._t = state.tolist()
