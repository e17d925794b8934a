"""Jerk-limited (S-curve) feed profile over a path block of length L.

Seven phases: jerk +J, constant acceleration, jerk -J (v0 -> vp); cruise at vp; jerk -J,
constant deceleration, jerk +J (vp -> v1). Acceleration never exceeds A, jerk never J, and both
are continuous from zero at the block's ends of the acceleration ramps.

A velocity change dv under limits (A, J) takes::

    dv >= A^2 / J :  Tj = A / J,  Ta = dv / A - A / J      (reaches A)
    otherwise       :  Tj = sqrt(dv / J),  Ta = 0            (peak acceleration J Tj < A)
    distance = (v_start + v_end) / 2 * (2 Tj + Ta)           (symmetric ramp)

The peak ``vp`` is the largest value <= vmax whose two ramps fit in L (bisection); the rest of
L is cruised at vp.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

import numpy as np


def phase_state(t0, s0, v0, a0, jerk, t):
    """``(s, v, a)`` at time ``t`` [s] of a constant-jerk phase that starts at ``t0`` with
    ``(s0, v0, a0)`` [m, m/s, m/s^2] and has jerk ``jerk`` [m/s^3]: Horner's form of the cubic.
    Scalars or numpy arrays (element-wise, the same bits); the batch kernel compiles it
    (:mod:`cnc_twin.run.period_kernel`), so the card's feed is this one function everywhere."""
    dt = t - t0
    return (s0 + dt * (v0 + dt * (0.5 * a0 + dt * jerk / 6.0)),
            v0 + dt * (a0 + 0.5 * jerk * dt),
            a0 + jerk * dt)


def ramp_times(dv: float, a_max: float, j_max: float) -> tuple[float, float]:
    """``(Tj, Ta)`` of a velocity change ``|dv|`` [s]."""
    dv = abs(dv)
    if dv * j_max >= a_max * a_max:
        return a_max / j_max, dv / a_max - a_max / j_max
    return math.sqrt(dv / j_max), 0.0


def ramp_distance(v_start: float, v_end: float, a_max: float, j_max: float) -> float:
    """Distance a jerk-limited ramp from ``v_start`` to ``v_end`` takes."""
    tj, ta = ramp_times(v_end - v_start, a_max, j_max)
    return 0.5 * (v_start + v_end) * (2.0 * tj + ta)


def reachable(v_start: float, length: float, a_max: float, j_max: float, v_cap: float) -> float:
    """Highest speed <= ``v_cap`` reachable from ``v_start`` within ``length`` (either direction)."""
    if ramp_distance(v_start, v_cap, a_max, j_max) <= length:
        return v_cap
    lo, hi = v_start, v_cap
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if ramp_distance(v_start, mid, a_max, j_max) <= length:
            lo = mid
        else:
            hi = mid
    return lo


class InfeasibleProfile(ValueError):
    """The block is too short to go from v0 to v1 within the limits."""


@dataclass(frozen=True)
class SCurve:
    """A planned block. Lengths in path units (m), speeds [m/s], ``a_max`` [m/s^2], ``j_max`` [m/s^3].

    Made on construction: ``duration`` [s]; ``phases``, the seven phases' start rows
    ``(t0, s0, v0, a0, jerk)``; ``phase_times``, their ``t0`` (a sorted list, for ``bisect``).
    """

    length: float
    v0: float
    vp: float
    v1: float
    a_max: float
    j_max: float

    @classmethod
    def plan(cls, length: float, v0: float, v1: float, *, v_max: float, a_max: float, j_max: float) -> "SCurve":
        """The fastest profile over ``length`` starting at ``v0`` and ending at ``v1``."""
        if length <= 0.0:
            raise InfeasibleProfile(f"block length must be > 0, got {length}")
        floor = max(v0, v1)
        if ramp_distance(v0, floor, a_max, j_max) + ramp_distance(floor, v1, a_max, j_max) > length * (1 + 1e-12):
            raise InfeasibleProfile(f"cannot change speed {v0:g} -> {v1:g} within {length:g}")
        v_max = max(v_max, floor)

        def fits(vp: float) -> bool:
            return ramp_distance(v0, vp, a_max, j_max) + ramp_distance(vp, v1, a_max, j_max) <= length

        if fits(v_max):
            vp = v_max
        else:
            lo, hi = floor, v_max
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if fits(mid) else (lo, mid)
            vp = lo
        return cls(length=length, v0=v0, vp=vp, v1=v1, a_max=a_max, j_max=j_max)

    def __post_init__(self) -> None:
        j = self.j_max
        tj1, ta1 = ramp_times(self.vp - self.v0, self.a_max, j)
        tj2, ta2 = ramp_times(self.vp - self.v1, self.a_max, j)
        cruise = self.length - ramp_distance(self.v0, self.vp, self.a_max, j) - ramp_distance(self.vp, self.v1, self.a_max, j)
        tv = max(0.0, cruise) / self.vp if self.vp > 0 else 0.0
        durations = (tj1, ta1, tj1, tv, tj2, ta2, tj2)
        jerks = (j, 0.0, -j, 0.0, -j, 0.0, j)
        # Phase start states (t, s, v, a), integrated exactly.
        starts = []
        t = s = a = 0.0
        v = self.v0
        for dt, jk in zip(durations, jerks):
            starts.append((t, s, v, a, jk))
            s += v * dt + a * dt * dt / 2 + jk * dt**3 / 6
            v += a * dt + jk * dt * dt / 2
            a += jk * dt
            t += dt
        object.__setattr__(self, "phases", tuple(starts))
        object.__setattr__(self, "phase_times", [st[0] for st in starts])
        object.__setattr__(self, "duration", t)
        object.__setattr__(self, "_end", (s, v, a))

    def positions_and_speeds(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(s, v)`` at the times ``t`` (shape (n,), sorted or not), as :meth:`state` gives them
        one by one, bit for bit (the same arithmetic, element-wise): the planner checks blocks
        against the limit curve with it."""
        t = np.asarray(t, dtype=np.float64)
        starts = np.array(self.phases)  # (7, 5): t0, s0, v0, a0, jerk
        phase = np.searchsorted(np.asarray(self.phase_times), t, side="right") - 1
        s, v, _ = phase_state(*(starts[np.clip(phase, 0, 6), i] for i in range(5)), t)
        end, start = t >= self.duration, t <= 0.0
        s = np.where(end, self.length, np.where(start, 0.0, s))
        v = np.where(end, self.v1, np.where(start, self.v0, v))
        return s, v

    def state(self, t: float) -> tuple[float, float, float]:
        """``(s, v, a)`` at time ``t`` into the block; clamped to the block's end."""
        if t >= self.duration:
            return self.length, self.v1, 0.0
        if t <= 0.0:
            return 0.0, self.v0, 0.0
        return phase_state(*self.phases[bisect.bisect_right(self.phase_times, t) - 1], t)
