"""Jerk-limited changes of the feed along curve blocks: holds, resumes, override changes.

A curve block runs on its S-curve's clock ``tau`` scaled by ``lambda`` (the override, see
:mod:`cnc_twin.dsp.interpolator`): path speed ``sigma = lambda v(tau)``, path acceleration
``lambda^2 a(tau)``. When the target scale ``lambda_T`` differs (a feed hold, a starved hold, an
override record, the force loop's feed factor), a slew of ``lambda`` limited in acceleration
only (as moves have it) would make each hold an acceleration step, a jerk of about ``a / T``.
Here the path itself moves instead, in path space, from its speed and
acceleration ``(sigma, alpha)`` to the target's ``(lambda_T v, lambda_T^2 a)`` along a
:func:`transition`: a jerk ramp to a peak acceleration, a constant-acceleration phase if that
peak would exceed ``A``, a jerk ramp to the target's acceleration, with ``|jerk| = J``.

Every period the transition is planned again from where the path is (a static target, a stop,
gives the same plan again, so the motion is that plan; a target that moves with the block's own
profile is followed), the path advances along it by exactly one period, and the block clock
``tau`` is the one at which the S-curve has covered that path (:func:`time_at`). Once a plan
ends within a period the scale is ``lambda_T`` again. So a starved hold stops within
:func:`stop_distance` with path jerk within ``J``, the tangential budget the planner gave the
block (with the interpolator's margin): the axes keep their jerk limits as on the planned path.

Units: path [m], speeds [m/s], accelerations [m/s^2], jerks [m/s^3], times [s].
"""

from __future__ import annotations

import math

from cnc_twin.motion.scurve import SCurve


def transition(sigma0: float, alpha0: float, sigma1: float, alpha1: float, a_max: float,
               j_max: float) -> tuple[float, float, float, float, float]:
    """The fastest change of path speed and acceleration from ``(sigma0, alpha0)`` to
    ``(sigma1, alpha1)`` with ``|jerk| = j_max`` and ``|alpha| <= a_max`` (or the larger of the
    two ends, if one is beyond it): ``(j1, t1, t2, j3, t3)``, the jerk and duration [s] of the
    ramp to the peak acceleration, the peak's plateau [s], the jerk and duration of the ramp to
    ``alpha1``.

    With the plateau empty the speed change is ``F(peak)``, the area under two linear ramps;
    ``F`` is ``(alpha1^2 - alpha0^2) / 2J`` on the single ramp ``alpha0 -> alpha1`` and
    quadratic beyond it, so the peak solves a quadratic (the root nearest the ends)."""
    d = sigma1 - sigma0
    lo, hi = min(alpha0, alpha1), max(alpha0, alpha1)
    squares = 0.5 * (alpha0 * alpha0 + alpha1 * alpha1)
    d_direct = 0.5 * (alpha0 + alpha1) * (hi - lo) / j_max
    limit = max(a_max, hi, -lo)
    plateau = 0.0
    if d > d_direct:  # a peak above both ends
        root = math.sqrt(max(j_max * d + squares, 0.0))
        peak = -root if -root > hi else root
        if peak > limit:
            peak = limit
            plateau = (d - (limit * limit - squares) / j_max) / limit
    elif d < d_direct:  # a trough below both ends
        root = math.sqrt(max(squares - j_max * d, 0.0))
        peak = root if root < lo else -root
        if peak < -limit:
            peak = -limit
            plateau = (d - (squares - limit * limit) / j_max) / -limit
    else:
        peak = alpha0
    return (math.copysign(j_max, peak - alpha0), abs(peak - alpha0) / j_max, max(plateau, 0.0),
            math.copysign(j_max, alpha1 - peak), abs(alpha1 - peak) / j_max)


def duration(plan: tuple[float, float, float, float, float]) -> float:
    """How long ``plan`` (:func:`transition`) takes [s]."""
    return plan[1] + plan[2] + plan[4]


def follow(sigma0: float, alpha0: float, plan: tuple[float, float, float, float, float],
           t: float) -> tuple[float, float, float]:
    """``(path covered, speed, acceleration)`` at ``t`` [s] into ``plan`` (:func:`transition`),
    integrated exactly phase by phase; past its end the last acceleration holds."""
    j1, t1, t2, j3, t3 = plan
    s, v, a = 0.0, sigma0, alpha0
    for jerk, span in ((j1, t1), (0.0, t2), (j3, t3), (0.0, math.inf)):
        dt = min(span, t)
        s += dt * (v + dt * (0.5 * a + dt * jerk / 6.0))
        v += dt * (a + 0.5 * jerk * dt)
        a += jerk * dt
        t -= dt
        if t <= 0.0:
            break
    return s, v, a


