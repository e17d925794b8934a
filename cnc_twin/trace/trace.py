"""A run's recorded signals as arrays (:class:`~cnc_twin.trace.trace.Trace`), and the per-period
samples an export reads.

Each signal is kept at its natural width and rate (:data:`~cnc_twin.trace.layout.TICK_BYTES`,
:data:`~cnc_twin.trace.layout.PERIOD_DTYPE`), so a trace's memory is the raw bytes of what was
recorded; ``time``, ``period``, ``ferr`` and the per-tick view of the per-period signals are
computed when asked for.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from cnc_twin.core.axes import AXES
from cnc_twin.dsp.encoder import count_error
from cnc_twin.dsp.frame import PERIOD_FIELDS
from cnc_twin.trace.layout import FLOAT_PERIOD_FIELDS, TOOL_FIELDS, raw_bytes


PIECE_PERIODS = 1 << 14
"""periods in a piece of a trace worked through piece by piece (:meth:`Trace.chunks`): a row group
of its file (16.4 s at 1 ms), so a trace in memory and in its file are cut alike"""


class PeriodSignals(Mapping):
    """The per-period signals, one value per servo tick on access (``signals["state"]``: (n,));
    stored once per period. Integer fields come out as int64, the others as float64."""

    def __init__(self, periods: np.ndarray, ticks_per_period: int, n_ticks: int):
        self._periods = periods
        self._tpp = ticks_per_period
        self._n = n_ticks

    def __getitem__(self, name: str) -> np.ndarray:
        values = self._periods[name]
        dtype = np.float64 if name in FLOAT_PERIOD_FIELDS else np.int64
        return np.repeat(values.astype(dtype), self._tpp)[: self._n]

    def per_period(self, name: str) -> np.ndarray:
        """``name`` once per period, shape ``(periods,)``, at its stored width (a view)."""
        return self._periods[name]

    def __iter__(self):
        return iter(PERIOD_FIELDS)

    def __len__(self) -> int:
        return len(PERIOD_FIELDS)


@dataclass
class Trace:
    """The recorded signals as arrays. ``n`` = number of servo ticks.

    Stored (see :data:`~cnc_twin.trace.layout.TICK_BYTES`,
    :data:`~cnc_twin.trace.layout.PERIOD_DTYPE`): command : (n, 6) float64 [counts]; actual : (n, 6)
    int32 [counts]; dac : (n, 6) int16 codes; pad_force : (n,) [N]; periods : per-period signals,
    structured, one row per period; counts_per_unit : (6,) counts per m or rad, to convert counts to
    SI; tool : (periods, 6) float64 [m], the tool's true pose per period
    (:data:`~cnc_twin.trace.layout.TOOL_FIELDS`: tip, pivot, world frame).

    Computed on access: ``time`` (n,) [s], ``period`` (n,) int64, ``following_error`` (n, 6)
    [counts], ``period_signals`` (per tick, see :class:`PeriodSignals`).
    """

    command: np.ndarray
    actual: np.ndarray
    dac: np.ndarray
    pad_force: np.ndarray
    periods: np.ndarray
    servo_period: float
    ticks_per_period: int
    counts_per_unit: np.ndarray
    tool: np.ndarray
    first: int = 0
    """the run's tick of the first row (a piece of a trace, :meth:`chunks`; 0 for a whole run)"""

    @property
    def time(self) -> np.ndarray:
        """Simulated time at which each tick sampled its inputs [s], shape ``(n,)``."""
        return np.arange(self.first, self.first + len(self), dtype=np.int64) * self.servo_period

    @property
    def period(self) -> np.ndarray:
        """Interpolation period of each tick, shape ``(n,)`` int64."""
        return np.arange(self.first, self.first + len(self), dtype=np.int64) // self.ticks_per_period

    def chunks(self, periods: int = PIECE_PERIODS):
        """The trace in consecutive pieces of ``periods`` whole periods (the last may be shorter),
        each a :class:`Trace` of views with its ``first`` tick: what works through a long run
        piece by piece (the file's row groups, the metrics) holds one piece's temporaries at a
        time, not the whole run's."""
        tpp, n = self.ticks_per_period, len(self)
        for p0 in range(0, max(1, -(-n // tpp)), periods):
            t0, t1 = p0 * tpp, min(n, (p0 + periods) * tpp)
            yield Trace(command=self.command[t0:t1], actual=self.actual[t0:t1], dac=self.dac[t0:t1],
                        pad_force=self.pad_force[t0:t1], periods=self.periods[p0:p0 + periods],
                        servo_period=self.servo_period, ticks_per_period=tpp, counts_per_unit=self.counts_per_unit,
                        tool=self.tool[p0:p0 + periods], first=self.first + t0)

    @property
    def following_error(self) -> np.ndarray:
        """command - actual [counts], shape ``(n, 6)``, as the card computes it (32-bit wrap)."""
        return count_error.py_func(self.command, self.actual.astype(np.float64))

    def at_period_ends(self, name: str) -> np.ndarray:
        """A per-period signal at the end of each whole period, shape ``(whole periods,)``: what
        ``period_signals[name][ticks_per_period - 1::ticks_per_period]`` gives, without making it
        for every tick first (int64, or float64 for the float fields)."""
        values = self.periods[name][: self.whole_periods]
        return values.astype(np.float64 if name in FLOAT_PERIOD_FIELDS else np.int64)

    @property
    def period_signals(self) -> PeriodSignals:
        """The per-period signals, per tick on access."""
        return PeriodSignals(self.periods, self.ticks_per_period, len(self))

    def __len__(self) -> int:
        return len(self.pad_force)

    @property
    def whole_periods(self) -> int:
        """Periods recorded whole (every tick of them)."""
        return len(self) // self.ticks_per_period

    def columns(self) -> dict[str, np.ndarray]:
        """Flat named columns (see the module table)."""
        cols: dict[str, np.ndarray] = {"time": self.time, "period": self.period}
        for prefix, array in (("command", self.command), ("actual", self.actual),
                              ("ferr", self.following_error), ("dac", self.dac)):
            for i, axis in enumerate(AXES):
                cols[f"{prefix}_{axis}"] = array[:, i]
        cols["pad_force"] = self.pad_force
        cols.update(self.period_signals)
        for j, name in enumerate(TOOL_FIELDS):  # per tick, as the per-period signals
            cols[name] = np.repeat(self.tool[:, j], self.ticks_per_period)[: len(self)]
        return cols

    def nbytes(self) -> int:
        """Bytes the stored signals take (views count their part of the recorder's columns)."""
        return sum(a.nbytes for a in (self.command, self.actual, self.dac, self.pad_force, self.periods, self.tool))

    def raw_nbytes(self) -> int:
        """The raw bytes of the recorded signals: :data:`~cnc_twin.trace.layout.TICK_BYTES` per
        tick, one :data:`~cnc_twin.trace.layout.PERIOD_DTYPE` and
        :data:`~cnc_twin.trace.layout.TOOL_BYTES` per period."""
        return raw_bytes(len(self), len(self.periods))

    def held_nbytes(self) -> int:
        """Bytes of memory the trace keeps alive (whole recorder columns when it holds views)."""
        arrays = (self.command, self.actual, self.dac, self.pad_force, self.periods, self.tool)
        return sum((a.base if a.base is not None else a).nbytes for a in arrays)


@dataclass
class PeriodSamples:
    """The recorded signals at the last tick of periods ``first`` to ``first + n - 1``: all that an
    export and the path metrics read of a run (``n`` whole periods).

    command : (n, 6) float64 [counts]; actual : (n, 6) int32 [counts]; dac : (n, 6) int16 [code];
    pad_force : (n,) float64 [N]; periods : (n,) :data:`~cnc_twin.trace.layout.PERIOD_DTYPE`; tool :
    (n, 6) float64 [m] (:data:`~cnc_twin.trace.layout.TOOL_FIELDS`); counts_per_unit : (6,) as the
    trace's.
    """

    first: int
    command: np.ndarray
    actual: np.ndarray
    dac: np.ndarray
    pad_force: np.ndarray
    periods: np.ndarray
    tool: np.ndarray
    counts_per_unit: np.ndarray | None = None

    @classmethod
    def take(cls, source, first: int, stop: int) -> "PeriodSamples":
        """Periods ``first .. stop - 1`` of the run from a :class:`Trace` or a
        :class:`~cnc_twin.trace.recorder.Recorder` (same column names; either may hold a stretch of
        the run from its tick ``first``, a whole period), copied."""
        if hasattr(source, "period_samples"):  # a trace in its file: read from the row groups concerned
            return source.period_samples(first, stop)
        tpp = source.ticks_per_period
        base = source.first // tpp  # the period of the source's first row
        ticks = np.arange(first - base, stop - base) * tpp + (tpp - 1)
        rows = slice(first - base, stop - base)
        return cls(first=first, command=source.command[ticks], actual=source.actual[ticks],
                   dac=source.dac[ticks], pad_force=source.pad_force[ticks],
                   periods=source.periods[rows].copy(), tool=source.tool[rows].copy(),
                   counts_per_unit=getattr(source, "counts_per_unit", None))

    @classmethod
    def whole(cls, trace: Trace) -> "PeriodSamples":
        """Every whole period of ``trace`` (a run, or a piece of one)."""
        base = trace.first // trace.ticks_per_period
        return cls.take(trace, base, base + trace.whole_periods)

    @classmethod
    def join(cls, parts: list["PeriodSamples"]) -> "PeriodSamples":
        """Consecutive stretches as one."""
        if len(parts) == 1:
            return parts[0]
        for a, b in zip(parts, parts[1:]):
            if b.first != a.first + len(a):
                raise ValueError(f"stretches not consecutive: periods {a.first}+{len(a)} then {b.first}")
        return cls(first=parts[0].first, counts_per_unit=parts[0].counts_per_unit,
                   **{name: np.concatenate([getattr(p, name) for p in parts]) for name in SAMPLED})

    def slice(self, first: int, stop: int) -> "PeriodSamples":
        """Periods ``first .. stop - 1`` of the run (within these), as views."""
        rows = slice(first - self.first, stop - self.first)
        return PeriodSamples(first=first, counts_per_unit=self.counts_per_unit,
                             **{name: getattr(self, name)[rows] for name in SAMPLED})

    def signal(self, name: str) -> np.ndarray:
        """A per-period field as :meth:`Trace.at_period_ends` gives it (int64, or float64 for the float fields)."""
        return self.periods[name].astype(np.float64 if name in FLOAT_PERIOD_FIELDS else np.int64)

    def __len__(self) -> int:
        return len(self.pad_force)


SAMPLED = ("command", "actual", "dac", "pad_force", "periods", "tool")
"""the arrays of a :class:`PeriodSamples`, one row per period"""
