"""Coarse interpolation: one setpoint per axis per interpolation period, from segments.

Inputs: segments (see :mod:`cnc_twin.planner.segments`) in machine positions [m | rad].
Output per period: the commanded position at the *end* of the period [counts], relative to the
encoder's power-on position, for the servo task to fine-interpolate towards.

Algorithm, once per period, in segment ``seg`` at period index ``k`` (0-based)::

    t = (k + 1) * T                    # end of this period
    s = 1 exactly on the last period, else profile.evaluate(t).s
    p = start + s * (end - start)      # per axis, [m | rad]
    counts = (p - power_on) * counts_per_unit
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Sequence

from cnc_twin.planner.segments import DwellSegment, MoveSegment, Segment


class SegmentInterpolator:
    """Walks a queue of segments one interpolation period at a time.

    Parameters
    ----------
    counts_per_unit : per axis encoder resolution, shape ``(6,)``.
    power_on : per axis position where the encoders were cleared [m | rad], shape ``(6,)``.
    period : interpolation period [s].
    """

    def __init__(self, *, counts_per_unit: Sequence[float], power_on: Sequence[float], period: float):
        self.counts_per_unit = [float(c) for c in counts_per_unit]
        self.power_on = [float(p) for p in power_on]
        self.period = period
        self._queue: deque[Segment] = deque()
        self._segment: Segment | None = None
        self._k = 0
        self._hold = [0.0] * len(self.counts_per_unit)
        self.segments_done = 0

    def extend(self, segments: Iterable[Segment]) -> None:
        """Append segments to the queue."""
        self._queue.extend(segments)

    @property
    def idle(self) -> bool:
        """True when no segment is running or queued."""
        return self._segment is None and not self._queue

    def next_period(self) -> list[float]:
        """Commanded position at the end of the coming period [counts], shape ``(6,)``.

        With nothing to do it holds the last commanded position.
        """
        if self._segment is None:
            if not self._queue:
                return list(self._hold)
            self._segment = self._queue.popleft()
            self._k = 0
        seg = self._segment
        self._k += 1
        if isinstance(seg, MoveSegment):
            if self._k >= seg.periods:
                positions = seg.end
            else:
                s = seg.profile.evaluate(self._k * self.period)[0]
                positions = [p0 + s * (p1 - p0) for p0, p1 in zip(seg.start, seg.end)]
        elif isinstance(seg, DwellSegment):
            positions = seg.position
        else:  # pragma: no cover - a new segment type without interpolation is a programming error
            raise TypeError(f"cannot interpolate {type(seg).__name__}")
        if self._k >= seg.periods:
            self._segment = None
            self.segments_done += 1
        self._hold = [
            (p - zero) * cpu for p, zero, cpu in zip(positions, self.power_on, self.counts_per_unit)
        ]
        return list(self._hold)
