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

Soft limits are checked at load on the whole planned path (:mod:`cnc_twin.scenario.load`), so the
run-time check is the second line: it catches what only happens at run time (a force loop's
depth, a retract, an override). Motion-chip programs (home return, jog) run before the machine
is referenced, so they get neither soft limits nor the hard-limit fault: the chip itself stops
an axis at a limit switch and raises an event.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from cnc_twin.core.config import AxisConfig, SupervisorConfig
from cnc_twin.motion.trapezoid import Trapezoid
from cnc_twin.core.axes import SWITCH_LIMIT_NEG, SWITCH_LIMIT_POS
from cnc_twin.whiteboard.status import FaultCode

STOP_DISABLE, STOP_CONTROLLED, STOP_RETRACT = "disable", "controlled", "retract"


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
        cpu = [a.counts_per_unit for a in axes]
        self._ferr_limit = [(i, a.following_error_limit * c) for i, (a, c) in enumerate(zip(axes, cpu))
                            if a.following_error_limit > 0.0]
        self._soft = []
        if referenced:
            for i, (a, c, p0) in enumerate(zip(axes, cpu, power_on)):
                if a.allowed is not None:
                    self._soft.append((i, (a.allowed[0] - p0) * c, (a.allowed[1] - p0) * c))
        self.check_switches = referenced
        self._sat_limit = math.ceil(config.dac_saturation_time / period - 1e-9) if config.dac_saturation_time > 0 else 0
        self._sat_seen = [0] * len(axes)
        self._sat_run = [0] * len(axes)
        self.soft_tripped = False

    def check(self, command: Sequence[float], actual: Sequence[int], saturations: Sequence[int],
              inputs: Sequence[int] | None, force: float) -> Trip | None:
        """The first check that trips on the last tick's signals, or None."""
        for i, limit in self._ferr_limit:
            error = command[i] - actual[i]
            if error > limit or -error > limit:
                a = self.axes[i]
                f = a.display_factor / a.counts_per_unit
                return Trip(FaultCode.FOLLOWING_ERROR, i,
                            f"{a.name} following error {error * f:.3f} {a.display_unit} beyond the limit "
                            f"{limit * f:g} {a.display_unit}", self.config.following_error_stop)
        if self.check_switches and inputs is not None:
            for i, bits in enumerate(inputs):
                if bits & (SWITCH_LIMIT_POS | SWITCH_LIMIT_NEG):
                    side = "+" if bits & SWITCH_LIMIT_POS else "-"
                    return Trip(FaultCode.HARD_LIMIT, i, f"{self.axes[i].name} {side} limit switch", STOP_DISABLE)
        if self._sat_limit:
            ticks = self.ticks_per_period
            seen, run = self._sat_seen, self._sat_run
            for i, count in enumerate(saturations):
                run[i] = run[i] + 1 if count - seen[i] >= ticks else 0
                seen[i] = count
                if run[i] >= self._sat_limit:
                    return Trip(FaultCode.DAC_SATURATION, i,
                                f"{self.axes[i].name} DAC clamped at full scale for "
                                f"{self.config.dac_saturation_time * 1e3:g} ms", STOP_DISABLE)
        if self.config.max_force > 0.0 and force > self.config.max_force:
            return Trip(FaultCode.FORCE_LIMIT, -1, f"pad force {force:.1f} N above the maximum "
                        f"{self.config.max_force:g} N", STOP_RETRACT)
        return None

    def clamp(self, setpoint: list[float]) -> Trip | None:
        """Hold ``setpoint`` [counts] (in place) within the soft limits; a Trip the first time
        it had to (the clamp stays in force for the rest of the run)."""
        trip = None
        for i, lo, hi in self._soft:
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
