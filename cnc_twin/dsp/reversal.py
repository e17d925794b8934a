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
bundled circle's start 28 um off. The direction is held across standstill, as the friction is.

**Stops and starts** (``standstill``, a share of the pulse; 0: off), as FANUC's static friction
compensation and Mitsubishi's at the start from rest: MuJoCo's friction is a soft constraint, so
under a speed of about a millimetre a second it fades and the integrator's push, which held the
full friction while the axis moved, creeps the axis on past its stop; at rest the position loop
bleeds the integrator down to about nothing. A reversal's swing is then a stop's half and a
start's half::

    stop     |velocity| falls below stop_speed, decelerating, after an armed move, while another
             axis moves (``path_on``: a contour's stop; no reversal predicted):
                                         pulse = -standstill x amplitude x sign(velocity)
    start    |velocity| rises above start_speed, accelerating, after a stop's pulse (the other
             way, or from rest, or past stop_speed again the same way) or a standstill longer
             than ``patience``:          pulse = +standstill x amplitude x sign(velocity)

A reversal predicted ahead that ends in a stop gives the stop's half. A point-to-point move's stop,
where every axis comes to rest together, gets none: there it moved a worn screw's positioning
by up to 10 um along the travel, and a position loop at rest bleeds the integral down by itself
(the next start, after ``patience``, gets its share). On the commissioned
6 m/min circle the start after the approach (X 12 um behind while its integrator built up the
friction) and the end (X 11 um past its stop) went from 14.0 and 11.2 um off the circle to 5.3 and
3.2.
The start waits for ``start_speed`` (0.3 mm/s) so that the pulse does not push an axis whose
command has hardly begun to move (at the first tick of motion it pushed the circle's start 10 um
inside); a stop's hysteresis (a re-start the same way only past ``stop_speed``) keeps the pulses
from chattering where a slow axis's period velocity wobbles around ``start_speed``, as it did on
the published guitar curve (25.5 -> 54.8 um before the hysteresis, 18.9 with it).

:data:`REVERSAL` is one axis's record; :func:`reversal_pulse` the block (plain, compiled with
numba from this source for every path that runs the servo); :func:`pulse_height` the pulse's
height at a reversal's acceleration (the adaptation, ``adapt_*``).
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
                     ("still", np.int64), ("pending", np.float64), ("count", np.int64),
                     ("standstill", np.float64), ("start_speed", np.float64), ("stop_speed", np.float64),
                     ("unloaded", np.int64), ("adapt_amplitude", np.float64), ("adapt_from", np.float64),
                     ("adapt_to", np.float64)])
"""One axis's reversal compensation:

===============  ======  ======================================================  ======================
field            unit    meaning                                                 written by
===============  ======  ======================================================  ======================
amplitude        V       the pulse's height at the reversal (0: off)             :func:`setup_reversal`
decay            -       the pulse's factor per tick, ``exp(-dt / T)``           :func:`setup_reversal`
lead             s       how far ahead the velocity is predicted                 :func:`setup_reversal`
rise             -       the output's step towards the pulse per tick,           :func:`setup_reversal`
                         ``1 - exp(-dt / T_rise)`` (1: no low-pass)
patience         ticks   the longest standstill a reversal may follow            :func:`setup_reversal`
arm_speed        c/s     the speed a move must reach for its reversal to count   :func:`setup_reversal`
armed            0 / 1   it has, since the last reversal (state)                 :func:`reversal_pulse`
direction        -       +1 / -1 / 0, the last commanded direction (state)       :func:`reversal_pulse`
pulse            V       the pulse before its low-pass (state)                   :func:`reversal_pulse`
output           V       the pulse after it, this tick's (state)                 :func:`reversal_pulse`
still            ticks   since the commanded velocity last exceeded REST_SPEED   :func:`reversal_pulse`
pending          -       the new direction of a pulse the prediction fired,      :func:`reversal_pulse`
                         until the velocity itself turns (0: none)
count            -       reversals seen since set up (state)                     :func:`reversal_pulse`
standstill       -       the share of the pulse given at a stop and a start      :func:`setup_reversal`
                         (0: none)
start_speed      c/s     the speed a start's pulse waits for                     :func:`setup_reversal`
stop_speed       c/s     the speed under which a stop's pulse comes              :func:`setup_reversal`
unloaded         -       a stop's pulse was given: the direction it stopped in   :func:`reversal_pulse`
                         (+1 / -1), 2 at rest, 0 none (state)
adapt_amplitude  V       the pulse's height at a reversal with the commanded     :func:`setup_reversal`
                         acceleration ``adapt_to`` (:func:`pulse_height`)
adapt_from       c/s^2   up to this acceleration the height is ``amplitude``     :func:`setup_reversal`
adapt_to         c/s^2   from this one ``adapt_amplitude``; linear between       :func:`setup_reversal`
===============  ======  ======================================================  ======================
"""


