"""The recorder: signals into preallocated typed columns, one row per servo tick and one per period.

The servo loop writes each tick's signals into the columns and the per-period signals once per
period; nothing else happens per tick (layout: :mod:`cnc_twin.trace.layout`). A long run's
recorder holds a window of the run, :data:`SPILL_GROUPS` row groups of its file: when the window
is full, what it holds goes to ``trace.parquet`` (:class:`~cnc_twin.trace.parquet.TraceWriter`)
and the window starts again, so its memory does not grow with the run.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from cnc_twin.core.axes import AXES
from cnc_twin.trace.layout import PERIOD_DTYPE, TICK_BYTES, TOOL_FIELDS
from cnc_twin.trace.trace import PIECE_PERIODS, Trace

SPILL_GROUPS = 4
"""a spilling recorder's window, in row groups of its file (4 x 16 384 periods: 65.5 s at 1 ms,
35 MB at 4 ticks a period)"""


class Recorder:
    """Preallocated typed columns, one row per servo tick and one per interpolation period.

    Sized for the planned run; :meth:`grow` adds half again when a run takes longer (feed holds,
    missed exchanges), so a run never stops for lack of room. Every period has
    ``ticks_per_period`` ticks, so tick ``t`` belongs to period ``t // ticks_per_period``.

    Attributes
    ----------
    command : (capacity, 6) float64 [counts]; actual : (capacity, 6) int32 [counts]
    dac : (capacity, 6) int16 [code]; pad_force : (capacity,) float64 [N]
    periods : (capacity / ticks_per_period,) structured array of
    :data:`~cnc_twin.trace.layout.PERIOD_DTYPE` tool : (capacity / ticks_per_period, 6) float64 [m]:
    the tool's true pose at each period's last tick (:data:`~cnc_twin.trace.layout.TOOL_FIELDS`),
    written by the plant's side count : ticks recorded so far

    first : the run's tick of row 0 (0 until the window moves on)
    servo_period : [s] of a tick (the file's ``time`` column)

    ``spill``: makes the :class:`~cnc_twin.trace.parquet.TraceWriter` of the run's file, called
    when the run first outgrows its window (:data:`SPILL_GROUPS` of the writer's row groups); from
    then on :meth:`make_room` hands the window's periods to it and starts the window again. The
    rows, periods and tool rows of tick ``t`` / period ``k`` are :meth:`row`, :meth:`period_row`.

    ``scratch=True`` keeps one period only, rewritten every period (:meth:`row` maps every tick
    onto it): the same work per tick without the memory, to measure what recording costs
    (``cnc-twin bench``). It never needs to grow (:attr:`room` is unlimited).
    """

    def __init__(self, n_periods: int, ticks_per_period: int, n_axes: int = len(AXES), *, scratch: bool = False,
                 spill: Callable | None = None, spill_group_periods: int = PIECE_PERIODS, servo_period: float = 0.0):
        self.ticks_per_period = ticks_per_period
        self.servo_period = servo_period
        self.n_axes = n_axes
        self.count = 0
        self.first = 0
        self.scratch = scratch
        self.spill = None if scratch else spill
        self.window = SPILL_GROUPS * spill_group_periods
        """[periods] the most a spilling recorder holds"""
        self.writer = None
        """the run's file once the run outgrew the window (see ``spill``)"""
        n_periods = max(1, n_periods)
        if self.spill is not None:
            n_periods = min(n_periods, self.window)
        self._allocate(1 if scratch else n_periods)

    def _allocate(self, n_periods: int) -> None:
        n = n_periods * self.ticks_per_period
        self.command = np.zeros((n, self.n_axes), dtype=np.float64)
        self.actual = np.zeros((n, self.n_axes), dtype=np.int32)
        self.dac = np.zeros((n, self.n_axes), dtype=np.int16)
        self.pad_force = np.zeros(n, dtype=np.float64)
        self.periods = np.zeros(n_periods, dtype=PERIOD_DTYPE)
        self.tool = np.zeros((n_periods, len(TOOL_FIELDS)), dtype=np.float64)

    @property
    def capacity(self) -> int:
        """Ticks the columns hold."""
        return len(self.pad_force)

    @property
    def room(self) -> float:
        """The run's tick up to which the columns have room (unlimited for scratch): from there,
        :meth:`make_room` first."""
        return math.inf if self.scratch else self.first + self.capacity

    def row(self, t: int) -> int:
        """The row that tick ``t`` is written to."""
        return t % self.ticks_per_period if self.scratch else t - self.first

    def period_row(self, k: int) -> int:
        """The row of ``periods`` (and ``tool``) of period ``k``."""
        return 0 if self.scratch else k - self.first // self.ticks_per_period

    def make_room(self, t: int) -> None:
        """Room for the period from tick ``t`` (a period's first tick, the columns full up to
        it): the columns grown, or a spilling recorder's window written to its file and begun
        again at ``t``."""
        if self.spill is None or len(self.periods) < self.window:
            self.grow()
            return
        if self.writer is None:
            self.writer = self.spill()
        self.count = t
        self.writer.write(self._held(t - self.first))
        self.first = t

    @property
    def spilled(self) -> bool:
        """True when the run outgrew the window: its trace is in the file, not here."""
        return self.writer is not None

    def finish_file(self) -> None:
        """A spilling recorder's last stretch (the ``count`` ticks recorded) into its file, which
        is then closed, whole (once; the footer written even when the write fails)."""
        if self.writer is not None and not self.writer.closed:
            try:
                self.writer.write(self._held(self.count - self.first))
            finally:
                self.writer.close()

    def _held(self, n: int) -> Trace:
        """The first ``n`` rows held, as a :class:`Trace` of views from tick :attr:`first`."""
        periods = -(-n // self.ticks_per_period)
        return Trace(command=self.command[:n], actual=self.actual[:n], dac=self.dac[:n], pad_force=self.pad_force[:n],
                     periods=self.periods[:periods], tool=self.tool[:periods], servo_period=self.servo_period,
                     ticks_per_period=self.ticks_per_period, counts_per_unit=np.zeros(self.n_axes), first=self.first)

    def grow(self) -> None:
        """Enlarge by half (at least 16 periods), keeping what was recorded."""
        old = (self.command, self.actual, self.dac, self.pad_force, self.periods, self.tool)
        periods = len(self.periods) + max(16, len(self.periods) // 2)
        self._allocate(periods if self.spill is None else min(periods, self.window))
        for new, kept in zip((self.command, self.actual, self.dac, self.pad_force, self.periods, self.tool), old):
            new[: len(kept)] = kept

    def record_tick(self, t: int, frame: list) -> None:
        """Row ``t`` from the servo task's ``frame`` (command x6, actual x6, DAC x6, force, ...)."""
        n = self.n_axes
        t = self.row(t)
        self.command[t] = frame[0:n]
        self.actual[t] = frame[n:2 * n]
        self.dac[t] = frame[2 * n:3 * n]
        self.pad_force[t] = frame[3 * n]

    def tool_row(self, t: int) -> np.ndarray:
        """The row of ``tool`` for the period of tick ``t`` (shape ``(6,)``, a view)."""
        return self.tool[self.period_row(t // self.ticks_per_period)]

    def record_period(self, k: int, frame: list, first: int) -> None:
        """Period ``k``'s signals from ``frame[first:]`` (the per-period fields)."""
        self.periods[self.period_row(k)] = tuple(frame[first:])

    def trace(self, *, servo_period: float, counts_per_unit: np.ndarray, copy: bool) -> Trace:
        """The ``count`` ticks recorded as a :class:`~cnc_twin.trace.trace.Trace`: copies
        (``copy=True``, for a run in progress), else views, or copies when the run used less than
        :data:`KEEP_FRACTION` of the room (so a trace never holds much more memory than its
        signals)."""
        n = min(self.count - self.first, self.capacity)  # a scratch recorder holds the last period only
        periods = -(-n // self.ticks_per_period)
        # a long run's trace keeps its columns however much room is left: a copy would hold the
        # signals twice at once (the columns hold at most 1.5 times them, see grow)
        small = n * TICK_BYTES <= KEEP_ALWAYS_BYTES
        copy = copy or (small and n < KEEP_FRACTION * self.capacity)
        take = (lambda a, m: a[:m].copy()) if copy else (lambda a, m: a[:m])
        return Trace(command=take(self.command, n), actual=take(self.actual, n), dac=take(self.dac, n),
                     pad_force=take(self.pad_force, n), periods=take(self.periods, periods),
                     tool=take(self.tool, periods),
                     servo_period=servo_period, ticks_per_period=self.ticks_per_period,
                     counts_per_unit=np.asarray(counts_per_unit, dtype=np.float64), first=self.first)


KEEP_FRACTION = 0.9
"""a finished run's trace keeps the recorder's columns (views) when it filled at least this
fraction of them; otherwise it copies what was recorded and the recorder's room is freed"""
KEEP_ALWAYS_BYTES = 64 << 20
"""a trace of more signal bytes than this keeps the recorder's columns whatever their room"""
