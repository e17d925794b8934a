"""A trace as Parquet: one row per servo tick, each field carrying its unit in the field metadata.

The file is written in row groups of :data:`ROW_GROUP_PERIODS` periods by :class:`TraceWriter`,
whole (:func:`write_trace`) or while the run runs (a long run's recorder hands it each stretch it
no longer holds, :class:`~cnc_twin.trace.recorder.Recorder`): either way the same row groups, the
same bytes.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from cnc_twin.core.axes import AXES
from cnc_twin.trace.layout import column_unit
from cnc_twin.trace.trace import PIECE_PERIODS, Trace


ROW_GROUP_PERIODS = PIECE_PERIODS
"""periods per row group (16.4 s at 1 ms, 65 536 rows at 4 ticks a period): the columns of one are
made at a time; a piece of the trace as the metrics read it"""


class TraceWriter:
    """Writes a trace to ``path`` piece by piece, in row groups of ``group_periods`` periods.

    ``write(piece)`` takes consecutive pieces of whole periods (the last piece of a run may end
    in a period); each is cut into row groups at multiples of ``group_periods`` from the run's
    start, so a trace written in pieces gives the same file as written whole, as long as every
    piece but the last is a multiple of ``group_periods`` long. The file is created at the first
    piece; :meth:`close` writes its footer (a file is readable once closed)."""

    def __init__(self, path: Path, *, scenario_name: str, counts_per_unit: np.ndarray,
                 group_periods: int = ROW_GROUP_PERIODS):
        self.path = Path(path)
        self.group_periods = group_periods
        self.meta = {
            "scenario": scenario_name,
            "axes": " ".join(AXES),
            "counts_per_unit": json.dumps(dict(zip(AXES, np.asarray(counts_per_unit).tolist()))),
        }
        self._writer = None
        self.ticks = 0
        """ticks written so far"""
        self.closed = False
        """True once :meth:`close` wrote the footer"""

    def write(self, trace: Trace) -> None:
        """Append ``trace`` (a piece that begins where the last ended: ``trace.first == ticks``)."""
        import pyarrow as pa  # here: runs that write no files (sweeps, scripts) never import it
        import pyarrow.parquet as pq

        if trace.first != self.ticks:
            raise ValueError(f"trace piece starts at tick {trace.first}, the file ends at {self.ticks}")
        for piece in trace.chunks(self.group_periods):
            fields, arrays = [], []
            for name, values in piece.columns().items():
                array = _arrow_array(pa, values)
                fields.append(pa.field(name, array.type, metadata={"unit": column_unit(name)}))
                arrays.append(array)
            table = pa.Table.from_arrays(arrays, schema=pa.schema(fields, metadata=self.meta))
            if self._writer is None:
                # no dictionaries: the columns are measured values, nearly all distinct; trying
                # one per column took 0.4 s of a 184 000-tick trace's 0.55 s and made it larger
                self._writer = pq.ParquetWriter(self.path, table.schema, use_dictionary=False)
            self._writer.write_table(table)
        self.ticks += len(trace)

    @property
    def started(self) -> bool:
        """True once the file exists (a piece was written)."""
        return self._writer is not None

    def close(self) -> None:
        """Write the footer (the file is whole and readable from then on); idempotent."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None
        self.closed = True


def write_trace(trace: Trace, path: Path, *, scenario_name: str, group_periods: int = ROW_GROUP_PERIODS) -> None:
    """Write ``trace`` as Parquet, each field carrying its unit in the field metadata, a row group
    per ``group_periods`` periods (the flat columns of one are made at a time: a long run's
    whole set would take three times its trace)."""
    writer = TraceWriter(path, scenario_name=scenario_name, counts_per_unit=trace.counts_per_unit,
                         group_periods=group_periods)
    try:
        writer.write(trace)
    finally:
        writer.close()


def _arrow_array(pa, values: np.ndarray):
    """A numeric column as an Arrow array over the same bytes.

    Not ``pa.array``: on a NumPy array it imports pandas (0.4 s of a run's start) to ask whether
    the array is a pandas Series. Trace columns are plain numbers (no nulls, no booleans, which
    Arrow packs as bits), so the column's own buffer is the Arrow array's data buffer.
    """
    values = np.ascontiguousarray(values)
    if values.dtype.kind not in "iuf":
        return pa.array(values)
    return pa.Array.from_buffers(pa.from_numpy_dtype(values.dtype), len(values), [None, pa.py_buffer(values)])


def read_trace(path: Path) -> dict[str, np.ndarray]:
    """Read a trace file back as named columns."""
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    return {name: table.column(name).to_numpy() for name in table.column_names}
