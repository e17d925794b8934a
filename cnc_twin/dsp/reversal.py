"""Reversal (quadrant error) compensation: a decaying speed pulse when an axis's commanded velocity
changes sign, as CNCs offer it for the friction at a reversal (Siemens' friction compensation
with amplitude and decay time, Mitsubishi's lost-motion compensation, Heidenhain's reversal
spike compensation).

Why: at a reversal the friction that the drive's velocity integrator held one way must be held
the other way. Until the integrator has swung through twice the Coulomb friction the axis
sticks, and the circular test shows the sticking axis as an outward spike at the quadrant. The
pulse adds to the speed command what the drive's proportional gain turns into that swing at
once, and fades as the integrator takes it over.

Per servo tick, with ``velocity`` the period's commanded velocity [counts/s], ``acceleration``
and ``jerk`` its changes [counts/s^2, counts/s^3]::

    v          velocity + lead acceleration + lead^2 / 2 jerk    # the velocity `lead` seconds ahead
    sign       +1 / -1 with v; held while |v| <= REST_SPEED (0 before the first move)
    still      ticks since |velocity| > REST_SPEED (before this tick's velocity counts)
    armed      |velocity| has exceeded arm_speed since the last reversal
    if sign flips between +1 and -1 and still <= patience and armed:
                                      pulse = amplitude x sign           # a reversal
    else:                             pulse = pulse x decay               # decay = exp(-dt / T)
    a pulse fired ahead of the turn is cancelled (pulse = 0, the old direction kept) if the
    velocity comes to rest instead of turning: a stop at constant deceleration (a trapezoid's)
    predicts like a reversal
    output += rise x (pulse - output)                                     # rise = 1 - exp(-dt / T_rise)
    output [V], added to the position loop's output before the DAC

The prediction is of second order so that a stop is no reversal: a jerk-limited stop's velocity
touches zero without crossing it (quadratic or cubic in the time left), and so does its
prediction, where a first-order one crosses ``2 lead`` before the stop and pulled a stopping
axis back (27 um at the end of the bundled circle). A circle's reversal crosses with a finite
acceleration, and the prediction with it.

:data:`REST_SPEED` keeps an axis that stands from reversing on the rounding of its command: a
standing axis's chord velocity is the difference of two floating-point setpoints, +-1e-8
counts/s of noise on a path whose other axes move, which flipped the sign a thousand times in a
circle.

A pulse ahead of the turn fires only while another axis moves at its arming speed (``path_on``):
a contour's reversal is one axis turning while the path goes on; where every axis comes to rest
together (a point-to-point move's trapezoid, a path's exact stop) the deceleration predicts a
turn that never comes, and a pulse there pulled a single Y move 4 counts off its target. Without
the path, the pulse fires when the velocity itself turns.

A reversal counts only after a move of at least ``arm_speed``: a grinding-force loop turns its
axis back and forth at well under a millimetre a second hundreds of times a minute, and a pulse
sized for a contour's reversal at each of those raised the force error by a third.

The first move from rest is no reversal (the integrator holds no friction yet), nor is a start
the other way after a standstill longer than ``patience`` (twice the decay time): the pulse is
for a contour's quadrant, where the axis turns without stopping; a position loop at rest has let
its drive's integrator settle anywhere within the friction, and a full pulse there pushed the
bundled circle's start 28 um off. Half of one (the average swing, were the integrator anywhere in
the band) took the commissioned circle's contour error from 14.0 to 12.0 um and the tilted
curve's from 63.5 to 73.5: where it stands is not known, so no guess is made. The direction is
held across standstill, as the friction is.

:data:`REVERSAL` is one axis's record; :func:`reversal_pulse` the block (plain, compiled with
numba from this source for every path that runs the servo).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

REST_SPEED = 0.01
"""[counts/s] at or below this the commanded velocity counts as standstill (the direction is held):
far above a standing axis's rounding noise, far below any motion (one count in 100 s)"""

REVERSAL = np.dtype([("amplitude", np.float64), ("decay", np.float64), ("lead", np.float64), ("rise", np.float64),
                     ("patience", np.int64), ("arm_speed", np.float64), ("armed", np.int64),
                     ("direction", np.float64), ("pulse", np.float64), ("output", np.float64),
                     ("still", np.int64), ("pending", np.float64), ("count", np.int64)])
"""One axis's reversal compensation:

=========  ======  ======================================================  ==================
field      unit    meaning                                                 written by
=========  ======  ======================================================  ==================
amplitude  V       the pulse's height at the reversal (0: off)             :func:`setup_reversal`
decay      -       the pulse's factor per tick, ``exp(-dt / T)``            :func:`setup_reversal`
lead       s       how far ahead the velocity is predicted                 :func:`setup_reversal`
rise       -       the output's step towards the pulse per tick,           :func:`setup_reversal`
                   ``1 - exp(-dt / T_rise)`` (1: no low-pass)
patience   ticks   the longest standstill a reversal may follow            :func:`setup_reversal`
arm_speed  c/s     the speed a move must reach for its reversal to count   :func:`setup_reversal`
armed      0 / 1   it has, since the last reversal (state)                 :func:`reversal_pulse`
direction  -       +1 / -1 / 0, the last commanded direction (state)       :func:`reversal_pulse`
pulse      V       the pulse before its low-pass (state)                   :func:`reversal_pulse`
output     V       the pulse after it, this tick's (state)                 :func:`reversal_pulse`
still      ticks   since the commanded velocity last exceeded REST_SPEED   :func:`reversal_pulse`
pending    -       the new direction of a pulse the prediction fired,      :func:`reversal_pulse`
                   until the velocity itself turns (0: none)
count      -       reversals seen since set up (state)                     :func:`reversal_pulse`
=========  ======  ======================================================  ==================
"""


