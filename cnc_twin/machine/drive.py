"""Servo amplifiers in position mode, on the machine side of a pulse-train card.

The MJCF drives are velocity-mode amplifiers (their speed loop runs in MuJoCo, in C, at the
physics rate; see :mod:`cnc_twin.machine.plant`). In position mode the same amplifier counts the step
pulses it receives into a position command and closes a position loop around its own motor
encoder, feeding its speed loop the way the analog input would. Per servo tick, for one axis::

    command  += pulses                                  # pulse counter [counts]
    error     = command - encoder(position)             # drive's own QEP [counts]
    rate      = rate + (pulses / tick - rate) x tick / (tick + T_ff)   # filtered pulse frequency
    speed     = Kp x error / cpu + K_ff x rate / cpu    # [m/s | rad/s]
    volts     = clamp(speed / speed_per_volt, +-10)     # into the velocity loop

``Kp`` is the drive's position-loop gain [1/s], ``K_ff`` its velocity feed-forward (0..1) and
``T_ff`` the feed-forward filter time constant [s] that smooths the integer pulse counts.
"""

from __future__ import annotations

from collections.abc import Sequence

from cnc_twin.core.config import AxisConfig
from cnc_twin.dsp.encoder import new_encoder, qep_sample

INPUT_LIMIT = 10.0
"""the speed loop's command range, as for the analog input [V-equivalent]"""


class PositionModeDrive:
    """One axis's amplifier in position mode (see the module docstring).

    Parameters
    ----------
    axis : the axis (encoder resolution, drive scaling and the ``drive_*`` position-mode gains).
    tick : servo tick [s], the rate at which pulses arrive and the position loop runs.
    power_on : axis position when the drive powered up [m | rad].
    """

    __slots__ = ("encoder", "command", "_kp_volts", "_ff_volts", "_rate", "_alpha", "_inv_tick")

    def __init__(self, axis: AxisConfig, *, tick: float, power_on: float):
        cpu, spv = axis.counts_per_unit, axis.speed_per_volt
        self.encoder = new_encoder(cpu, position_at_power_on=power_on)
        """the drive's own QEP channel (:data:`~cnc_twin.dsp.encoder.QEP`)"""
        self.command = 0
        """pulses counted so far [counts]"""
        self._kp_volts = axis.drive_position_gain / (cpu * spv)
        self._ff_volts = axis.drive_velocity_ff / (cpu * spv)
        self._rate = 0.0
        self._alpha = tick / (tick + axis.drive_ff_filter)
        self._inv_tick = 1.0 / tick

    def update(self, pulses: int, position: float) -> float:
        """Count ``pulses``, run the position loop at ``position`` [m | rad]; the speed command [V]."""
        self.command += pulses
        error = self.command - qep_sample(self.encoder, position, 0)
        self._rate += (pulses * self._inv_tick - self._rate) * self._alpha
        volts = self._kp_volts * error + self._ff_volts * self._rate
        if volts > INPUT_LIMIT:
            return INPUT_LIMIT
        if volts < -INPUT_LIMIT:
            return -INPUT_LIMIT
        return volts


class PositionModeDrives:
    """The six amplifiers in position mode: pulses in, speed commands out."""

    def __init__(self, axes: Sequence[AxisConfig], *, tick: float, power_on: Sequence[float]):
        self.drives = [PositionModeDrive(a, tick=tick, power_on=p) for a, p in zip(axes, power_on)]
        self._update = [d.update for d in self.drives]

    def update(self, pulses: Sequence[int], positions: Sequence[float]) -> list[float]:
        """Speed commands [V] for this tick's ``pulses`` at the true ``positions``, shape ``(6,)``."""
        return [u(n, p) for u, n, p in zip(self._update, pulses, positions)]
