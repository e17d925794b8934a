"""12-bit bipolar DAC driving a servo amplifier's +/-10 V analog command input.

Inputs: ``volts`` [V], the loop output. Outputs: ``code`` in -2048..2047 and the voltage it
produces, ``code * full_scale / 2048`` [V]. Saturation is counted per channel.

One channel's state is a :data:`DAC` record:

===============  =======  ==========  ===========================================  ======================
field            type     unit        meaning                                      written by
===============  =======  ==========  ===========================================  ======================
codes_per_volt   float64  1/V         2048 / full_scale                            :func:`setup_dac`
volts_per_code   float64  V           full_scale / 2048 (one LSB, 4.88 mV)         :func:`setup_dac`
code             int64    -           the code the card wrote last                 :func:`dac_write`
saturations      int64    ticks       writes that were clamped                     :func:`dac_write`
stuck            int64    0 / 1       the output no longer follows the card        the fault injector
stuck_code       int64    -           the code the output is stuck at              the fault injector
===============  =======  ==========  ===========================================  ======================

Algorithm (:func:`dac_write`)::

    ideal = volts * 2048 / full_scale
    code  = floor(ideal + 0.5)                  # round half up, as the DSP's fixed-point path does
    if code > 2047 or code < -2048: code = clamp(code); saturations += 1
    output = (stuck_code if stuck else code) * full_scale / 2048

A stuck channel (fault ``dac_stuck``, ``dac_dead``) still counts what the card writes: the card
cannot tell it from a good one.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

BITS = 12
CODE_MIN = -(1 << (BITS - 1))
CODE_MAX = (1 << (BITS - 1)) - 1

DAC = np.dtype([("codes_per_volt", np.float64), ("volts_per_code", np.float64), ("code", np.int64),
                ("saturations", np.int64), ("stuck", np.int64), ("stuck_code", np.int64)])
"""one DAC channel's record: see the module docstring for its fields"""


def setup_dac(dac, full_scale: float = 10.0) -> None:
    """Fill ``dac`` (a :data:`DAC` record) for a +/-``full_scale`` [V] output and clear it."""
    dac["codes_per_volt"] = (CODE_MAX + 1) / full_scale
    dac["volts_per_code"] = full_scale / (CODE_MAX + 1)
    dac["code"] = dac["saturations"] = dac["stuck"] = dac["stuck_code"] = 0


def new_dac(full_scale: float = 10.0) -> np.void:
    """A :data:`DAC` record for a +/-``full_scale`` [V] output (the card's +/-10 V by default)."""
    record = np.zeros(1, DAC)[0]
    setup_dac(record, full_scale)
    return record


@njit(cache=True)
def dac_write(dac, volts):
    """Convert ``volts`` [V] to a code, latch it, return the voltage at the output [V]."""
    code = np.int64(math.floor(volts * dac.codes_per_volt + 0.5))
    if code > CODE_MAX:
        code = CODE_MAX
        dac.saturations += 1
    elif code < CODE_MIN:
        code = CODE_MIN
        dac.saturations += 1
    dac.code = code
    if dac.stuck != 0:
        return dac.stuck_code * dac.volts_per_code
    return code * dac.volts_per_code
