"""Recording: signals into preallocated columnar arrays, metrics, and the run directory.

The servo loop writes each tick's signals into preallocated typed columns (:class:`Recorder`),
and the per-period signals once per period; nothing else happens per tick. Each signal is kept
at its natural width and rate (:data:`TICK_BYTES`, :data:`PERIOD_DTYPE`), so a trace's memory is the raw bytes of what
was recorded; ``time``, ``period``, ``ferr`` and the per-tick view of the per-period signals are
computed when asked for. Columns, per axis ``X Y Z A B C``:

==================  ======  ===========================================================
column              unit    meaning
==================  ======  ===========================================================
``time``            s       simulated time at which the tick sampled its inputs
``period``          -       interpolation period counter
``command_<axis>``  counts  fine-interpolated position command
``actual_<axis>``   counts  encoder position (32-bit extended QEP)
``ferr_<axis>``     counts  following error, command - actual
``dac_<axis>``      code    DAC code, -2048..2047 (x 10/2048 V); with ``command_output:
                            pulse``, the step pulses sent in the tick (signed)
``pad_force``       N       load cell through the ADC, tared at servo-on
``state``           -       controller state (0 IDLE, 1 RUNNING, 2 FEED_HOLD, 3 STOPPING,
                            4 FAULT, 5 FINISHED), per interpolation period
``fault``           -       fault code (0 none, else :class:`~cnc_twin.whiteboard.status.FaultCode`)
``fifo_fill``       words   command FIFO fill after the period's exchange
``feed_override``   -       effective feed scale of the running move (0 while held)
``missed_exchanges`` -      periods so far whose exchange the planner missed (real-time mode)
``records_rejected`` -      records rejected so far (CRC, framing, sequence)
``last_seq_executed`` -     sequence number of the last record executed
``path_u``          -       NURBS parameter at the period's end (-1 when not on a curve)
``path_ds``         m       arc length commanded along the curve in the period
``force_state``     -       force loop (0 OFF, 1 SEEK, 2 RAMP, 3 TRACK, 4 RAMP_DOWN, 5 RETRACT)
``force_setpoint``  N       force setpoint in effect in the period
``force_depth``     m       force loop's push along the tool axis (negative: standing off)
``feed_factor``     -       feed adaptation factor (1, or reduced while the force error is large)
``mark``            -       number of the last Mark record executed (0 before any)
``events``          -       motion-chip events raised in the period: bits ``event << 4 axis``
                            (1 motion done, 2 home found, 4 + limit, 8 - limit; :mod:`cnc_twin.dsp.chip`)
==================  ======  ===========================================================

A run directory holds ``scenario.yaml`` (the file as written), ``trace.parquet`` and
``metrics.json``. It is written under a hidden temporary name and renamed when complete, so a
directory with the final name is always whole.
"""

from __future__ import annotations

import json
import math
import os
import shutil
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cnc_twin.core.axes import AXES
from cnc_twin.dsp.servo import PERIOD_FIELDS
from cnc_twin.core.config import Scenario

_FLOAT_PERIOD_FIELDS = ("feed_override", "path_u", "path_ds", "force_setpoint", "force_depth", "feed_factor")
_INT8_PERIOD_FIELDS = ("state", "fault", "force_state")
PERIOD_DTYPE = np.dtype([(name, np.float64 if name in _FLOAT_PERIOD_FIELDS else
                          np.int8 if name in _INT8_PERIOD_FIELDS else np.int32) for name in PERIOD_FIELDS])
"""one interpolation period's signals, packed, each at its natural width (75 bytes)"""
TICK_BYTES = 6 * 8 + 6 * 4 + 6 * 2 + 8
"""one servo tick's signals: command float64 x6, actual int32 x6, DAC code int16 x6, force float64"""
TRACE_FILE = "trace.parquet"
METRICS_FILE = "metrics.json"
SCENARIO_FILE = "scenario.yaml"
RECORDING_FILE = "recording.rrd"


