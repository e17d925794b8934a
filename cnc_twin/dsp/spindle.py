"""The polishing spindle (C) in speed mode: its speed ramped within C's acceleration, its angle.

One plain function, run by the card's Python task (:class:`~cnc_twin.dsp.interpolator.SegmentInterpolator`)
and compiled into the batch kernel (:mod:`cnc_twin.run.period_kernel`).
"""

from __future__ import annotations


def spindle_turn(spin: float, target: float, step: float, period: float) -> tuple[float, float]:
    """One interpolation period of the spindle: ``spin`` [rad/s] moves toward ``target`` [rad/s]
    by at most ``step`` [rad/s] (C's acceleration times the period); returns the new speed and
    the angle turned meanwhile [rad] (trapezoidal: the mean of the two speeds times ``period`` [s])."""
    turned = min(target, spin + step) if target > spin else max(target, spin - step)
    return turned, 0.5 * (spin + turned) * period
