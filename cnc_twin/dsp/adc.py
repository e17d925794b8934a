"""Unipolar ADC reading the pad load cell (12-bit on the F2812).

Inputs: ``value`` [N], the load cell's force. Outputs: ``code`` in 0..2^bits - 1 and the force it
stands for, ``range_min + code * lsb`` [N], so the conversion error is at most lsb/2 inside
the range. Out-of-range inputs clamp to code 0 or full scale.

One channel's state is an :data:`ADC` record:

==========  =======  ======  ==================================  ===================
field       type     unit    meaning                             written by
==========  =======  ======  ==================================  ===================
range_min   float64  N       the value at code 0                 :func:`setup_adc`
range_max   float64  N       the value at code 2^bits            :func:`setup_adc`
lsb         float64  N       (range_max - range_min) / 2^bits    :func:`setup_adc`
code_max    int64    -       2^bits - 1                          :func:`setup_adc`
code        int64    -       the last conversion's code          :func:`adc_convert`
==========  =======  ======  ==================================  ===================

Algorithm (:func:`adc_convert`)::

    code = clamp(floor((value - range_min) / lsb + 0.5), 0, 2^bits - 1)
    return range_min + code * lsb
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

ADC = np.dtype([("range_min", np.float64), ("range_max", np.float64), ("lsb", np.float64), ("code_max", np.int64),
                ("code", np.int64)])
"""one ADC channel's record: see the module docstring for its fields"""


def setup_adc(adc, range_min: float, range_max: float, *, bits: int = 12) -> None:
    """Fill ``adc`` (an :data:`ADC` record) for ``range_min`` to ``range_max`` [N] at ``bits``."""
    if not range_min < range_max:
        raise ValueError(f"need range_min < range_max, got {range_min}, {range_max}")
    adc["range_min"], adc["range_max"] = range_min, range_max
    adc["lsb"] = (range_max - range_min) / (1 << bits)
    adc["code_max"] = (1 << bits) - 1
    adc["code"] = 0


def new_adc(range_min: float, range_max: float, *, bits: int = 12) -> np.void:
    """An :data:`ADC` record mapped onto ``range_min`` to ``range_max`` [N]."""
    record = np.zeros(1, ADC)[0]
    setup_adc(record, range_min, range_max, bits=bits)
    return record


@njit(cache=True)
def adc_convert(adc, value):
    """Sample ``value`` [N]; latch the code and return the value it stands for [N]."""
    code = np.int64(math.floor((value - adc.range_min) / adc.lsb + 0.5))
    if code < 0:
        code = 0
    elif code > adc.code_max:
        code = adc.code_max
    adc.code = code
    return adc.range_min + code * adc.lsb
