"""12-bit bipolar DAC driving a servo amplifier's +/-10 V analog command input.

Inputs: ``volts`` [V], the loop output. Outputs: ``code`` in -2048..2047 and the voltage it
produces, ``code * full_scale / 2048`` [V]. Saturation is counted per channel.

Algorithm::

    ideal = volts * 2048 / full_scale
    code  = floor(ideal + 0.5)                  # round half up, as the DSP's fixed-point path does
    if code > 2047 or code < -2048: code = clamp(code); saturations += 1
"""

from __future__ import annotations

import math

BITS = 12
CODE_MIN = -(1 << (BITS - 1))
CODE_MAX = (1 << (BITS - 1)) - 1


class Dac12:
    """One DAC channel.

    Parameters
    ----------
    full_scale : volts at code -2048 (negated) [V]; the card's +/-10 V range by default.
    """

    __slots__ = ("full_scale", "_codes_per_volt", "_volts_per_code", "code", "saturations")

    def __init__(self, *, full_scale: float = 10.0):
        self.full_scale = full_scale
        self._codes_per_volt = (CODE_MAX + 1) / full_scale
        self._volts_per_code = full_scale / (CODE_MAX + 1)
        self.code = 0
        self.saturations = 0

    def write(self, volts: float) -> float:
        """Convert ``volts`` to a code, latch it, return the output voltage [V]."""
        code = math.floor(volts * self._codes_per_volt + 0.5)
        if code > CODE_MAX:
            code = CODE_MAX
            self.saturations += 1
        elif code < CODE_MIN:
            code = CODE_MIN
            self.saturations += 1
        self.code = code
        return code * self._volts_per_code

    def volts(self, code: int) -> float:
        """Output voltage of ``code`` [V]."""
        return code * self._volts_per_code

    @property
    def lsb(self) -> float:
        """One code step [V] (4.88 mV for +/-10 V)."""
        return self._volts_per_code
