"""A run's trace read back from its ``trace.parquet``
(:class:`~cnc_twin.trace.trace_file.TraceFile`): a long run's trace, which the recorder wrote to the
file while the run ran and does not hold in memory.

Its pieces (:meth:`TraceFile.chunks`, one per row group) are :class:`~cnc_twin.trace.trace.Trace`
objects as the recorder held them, bit for bit: the file's per-tick columns of per-period signals
and tool poses give back one value per period, at the recorded width. What reads a run piece by
piece (the metrics, an export) holds one row group at a time; the whole-run arrays
(``command``, ``actual``, ...) are read once, when first asked for.
"""

from __future__ import annotations

import shutil
import weakref
from pathlib import Path

import numpy as np

from cnc_twin.core.axes import AXES
from cnc_twin.trace.layout import PERIOD_DTYPE, TOOL_FIELDS, raw_bytes
from cnc_twin.trace.trace import PIECE_PERIODS, PeriodSamples, Trace

WHOLE_ARRAYS = ("command", "actual", "dac", "pad_force", "periods", "tool", "time", "period", "following_error",
                "period_signals", "columns", "at_period_ends", "nbytes", "held_nbytes")
"""what a :class:`~cnc_twin.trace.trace.Trace` has of the whole run: read from the file on first
use"""


