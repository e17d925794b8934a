"""Position loop: PID on the following error in counts, plus velocity and acceleration
feed-forward, with integrator anti-windup and an output clamp. Output is a drive voltage.

Inputs (per servo tick)
-----------------------
command : commanded position [counts]
feedback : encoder position [counts]
velocity : commanded velocity [counts/s] (feed-forward)
acceleration : commanded acceleration [counts/s^2] (feed-forward)

Output: drive command [V], within +/- ``output_limit``.

Gains are given in machine terms and converted once with the drive scaling ``speed_per_volt``
[unit/s/V] and the encoder ``counts_per_unit`` [counts/unit]; ``g = 1 / (speed_per_volt *
counts_per_unit)`` is volts per (count/s):

=======  ==========  =====================================  ==================
gain     given in    meaning                                inside [V per ...]
=======  ==========  =====================================  ==================
kp       1/s         speed per unit of following error      count:      kp g
ki       1/s^2       speed per unit of integrated error     count*s:    ki g
kd       -           speed per unit of error rate           count/s:    kd g
kvff     -           fraction of the commanded speed        count/s:    kvff g
kaff     s           speed per unit commanded acceleration  count/s^2:  kaff g
fff      V           friction feed-forward, full beyond     (volts):    fff
                     ``friction_ff_band`` [unit/s]
=======  ==========  =====================================  ==================

0 for any gain means that term is off.

Algorithm (dt = servo period)::

    e = command - feedback
    i_try = clamp(i + ki_c * e * dt, -integrator_limit, +integrator_limit)
    ramp = clamp(velocity / (friction_ff_band * counts_per_unit), -1, +1)   # the friction's sign, softened
    u = kp_c*e + i_try + kd_c*(e - e_prev)/dt + kvff_c*velocity + kaff_c*acceleration + fff*ramp
    if |u| > output_limit and e has the sign of u:  keep i (conditional integration)
    else:                                           i = i_try
    output = clamp(kp_c*e + i + kd_c*(e - e_prev)/dt + ff, -output_limit, +output_limit)
"""

from __future__ import annotations


class PidFF:
    """One axis's position loop. See the module docstring.

    Parameters
    ----------
    kp, ki, kd, kvff, kaff : gains in machine terms (1/s, 1/s^2, -, -, s).
    friction_ff : friction feed-forward [V]; friction_ff_band : commanded speed [m/s | rad/s] over
        which it ramps in, so that it does not chatter at rest.
    speed_per_volt : drive scaling [m/s/V | rad/s/V].
    counts_per_unit : encoder resolution [counts/m | counts/rad].
    dt : servo period [s].
    output_limit : [V]. integrator_limit : [V].
    """

    __slots__ = (
        "dt", "kp", "ki_dt", "kd_over_dt", "kvff", "kaff", "friction_ff", "friction_rate",
        "output_limit", "integrator_limit", "integrator", "previous_error",
    )

    def __init__(
        self,
        *,
        kp: float,
        ki: float = 0.0,
        kd: float = 0.0,
        kvff: float = 0.0,
        kaff: float = 0.0,
        friction_ff: float = 0.0,
        friction_ff_band: float = 1e-3,
        speed_per_volt: float,
        counts_per_unit: float,
        dt: float,
        output_limit: float = 10.0,
        integrator_limit: float = 10.0,
    ):
        if not (speed_per_volt > 0 and counts_per_unit > 0 and dt > 0):
            raise ValueError("speed_per_volt, counts_per_unit and dt must be > 0")
        volts_per_count_rate = 1.0 / (speed_per_volt * counts_per_unit)
        self.dt = dt
        self.kp = kp * volts_per_count_rate
        self.ki_dt = ki * volts_per_count_rate * dt
        self.kd_over_dt = kd * volts_per_count_rate / dt
        self.kvff = kvff * volts_per_count_rate
        self.kaff = kaff * volts_per_count_rate
        self.friction_ff = friction_ff
        self.friction_rate = 1.0 / (friction_ff_band * counts_per_unit)  # [1/(count/s)]
        self.output_limit = output_limit
        self.integrator_limit = integrator_limit
        self.integrator = 0.0
        self.previous_error = 0.0

    def update(self, command: float, feedback: float, velocity: float, acceleration: float) -> float:
        """One servo tick; returns the clamped drive voltage [V]."""
        error = command - feedback
        ramp = velocity * self.friction_rate
        if ramp > 1.0:
            ramp = 1.0
        elif ramp < -1.0:
            ramp = -1.0
        fixed = (
            self.kp * error
            + self.kd_over_dt * (error - self.previous_error)
            + self.kvff * velocity
            + self.kaff * acceleration
            + self.friction_ff * ramp
        )
        self.previous_error = error
        limit = self.integrator_limit
        integrator = self.integrator + self.ki_dt * error
        if integrator > limit:
            integrator = limit
        elif integrator < -limit:
            integrator = -limit
        out = fixed + integrator
        umax = self.output_limit
        if out > umax:
            if error <= 0.0:
                self.integrator = integrator
            out = fixed + self.integrator
            return umax if out > umax else out
        if out < -umax:
            if error >= 0.0:
                self.integrator = integrator
            out = fixed + self.integrator
            return -umax if out < -umax else out
        self.integrator = integrator
        return out

    def reset(self) -> None:
        """Clear the integrator and the previous error (the drive was disabled)."""
        self.integrator = 0.0
        self.previous_error = 0.0
