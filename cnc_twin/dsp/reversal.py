"""Reversal (quadrant error) compensation: a decaying speed pulse when an axis's commanded velocity
changes sign, as CNCs offer it for the friction at a reversal (Siemens' friction compensation
with amplitude and decay time, Mitsubishi's lost-motion compensation, Heidenhain's reversal
spike compensation).

Why: at a reversal the friction that the drive's velocity integrator held one way must be held
the other way. Until the integrator has swung through twice the Coulomb friction the axis
sticks, and the circular test shows the sticking axis as an outward spike at the quadrant. The
pulse adds to the speed command what the drive's proportional gain turns into that swing at
once, and fades as the integrator takes it over.

Per servo tick, with ``velocity`` the period's commanded velocity [counts/s]::

    sign       +1 / -1 with velocity; held while it is 0 (0 before the first move)
    if sign flips between +1 and -1:  pulse = amplitude x sign           # a reversal
    else:                             pulse = pulse x decay               # decay = exp(-dt / T)
    output: pulse [V], added to the position loop's output before the DAC

The first move from rest is no reversal (the integrator holds no friction yet), and a pause at
rest does not re-arm it: the direction is held across standstill, as the friction is.

:data:`REVERSAL` is one axis's record; :func:`reversal_pulse` the block (plain, compiled with
numba from this source for every path that runs the servo).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

REVERSAL = np.dtype([("amplitude", np.float64), ("decay", np.float64), ("lead", np.float64), ("rise", np.float64),
                     ("direction", np.float64), ("pulse", np.float64), ("output", np.float64), ("count", np.int64)])
"""One axis's reversal compensation:

=========  ======  ======================================================  ==================
field      unit    meaning                                                 written by
=========  ======  ======================================================  ==================
amplitude  V       the pulse's height at the reversal (0: off)             :func:`setup_reversal`
decay      -       the pulse's factor per tick, ``exp(-dt / T)``            :func:`setup_reversal`
direction  -       +1 / -1 / 0, the last commanded direction (state)       :func:`reversal_pulse`
pulse      V       the pulse this tick (state)                             :func:`reversal_pulse`
count      -       reversals seen since set up (state)                     :func:`reversal_pulse`
=========  ======  ======================================================  ==================
"""


def setup_reversal(r, *, amplitude: float, time: float, speed_per_volt: float, dt: float, lead: float = 0.0,
                   rise: float = 0.0) -> None:
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
    reset_reversal(r)


def reset_reversal(r) -> None:
    """The state at power-on: no direction known, no pulse."""
    r["direction"] = 0.0
    r["pulse"] = 0.0
    r["output"] = 0.0
    r["count"] = 0


@njit(cache=True)
def reversal_pulse(r, velocity, acceleration):
    """The pulse [V] to add to this tick's drive command, ``velocity`` the period's commanded
    velocity [counts/s]; advances ``r`` (a :data:`REVERSAL` record)."""
    velocity = velocity + r.lead * acceleration
    if velocity > 0.0:
        sign = 1.0
    elif velocity < 0.0:
        sign = -1.0
    else:
        sign = r.direction
    if sign != r.direction and r.direction != 0.0:
        r.pulse = r.amplitude * sign
        r.count += 1
    else:
        r.pulse *= r.decay
    r.direction = sign
    r.output += r.rise * (r.pulse - r.output)
    return r.output
