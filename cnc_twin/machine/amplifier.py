"""Servo amplifiers with loops of their own: what a real drive does between the card's DAC and the
motor, run at the physics rate.

A compliant machine's MJCF gives each drive as a current-mode actuator on the motor hinge
(``dyntype="filterexact"``: the current loop as a first-order lag, its time constant set from
the bandwidth here; ``gear`` = lead / 2 pi or 1 / ratio, so forces are in axis units). The
velocity loop, the notch filters and the torque limit are the amplifier's, computed before every
physics step from the DAC voltage and the motor's speed::

    w*     = speed_per_volt V                        # the analog input [m/s | rad/s at the axis]
    w_act  = feedback(q_motor)                       # the actual speed, axis units (below)
    e      = w* - w_act
    u      = kp e + I                               # PI
    I     += kp e dt / tn    unless u is limited and e pushes further (anti-windup)
    u      = T += beta (u - T)                      # the torque reference filter, a first-order
                                                    # low-pass (exact: beta = 1 - exp(-dt / tf))
    u      = notch_k(u) for each notch              # biquads, bilinear with prewarping
    force  = clamp(u, +-force_limit)                # -> ctrl; MuJoCo lags it (the current loop)

The actual speed is what a drive measures, not MuJoCo's exact ``qvel``: the motor feedback's counts
(``feedback_counts`` per motor revolution; not quantised when 0) differenced over the step, then a
first-order low-pass at ``speed_filter`` [Hz] (a drive's velocity-feedback bandwidth: Beckhoff's
AX2000 defaults to 600 Hz, "a compromise between phase lag and noise"), discretised exactly::

    n      = floor(q_motor counts_per_rad)          # the feedback's count
    w_diff = (n - n_last) / counts_per_rad / dt      # MuJoCo's step makes q - q_last = dt qvel: no lag
    w_act += alpha (w_diff - w_act),  alpha = 1 - exp(-2 pi speed_filter dt)

With neither (both 0) the loop reads ``qvel`` exactly, as before these were modelled.

An axis whose drive is the MJCF's own velocity-mode actuator (a rigid machine's ideal velocity
source) passes the voltage through: ``ctrl = V``.

The state of all six is one :data:`AMP` record array; :func:`drive_amps` is its one algorithm,
compiled with numba and called by :class:`~cnc_twin.machine.plant.Plant` from Python and by the
compiled servo kernels on the same records. :func:`notch_coefficients` is also what the linear
analysis (:mod:`cnc_twin.studies.linearize`) builds its notch filters from.

=================  ======================  ===========================================  ======================
field              unit                    meaning                                      written by
=================  ======================  ===========================================  ======================
modelled           -                       the drive's loops run here (else ctrl = V)   set up
speed_per_volt     m/s/V | rad/s/V         the analog input's scaling                   set up
kp                 N/(m/s) | N m/(rad/s)   velocity-loop gain                           set up
ki_dt              N/m | N m/rad           kp dt / tn: the integral's gain per step     set up
limit              N | N m                 the force limit                              set up
dof_adr            -                       the motor hinge's dof (its speed)            set up
scale              m/rad | rad/rad         motor to axis units (the drive's gear)       set up
n_notches          -                       notch filters in use (0 .. 2)                set up
notch              -                       per notch: b0, b1, b2, a1, a2                set up
qpos_adr           -                       the motor hinge's qpos (its feedback)        set up
counts_per_rad     1/rad                   feedback counts per motor rad; 0: exact      set up
alpha              -                       the speed filter's step gain; 0: no filter   set up
beta               -                       the torque filter's step gain; 0: no filter  set up
inv_dt             1/s                     1 / the physics step                         set up
notch_state        -                       per notch: the biquad's two delays           :func:`amp_force`
integral           N | N m                 the PI's integral                            :func:`amp_force`
torque             N | N m                 the torque filter's output                   :func:`amp_force`
last_count         -                       the feedback's count at the last step        :func:`feedback_speed`
speed              m/s | rad/s             the filtered actual speed                    :func:`feedback_speed`
primed             -                       ``last_count`` holds a count                 :func:`feedback_speed`
=================  ======================  ===========================================  ======================
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numba import njit

MAX_NOTCHES = 2

AMP = np.dtype([("modelled", np.bool_), ("speed_per_volt", np.float64), ("kp", np.float64), ("ki_dt", np.float64),
                ("limit", np.float64), ("dof_adr", np.int64), ("scale", np.float64), ("n_notches", np.int64),
                ("notch", np.float64, (MAX_NOTCHES, 5)), ("qpos_adr", np.int64), ("counts_per_rad", np.float64),
                ("alpha", np.float64), ("beta", np.float64), ("inv_dt", np.float64),
                ("notch_state", np.float64, (MAX_NOTCHES, 2)), ("integral", np.float64), ("torque", np.float64),
                ("last_count", np.float64), ("speed", np.float64), ("primed", np.bool_)])
"""one amplifier's record: see the module docstring"""


