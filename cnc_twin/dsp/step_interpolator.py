"""The older cards' step interpolators on the card: a StepContour element, clocked by its S-curve.

A CPLD or 8051 card runs point-by-point comparison or DDA (:mod:`cnc_twin.legacy`) one cycle
per clock edge, emitting at most one step per axis per cycle. The clock's frequency follows the
feed: ``f(t) = N v(t) / L`` for an element of ``N`` cycles and nominal length ``L`` (the feed
rate number of the DDA cards), ramped by the element's rest-to-rest S-curve. So by time ``t``
into the element the card has completed::

    k(t) = floor(N s(t) / L)        cycles   (N exactly when s = L)

and the axes stand on the lattice point after cycle ``k``. The card samples that point at every
servo tick (:meth:`StepRun.point_at`): the fine interpolation of a step card is its own lattice,
never a straight line between period setpoints.

The cycles are generated when the record is accepted (the card decodes ahead), as cumulative
lattice points, shape ``(N + 1, 2)``; the generators are the exact integer algorithms, so this
is what the card's registers would produce cycle by cycle.
"""

from __future__ import annotations

import math

import numpy as np

from cnc_twin.dsp.path_blocks import slew
from cnc_twin.legacy import dda, point_by_point
from cnc_twin.whiteboard.records import STEP_ARC, STEP_DDA, STEP_LINE, STEP_POINT_BY_POINT, StepContour


def lattice_steps(record: StepContour):
    """The element's per-cycle steps ``(sx, sy)`` from the legacy generator (an iterator)."""
    x0, y0 = record.start
    x1, y1 = record.end
    bits = record.dda_bits or None
    if record.kind == STEP_LINE:
        if record.method == STEP_POINT_BY_POINT:
            return point_by_point.line(x1 - x0, y1 - y0)
        if record.method == STEP_DDA:
            return dda.line(x1 - x0, y1 - y0, bits=bits)
    elif record.kind == STEP_ARC:
        cx, cy = record.center
        args = (x0 - cx, y0 - cy, x1 - cx, y1 - cy)
        if record.method == STEP_POINT_BY_POINT:
            return point_by_point.arc(*args, clockwise=record.clockwise)
        if record.method == STEP_DDA:
            return dda.arc(*args, clockwise=record.clockwise, bits=bits)
    raise ValueError(f"unknown step method {record.method} or element kind {record.kind}")


class StepRun:
    """One StepContour element ready to run: its lattice points and its clock.

    Parameters
    ----------
    record : the element.
    held : the other axes' commands while it runs [counts], shape ``(6,)``; X and Y are replaced.
    """

    def __init__(self, record: StepContour, held: list[float]):
        self.profile = record.profile
        points = point_by_point.trace(lattice_steps(record), record.start)
        if tuple(points[-1]) != tuple(record.end):  # the generators' end-point judgement guarantees this
            raise ValueError(f"step interpolation ended at {tuple(points[-1])}, not {record.end}")
        self.cycles = len(points) - 1
        """N, the element's interpolation cycles (steps for point-by-point, iterations for DDA)"""
        self._x = points[:, 0].astype(np.float64).tolist()
        self._y = points[:, 1].astype(np.float64).tolist()
        self.held = list(held)
        self.periods = 0
        """the element's duration [interpolation periods], set by the interpolator"""
        self._scale = self.cycles / self.profile.length if self.profile.length > 0.0 else 0.0

    def point_at(self, tau: float) -> list[float]:
        """Commands of all six axes at ``tau`` [s] into the element [counts]."""
        if tau >= self.profile.duration:
            k = self.cycles
        else:
            k = min(self.cycles, math.floor(self.profile.state(tau)[0] * self._scale + 1e-9))
        out = list(self.held)
        out[0] = self._x[k]
        out[1] = self._y[k]
        return out

    def advance(self, tau: float, lam: float, target: float, period: float,
                ticks_per_period: int) -> tuple[list[list[float]], float, float, bool]:
        """One interpolation period [s] from ``tau`` [s] into the element at time scale ``lam``,
        slewed toward ``target`` within the S-curve's acceleration: the lattice point of every
        servo tick [counts], the new ``tau`` and ``lam``, and whether the element ended."""
        prof = self.profile
        if lam != target:
            _, v, a = prof.state(tau)
            lam = slew(lam, target, v, a, prof.a_max, period)
        dt = lam * period / ticks_per_period
        ticks = [self.point_at(tau + dt * (j + 1)) for j in range(ticks_per_period)]
        tau = tau + lam * period
        return ticks, tau, lam, tau >= prof.duration - 1e-9 * period

    @property
    def end(self) -> list[float]:
        return self.point_at(math.inf)
