"""The force loop's period, compiled, for the period batch (:mod:`cnc_twin.run.period_kernel`).

:meth:`~cnc_twin.dsp.force.ForceController.update` is the reference: the seek (the push grows
until the load cell reads contact), the ramps (the setpoint from the contact force to the
programmed one, and down to zero, with the PI loop), TRACK (the programmed force at the path
length so far, the PI step with its clamp and anti-windup, the feed adaptation) and the retract.
:func:`advance` does the same IEEE operations in the same order on a state vector, so the depth and
the force setpoint of every period are the same bit for bit (``tests/test_polish_batch.py``). A
period that changes the state (contact, a ramp's end, the retract's end) or, in TRACK, the feed
factor is left to the reference: :func:`advance` says so, and the batch ends before it. A frozen
loop (the supervisor's retract) stays with the reference too.

Parameters (float64, shape ``(N_PARAMS,)``) and state (float64, shape ``(N_STATE,)``)::

    params: kp [m/N], ki [m/(N s)], lo = -standoff [m], hi = max_depth [m], adapt_threshold,
            adapt_feed, adapt_hold [s], setpoint [N], period [s], seek_speed [m/s],
            retract_speed [m/s], ramp_time [s], contact_threshold [N]
    state:  integral [m], depth [m], target [N], feed_factor, calm [s], t [s], the state
            (:class:`~cnc_twin.dsp.force.ForceState`), the ramp's start force [N]
"""

from __future__ import annotations

import numpy as np
from numba import njit

from cnc_twin.dsp.force import ForceController, ForceState
from cnc_twin.dsp.span_kernel import bisect_right

KP, KI, LO, HI, ADAPT_THRESHOLD, ADAPT_FEED, ADAPT_HOLD, SETPOINT, PERIOD, SEEK_SPEED, RETRACT_SPEED, RAMP_TIME, \
    THRESHOLD = range(13)
N_PARAMS = 13
INTEGRAL, DEPTH, TARGET, FEED_FACTOR, CALM, T, STATE, RAMP_FROM = range(8)
N_STATE = 8
_SEEK, _RAMP, _TRACK, _RAMP_DOWN, _RETRACT = (ForceState.SEEK, ForceState.RAMP, ForceState.TRACK,
                                              ForceState.RAMP_DOWN, ForceState.RETRACT)


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
def _pi(params, state, error):
    """ForceController._pi"""
    lo, hi = params[LO], params[HI]
    integral = state[INTEGRAL] + params[KI] * error * params[PERIOD]
    depth = integral + params[KP] * error
    if depth > hi or depth < lo:
        depth = min(hi, max(lo, depth))
        if (depth >= hi and error > 0.0) or (depth <= lo and error < 0.0):
            integral = state[INTEGRAL]  # anti-windup
    state[INTEGRAL] = min(hi, max(lo, integral))
    state[DEPTH] = depth


@njit(cache=True)
def _adapt(params, state, error):
    """ForceController._adapt"""
    limit = params[ADAPT_THRESHOLD] * abs(state[TARGET])
    if limit <= 0.0:
        return
    if abs(error) > limit:
        state[FEED_FACTOR] = params[ADAPT_FEED]
        state[CALM] = 0.0
    elif state[FEED_FACTOR] < 1.0:
        state[CALM] = state[CALM] + params[PERIOD] if abs(error) < 0.5 * limit else 0.0
        if state[CALM] >= params[ADAPT_HOLD]:
            state[FEED_FACTOR] = 1.0


@njit(cache=True)
def advance(params, xs, fs, measured, path_s, state):
    """One period on ``state`` (in place), as :meth:`ForceController.update` (not OFF, not frozen):
    ``measured`` the load cell [N], ``path_s`` the path length so far [m]. False when the period
    changes the state or the feed factor: the caller leaves it to the reference (``state`` is
    then half-way; work on a copy)."""
    period = params[PERIOD]
    mode = state[STATE]
    state[T] += period
    if mode == _SEEK:
        state[DEPTH] = min(state[DEPTH] + params[SEEK_SPEED] * period, params[HI])
        state[INTEGRAL] = state[DEPTH]
        return not measured >= params[THRESHOLD]
    if mode == _RETRACT:
        state[DEPTH] = max(state[DEPTH] - params[RETRACT_SPEED] * period, params[LO])
        return not state[DEPTH] <= params[LO]
    if mode == _RAMP:
        goal = setpoint_at(params, xs, fs, path_s)
        frac = min(1.0, state[T] / params[RAMP_TIME]) if params[RAMP_TIME] > 0 else 1.0
        state[TARGET] = state[RAMP_FROM] + (goal - state[RAMP_FROM]) * frac
        if frac >= 1.0:
            return False  # on to TRACK
    elif mode == _TRACK:
        state[TARGET] = setpoint_at(params, xs, fs, path_s)
    else:  # RAMP_DOWN
        frac = min(1.0, state[T] / params[RAMP_TIME]) if params[RAMP_TIME] > 0 else 1.0
        state[TARGET] = state[RAMP_FROM] * (1.0 - frac)
        if frac >= 1.0:
            return False  # on to RETRACT
    error = state[TARGET] - measured
    _pi(params, state, error)
    if mode == _TRACK:
        feed = state[FEED_FACTOR]
        _adapt(params, state, error)
        return state[FEED_FACTOR] == feed
    return True


def arrays_of(force: ForceController) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(params, xs, fs, state)`` of a controller (its parameters those of its last ``start``)."""
    p = force._p
    params = np.zeros(N_PARAMS)
    params[PERIOD] = force.period
    if p is not None:
        params[[KP, KI, LO, HI, ADAPT_THRESHOLD, ADAPT_FEED, ADAPT_HOLD, SETPOINT, SEEK_SPEED, RETRACT_SPEED,
                RAMP_TIME, THRESHOLD]] = (p.kp, p.ki, -p.standoff, p.max_depth, p.adapt_threshold, p.adapt_feed,
                                          p.adapt_hold, p.setpoint, p.seek_speed, p.retract_speed, p.ramp_time,
                                          p.contact_threshold)
    state = np.array([force._integral, force.depth, force.target, force.feed_factor, force._calm, force._t,
                      float(force.state), force._ramp_from])
    return (params, np.array(force._profile_s, dtype=np.float64), np.array(force._profile_f, dtype=np.float64),
            state)


def store(force: ForceController, state: np.ndarray) -> None:
    """Leave the controller as the reference would after the periods run on ``state`` (the state
    itself is unchanged: a period that changes it is the reference's)."""
    force._integral, force.depth, force.target, force.feed_factor, force._calm, force._t = state[:STATE].tolist()
