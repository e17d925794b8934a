"""Trapezoid velocity profile over a normalised path s: 0 -> 1.

A move of displacement ``d`` (per axis) follows ``p(t) = start + s(t) * d``; limits on s
(``v`` [1/s], ``a`` [1/s^2]) are the tightest of every axis's ``v_max / |d|`` and
``a_max / |d|``, so all axes arrive together and none exceeds its own limits.

Shape: accelerate at ``a`` for ``t_acc``, cruise at ``v_peak`` for ``t_flat``, decelerate at
``a`` for ``t_acc``; a triangle when the cruise speed is never reached. ``quantised`` stretches
time so the duration is a whole number of interpolation periods (speed scales by 1/k and
acceleration by 1/k^2 for a stretch k >= 1, so limits still hold).
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Trapezoid:
    """Normalised trapezoid profile. Times [s], ``v_peak`` [1/s], ``accel`` [1/s^2]."""

    t_acc: float
    t_flat: float
    v_peak: float
    accel: float

    @property
    def duration(self) -> float:
        """Total time [s]."""
        return 2.0 * self.t_acc + self.t_flat

    @classmethod
    def fastest(cls, v_max: float, a_max: float) -> "Trapezoid":
        """Shortest profile for unit distance with ``|s'| <= v_max`` and ``|s''| <= a_max``."""
        if not (v_max > 0 and a_max > 0):
            raise ValueError(f"limits must be > 0, got v_max={v_max}, a_max={a_max}")
        if v_max * v_max / a_max >= 1.0:  # cruise speed never reached: triangle
            t_acc = math.sqrt(1.0 / a_max)
            return cls(t_acc=t_acc, t_flat=0.0, v_peak=a_max * t_acc, accel=a_max)
        t_acc = v_max / a_max
        return cls(t_acc=t_acc, t_flat=1.0 / v_max - t_acc, v_peak=v_max, accel=a_max)

    def quantised(self, period: float) -> tuple["Trapezoid", int]:
        """Stretch to a whole number of ``period`` [s]; returns (profile, number of periods)."""
        n = max(1, math.ceil(self.duration / period - 1e-9))
        k = n * period / self.duration
        stretched = Trapezoid(
            t_acc=self.t_acc * k, t_flat=self.t_flat * k, v_peak=self.v_peak / k, accel=self.accel / k**2
        )
        return stretched, n

    def evaluate(self, t: float) -> tuple[float, float, float]:
        """``(s, ds/dt, d2s/dt2)`` at time ``t`` [s] after the start."""
        return trapezoid_state(self.t_acc, self.accel, self.t_flat, self.v_peak, self.duration, t)


def trapezoid_state(t_acc: float, accel: float, t_flat: float, v_peak: float, duration: float,
                    t: float) -> tuple[float, float, float]:
    """``(s, ds/dt, d2s/dt2)`` of the normalised path (s: 0 -> 1) at time ``t`` [s] after the
    start: ``accel`` [1/s^2] for ``t_acc`` [s], ``v_peak`` [1/s] for ``t_flat`` [s], then down to
    rest at ``duration`` [s]. :meth:`Trapezoid.evaluate` and the batch kernel run this function."""
    if t <= 0.0:
        return 0.0, 0.0, 0.0
    if t < t_acc:
        return 0.5 * accel * t * t, accel * t, accel
    if t < t_acc + t_flat:
        return 0.5 * accel * t_acc * t_acc + v_peak * (t - t_acc), v_peak, 0.0
    remaining = duration - t
    if remaining > 0.0:
        return 1.0 - 0.5 * accel * remaining * remaining, accel * remaining, -accel
    return 1.0, 0.0, 0.0