def setup_reversal(r, *, amplitude: float, time: float, speed_per_volt: float, dt: float, lead: float = 0.0,
                   rise: float = 0.0, arm_speed: float = 0.0, counts_per_unit: float = 1.0,
                   standstill: float = 0.0, start_speed: float = 0.0, stop_speed: float = 0.0,
                   adapt_amplitude: float = 0.0, adapt_from: float = 0.0, adapt_to: float = 0.0) -> None:
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
    standstill, start_speed, stop_speed
        the share of the pulse given at a stop and at a start from it (0: none, 0.5: the
        integrator at rest holds no friction) [-]; the speeds a start rises above and a stop
        falls below [m/s | rad/s].
    adapt_amplitude, adapt_from, adapt_to
        the adaptation characteristic: the pulse's height at a reversal with the commanded
        acceleration ``adapt_to`` [m/s | rad/s] (0: ``amplitude`` at every acceleration), going
        linearly from ``amplitude`` at ``adapt_from`` [m/s^2 | rad/s^2], held beyond both.
    """
    if not (speed_per_volt > 0 and dt > 0):
        raise ValueError("speed_per_volt and dt must be > 0")
    if amplitude < 0 or time < 0:
        raise ValueError("the reversal compensation's amplitude and time must be >= 0")
    if not 0.0 <= standstill <= 1.0 or start_speed < 0 or stop_speed < 0:
        raise ValueError("the standstill share must be within 0..1 and its speeds >= 0")
    if adapt_amplitude < 0 or (adapt_amplitude > 0 and not 0 <= adapt_from < adapt_to):
        raise ValueError("the adaptation's amplitude must be >= 0, and with one 0 <= adapt_from < adapt_to")
    on = amplitude > 0 and time > 0
    r["amplitude"] = amplitude / speed_per_volt if on else 0.0
    adapted = on and adapt_amplitude > 0
    r["adapt_amplitude"] = adapt_amplitude / speed_per_volt if adapted else r["amplitude"]
    r["adapt_from"] = adapt_from * counts_per_unit if adapted else 0.0
    r["adapt_to"] = adapt_to * counts_per_unit if adapted else 1.0
    r["decay"] = math.exp(-dt / time) if on else 0.0
    r["lead"] = lead
    r["rise"] = 1.0 - math.exp(-dt / rise) if rise > 0 else 1.0
    r["patience"] = int(round(2.0 * time / dt)) if on else 0
    r["arm_speed"] = max(arm_speed * counts_per_unit, REST_SPEED)
    r["standstill"] = standstill if on else 0.0
    r["start_speed"] = max(start_speed * counts_per_unit, REST_SPEED)
    r["stop_speed"] = max(stop_speed * counts_per_unit, REST_SPEED)
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
    r.unloaded = 0


@njit(cache=True)
def pulse_height(r, acceleration):
    """The reversal pulse's height [V] at the commanded ``acceleration`` [counts/s^2] (a
    :data:`REVERSAL` record): ``amplitude`` up to ``adapt_from``, ``adapt_amplitude`` from
    ``adapt_to``, linear between (Siemens' adaptation characteristic, measured here by circular
    tests at two feeds; held beyond them rather than extrapolated)."""
    share = (abs(acceleration) - r.adapt_from) / (r.adapt_to - r.adapt_from)
    share = min(max(share, 0.0), 1.0)
    return r.amplitude + share * (r.adapt_amplitude - r.amplitude)


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
            r.pulse = r.standstill * r.amplitude * r.pending  # a stop's half, if stops have one
            r.direction = -r.pending
            r.pending = 0.0
            r.count -= 1
            if r.standstill > 0.0:  # the stop's half was given: the next start loads the friction
                r.unloaded = 2
                r.armed = 0
            else:
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
    heading = 1 if velocity > 0.0 else -1
    if not moving and r.standstill > 0.0 and (r.unloaded != 0 or r.still > r.patience):
        r.unloaded = 2  # at rest, unloaded or long enough for the position loop to bleed it: a start either way loads
    stopping = r.standstill > 0.0 and r.unloaded == 0 and r.armed == 1 and r.pending == 0.0 and path_on \
        and not cancelled and -r.stop_speed < velocity < r.stop_speed and velocity * acceleration < 0.0
    starting = r.unloaded != 0 and velocity * acceleration > 0.0 \
        and (velocity > r.start_speed or velocity < -r.start_speed) \
        and (r.unloaded == 2 or r.unloaded != heading or velocity > r.stop_speed or velocity < -r.stop_speed)
    if stopping:  # unload: the push that held the friction would creep the axis past its stop
        r.pulse = -r.standstill * r.amplitude * heading
        r.unloaded = heading
        r.armed = 0
    elif starting:  # load the friction again
        r.pulse = r.standstill * r.amplitude * heading
        r.unloaded = 0
        sign = float(heading)
    elif sign != r.direction and r.direction != 0.0 and waited <= r.patience and r.pending == 0.0 \
            and r.armed == 1 and (path_on or not ahead):  # armed by the moves before this tick
        r.pulse = pulse_height(r, acceleration) * sign
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
