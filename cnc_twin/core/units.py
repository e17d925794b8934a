"""Unit conversions between what machinists write in scenarios and SI used inside.

Scenario files use mm, mm/min, mm/s^2 for linear axes; deg, deg/min, deg/s^2 for rotary
axes; N, s, ms, rpm elsewhere. Everything is converted once, at load, with these factors.
"""

import math

MM = 1e-3
"""metres per millimetre"""
MM_PER_MIN = 1e-3 / 60.0
"""(m/s) per (mm/min)"""
MS = 1e-3
"""seconds per millisecond"""
DEG = math.pi / 180.0
"""radians per degree"""
DEG_PER_MIN = DEG / 60.0
"""(rad/s) per (deg/min)"""
RPM = 2.0 * math.pi / 60.0
"""(rad/s) per (rev/min)"""


def position_factor(rotary: bool) -> float:
    """SI per scenario unit for an axis position: mm -> m, or deg -> rad."""
    return DEG if rotary else MM


def velocity_factor(rotary: bool) -> float:
    """SI per scenario unit for an axis velocity: mm/min -> m/s, or deg/min -> rad/s."""
    return DEG_PER_MIN if rotary else MM_PER_MIN


def position_unit(rotary: bool) -> str:
    """Unit name used in messages and metrics for an axis position."""
    return "deg" if rotary else "mm"
