"""Unipolar ADC reading the pad load cell (12-bit on the F2812).

Inputs: ``value`` [N], the load cell's force. Outputs: ``code`` in 0..2^bits - 1 and the force it
stands for, ``range_min + code * lsb`` [N], so the conversion error is at most lsb/2 inside
the range. Out-of-range inputs clamp to code 0 or full scale.

Algorithm::

    lsb  = (range_max - range_min) / 2^bits
    code = clamp(floor((value - range_min) / lsb + 0.5), 0, 2^bits - 1)
"""

from __future__ import annotations

import math


class Adc:
    """One ADC channel mapped onto a physical range.

    Parameters
    ----------
    range_min, range_max : physical value at code 0 and at 2^bits [N].
    bits : resolution.
    """

    __slots__ = ("range_min", "range_max", "bits", "lsb", "_code_max", "code")

    def __init__(self, range_min: float, range_max: float, *, bits: int = 12):
        if not range_min < range_max:
            raise ValueError(f"need range_min < range_max, got {range_min}, {range_max}")
        self.range_min = range_min
        self.range_max = range_max
        self.bits = bits
        self.lsb = (range_max - range_min) / (1 << bits)
        self._code_max = (1 << bits) - 1
        self.code = 0

    def convert(self, value: float) -> float:
        """Sample ``value``; latch the code and return the value it stands for."""
        code = math.floor((value - self.range_min) / self.lsb + 0.5)
        if code < 0:
            code = 0
        elif code > self._code_max:
            code = self._code_max
        self.code = code
        return self.range_min + code * self.lsb