class TraceFile:
    """The trace in ``path`` (written by :class:`~cnc_twin.trace.parquet.TraceWriter`), with the
    run's ``servo_period`` [s], ``ticks_per_period`` and ``counts_per_unit`` (6,).

    Used as a :class:`~cnc_twin.trace.trace.Trace`: ``len``, :attr:`whole_periods`, :meth:`chunks`
    and :meth:`period_samples` read it a row group at a time; the other attributes of a
    :class:`~cnc_twin.trace.trace.Trace` (``command``, ``period_signals``, ...) read the whole file
    once into one (:meth:`load`)."""

    def __init__(self, path: Path, *, servo_period: float, ticks_per_period: int, counts_per_unit: np.ndarray,
                 temporary_folder: Path | None = None, staged: bool = True):
        import pyarrow.parquet as pq

        self.path = Path(path)
        self.staged = staged
        """True while the file is the run's own, not yet in a run directory: writing the run
        directory moves it in (:meth:`move_to`); else it copies it"""
        if temporary_folder is not None:  # the run's own folder, gone with this object
            weakref.finalize(self, shutil.rmtree, str(temporary_folder), True)
        self.servo_period = servo_period
        self.ticks_per_period = ticks_per_period
        self.counts_per_unit = np.asarray(counts_per_unit, dtype=np.float64)
        self.first = 0
        meta = pq.ParquetFile(self.path).metadata
        self._rows = meta.num_rows
        self._groups = [meta.row_group(i).num_rows for i in range(meta.num_row_groups)]
        self._whole: Trace | None = None

    def __len__(self) -> int:
        return self._rows

    def move_to(self, path: Path) -> None:
        """The file into ``path`` (a run directory's ``trace.parquet``): moved if staged (renamed
        on one file system), else copied; this trace reads it there from then on."""
        if self.staged:
            shutil.move(self.path, path)
            self.path, self.staged = Path(path), False
        else:
            shutil.copyfile(self.path, path)

    @property
    def whole_periods(self) -> int:
        """Periods recorded whole (every tick of them)."""
        return self._rows // self.ticks_per_period

    def raw_nbytes(self) -> int:
        """As :meth:`~cnc_twin.trace.trace.Trace.raw_nbytes`."""
        return raw_bytes(self._rows, -(-self._rows // self.ticks_per_period))

    def chunks(self, periods: int = PIECE_PERIODS):
        """The trace in consecutive pieces of ``periods`` whole periods (the last may be shorter),
        each a :class:`~cnc_twin.trace.trace.Trace` with its ``first`` tick, as
        :meth:`~cnc_twin.trace.trace.Trace.chunks` cuts the trace in memory (so what sums piece by
        piece sums the same numbers in the same order), read a row group at a time."""
        held: list[Trace] = []
        held_periods = 0
        for piece in self.row_groups():
            held.append(piece)
            held_periods += len(piece.periods)
            while held_periods > periods:  # a whole piece, and more after it
                whole = _joined(held)
                yield next(whole.chunks(periods))
                rest = _rest(whole, periods)
                held, held_periods = [rest], len(rest.periods)
        if held or not self._groups:
            yield from (_joined(held) if held else self._empty()).chunks(periods)

    def row_groups(self):
        """The file's row groups in order, each as a :class:`~cnc_twin.trace.trace.Trace` with its
        ``first`` tick."""
        import pyarrow.parquet as pq

        source = pq.ParquetFile(self.path)
        first = 0
        for i, rows in enumerate(self._groups):
            yield self._piece(source.read_row_group(i, columns=STORED), first)
            first += rows

    def _empty(self) -> Trace:
        return Trace(command=np.zeros((0, 6)), actual=np.zeros((0, 6), np.int32), dac=np.zeros((0, 6), np.int16),
                     pad_force=np.zeros(0), periods=np.zeros(0, PERIOD_DTYPE), tool=np.zeros((0, 6)),
                     servo_period=self.servo_period, ticks_per_period=self.ticks_per_period,
                     counts_per_unit=self.counts_per_unit)

    def _piece(self, table, first: int) -> Trace:
        """A row group's table as a :class:`Trace` beginning at tick ``first``."""
        tpp = self.ticks_per_period

        def column(name: str) -> np.ndarray:
            return table.column(name).to_numpy()

        def axes(prefix: str) -> np.ndarray:
            return np.column_stack([column(f"{prefix}_{axis}") for axis in AXES])

        n = table.num_rows
        periods = np.empty(-(-n // tpp), dtype=PERIOD_DTYPE)
        for name in PERIOD_DTYPE.names:  # stored per tick, the same value through the period
            periods[name] = column(name)[::tpp]
        tool = np.column_stack([column(name)[::tpp] for name in TOOL_FIELDS]) if n else np.zeros((0, 6))
        return Trace(command=axes("command"), actual=axes("actual"), dac=axes("dac"), pad_force=column("pad_force"),
                     periods=periods, tool=tool, servo_period=self.servo_period, ticks_per_period=tpp,
                     counts_per_unit=self.counts_per_unit, first=first)

    def period_samples(self, first: int, stop: int) -> PeriodSamples:
        """:meth:`~cnc_twin.trace.trace.PeriodSamples.take` of periods ``first .. stop - 1``, from
        the row groups they are in."""
        parts = []
        for piece in self.row_groups():
            p0 = piece.first // self.ticks_per_period
            p1 = p0 + piece.whole_periods
            if p1 > first and p0 < stop:
                parts.append(PeriodSamples.take(piece, max(first, p0), min(stop, p1)))
            if p1 >= stop:
                break
        return PeriodSamples.join(parts) if parts else PeriodSamples.take(self._empty(), 0, 0)

    def load(self) -> Trace:
        """The whole trace in memory (read once, kept)."""
        if self._whole is None:
            self._whole = _joined(list(self.row_groups())) if self._groups else self._empty()
        return self._whole

    def __getattr__(self, name: str):
        if name in WHOLE_ARRAYS:
            return getattr(self.load(), name)
        raise AttributeError(name)


SIGNALS = ("command", "actual", "dac", "pad_force", "periods", "tool")
"""what a :class:`~cnc_twin.trace.trace.Trace` stores"""
STORED = ([f"{prefix}_{axis}" for prefix in ("command", "actual", "dac") for axis in AXES]
          + ["pad_force", *PERIOD_DTYPE.names, *TOOL_FIELDS])
"""the file's columns a :class:`~cnc_twin.trace.trace.Trace` is made of (not those computed from
them: time, period, ferr)"""


def _joined(pieces: list[Trace]) -> Trace:
    """Consecutive pieces (each but the last of whole periods) as one."""
    if len(pieces) == 1:
        return pieces[0]
    first = pieces[0]
    return Trace(**{name: np.concatenate([getattr(p, name) for p in pieces]) for name in SIGNALS},
                 servo_period=first.servo_period, ticks_per_period=first.ticks_per_period,
                 counts_per_unit=first.counts_per_unit, first=first.first)


def _rest(trace: Trace, periods: int) -> Trace | None:
    """What follows ``trace``'s first ``periods`` periods, copied (None if nothing does)."""
    tpp = trace.ticks_per_period
    t0 = periods * tpp
    if t0 >= len(trace):
        return None
    return Trace(**{name: getattr(trace, name)[t0 if name not in ("periods", "tool") else periods:].copy()
                    for name in SIGNALS},
                 servo_period=trace.servo_period, ticks_per_period=tpp, counts_per_unit=trace.counts_per_unit,
                 first=trace.first + t0)
