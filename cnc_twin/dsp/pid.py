"""Position loop: PID on the following error in counts, plus velocity, acceleration and friction
feed-forward, with integrator anti-windup and an output clamp. Output is a drive voltage.

Inputs (per servo tick, :func:`pid_update`)
-------------------------------------------
command : commanded position [counts]
feedback : encoder position [counts]
velocity : commanded velocity [counts/s] (feed-forward)
acceleration : commanded acceleration [counts/s^2] (feed-forward)

Output: drive command [V], within +/- ``output_limit``.

One loop's state is a :data:`PID` record:

================  =====================  ======================================  ==============
field             unit                   meaning                                 written by
================  =====================  ======================================  ==============
kp                V per count            ``kp g``                                :func:`setup_pid`
ki_dt             V per count, per tick  ``ki g dt``                             :func:`setup_pid`
kd_over_dt        V per count            ``kd g / dt``                           :func:`setup_pid`
kvff              V per count/s          ``kvff g``                              :func:`setup_pid`
kaff              V per count/s^2        ``kaff g``                              :func:`setup_pid`
friction_ff       V                      friction feed-forward at full           :func:`setup_pid`
friction_rate     1 / (count/s)          1 / (friction_ff_band x cpu)            :func:`setup_pid`
output_limit      V                      output clamp                            :func:`setup_pid`
integrator_limit  V                      integrator clamp                        :func:`setup_pid`
integrator        V                      the integral term                       :func:`pid_update`
previous_error    counts                 last tick's error                       :func:`pid_update`
================  =====================  ======================================  ==============

Gains are given in machine terms and converted once with the drive scaling ``speed_per_volt``
[unit/s/V] and the encoder ``counts_per_unit`` [counts/unit]; ``g = 1 / (speed_per_volt *
counts_per_unit)`` is volts per (count/s):

=======  ==========  =====================================
gain     given in    meaning
=======  ==========  =====================================
kp       1/s         speed per unit of following error
ki       1/s^2       speed per unit of integrated error
kd       -           speed per unit of error rate
kvff     -           fraction of the commanded speed
kaff     s           speed per unit commanded acceleration
fff      V           friction feed-forward, full beyond ``friction_ff_band`` [unit/s]
=======  ==========  =====================================

0 for any gain means that term is off.

Algorithm (dt = servo period)::

    e = command - feedback        (in 32-bit arithmetic: wrapped into [-2^31, 2^31), count_error)
    i_try = clamp(i + ki_c * e * dt, -integrator_limit, +integrator_limit)
    ramp = clamp(velocity / (friction_ff_band * counts_per_unit), -1, +1)   # the friction's sign, softened
    u = kp_c*e + i_try + kd_c*(e - e_prev)/dt + kvff_c*velocity + kaff_c*acceleration + fff*ramp
    if |u| > output_limit and e has the sign of u:  keep i (conditional integration)
    else:                                           i = i_try
    output = clamp(kp_c*e + i + kd_c*(e - e_prev)/dt + ff, -output_limit, +output_limit)
"""

from __future__ import annotations

import numpy as np
from numba import njit

from cnc_twin.dsp.encoder import count_error

PID = np.dtype([(name, np.float64) for name in (
    "kp", "ki_dt", "kd_over_dt", "kvff", "kaff", "friction_ff", "friction_rate", "output_limit",
    "integrator_limit", "integrator", "previous_error")])
"""one position loop's record: see the module docstring for its fields"""


def setup_pid(pid, *, kp: float, ki: float = 0.0, kd: float = 0.0, kvff: float = 0.0, kaff: float = 0.0,
              friction_ff: float = 0.0, friction_ff_band: float = 1e-3, speed_per_volt: float,
              counts_per_unit: float, dt: float, output_limit: float = 10.0, integrator_limit: float = 10.0) -> None:
    """Fill ``pid`` (a :data:`PID` record) from gains in machine terms and clear its state.

    Parameters
    ----------
    kp, ki, kd, kvff, kaff
        gains in machine terms (1/s, 1/s^2, -, -, s).
    friction_ff, friction_ff_band
        friction feed-forward [V]; the commanded speed [m/s | rad/s] over which it ramps in, so
        that it does not chatter at rest.
    speed_per_volt
        drive scaling [m/s/V | rad/s/V].
    counts_per_unit
        encoder resolution [counts/m | counts/rad].
    dt
        servo period [s].
    output_limit, integrator_limit
        [V].
    """
    if not (speed_per_volt > 0 and counts_per_unit > 0 and dt > 0):
        raise ValueError("speed_per_volt, counts_per_unit and dt must be > 0")
    volts_per_count_rate = 1.0 / (speed_per_volt * counts_per_unit)
    pid["kp"] = kp * volts_per_count_rate
    pid["ki_dt"] = ki * volts_per_count_rate * dt
    pid["kd_over_dt"] = kd * volts_per_count_rate / dt
    pid["kvff"] = kvff * volts_per_count_rate
    pid["kaff"] = kaff * volts_per_count_rate
    pid["friction_ff"] = friction_ff
    pid["friction_rate"] = 1.0 / (friction_ff_band * counts_per_unit)
    pid["output_limit"] = output_limit
    pid["integrator_limit"] = integrator_limit
    pid["integrator"] = 0.0
    pid["previous_error"] = 0.0


def new_pid(**gains) -> np.void:
    """A :data:`PID` record set up by :func:`setup_pid` with ``gains``."""
    record = np.zeros(1, PID)[0]
    setup_pid(record, **gains)
    return record


@njit(cache=True)
def pid_update(pid, command, feedback, velocity, acceleration):
    """One servo tick of ``pid`` (a :data:`PID` record); returns the clamped drive voltage [V]."""
    error = count_error(command, feedback)  # the 32-bit position may have wrapped
    ramp = velocity * pid.friction_rate
    if ramp > 1.0:
        ramp = 1.0
    elif ramp < -1.0:
        ramp = -1.0
    fixed = (pid.kp * error
             + pid.kd_over_dt * (error - pid.previous_error)
             + pid.kvff * velocity
             + pid.kaff * acceleration
             + pid.friction_ff * ramp)
    pid.previous_error = error
    limit = pid.integrator_limit
    integrator = pid.integrator + pid.ki_dt * error
    if integrator > limit:
        integrator = limit
    elif integrator < -limit:
        integrator = -limit
    out = fixed + integrator
    umax = pid.output_limit
    if out > umax:
        if error <= 0.0:
            pid.integrator = integrator
        out = fixed + pid.integrator
        return umax if out > umax else out
    if out < -umax:
        if error >= 0.0:
            pid.integrator = integrator
        out = fixed + pid.integrator
        return -umax if out < -umax else out
    pid.integrator = integrator
    return out


@njit(cache=True)
def pid_reset(pid):
    """Clear the integrator and the previous error (the drive was disabled)."""
    pid.integrator = 0.0
    pid.previous_error = 0.0
