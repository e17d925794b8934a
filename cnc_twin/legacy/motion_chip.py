"""A 4-axis motion chip's per-axis pulse profiles: index moves, jogs, linear interpolation.

The chip is told a move in pulses and limits in pulses/s, pulses/s^2, pulses/s^3; every servo
cycle of ``dt`` seconds it emits an integer number of pulses per axis. Three profile kinds,
picked by which limits are given:

    a_max is None                : constant speed   (velocity steps to v_max and back to 0)
    a_max given, j_max is None   : trapezoid        (acceleration steps between +-a_max and 0)
    a_max and j_max given        : S-curve          (jerk +-j_max, acceleration continuous)

Continuous profile: piecewise-constant jerk phases ``(duration, a_start, jerk)``; s and v are
integrated exactly, a starts each phase at ``a_start`` (continuous for the S-curve, stepped for
the trapezoid). Rest-to-rest peak speed ``vp`` over a length L (closed form, no bisection)::

    constant speed : vp = v_max
    trapezoid      : vp = min(v_max, sqrt(L a)),  ramp distance vp^2 / a
    S-curve        : a ramp 0 -> vp takes Tj = min(a/j, sqrt(vp/j)), Ta = max(0, vp/a - a/j),
                     distance of both ramps D(vp) = vp (2 Tj + Ta):
                         D(vp) = vp^2/a + vp a/j      (vp >= a^2/j: acceleration reaches a)
                         D(vp) = 2 vp sqrt(vp/j)       (otherwise)
                     vp = v_max if D(v_max) <= L, else D(vp) = L solved in the matching branch
    cruise at vp for (L - D(vp)) / vp

Pulses per cycle: the chip's position accumulator carries the fractional remainder, so after
cycle k it has emitted ``round(s(k dt))`` pulses in total (half up) and cycle k emits
``round(s(k dt)) - round(s((k-1) dt))``. The position is clamped to L from the end of the
profile on, so the last cycle (the one containing the end) absorbs the remaining rounding and
an index move ends exactly on its target; on the way it is within half a pulse of s(t).

Jog: ramp to v, cruise until :meth:`Jog.stop`, then the fastest stop from the current state
(S-curve: jerk -j until the acceleration is 0, then the ramp down from the speed reached).

Linear interpolation (up to 4 axes, as the chip's interpolation unit): the path profile runs
over the Euclidean length; the longest axis (D pulses) is the master with
``M_k = round(D s_k / L)`` pulses in total, every other axis i follows integer-only with
``round(d_i M_k / D)`` (Bresenham rounding). Each slave is within half a pulse of the exact line
point at the master's position, so a point is within ``0.5 sqrt(n - 1) < 1`` pulse of the line,
and all axes end exactly on their deltas.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Iterator, Sequence

import numpy as np

from cnc_twin.motion.scurve import phase_state

MAX_AXES = 4

Segment = tuple[float, float, float]
"""(duration [s], acceleration at its start [pulses/s^2], jerk [pulses/s^3])"""


def _ramp(dv: float, a_max: float | None, j_max: float | None) -> list[Segment]:
    """Segments changing the speed by ``dv`` (sign gives the direction) from acceleration 0."""
    if dv == 0.0 or a_max is None:
        return []  # constant speed: the caller steps the velocity
    sign = 1.0 if dv > 0 else -1.0
    dv = abs(dv)
    if j_max is None:
        return [(dv / a_max, sign * a_max, 0.0)]
    if dv * j_max >= a_max * a_max:
        tj, ta = a_max / j_max, dv / a_max - a_max / j_max
    else:
        tj, ta = math.sqrt(dv / j_max), 0.0
    peak = sign * j_max * tj
    return [(tj, 0.0, sign * j_max), (ta, peak, 0.0), (tj, peak, -sign * j_max)]


def _ramps_distance(vp: float, a_max: float, j_max: float | None) -> float:
    """Distance of the ramps 0 -> vp -> 0 together [pulses]."""
    if j_max is None:
        return vp * vp / a_max
    if vp * j_max >= a_max * a_max:
        return vp * vp / a_max + vp * a_max / j_max
    return 2.0 * vp * math.sqrt(vp / j_max)


def _peak_speed(length: float, v_max: float, a_max: float, j_max: float | None) -> float:
    """Highest speed <= v_max whose rest-to-rest ramps fit in ``length`` (module docstring)."""
    if _ramps_distance(v_max, a_max, j_max) <= length:
        return v_max
    if j_max is None:
        return math.sqrt(length * a_max)
    if length >= 2.0 * a_max**3 / j_max**2:  # D(a^2/j): the acceleration reaches a_max
        k = a_max * a_max / j_max
        return 0.5 * (-k + math.sqrt(k * k + 4.0 * length * a_max))
    return (0.5 * length * math.sqrt(j_max)) ** (2.0 / 3.0)


def _check_limits(v: float, a_max: float | None, j_max: float | None, dt: float) -> None:
    if not v > 0:
        raise ValueError(f"speed must be > 0, got {v}")
    if a_max is not None and not a_max > 0:
        raise ValueError(f"a_max must be > 0 or None, got {a_max}")
    if j_max is not None and (a_max is None or not j_max > 0):
        raise ValueError(f"j_max needs a_max and must be > 0, got a_max={a_max}, j_max={j_max}")
    if not dt > 0:
        raise ValueError(f"dt must be > 0, got {dt}")


class Profile:
    """Continuous piecewise-constant-jerk motion from ``(t0, s0, v0)``, in pulses and seconds.

    After the last segment the motion holds its final speed (a jog's cruise), or with ``rest``
    stands still at the final position, or at ``end`` when given (which absorbs the float error
    of integrating to a planned length).
    """

    __slots__ = ("_starts", "_times", "_array", "duration", "end_position", "end_velocity")

    def __init__(self, segments: Sequence[Segment], *, t0: float = 0.0, s0: float = 0.0, v0: float = 0.0,
                 rest: bool = False, end: float | None = None):
        starts = []
        t, s, v = t0, s0, v0
        for duration, a, jerk in segments:
            if duration <= 0.0:
                continue
            starts.append((t, s, v, a, jerk))
            s += duration * (v + duration * (0.5 * a + duration * jerk / 6.0))
            v += duration * (a + 0.5 * jerk * duration)
            t += duration
        if rest or end is not None:
            s, v = (s if end is None else end), 0.0
        starts.append((t, s, v, 0.0, 0.0))
        self._starts = starts
        self._times = [st[0] for st in starts]
        self._array = np.array(starts)
        self.duration = t - t0
        self.end_position = s
        self.end_velocity = v

    def state(self, t: float) -> tuple[float, float, float, float]:
        """``(s, v, a, j)`` at time ``t`` [s] (t >= t0)."""
        t0, s0, v0, a0, jerk = self._starts[max(0, bisect.bisect_right(self._times, t) - 1)]
        return (*phase_state(t0, s0, v0, a0, jerk, t), jerk)

    def sample(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Vectorised :meth:`state`: arrays ``(s, v, a, j)`` at the times ``t``."""
        idx = np.maximum(np.searchsorted(self._array[:, 0], t, side="right") - 1, 0)
        t0, s0, v0, a0, jerk = self._array[idx].T
        return (*phase_state(t0, s0, v0, a0, jerk, t), jerk)


def rest_to_rest(length: float, v_max: float, a_max: float | None, j_max: float | None) -> Profile:
    """The fastest profile over ``length`` >= 0 [pulses] from rest to rest within the limits."""
    if length <= 0.0:
        return Profile([], end=0.0)
    if a_max is None:
        return Profile([(length / v_max, 0.0, 0.0)], v0=v_max, end=length)
    vp = _peak_speed(length, v_max, a_max, j_max)
    cruise = max(0.0, length - _ramps_distance(vp, a_max, j_max)) / vp
    return Profile(_ramp(vp, a_max, j_max) + [(cruise, 0.0, 0.0)] + _ramp(-vp, a_max, j_max), end=length)


def _cycles(duration: float, dt: float) -> int:
    """Whole cycles covering ``duration``; a float hair over a whole number does not add one."""
    return max(0, math.ceil(duration / dt - 1e-9))


def _rounded(x: np.ndarray) -> np.ndarray:
    """Round half up to int64 (positions here are >= 0)."""
    return np.floor(x + 0.5).astype(np.int64)


class IndexMove:
    """A fixed-length move of one axis: per-cycle pulse counts ending exactly on the target.

    Parameters
    ----------
    distance_pulses
        signed move length [pulses].
    v_max
        [pulses/s].
    a_max
        [pulses/s^2] or None (constant speed).
    j_max
        [pulses/s^3] or None (trapezoid).
    dt
        cycle time [s].

    Attributes (signed, sampled at the cycle boundaries ``t = k dt``, k = 0..n)
    -----------------------------------------------------------------------------
    t, position, velocity, acceleration, jerk
        the continuous profile [s, pulses, /s, /s^2, /s^3]; ``jerk`` is the phase's jerk
        (acceleration steps of a trapezoid are not in it).
    pulses
        int64 array of n per-cycle pulse counts; ``pulses.sum() == distance_pulses``.
    """

    def __init__(self, distance_pulses: int, v_max: float, a_max: float | None, j_max: float | None,
                 dt: float):
        _check_limits(v_max, a_max, j_max, dt)
        self.distance = int(distance_pulses)
        self.dt = dt
        sign = -1 if self.distance < 0 else 1
        length = abs(self.distance)
        self.profile = rest_to_rest(float(length), v_max, a_max, j_max)
        n = _cycles(self.profile.duration, dt)
        self.t = np.arange(n + 1) * dt
        s, v, a, j = self.profile.sample(self.t)
        s[-1] = length  # the end lies within the last cycle
        self.position, self.velocity, self.acceleration, self.jerk = sign * s, sign * v, sign * a, sign * j
        # Carry the fraction: emitted total after cycle k is round(s_k); monotone against float
        # noise, capped at the target, which the last sample is exactly.
        total = np.minimum(np.maximum.accumulate(_rounded(s)), length)
        self.pulses = sign * np.diff(total)

    @property
    def duration(self) -> float:
        """Length of the continuous profile [s] (the pulses take ``len(self)`` whole cycles)."""
        return self.profile.duration

    def __len__(self) -> int:
        return len(self.pulses)

    def __iter__(self) -> Iterator[int]:
        return (int(p) for p in self.pulses)


class Jog:
    """A continuous move at speed ``v`` (signed) [pulses/s] until :meth:`~Jog.stop`.

    Iterate for the pulses of each cycle; the iteration ends with the cycle in which the axis
    comes to rest after ``stop()``. ``a_max`` None: constant speed (starts and stops at once);
    ``j_max`` None: trapezoid ramps. Limits as :class:`IndexMove`.
    """

    __slots__ = ("dt", "a_max", "j_max", "_sign", "_profile", "_cycle", "_emitted", "_stop_end", "_done")

    def __init__(self, v: float, a_max: float | None, j_max: float | None, dt: float):
        _check_limits(abs(v), a_max, j_max, dt)
        self.dt = dt
        self.a_max = a_max
        self.j_max = j_max
        self._sign = -1 if v < 0 else 1
        speed = abs(v)
        if a_max is None:
            self._profile = Profile([], v0=speed)
        else:
            self._profile = Profile(_ramp(speed, a_max, j_max))  # then cruises at its end speed
        self._cycle = 0
        self._emitted = 0
        self._stop_end: float | None = None
        self._done = False

    @property
    def time(self) -> float:
        """Time of the current cycle boundary [s]."""
        return self._cycle * self.dt

    @property
    def position(self) -> int:
        """Pulses emitted so far (signed)."""
        return self._sign * self._emitted

    @property
    def velocity(self) -> float:
        """Continuous velocity at the current cycle boundary [pulses/s] (signed)."""
        return self._sign * self._profile.state(self.time)[1]

    @property
    def acceleration(self) -> float:
        """Continuous acceleration at the current cycle boundary [pulses/s^2] (signed)."""
        return self._sign * self._profile.state(self.time)[2]

    def _stop_segments(self) -> tuple[list[Segment], float, float]:
        """Segments of the fastest stop from now, with the start position and speed."""
        s, v, a, _ = self._profile.state(self.time)
        if self.a_max is None or v <= 0.0:
            return [], s, 0.0
        if self.j_max is None:
            return [(v / self.a_max, -self.a_max, 0.0)], s, v
        # Still accelerating (a >= 0 on a ramp up): jerk -j until a = 0 gains a^2 / 2j of speed,
        # then the ordinary ramp down continues with the same jerk, so a stays continuous.
        first = (a / self.j_max, a, -self.j_max)
        return [first] + _ramp(-(v + a * a / (2.0 * self.j_max)), self.a_max, self.j_max), s, v

    def braking_distance(self) -> float:
        """Distance to rest if :meth:`stop` were called now [pulses] (>= 0)."""
        segments, s, v = self._stop_segments()
        return Profile(segments, s0=s, v0=v).end_position - s

    def stop(self) -> None:
        """Decelerate to rest from the current cycle boundary on."""
        if self._stop_end is not None:
            return
        segments, s, v = self._stop_segments()
        self._profile = Profile(segments, t0=self.time, s0=s, v0=v, rest=True)
        self._stop_end = self.time + self._profile.duration

    def __iter__(self) -> "Jog":
        return self

    def __next__(self) -> int:
        if self._done:
            raise StopIteration
        self._cycle += 1
        s = self._profile.state(self.time)[0]
        total = max(self._emitted, math.floor(s + 0.5))
        pulses = total - self._emitted
        self._emitted = total
        if self._stop_end is not None and self.time >= self._stop_end - 1e-12:
            self._done = True
        return self._sign * pulses


def linear_move(deltas: Sequence[int], v_path: float, a_path: float | None, j_path: float | None,
                dt: float) -> np.ndarray:
    """Per-cycle pulse vectors of a straight move by ``deltas`` [pulses] on up to 4 axes.

    ``v_path`` [pulses/s], ``a_path``, ``j_path`` limit the motion along the path (Euclidean
    length in pulses); None as for :class:`IndexMove`. Returns an int64 array (cycles, axes)
    whose column sums are ``deltas``; the cumulative sums stay within one pulse of the line.
    """
    d = [int(x) for x in deltas]
    if not 1 <= len(d) <= MAX_AXES:
        raise ValueError(f"1 to {MAX_AXES} axes, got {len(d)}")
    if max(abs(x) for x in d) >= 1 << 31:  # the chip's 32-bit counters; keeps 2 d M in int64
        raise ValueError(f"deltas must fit in 32-bit pulse counters, got {d}")
    _check_limits(v_path, a_path, j_path, dt)
    master = max(abs(x) for x in d)
    if master == 0:
        return np.zeros((0, len(d)), dtype=np.int64)
    length = math.sqrt(sum(x * x for x in d))
    profile = rest_to_rest(length, v_path, a_path, j_path)
    n = _cycles(profile.duration, dt)
    s = profile.sample(np.arange(n + 1) * dt)[0]
    m = np.minimum(np.maximum.accumulate(_rounded(master * s / length)), master)
    m[-1] = master
    # Bresenham rounding of each axis against the master's count, in integers, sign-symmetric.
    cumulative = np.stack([np.sign(x) * ((2 * abs(x) * m + master) // (2 * master)) for x in d], axis=1)
    return np.diff(cumulative, axis=0).astype(np.int64)
