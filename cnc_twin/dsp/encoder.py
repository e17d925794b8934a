"""QEP: quadrature encoder interface, as on the F2812's event manager.

Inputs
------
position : axis position [m | rad], the true (continuous) motor-side position.

Outputs
-------
counter16 : the hardware counter, 0..65535, wraps in both directions.
position32 : the software-extended position [counts], signed 32-bit.

Parameters
----------
counts_per_unit : counts per m or per rad = 4 x lines/rev x gear ratio / lead (x4 decoding).

Algorithm, once per servo tick::

    edges      = floor(position * counts_per_unit) - floor(position_at_power_on * counts_per_unit)
    counter16  = edges mod 2^16                                  # what the hardware latches
    delta      = ((counter16 - last_counter16 + 2^15) mod 2^16) - 2^15   # shortest signed step
    position32 = wrap_int32(position32 + delta)

The extension is exact as long as the axis moves fewer than 2^15 counts per tick (X at 0.5 m/s
and 1 um/count moves 125 counts per 0.25 ms tick).
"""

from __future__ import annotations

import math

COUNTER_BITS = 16
_COUNTER_MOD = 1 << COUNTER_BITS
_COUNTER_HALF = 1 << (COUNTER_BITS - 1)
_INT32_MOD = 1 << 32
_INT32_HALF = 1 << 31


def wrap_int32(value: int) -> int:
    """Two's-complement wrap of a Python int to the signed 32-bit range."""
    return ((value + _INT32_HALF) % _INT32_MOD) - _INT32_HALF


def extend_counter(position32: int, last_counter16: int, counter16: int) -> int:
    """Extend a 16-bit counter reading into the 32-bit software position [counts]."""
    delta = ((counter16 - last_counter16 + _COUNTER_HALF) % _COUNTER_MOD) - _COUNTER_HALF
    return wrap_int32(position32 + delta)


class QuadratureEncoder:
    """One QEP channel. See the module docstring for the algorithm.

    Parameters
    ----------
    counts_per_unit : counts per m (linear) or per rad (rotary).
    position_at_power_on : axis position when the counter was cleared [m | rad]; counts are
        relative to it, as a real incremental encoder's are.
    """

    __slots__ = ("counts_per_unit", "_zero_edges", "counter16", "position32")

    def __init__(self, counts_per_unit: float, *, position_at_power_on: float = 0.0):
        if not counts_per_unit > 0:
            raise ValueError(f"counts_per_unit must be > 0, got {counts_per_unit}")
        self.counts_per_unit = counts_per_unit
        self._zero_edges = math.floor(position_at_power_on * counts_per_unit)
        self.counter16 = 0
        self.position32 = 0

    def sample(self, position: float) -> int:
        """Latch the counter at ``position`` [m | rad]; return the 32-bit position [counts]."""
        # Same arithmetic as extend_counter(), inlined: this runs six times per servo tick.
        # For Python ints, "& 0xFFFF" is the two's-complement "mod 2^16" of the hardware.
        counter16 = (math.floor(position * self.counts_per_unit) - self._zero_edges) & 0xFFFF
        position32 = self.position32 + (((counter16 - self.counter16 + 0x8000) & 0xFFFF) - 0x8000)
        if not -_INT32_HALF <= position32 < _INT32_HALF:
            position32 = wrap_int32(position32)
        self.counter16 = counter16
        self.position32 = position32
        return position32
