"""Recording: signals into preallocated columnar arrays, metrics, and the run directory.

The servo loop copies the servo task's ``frame`` into one preallocated row per tick; nothing
else happens per tick. Columns, per axis ``X Y Z A B C``:

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
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from cnc_twin.axes import AXES
from cnc_twin.dsp.servo import FRAME_FIELDS, PERIOD_FIELDS
from cnc_twin.config import Scenario

_FLOAT_PERIOD_FIELDS = ("feed_override", "path_u", "path_ds", "force_setpoint", "force_depth", "feed_factor")
TRACE_FILE = "trace.parquet"
METRICS_FILE = "metrics.json"
SCENARIO_FILE = "scenario.yaml"
RECORDING_FILE = "recording.rrd"


class FrameBuffer:
    """Preallocated ``(n_ticks, frame_width)`` float64 rows, filled one per servo tick.

    Sized for the planned run; :meth:`grow` adds half again when a run takes longer (feed holds,
    missed exchanges), so a run never stops for lack of room.
    """

    def __init__(self, n_ticks: int, frame_width: int):
        self.rows = np.zeros((max(1, n_ticks), frame_width), dtype=np.float64)
        self.count = 0

    def grow(self) -> np.ndarray:
        """Enlarge by half (at least one period's worth); returns the new rows array."""
        extra = np.zeros((max(64, len(self.rows) // 2), self.rows.shape[1]), dtype=np.float64)
        self.rows = np.concatenate((self.rows, extra))
        return self.rows


@dataclass
class Trace:
    """The recorded signals as arrays. ``n`` = number of servo ticks.

    Attributes
    ----------
    time : (n,) [s]; period : (n,) int64
    command, actual, following_error : (n, 6) [counts]
    dac : (n, 6) int16 codes
    pad_force : (n,) [N]
    counts_per_unit : (6,) counts per m or rad, to convert counts to SI
    period_signals : per-period columns (state, fault, fifo_fill, ...), each (n,)
    """

    time: np.ndarray
    period: np.ndarray
    command: np.ndarray
    actual: np.ndarray
    following_error: np.ndarray
    dac: np.ndarray
    pad_force: np.ndarray
    counts_per_unit: np.ndarray
    period_signals: dict[str, np.ndarray]

    @classmethod
    def from_frames(cls, frames: FrameBuffer, *, servo_period: float, ticks_per_period: int,
                    counts_per_unit: np.ndarray) -> "Trace":
        rows = frames.rows[: frames.count]
        n_axes = len(AXES)
        groups = {name: rows[:, g * n_axes:(g + 1) * n_axes] for g, name in enumerate(FRAME_FIELDS)}
        ticks = np.arange(frames.count, dtype=np.int64)
        command = np.ascontiguousarray(groups["command"])
        actual = np.ascontiguousarray(groups["actual"])
        return cls(
            time=ticks * servo_period,
            period=ticks // ticks_per_period,
            command=command,
            actual=actual,
            following_error=command - actual,
            dac=groups["dac"].astype(np.int16),
            pad_force=np.ascontiguousarray(rows[:, len(FRAME_FIELDS) * n_axes]),
            counts_per_unit=np.asarray(counts_per_unit, dtype=np.float64),
            period_signals={
                name: (rows[:, len(FRAME_FIELDS) * n_axes + 1 + i].astype(
                    np.float64 if name in _FLOAT_PERIOD_FIELDS else np.int64))
                for i, name in enumerate(PERIOD_FIELDS)
            },
        )

    def __len__(self) -> int:
        return len(self.time)

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
        return sum(a.nbytes for a in self.columns().values())


_UNITS = {"time": "s", "period": "1", "command": "counts", "actual": "counts", "ferr": "counts",
          "dac": "code", "pad_force": "N", "state": "1", "fault": "1", "fifo_fill": "words",
          "feed_override": "1", "missed_exchanges": "1", "records_rejected": "1", "last_seq_executed": "1",
          "path_u": "1", "path_ds": "m", "force_state": "1", "force_setpoint": "N", "force_depth": "m",
          "feed_factor": "1", "mark": "1", "events": "1"}


def write_trace(trace: Trace, path: Path, *, scenario_name: str) -> None:
    """Write ``trace`` as Parquet, each field carrying its unit in the field metadata."""
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
