"""The card's fault supervisor: checks once per interpolation period, the stop each fault makes.

Inputs, from the last servo tick of the period before (``check``): command and actual
position per axis [counts], each DAC channel's saturation count, the switch inputs per axis
(:data:`cnc_twin.core.axes.SWITCH_LIMIT_POS` ...), the tared load-cell force [N]. And the coming
period's setpoint [counts] (``clamp``).

Checks, in this order; the first that trips is reported::

    |command - actual| > following_error_limit            FOLLOWING_ERROR  stop: configured
    a limit switch is on (not in motion-chip programs)      HARD_LIMIT       stop: disable
    a DAC channel clamped every tick for dac_saturation_time DAC_SATURATION  stop: disable
    force > max_force                                       FORCE_LIMIT      stop: retract
    setpoint beyond a soft limit (clamped there from then)  SOFT_LIMIT       stop: controlled

The watchdog (WATCHDOG, stop: disable) is a hardware timer outside the task, in
:mod:`cnc_twin.run.twin`: it trips when no servo interrupt has run for ``watchdog`` seconds.

Stops (the end state is always FAULT, with the machine at rest):

- ``disable``: the amplifiers are disabled at once (MuJoCo drive gains zeroed) and the card goes
  into follow-up (command = actual, DAC 0 V); the axes coast to rest on their friction, Z held by
  its counterbalance and friction.
- ``controlled``: the path decelerates to rest within every axis's acceleration limit (the
  interpolator's hold); the drives stay on and hold position.
- ``retract``: a controlled stop plus a move of the tool away from the work along the tool axis
  (``retract`` at ``retract_speed``, trapezoid at 90 % of the slowest X/Y/Z acceleration); the
  force loop's depth is frozen.

The checks are one function, :func:`supervise`, over the supervisor's records (:data:`LIMITS`
per axis, :data:`SUPERVISOR` once), compiled with numba: :meth:`Supervisor.check` calls it from
Python and the period batch (:mod:`cnc_twin.run.period_kernel`) on the same records.

Soft limits are checked at load on the whole planned path (:mod:`cnc_twin.scenario.load`), so the
run-time check is the second line: it catches what only happens at run time (a force loop's
depth, a retract, an override). Motion-chip programs (home return, jog) run before the machine
is referenced, so they get neither soft limits nor the hard-limit fault: the chip itself stops
an axis at a limit switch and raises an event.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numba import njit

from cnc_twin.core.axes import SWITCH_LIMIT_NEG, SWITCH_LIMIT_POS
from cnc_twin.core.config import AxisConfig, SupervisorConfig
from cnc_twin.dsp.encoder import count_error
from cnc_twin.motion.trapezoid import Trapezoid
from cnc_twin.whiteboard.status import FaultCode

STOP_DISABLE, STOP_CONTROLLED, STOP_RETRACT = "disable", "controlled", "retract"

LIMITS = np.dtype([("ferr_limit", np.float64), ("soft_lo", np.float64), ("soft_hi", np.float64),
                   ("sat_seen", np.int64), ("sat_run", np.int64)])
"""One axis's supervision: ``ferr_limit`` the following-error limit [counts] (0: none),
``soft_lo`` / ``soft_hi`` the soft limits [counts] (+-inf: none), set up; ``sat_seen`` the DAC's
saturation count at the last check and ``sat_run`` the periods in a row it clamped every tick,
written by :func:`supervise`."""
SUPERVISOR = np.dtype([("sat_limit", np.int64), ("ticks", np.int64), ("max_force", np.float64),
                       ("check_switches", np.int64)])
"""The supervisor's settings: ``sat_limit`` periods of DAC saturation that trip (0: off),
``ticks`` servo ticks per period, ``max_force`` [N] (0: off), ``check_switches`` (0 / 1)."""
_FOLLOWING_ERROR, _HARD_LIMIT, _DAC_SATURATION, _FORCE_LIMIT = (
    FaultCode.FOLLOWING_ERROR, FaultCode.HARD_LIMIT, FaultCode.DAC_SATURATION, FaultCode.FORCE_LIMIT)


@njit(cache=True)
def supervise(settings, limits, command, actual, saturations, inputs, force):
    """The first check that trips on the last tick's signals: ``(fault code, axis)``, ``(0, -1)``
    for none. ``command`` [counts], ``actual`` [counts], ``saturations`` (each DAC's count) and
    ``inputs`` (switch bits; empty: no inputs) per axis, ``force`` [N]. Updates the DAC
    saturation runs in ``limits`` up to the axis that trips."""
    n = limits.shape[0]
    for i in range(n):
        limit = limits[i].ferr_limit
        if limit > 0.0:
            error = count_error(command[i], actual[i])
            if error > limit or -error > limit:
                return _FOLLOWING_ERROR, i
    if settings.check_switches != 0:
        for i in range(inputs.shape[0]):
            if inputs[i] & (SWITCH_LIMIT_POS | SWITCH_LIMIT_NEG):
                return _HARD_LIMIT, i
    if settings.sat_limit != 0:
        for i in range(n):
            a = limits[i]
            a.sat_run = a.sat_run + 1 if saturations[i] - a.sat_seen >= settings.ticks else 0
            a.sat_seen = saturations[i]
            if a.sat_run >= settings.sat_limit:
                return _DAC_SATURATION, i
    if settings.max_force > 0.0 and force > settings.max_force:
        return _FORCE_LIMIT, -1
    return 0, -1


class Trip:
    """A tripped check: fault ``code``, ``axis`` (-1 for none), a one-line ``message``, the ``stop``."""

    __slots__ = ("code", "axis", "message", "stop")

    def __init__(self, code: int, axis: int, message: str, stop: str):
        self.code, self.axis, self.message, self.stop = code, axis, message, stop


class Supervisor:
    """Per-period checks of the card (see the module docstring).

    Parameters
    ----------
    axes : the six axes (limits, encoder resolution).
    config : the supervisor's settings.
    power_on : per axis position where the encoders were cleared [m | rad].
    period : interpolation period [s].
    ticks_per_period : servo ticks per period.
    referenced : soft limits and hard-limit faults apply (False for motion-chip programs).
    """

    def __init__(self, axes: Sequence[AxisConfig], config: SupervisorConfig, *, power_on: Sequence[float],
                 period: float, ticks_per_period: int, referenced: bool = True):
        self.axes = tuple(axes)
        self.config = config
        self.ticks_per_period = ticks_per_period
        self.limits = np.zeros(len(axes), LIMITS)
        """per axis: the limits in counts and the DAC saturation runs (:data:`LIMITS`)"""
        self.limits["soft_lo"], self.limits["soft_hi"] = -np.inf, np.inf
        for i, (a, p0) in enumerate(zip(axes, power_on)):
            c = a.counts_per_unit
            self.limits[i]["ferr_limit"] = a.following_error_limit * c if a.following_error_limit > 0.0 else 0.0
            if referenced and a.allowed is not None:
                self.limits[i]["soft_lo"], self.limits[i]["soft_hi"] = (a.allowed[0] - p0) * c, (a.allowed[1] - p0) * c
        self.settings = np.zeros(1, SUPERVISOR)
        """the settings (:data:`SUPERVISOR`), shape ``(1,)``"""
        s = self.settings[0]
        s["sat_limit"] = math.ceil(config.dac_saturation_time / period - 1e-9) if config.dac_saturation_time > 0 else 0
        s["ticks"] = ticks_per_period
        s["max_force"] = config.max_force
        s["check_switches"] = 1 if referenced else 0
        self.check_switches = referenced
        self.soft_tripped = False
        self._no_inputs = np.zeros(0, np.int64)

    def check(self, command: Sequence[float], actual: Sequence[int], saturations: Sequence[int],
              inputs: Sequence[int] | None, force: float) -> Trip | None:
        """The first check that trips on the last tick's signals, or None (:func:`supervise`)."""
        n = len(self.axes)
        code, i = supervise(self.settings[0], self.limits, np.asarray(command[:n], dtype=np.float64),
                            np.asarray(actual[:n], dtype=np.float64), np.asarray(saturations, dtype=np.int64),
                            self._no_inputs if inputs is None else np.asarray(inputs, dtype=np.int64), force)
        if code == 0:
            return None
        if code == FaultCode.FOLLOWING_ERROR:
            a = self.axes[i]
            f = a.display_factor / a.counts_per_unit
            error, limit = count_error(command[i], actual[i]), float(self.limits[i]["ferr_limit"])
            return Trip(code, i, f"{a.name} following error {error * f:.3f} {a.display_unit} beyond the limit "
                                 f"{limit * f:g} {a.display_unit}", self.config.following_error_stop)
        if code == FaultCode.HARD_LIMIT:
            side = "+" if inputs[i] & SWITCH_LIMIT_POS else "-"
            return Trip(code, i, f"{self.axes[i].name} {side} limit switch", STOP_DISABLE)
        if code == FaultCode.DAC_SATURATION:
            return Trip(code, i, f"{self.axes[i].name} DAC clamped at full scale for "
                                 f"{self.config.dac_saturation_time * 1e3:g} ms", STOP_DISABLE)
        return Trip(code, -1, f"pad force {force:.1f} N above the maximum {self.config.max_force:g} N", STOP_RETRACT)

    def warm_up(self) -> None:
        """Compile :func:`supervise` (or load it from numba's cache) now, on copies of the records."""
        n = len(self.axes)
        supervise(self.settings.copy()[0], self.limits.copy(), np.zeros(n), np.zeros(n), np.zeros(n, np.int64),
                  self._no_inputs, 0.0)

    def clamp(self, setpoint: list[float]) -> Trip | None:
        """Hold ``setpoint`` [counts] (in place) within the soft limits; a Trip the first time
        it had to (the clamp stays in force for the rest of the run)."""
        trip = None
        for i, (lo, hi) in enumerate(zip(self.limits["soft_lo"].tolist(), self.limits["soft_hi"].tolist())):
            value = setpoint[i]
            if value < lo or value > hi:
                setpoint[i] = lo if value < lo else hi
                if not self.soft_tripped and trip is None:
                    a = self.axes[i]
                    trip = Trip(FaultCode.SOFT_LIMIT, i,
                                f"{a.name} command beyond its {a.allowed_name} "
                                f"{a.allowed[value > hi] * a.display_factor:g} {a.display_unit}", STOP_CONTROLLED)
        if trip is not None:
            self.soft_tripped = True
        return trip


class Retract:
    """The tool's retract along its axis after a force fault: a trapezoid of ``distance`` [m].

    Parameters
    ----------
    distance : [m]; speed : [m/s]; accel : [m/s^2]; period : interpolation period [s].
    direction : counts per metre of retract for X, Y, Z (the tool axis in counts).
    """

    def __init__(self, distance: float, speed: float, accel: float, period: float,
                 direction: tuple[float, float, float]):
        self.distance = distance
        self.period = period
        self.direction = direction
        self._profile = Trapezoid.fastest(speed / distance, accel / distance) if distance > 0 else None
        self._t = 0.0

    @property
    def done(self) -> bool:
        return self._profile is None or self._t >= self._profile.duration

    def offset(self) -> float:
        """Advance one period; the retract distance reached [m]."""
        if self._profile is None:
            return 0.0
        self._t = min(self._t + self.period, self._profile.duration)
        return self.distance * self._profile.evaluate(self._t)[0]
