"""A trace as Parquet: one row per servo tick, each field carrying its unit in the field metadata."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from cnc_twin.core.axes import AXES
from cnc_twin.trace.layout import column_unit
from cnc_twin.trace.trace import Trace


ROW_GROUP_PERIODS = 1 << 14
"""periods per row group (16.4 s at 1 ms, 65 536 rows at 4 ticks a period): the columns of one are made at a time"""


def write_trace(trace: Trace, path: Path, *, scenario_name: str, group_periods: int = ROW_GROUP_PERIODS) -> None:
    """Write ``trace`` as Parquet, each field carrying its unit in the field metadata, a row group
    per ``group_periods`` periods (the flat columns of one are made at a time: a long run's
    whole set would take three times its trace)."""
    import pyarrow as pa  # here: runs that write no files (sweeps, scripts) never import it
    import pyarrow.parquet as pq

    meta = {
        "scenario": scenario_name,
        "axes": " ".join(AXES),
        "counts_per_unit": json.dumps(dict(zip(AXES, trace.counts_per_unit.tolist()))),
    }
    writer = None
    try:
        for piece in trace.chunks(group_periods):
            fields, arrays = [], []
            for name, values in piece.columns().items():
                array = _arrow_array(pa, values)
                fields.append(pa.field(name, array.type, metadata={"unit": column_unit(name)}))
                arrays.append(array)
            table = pa.Table.from_arrays(arrays, schema=pa.schema(fields, metadata=meta))
            if writer is None:
                writer = pq.ParquetWriter(path, table.schema)
            writer.write_table(table)
    finally:
        if writer is not None:
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
