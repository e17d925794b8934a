"""Step/direction pulse output: the card's pulse-train command mode, one channel per axis.

Cards that drive servo amplifiers with pulse trains (and the older CPLD and motion-chip cards)
send each axis a step line and a direction line; the amplifier, in position mode, counts the
steps into its position command (:mod:`cnc_twin.machine.drive`). The card has no DAC in this mode.

Per servo tick, for a command ``p`` [counts, float] from the fine interpolator::

    target  = floor(p + 1/2)                          # the lattice point nearest the command
    n       = clamp(target - emitted, -N, +N)         # N = floor(max_rate x tick), the pulse
                                                      # generator's (and the drive input's) limit
    emitted = emitted + n                             # direction = sign(n), |n| step pulses

A clamped tick is counted (``limited_ticks``): the pulses it could not send are sent on later
ticks, so a rate limit shows up as a growing lag, never as lost steps.
"""

from __future__ import annotations

import math


class StepGenerator:
    """One axis's step/direction pulse generator.

    Parameters
    ----------
    max_rate : highest step rate the generator and the drive input accept [pulses/s].
    tick : servo tick [s]; pulses are counted per tick.
    """

    __slots__ = ("max_per_tick", "emitted", "limited_ticks")

    def __init__(self, max_rate: float, tick: float):
        if not max_rate * tick >= 1.0:
            raise ValueError(f"pulse rate limit {max_rate:g}/s allows no pulse in a {tick * 1e3:g} ms tick")
        self.max_per_tick = math.floor(max_rate * tick + 1e-9)
        self.emitted = 0
        """pulses sent so far, signed (the drive's position command if none was lost) [counts]"""
        self.limited_ticks = 0
        """ticks in which the rate limit held pulses back"""

    def emit(self, command: float) -> int:
        """Pulses to send this tick (signed: the sign is the direction line) for ``command`` [counts]."""
        n = math.floor(command + 0.5) - self.emitted
        limit = self.max_per_tick
        if n > limit:
            n = limit
            self.limited_ticks += 1
        elif n < -limit:
            n = -limit
            self.limited_ticks += 1
        self.emitted += n
        return n