def notch_coefficients(frequency: float, width: float, depth: float, dt: float) -> tuple[float, ...]:
    """``(b0, b1, b2, a1, a2)`` of a notch at ``frequency`` [Hz], ``width`` [Hz] (-3 dB), ``depth``
    [dB] of attenuation at the centre, sampled at ``dt`` [s]:
    ``H(s) = (s^2 + 2 zz w s + w^2) / (s^2 + 2 zp w s + w^2)``, ``zp = width / (2 frequency)``,
    ``zz = zp 10^(-depth / 20)``, by the bilinear transform prewarped at the centre (so the notch
    sits where it is set)."""
    w = 2.0 * math.pi * frequency
    zp = width / (2.0 * frequency)
    zz = zp * 10.0 ** (-depth / 20.0)
    k = w / math.tan(w * dt / 2.0)
    a0 = k * k + 2.0 * zp * w * k + w * w
    b0 = (k * k + 2.0 * zz * w * k + w * w) / a0
    b1 = (2.0 * w * w - 2.0 * k * k) / a0
    b2 = (k * k - 2.0 * zz * w * k + w * w) / a0
    a1 = b1
    a2 = (k * k - 2.0 * zp * w * k + w * w) / a0
    return b0, b1, b2, a1, a2


def setup_amps(drives: Sequence, taps: np.ndarray, dt: float) -> np.ndarray:
    """The six amplifiers' records: ``drives`` per axis a
    :class:`~cnc_twin.core.axis_config.DriveConfig` or None (the MJCF's velocity-mode drive: voltage
    passed through); ``taps`` each axis's motor
    (:attr:`~cnc_twin.machine.plant.Plant.motor_taps`, :data:`~cnc_twin.machine.plant.ENCODER_TAP`:
    the motor hinge's dof and gear);
    ``dt`` the physics step [s]."""
    amps = np.zeros(len(drives), AMP)
    for i, drive in enumerate(drives):
        if drive is None:
            continue
        a = amps[i]
        a["modelled"] = True
        a["speed_per_volt"], a["kp"], a["limit"] = drive.speed_per_volt, drive.kp, drive.force_limit
        a["ki_dt"] = drive.kp * dt / drive.tn if drive.tn > 0.0 else 0.0
        a["dof_adr"], a["scale"] = taps[i]["dof_adr"], taps[i]["scale"]
        a["qpos_adr"], a["inv_dt"] = taps[i]["qpos_adr"], 1.0 / dt
        a["counts_per_rad"] = drive.feedback_counts / (2.0 * math.pi)
        a["alpha"] = speed_filter_alpha(drive.speed_filter, dt)
        a["beta"] = torque_filter_beta(drive.torque_filter, dt)
        if len(drive.notches) > MAX_NOTCHES:
            raise ValueError(f"at most {MAX_NOTCHES} notch filters per drive, got {len(drive.notches)}")
        a["n_notches"] = len(drive.notches)
        for n, notch in enumerate(drive.notches):
            a["notch"][n] = notch_coefficients(notch.frequency, notch.width, notch.depth, dt)
    return amps


