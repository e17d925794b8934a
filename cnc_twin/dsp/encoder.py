"""QEP: quadrature encoder interface, as on the F2812's event manager.

One channel's state is a :data:`QEP` record (the block's interface, as a HAL component's pins):

==================  =======  ==============================  =====================================
field               type     unit                            written by
==================  =======  ==============================  =====================================
counts_per_unit     float64  counts per m or per rad         set up (:func:`new_encoder`)
zero_edges          int64    counts                          set up: floor(power-on position x cpu)
counter16           int64    0..65535                        :func:`qep_sample` (the hardware)
position32          int64    counts, signed 32-bit           :func:`qep_sample` (the card's software)
==================  =======  ==============================  =====================================

``counts_per_unit`` = 4 x lines/rev x gear ratio / lead (x4 decoding).

Algorithm, once per servo tick (:func:`qep_sample`)::

    edges      = floor(position * counts_per_unit) - zero_edges
    counter16  = edges mod 2^16                                  # what the hardware latches
    delta      = ((counter16 - last_counter16 + 2^15) mod 2^16) - 2^15   # shortest signed step
    position32 = wrap_int32(position32 + delta)
    reading    = position32 + injected                           # an injected fault's counts (0 normally)

The extension is exact as long as the axis moves fewer than 2^15 counts per tick (X at 0.5 m/s
and 1 um/count moves 125 counts per 0.25 ms tick).

:func:`qep_sample` is one plain function, compiled with numba; the compiled kernels call it, and
its ``py_func`` is the interpreted reference (``tests/test_block_kernels.py`` runs both).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

COUNTER_BITS = 16
_COUNTER_MOD = 1 << COUNTER_BITS
_COUNTER_HALF = 1 << (COUNTER_BITS - 1)
_INT32_MOD = 1 << 32
_INT32_HALF = 1 << 31

QEP = np.dtype([("counts_per_unit", np.float64), ("zero_edges", np.int64), ("counter16", np.int64),
                ("position32", np.int64)])
"""one QEP channel's record: see the module docstring for its fields"""


def new_encoder(counts_per_unit: float, *, position_at_power_on: float = 0.0) -> np.void:
    """A QEP record at power-on: counts are relative to ``position_at_power_on`` [m | rad], as a
    real incremental encoder's are.

    Raises ValueError for ``counts_per_unit <= 0``.
    """
    record = np.zeros(1, QEP)[0]
    setup_encoder(record, counts_per_unit, position_at_power_on)
    return record


def setup_encoder(qep, counts_per_unit: float, position_at_power_on: float) -> None:
    """Fill the set-up fields of ``qep`` (a :data:`QEP` record) and clear its counters."""
    if not counts_per_unit > 0:
        raise ValueError(f"counts_per_unit must be > 0, got {counts_per_unit}")
    qep["counts_per_unit"] = counts_per_unit
    qep["zero_edges"] = math.floor(position_at_power_on * counts_per_unit)
    qep["counter16"] = 0
    qep["position32"] = 0


def wrap_int32(value: int) -> int:
    """Two's-complement wrap of a Python int to the signed 32-bit range."""
    return ((value + _INT32_HALF) % _INT32_MOD) - _INT32_HALF


def extend_counter(position32: int, last_counter16: int, counter16: int) -> int:
    """Extend a 16-bit counter reading into the 32-bit software position [counts]."""
    delta = ((counter16 - last_counter16 + _COUNTER_HALF) % _COUNTER_MOD) - _COUNTER_HALF
    return wrap_int32(position32 + delta)


@njit(cache=True)
def count_error(command, reading):
    """``command - reading`` [counts] as the card's 32-bit arithmetic gives it: wrapped into
    [-2^31, 2^31), so the following error stays right when the 32-bit position wraps (a spindle
    at 2700 rpm, 450 000 counts/s, wraps after 80 minutes while its command runs on). Scalars in
    the compiled blocks; ``count_error.py_func`` takes arrays too (the trace's following error)."""
    d = command - reading
    return d - 4294967296.0 * np.floor((d + 2147483648.0) / 4294967296.0)


@njit(cache=True)
def qep_sample(qep, position, injected):
    """Latch the counter at ``position`` [m | rad]; return the card's reading [counts]: the
    32-bit position plus ``injected`` (counts an injected fault adds; 0 normally)."""
    # "& 0xFFFF" on int64 is the two's-complement "mod 2^16" of the hardware
    counter16 = (np.int64(math.floor(position * qep.counts_per_unit)) - qep.zero_edges) & 0xFFFF
    position32 = qep.position32 + (((counter16 - qep.counter16 + 0x8000) & 0xFFFF) - 0x8000)
    if position32 >= _INT32_HALF or position32 < -_INT32_HALF:
        position32 = ((position32 + _INT32_HALF) % (2 * _INT32_HALF)) - _INT32_HALF
    qep.counter16 = counter16
    qep.position32 = position32
    return position32 + injected
