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
aff_washout       -                      the acceleration's low-pass factor      :func:`setup_pid`
                                         per tick, ``1 - exp(-dt / washout)``
                                         (0: no high-pass)
reference_alpha   -                      the reference lag's factor per tick,    :func:`setup_pid`
                                         ``1 - exp(-dt / ff_equivalent_time)``
                                         (1: no lag)
friction_ff       V                      friction feed-forward at full           :func:`setup_pid`
friction_rate     1 / (count/s)          1 / (friction_ff_band x cpu)            :func:`setup_pid`
output_limit      V                      output clamp                            :func:`setup_pid`
integrator_limit  V                      integrator clamp                        :func:`setup_pid`
integrator        V                      the integral term                       :func:`pid_update`
previous_error    counts                 last tick's error                       :func:`pid_update`
aff_lowpass       counts/s^2             the acceleration's low-pass, taken      :func:`pid_update`
                                         off it by the high-pass
reference         counts                 the lagged command the loop compares    :func:`pid_update`
                                         with
reference_set     -                      1 once ``reference`` holds a command    :func:`pid_update`,
                                                                                 :func:`pid_reset`
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
kaff     s           speed per unit commanded acceleration (the drive's inertia over its
                     speed-loop gain, ``J / kp_speed``, in axis units)
fff      V           friction feed-forward, full beyond ``friction_ff_band`` [unit/s]
=======  ==========  =====================================

0 for any gain means that term is off.

Two terms make the feed-forward match a speed-controlled drive (the drive's speed loop a PI of
gain ``kp_speed`` and integral time ``tn`` on an inertia ``J``, whose closed loop is
``(kp_speed s + kp_speed / tn) / (J s^2 + kp_speed s + kp_speed / tn)``):

- the acceleration feed-forward through a first-order high-pass of time ``aff_washout`` (``tn``):
  ``v + (J / kp_speed) s tn / (1 + s tn) a`` is that loop's exact inverse, so its speed follows
  the commanded one; without the high-pass the term keeps pushing where the drive's integral
  already has, and shrinks a circle by about ``R kaff w^2 / kp`` (w its angular speed);
- the command the position loop compares with through a first-order lag of ``ff_equivalent_time``
  (the speed loop's remaining equivalent time: its filters, the current loop, the dead time), so
  that the loop does not correct a lag the feed-forward's axis has anyway (Siemens' "symmetrising"
  of the feed-forward, MD32810): with it, the axis follows the lagged command, a pure shape-keeping
  lag where all axes have the same time; without it, the lag ``T`` grows a circle by about
  ``R T w^2 / kp``.

Algorithm (dt = servo period)::

    r = command on the first tick (or after pid_reset), else r + reference_alpha (command - r)
    lp = lp + aff_washout (acceleration - lp)
    e = r - feedback              (in 32-bit arithmetic: wrapped into [-2^31, 2^31), count_error)
    i_try = clamp(i + ki_c * e * dt, -integrator_limit, +integrator_limit)
    ramp = clamp(velocity / (friction_ff_band * counts_per_unit), -1, +1)   # the friction's sign, softened
    u = kp_c*e + i_try + kd_c*(e - e_prev)/dt + kvff_c*velocity + kaff_c*(acceleration - lp) + fff*ramp
    if |u| > output_limit and e has the sign of u:  keep i (conditional integration)
    else:                                           i = i_try
    output = clamp(kp_c*e + i + kd_c*(e - e_prev)/dt + ff, -output_limit, +output_limit)
"""

from __future__ import annotations

import numpy as np
from numba import njit

from cnc_twin.dsp.encoder import count_error

PID = np.dtype([(name, np.float64) for name in (
    "kp", "ki_dt", "kd_over_dt", "kvff", "kaff", "aff_washout", "reference_alpha", "friction_ff", "friction_rate",
    "output_limit", "integrator_limit", "integrator", "previous_error", "aff_lowpass", "reference",
    "reference_set")])
"""one position loop's record: see the module docstring for its fields"""


def setup_pid(pid, *, kp: float, ki: float = 0.0, kd: float = 0.0, kvff: float = 0.0, kaff: float = 0.0,
              aff_washout: float = 0.0, ff_equivalent_time: float = 0.0, friction_ff: float = 0.0,
              friction_ff_band: float = 1e-3, speed_per_volt: float, counts_per_unit: float, dt: float,
              output_limit: float = 10.0, integrator_limit: float = 10.0) -> None:
    """Fill ``pid`` (a :data:`PID` record) from gains in machine terms and clear its state.

    Parameters
    ----------
    kp, ki, kd, kvff, kaff
        gains in machine terms (1/s, 1/s^2, -, -, s).
    aff_washout
        the acceleration feed-forward's high-pass time constant [s]; 0 = none.
    ff_equivalent_time
        the lag of the command the loop compares with [s]; 0 = none.
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
    pid["aff_washout"] = -np.expm1(-dt / aff_washout) if aff_washout > 0 else 0.0
    pid["reference_alpha"] = -np.expm1(-dt / ff_equivalent_time) if ff_equivalent_time > 0 else 1.0
    pid["friction_ff"] = friction_ff
    pid["friction_rate"] = 1.0 / (friction_ff_band * counts_per_unit)
    pid["output_limit"] = output_limit
    pid["integrator_limit"] = integrator_limit
    for state in ("integrator", "previous_error", "aff_lowpass", "reference", "reference_set"):
        pid[state] = 0.0


def new_pid(**gains) -> np.void:
    """A :data:`PID` record set up by :func:`setup_pid` with ``gains``."""
    record = np.zeros(1, PID)[0]
    setup_pid(record, **gains)
    return record


@njit(cache=True)
def pid_update(pid, command, feedback, velocity, acceleration):
    """One servo tick of ``pid`` (a :data:`PID` record); returns the clamped drive voltage [V]."""
    if pid.reference_set == 0.0:
        pid.reference = command
        pid.reference_set = 1.0
    else:
        pid.reference += pid.reference_alpha * (command - pid.reference)
    pid.aff_lowpass += pid.aff_washout * (acceleration - pid.aff_lowpass)
    error = count_error(pid.reference, feedback)  # the 32-bit position may have wrapped
    ramp = velocity * pid.friction_rate
    if ramp > 1.0:
        ramp = 1.0
    elif ramp < -1.0:
        ramp = -1.0
    fixed = (pid.kp * error
             + pid.kd_over_dt * (error - pid.previous_error)
             + pid.kvff * velocity
             + pid.kaff * (acceleration - pid.aff_lowpass)
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
    """Clear the integrator, the previous error and the feed-forward's filters (the drive was
    disabled): the next tick's command is the reference again."""
    pid.integrator = 0.0
    pid.previous_error = 0.0
    pid.aff_lowpass = 0.0
    pid.reference = 0.0
    pid.reference_set = 0.0