def speed_filter_alpha(frequency: float, dt: float) -> float:
    """The step gain of a first-order low-pass at ``frequency`` [Hz] sampled at ``dt`` [s]
    (exact: ``1 - exp(-2 pi f dt)``); 0 when ``frequency`` is 0 (no filter)."""
    return 1.0 - math.exp(-2.0 * math.pi * frequency * dt) if frequency > 0.0 else 0.0


def torque_filter_beta(time_constant: float, dt: float) -> float:
    """The step gain of a first-order low-pass of ``time_constant`` [s] sampled at ``dt`` [s]
    (exact: ``1 - exp(-dt / tf)``); 0 when ``time_constant`` is 0 (no filter)."""
    return 1.0 - math.exp(-dt / time_constant) if time_constant > 0.0 else 0.0


def reset_amps(amps: np.ndarray) -> None:
    """The amplifiers as at power-on: no integral, the filters at rest, the feedback not yet read."""
    amps["integral"] = 0.0
    amps["notch_state"] = 0.0
    amps["torque"] = 0.0
    amps["speed"] = 0.0
    amps["primed"] = False


@njit(cache=True)
def feedback_speed(a, qpos, qvel):
    """Amplifier ``a``'s actual speed [m/s | rad/s at the axis] this step (see the module
    docstring); advances its feedback state."""
    if a.alpha == 0.0 and a.counts_per_rad == 0.0:
        return qvel[a.dof_adr] * a.scale
    if a.counts_per_rad > 0.0:
        count = np.floor(qpos[a.qpos_adr] * a.counts_per_rad)
        step = (count - a.last_count) / a.counts_per_rad
    else:
        count = qpos[a.qpos_adr]
        step = count - a.last_count
    if not a.primed:  # the first read after power-on: the speed of the step before is unknown
        a.primed = True
        step = qvel[a.dof_adr] / a.inv_dt
    a.last_count = count
    raw = step * a.inv_dt * a.scale
    if a.alpha == 0.0:
        a.speed = raw
    else:
        a.speed += a.alpha * (raw - a.speed)
    return a.speed


@njit(cache=True)
def amp_force(a, volts, speed):
    """One amplifier's force command [N | N m at the axis] for the voltage ``volts`` [V] and the
    motor's ``speed`` [m/s | rad/s at the axis]; advances ``a`` (an :data:`AMP` record) by one step."""
    error = a.speed_per_volt * volts - speed
    u = a.kp * error + a.integral
    # anti-windup: the integral stops while the output is limited and the error pushes further
    if not ((u > a.limit and error > 0.0) or (u < -a.limit and error < 0.0)):
        a.integral += a.ki_dt * error
    if a.beta > 0.0:
        a.torque += a.beta * (u - a.torque)
        u = a.torque
    for n in range(a.n_notches):
        c = a.notch[n]
        s = a.notch_state[n]
        y = c[0] * u + s[0]
        s[0] = c[1] * u - c[3] * y + s[1]
        s[1] = c[2] * u - c[4] * y
        u = y
    if u > a.limit:
        return a.limit
    if u < -a.limit:
        return -a.limit
    return u


@njit(cache=True)
def drive_amps(amps, volts, qpos, qvel, ctrl):
    """Every amplifier for one physics step: ``ctrl`` (MuJoCo's, the drives first) from the DACs'
    ``volts`` [V] and the motors' feedback (MuJoCo's ``qpos``, ``qvel``); a drive that is not
    modelled passes its voltage."""
    for i in range(amps.shape[0]):
        a = amps[i]
        if a.modelled:
            ctrl[i] = amp_force(a, volts[i], feedback_speed(a, qpos, qvel))
        else:
            ctrl[i] = volts[i]


def any_modelled(amps: np.ndarray) -> bool:
    """Whether any amplifier runs loops of its own (else ``ctrl`` is the voltages)."""
    return bool(amps["modelled"].any())