STOP_MARGIN = 1.5
"""a starved curve block starts holding when its remaining length is within 1.5x the stopping
distance (so new blocks that come while it slows can still be taken at speed)"""


def stop_distance(speed: float, accel: float, a_stop: float, j_stop: float, period: float) -> float:
    """Path [m] a starved hold needs to stop from path ``speed`` [m/s] and ``accel`` [m/s^2]
    with acceleration ``a_stop`` and jerk ``j_stop``, with its margins (:data:`STOP_MARGIN` on
    the braking distance, two periods of travel). A jerk ramp takes a positive acceleration to
    zero, then an S-curve ramp (:func:`cnc_twin.motion.scurve.ramp_distance`, written out here so
    the batch kernel compiles this very function) goes to rest; a negative acceleration is
    counted as zero (it only shortens the stop). Plain float arithmetic only (no ``**``): the
    batch kernel's compiled copy gives the same bits."""
    rise = max(accel, 0.0)
    climb = rise / j_stop  # [s] to take the acceleration to zero
    distance = climb * (speed + rise * climb / 3.0)
    top = speed + 0.5 * rise * climb
    if top * j_stop >= a_stop * a_stop:
        ramp = 2.0 * a_stop / j_stop + (top / a_stop - a_stop / j_stop)
    else:
        ramp = 2.0 * math.sqrt(top / j_stop)
    distance += 0.5 * top * ramp
    return distance * STOP_MARGIN + 2.0 * speed * period


def time_at(profile: SCurve, tau: float, s_target: float) -> tuple[float, tuple[float, float, float]]:
    """The block clock at or after ``tau`` [s] where ``profile`` has covered ``s_target`` [m]
    (below its length), with the S-curve's ``(s, v, a)`` there: safeguarded Newton steps."""
    lo, hi = tau, profile.duration
    state = profile.state(tau)
    t = tau
    for _ in range(60):
        miss = state[0] - s_target
        if miss == 0.0:
            break
        if miss > 0.0:
            hi = t
        else:
            lo = t
        step = miss / state[1] if state[1] > 0.0 else math.inf
        t_next = t - step
        if not lo < t_next < hi:  # Newton left the bracket (or the speed is zero): bisect
            t_next = 0.5 * (lo + hi)
        if t_next == t or hi - lo <= 1e-15 * max(hi, 1e-3):
            break
        t = t_next
        state = profile.state(t)
    return t, state


def advance(profile: SCurve, tau: float, state: tuple[float, float, float], lam: float,
            alpha: float | None, lam_target: float, period: float, a_max: float,
            j_max: float) -> tuple[float, float, float | None]:
    """One period of a block whose scale moves to ``lam_target``: ``(tau, lambda, alpha)`` at its
    end. ``state``: the S-curve's ``(s, v, a)`` at ``tau``; ``alpha``: the path acceleration the
    last period left [m/s^2] (None when the block ran at a constant scale: then
    ``lambda^2 a``); ``a_max`` / ``j_max``: the transition's limits. ``alpha`` comes back None
    once the target is reached. A ``tau`` past the block's duration means the path went past its
    end by ``(tau - duration) v1``: the caller continues into the next block."""
    s_now, v, a = state
    sigma = lam * v
    if alpha is None:
        alpha = lam * lam * a
    plan = transition(sigma, alpha, lam_target * v, lam_target * lam_target * a, a_max, j_max)
    span = duration(plan)
    done = span <= period
    ds, sigma_end, alpha_end = follow(sigma, alpha, plan, min(span, period))
    if sigma_end < 0.0 or (lam_target == 0.0 and done):  # at rest within this period
        ds, sigma_end, done = max(ds, 0.0), 0.0, True
    s_end = s_now + ds
    if s_end >= profile.length:  # past the block's end: the rest in the next block's clock
        over = (s_end - profile.length) / profile.v1 if profile.v1 > 0.0 else 0.0
        if done:
            return profile.duration + over + lam_target * (period - span), lam_target, None
        return profile.duration + over, (sigma_end / profile.v1 if profile.v1 > 0.0 else 0.0), alpha_end
    t, (_, v_end, _) = time_at(profile, tau, s_end)
    if done:  # the rest of the period at the target scale
        return t + lam_target * (period - span), lam_target, None
    return t, (sigma_end / v_end if v_end > 0.0 else lam_target), alpha_end
