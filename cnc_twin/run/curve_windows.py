"""One pass over a run's trace, a piece at a time, finding its curve runs as they end.

The trace's periods on a curve (``path_u >= 0``) fall into runs, one per card curve, in program
order: a run ends where the tool leaves the curve or the parameter starts again from the next
curve's beginning. :func:`curve_windows` reads the trace a piece at a time
(:meth:`~cnc_twin.trace.trace.Trace.chunks`, or a long run's file row group by row group) and
yields, for every piece, its periods' samples and the curve runs that ended in it, each with its
window (from :data:`BEFORE` periods before the run to its last period): what measures a run of
hours holds one piece and the open run's periods, not the whole run.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import NamedTuple

import numpy as np

from cnc_twin.trace.trace import PIECE_PERIODS, PeriodSamples, Trace

BEFORE = 2
"""periods before a curve run that its window holds too (the axis peaks' differences begin there)"""


class CurveRun(NamedTuple):
    """A curve run: periods ``first`` to ``stop - 1`` of the run, and ``window``: the samples of
    periods ``max(0, first - BEFORE)`` to ``stop - 1`` with ``path_u`` -1 before ``first`` (a copy)."""

    first: int
    stop: int
    window: PeriodSamples


def run_bounds(u: np.ndarray, before: float = -1.0, first: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Where curve runs start and where they stop (the period after their last) among periods
    ``first ..`` whose ``path_u`` is ``u``; ``before``: the ``path_u`` of the period before them.
    Run periods, each (k,) int64 ascending."""
    prev = np.concatenate([[before], u[:-1]])
    on, prev_on = u >= 0.0, prev >= 0.0
    restart = on & prev_on & (u < prev)
    starts = np.flatnonzero(on & (~prev_on | restart)) + first
    stops = np.flatnonzero(prev_on & (~on | restart)) + first
    return starts, stops


def curve_windows(trace: Trace, periods: int = PIECE_PERIODS) -> Iterator[tuple[PeriodSamples, list[CurveRun]]]:
    """``(samples, runs)`` for each piece of ``trace`` (``periods`` long) in order: the piece's
    whole periods' samples, and the curve runs that ended within it (the last run also at the
    trace's end). The runs and their windows do not depend on ``periods``."""
    held: list[PeriodSamples] = []  # from the open run's window (or the last BEFORE periods) on
    start = None  # the open run's first period
    last_u = -1.0
    end = 0
    for piece in trace.chunks(periods):
        samples = PeriodSamples.whole(piece)
        if not len(samples):
            continue
        u = samples.periods["path_u"]
        starts, stops = run_bounds(u, last_u, samples.first)
        last_u, end = float(u[-1]), samples.first + len(samples)
        held.append(samples)
        runs = []
        # a run that restarts stops and starts at the same period: its stop first
        for k, is_start in sorted([(k, False) for k in stops.tolist()] + [(k, True) for k in starts.tolist()]):
            if not is_start:
                runs.append(_run(held, start, k))
                start = None
            else:
                start = k
        # what a window may still need: the open run's periods and the BEFORE periods before it
        keep = (start if start is not None else end) - BEFORE
        while held[0].first + len(held[0]) <= keep:
            held.pop(0)
        held[0] = held[0].slice(max(keep, held[0].first), held[0].first + len(held[0]))
        yield samples, runs
    if start is not None:
        yield held[-1].slice(end, end), [_run(held, start, end)]


def _run(held: list[PeriodSamples], first: int, stop: int) -> CurveRun:
    begin = max(0, first - BEFORE, held[0].first)
    parts = [p.slice(max(begin, p.first), min(stop, p.first + len(p))) for p in held
             if p.first < stop and p.first + len(p) > begin]
    window = PeriodSamples.join(parts + [parts[-1].slice(stop, stop)])  # a copy, even of one part
    window.periods["path_u"][:first - begin] = -1.0
    return CurveRun(first, stop, window)