def setup_reversal(r, *, amplitude: float, time: float, speed_per_volt: float, dt: float, lead: float = 0.0,
                   rise: float = 0.0, arm_speed: float = 0.0, counts_per_unit: float = 1.0) -> None:
    """Fill ``r`` (a :data:`REVERSAL` record) and clear its state.

    Parameters
    ----------
    amplitude
        the pulse's height as a speed command [m/s | rad/s] (0: off).
    time
        its decay time constant [s] (0: off).
    speed_per_volt
        the drive's scaling [m/s/V | rad/s/V].
    dt
        the servo period [s].
    lead, rise
        how far ahead the velocity is predicted; the pulse's rise time constant [s] (0: a step).
    arm_speed, counts_per_unit
        the commanded speed a move must reach for its reversal to count [m/s | rad/s] (0: any);
        the encoder's counts per m | rad, to convert it.
    """
    if not (speed_per_volt > 0 and dt > 0):
        raise ValueError("speed_per_volt and dt must be > 0")
    if amplitude < 0 or time < 0:
        raise ValueError("the reversal compensation's amplitude and time must be >= 0")
    on = amplitude > 0 and time > 0
    r["amplitude"] = amplitude / speed_per_volt if on else 0.0
    r["decay"] = math.exp(-dt / time) if on else 0.0
    r["lead"] = lead
    r["rise"] = 1.0 - math.exp(-dt / rise) if rise > 0 else 1.0
    r["patience"] = int(round(2.0 * time / dt)) if on else 0
    r["arm_speed"] = max(arm_speed * counts_per_unit, REST_SPEED)
    reset_reversal(r)


def reset_reversal(r) -> None:
    """The state at power-on: no direction known, no pulse, no reversal counted."""
    forget_reversal(r)
    r["count"] = 0


@njit(cache=True)
def forget_reversal(r):
    """Clear ``r``'s state as at power-on (a :data:`REVERSAL` record): no direction known, no
    pulse. While a step interpolator commands the axis the block is not used, and what it knew
    before is stale after."""
    r.direction = 0.0
    r.pulse = 0.0
    r.output = 0.0
    r.still = 0
    r.armed = 0
    r.pending = 0.0


@njit(cache=True)
def is_moving(r, velocity):
    """Whether ``velocity`` [counts/s] is at ``r``'s arming speed (a :data:`REVERSAL` record)."""
    return velocity > r.arm_speed or velocity < -r.arm_speed


@njit(cache=True)
def reversal_pulse(r, velocity, acceleration, jerk, path_on):
    """The pulse [V] to add to this tick's drive command, ``velocity`` the period's commanded
    velocity [counts/s], ``acceleration`` and ``jerk`` its changes [counts/s^2, counts/s^3],
    ``path_on`` whether another axis moves at its arming speed (a prediction fires only then);
    advances ``r`` (a :data:`REVERSAL` record)."""
    waited = r.still  # the standstill before this tick
    moving = velocity > REST_SPEED or velocity < -REST_SPEED
    if moving:
        r.still = 0
    elif r.still <= r.patience:  # counted no further than needed: no overflow in a day at rest
        r.still += 1
    cancelled = False
    if r.pending != 0.0:
        if velocity * r.pending > 0.0 and moving:  # it turned: the pulse was for a reversal
            r.pending = 0.0
        elif not moving:  # it stopped instead: no reversal, the pulse ends and the direction stays
            r.pulse = 0.0
            r.direction = -r.pending
            r.pending = 0.0
            r.count -= 1
            r.armed = 1  # the move it was fired in still counts
            cancelled = True
    predicted = velocity + r.lead * (acceleration + 0.5 * r.lead * jerk)
    if predicted > REST_SPEED:
        sign = 1.0
    elif predicted < -REST_SPEED:
        sign = -1.0
    else:
        sign = r.direction
    if cancelled:  # the stop's own tick: its deceleration still predicts the turn that did not come
        sign = r.direction
    ahead = velocity * sign <= 0.0  # predicted: the velocity itself has not turned yet
    if ahead and not path_on:  # no prediction without a path going on: wait for the turn itself
        sign = r.direction
    if sign != r.direction and r.direction != 0.0 and waited <= r.patience and r.pending == 0.0 \
            and r.armed == 1 and (path_on or not ahead):  # armed by the moves before this tick
        r.pulse = r.amplitude * sign
        r.count += 1
        r.armed = 0
        if ahead:  # fired ahead of the turn: to be confirmed
            r.pending = sign
    else:
        r.pulse *= r.decay
    r.direction = sign
    if is_moving(r, velocity):  # the move the next reversal will end
        r.armed = 1
    r.output += r.rise * (r.pulse - r.output)
    return r.output