class Recorder:
    """Preallocated typed columns, one row per servo tick and one per interpolation period.

    Sized for the planned run; :meth:`grow` adds half again when a run takes longer (feed holds,
    missed exchanges), so a run never stops for lack of room. Every period has
    ``ticks_per_period`` ticks, so tick ``t`` belongs to period ``t // ticks_per_period``.

    Attributes
    ----------
    command : (capacity, 6) float64 [counts]; actual : (capacity, 6) int32 [counts]
    dac : (capacity, 6) int16 [code]; pad_force : (capacity,) float64 [N]
    periods : (capacity / ticks_per_period,) structured array of :data:`PERIOD_DTYPE`
    count : ticks recorded so far

    ``scratch=True`` keeps one period only, rewritten every period (:meth:`row` maps every tick
    onto it): the same work per tick without the memory, to measure what recording costs
    (``cnc-twin bench``). It never needs to grow (:attr:`room` is unlimited).
    """

    def __init__(self, n_periods: int, ticks_per_period: int, n_axes: int = len(AXES), *, scratch: bool = False):
        self.ticks_per_period = ticks_per_period
        self.n_axes = n_axes
        self.count = 0
        self.scratch = scratch
        self._allocate(1 if scratch else max(1, n_periods))

    def _allocate(self, n_periods: int) -> None:
        n = n_periods * self.ticks_per_period
        self.command = np.zeros((n, self.n_axes), dtype=np.float64)
        self.actual = np.zeros((n, self.n_axes), dtype=np.int32)
        self.dac = np.zeros((n, self.n_axes), dtype=np.int16)
        self.pad_force = np.zeros(n, dtype=np.float64)
        self.periods = np.zeros(n_periods, dtype=PERIOD_DTYPE)

    @property
    def capacity(self) -> int:
        """Ticks the columns hold."""
        return len(self.pad_force)

    @property
    def room(self) -> float:
        """Ticks that can be recorded before :meth:`grow` is needed (unlimited for scratch)."""
        return math.inf if self.scratch else self.capacity

    def row(self, t: int) -> int:
        """The row that tick ``t`` is written to."""
        return t % self.ticks_per_period if self.scratch else t

    def grow(self) -> None:
        """Enlarge by half (at least 16 periods), keeping what was recorded."""
        old = (self.command, self.actual, self.dac, self.pad_force, self.periods)
        self._allocate(len(self.periods) + max(16, len(self.periods) // 2))
        for new, kept in zip((self.command, self.actual, self.dac, self.pad_force, self.periods), old):
            new[: len(kept)] = kept

    def record_tick(self, t: int, frame: list) -> None:
        """Row ``t`` from the servo task's ``frame`` (command x6, actual x6, DAC x6, force, ...)."""
        n = self.n_axes
        t = self.row(t)
        self.command[t] = frame[0:n]
        self.actual[t] = frame[n:2 * n]
        self.dac[t] = frame[2 * n:3 * n]
        self.pad_force[t] = frame[3 * n]

    def record_period(self, k: int, frame: list, first: int) -> None:
        """Period ``k``'s signals from ``frame[first:]`` (the per-period fields)."""
        self.periods[0 if self.scratch else k] = tuple(frame[first:])

    def trace(self, *, servo_period: float, counts_per_unit: np.ndarray, copy: bool) -> "Trace":
        """The ``count`` ticks recorded as a :class:`Trace`: copies (``copy=True``, for a run in
        progress), else views, or copies when the run used less than :data:`KEEP_FRACTION` of the
        room (so a trace never holds much more memory than its signals)."""
        n = min(self.count, self.capacity)  # a scratch recorder holds the last period only
        periods = -(-n // self.ticks_per_period)
        copy = copy or n < KEEP_FRACTION * self.capacity
        take = (lambda a, m: a[:m].copy()) if copy else (lambda a, m: a[:m])
        return Trace(command=take(self.command, n), actual=take(self.actual, n), dac=take(self.dac, n),
                     pad_force=take(self.pad_force, n), periods=take(self.periods, periods),
                     servo_period=servo_period, ticks_per_period=self.ticks_per_period,
                     counts_per_unit=np.asarray(counts_per_unit, dtype=np.float64))


KEEP_FRACTION = 0.9
"""a finished run's trace keeps the recorder's columns (views) when it filled at least this
fraction of them; otherwise it copies what was recorded and the recorder's room is freed"""


class PeriodSignals(Mapping):
    """The per-period signals, one value per servo tick on access (``signals["state"]``: (n,));
    stored once per period. Integer fields come out as int64, the others as float64."""

    def __init__(self, periods: np.ndarray, ticks_per_period: int, n_ticks: int):
        self._periods = periods
        self._tpp = ticks_per_period
        self._n = n_ticks

    def __getitem__(self, name: str) -> np.ndarray:
        values = self._periods[name]
        dtype = np.float64 if name in _FLOAT_PERIOD_FIELDS else np.int64
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

    Stored (see :data:`TICK_BYTES`, :data:`PERIOD_DTYPE`):
    command : (n, 6) float64 [counts]; actual : (n, 6) int32 [counts]; dac : (n, 6) int16 codes;
    pad_force : (n,) [N]; periods : per-period signals, structured, one row per period;
    counts_per_unit : (6,) counts per m or rad, to convert counts to SI.

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

    @property
    def time(self) -> np.ndarray:
        """Simulated time at which each tick sampled its inputs [s], shape ``(n,)``."""
        return np.arange(len(self), dtype=np.int64) * self.servo_period

    @property
    def period(self) -> np.ndarray:
        """Interpolation period of each tick, shape ``(n,)`` int64."""
        return np.arange(len(self), dtype=np.int64) // self.ticks_per_period

    @property
    def following_error(self) -> np.ndarray:
        """command - actual [counts], shape ``(n, 6)``."""
        return self.command - self.actual

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
        return cols

    def nbytes(self) -> int:
        """Bytes the stored signals take (views count their part of the recorder's columns)."""
        return sum(a.nbytes for a in (self.command, self.actual, self.dac, self.pad_force, self.periods))

    def raw_nbytes(self) -> int:
        """The raw bytes of the recorded signals: :data:`TICK_BYTES` per tick and one
        :data:`PERIOD_DTYPE` per period."""
        return len(self) * TICK_BYTES + len(self.periods) * PERIOD_DTYPE.itemsize

    def held_nbytes(self) -> int:
        """Bytes of memory the trace keeps alive (whole recorder columns when it holds views)."""
        arrays = (self.command, self.actual, self.dac, self.pad_force, self.periods)
        return sum((a.base if a.base is not None else a).nbytes for a in arrays)


@dataclass
class PeriodSamples:
    """The recorded signals at the last tick of periods ``first .. first + n - 1``: all that an
    export reads of a run (``n`` whole periods).

    command : (n, 6) float64 [counts]; actual : (n, 6) int32 [counts]; dac : (n, 6) int16 [code];
    pad_force : (n,) float64 [N]; periods : (n,) :data:`PERIOD_DTYPE`.
    """

    first: int
    command: np.ndarray
    actual: np.ndarray
    dac: np.ndarray
    pad_force: np.ndarray
    periods: np.ndarray

    @classmethod
    def take(cls, source, first: int, stop: int) -> "PeriodSamples":
        """Periods ``first .. stop - 1`` from a :class:`Trace` or a :class:`Recorder` (same
        column names), copied."""
        tpp = source.ticks_per_period
        ticks = np.arange(first, stop) * tpp + (tpp - 1)
        return cls(first=first, command=source.command[ticks], actual=source.actual[ticks],
                   dac=source.dac[ticks], pad_force=source.pad_force[ticks],
                   periods=source.periods[first:stop].copy())

    @classmethod
    def join(cls, parts: list["PeriodSamples"]) -> "PeriodSamples":
        """Consecutive stretches as one."""
        if len(parts) == 1:
            return parts[0]
        for a, b in zip(parts, parts[1:]):
            if b.first != a.first + len(a):
                raise ValueError(f"stretches not consecutive: periods {a.first}+{len(a)} then {b.first}")
        return cls(first=parts[0].first, **{name: np.concatenate([getattr(p, name) for p in parts])
                                            for name in ("command", "actual", "dac", "pad_force", "periods")})

    def __len__(self) -> int:
        return len(self.pad_force)


_UNITS = {"time": "s", "period": "1", "command": "counts", "actual": "counts", "ferr": "counts",
          "dac": "code", "pad_force": "N", "state": "1", "fault": "1", "fifo_fill": "words",
          "feed_override": "1", "missed_exchanges": "1", "records_rejected": "1", "last_seq_executed": "1",
          "path_u": "1", "path_ds": "m", "force_state": "1", "force_setpoint": "N", "force_depth": "m",
          "feed_factor": "1", "mark": "1", "events": "1"}


def write_trace(trace: Trace, path: Path, *, scenario_name: str) -> None:
    """Write ``trace`` as Parquet, each field carrying its unit in the field metadata."""
    import pyarrow as pa  # here: runs that write no files (sweeps, scripts) never import it
    import pyarrow.parquet as pq

    fields, arrays = [], []
    for name, values in trace.columns().items():
        unit = _UNITS[name.split("_")[0]] if name not in _UNITS else _UNITS[name]
        array = pa.array(values)
        fields.append(pa.field(name, array.type, metadata={"unit": unit}))
        arrays.append(array)
    meta = {
        "scenario": scenario_name,
        "axes": " ".join(AXES),
        "counts_per_unit": json.dumps(dict(zip(AXES, trace.counts_per_unit.tolist()))),
    }
    table = pa.Table.from_arrays(arrays, schema=pa.schema(fields, metadata=meta))
    pq.write_table(table, path)


def read_trace(path: Path) -> dict[str, np.ndarray]:
    """Read a trace file back as named columns."""
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    return {name: table.column(name).to_numpy() for name in table.column_names}


def compute_metrics(trace: Trace, scenario: Scenario, *, wall_time: float, dac_saturations: list[int],
                    warnings: dict[str, int], final_error_ticks: int = 1) -> dict[str, Any]:
    """Summary figures of a run; following errors in counts and in mm / deg."""
    sim_time = float(len(trace)) * scenario.timing.servo_period
    ferr: dict[str, Any] = {}
    final: dict[str, Any] = {}
    for i, cfg in enumerate(scenario.axes):
        e = trace.following_error[:, i]
        to_user = cfg.display_factor / cfg.counts_per_unit
        max_c = float(np.max(np.abs(e))) if len(e) else 0.0
        rms_c = float(np.sqrt(np.mean(e * e))) if len(e) else 0.0
        ferr[cfg.name] = {"max_counts": max_c, "rms_counts": rms_c, "max": max_c * to_user,
                          "rms": rms_c * to_user, "unit": cfg.display_unit}
        last = float(e[-final_error_ticks:].mean()) if len(e) else 0.0
        final[cfg.name] = {"counts": last, "value": last * to_user, "unit": cfg.display_unit}
    return {
        "scenario": scenario.name,
        "status": "complete",
        "sim_time_s": sim_time,
        "wall_time_s": wall_time,
        "real_time_factor": sim_time / wall_time if wall_time > 0 else math.inf,
        "servo_ticks": len(trace),
        "physics_steps": len(trace) * scenario.timing.substeps_per_tick,
        "following_error": ferr,
        "final_following_error": final,
        "dac_saturation_ticks": dict(zip(AXES, dac_saturations)),
        "pad_force_max_n": float(np.max(trace.pad_force)) if len(trace) else 0.0,
        "mujoco_warnings": warnings,
    }


def write_run_dir(run_dir: Path, *, scenario: Scenario, trace: Trace, metrics: dict[str, Any],
                  extra=None) -> Path:
    """Write the run directory atomically: a hidden temporary folder renamed when complete.

    ``extra(folder)`` may add files (the rerun recording) before the rename.
    """
    run_dir = Path(run_dir)
    run_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = run_dir.parent / f".{run_dir.name}.partial-{os.getpid()}"
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    try:
        (tmp / SCENARIO_FILE).write_text(scenario.source_text, encoding="utf-8")
        write_trace(trace, tmp / TRACE_FILE, scenario_name=scenario.name)
        if extra is not None:
            extra(tmp)
        (tmp / METRICS_FILE).write_text(json.dumps(metrics, indent=2) + "\n", encoding="utf-8")
        if run_dir.exists():
            raise FileExistsError(f"run directory {run_dir} already exists")
        os.replace(tmp, run_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return run_dir
