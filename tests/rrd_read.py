"""Reading a recording back for tests, with rerun's own reader (``rerun.chunk.RrdReader``)."""

from __future__ import annotations

import collections
from pathlib import Path

ROW_ID = "rerun.controls.RowId"
TIMELINES = ("sim_time", "period")


def rrd_rows(path: Path) -> tuple[collections.Counter, collections.Counter]:
    """(temporal rows, static rows) per entity path of the recording store."""
    from rerun.chunk import RrdReader

    temporal: collections.Counter = collections.Counter()
    static: collections.Counter = collections.Counter()
    for chunk in RrdReader(path).stream():
        (static if chunk.is_static else temporal)[chunk.entity_path] += chunk.num_rows
    return temporal, static


def rrd_contents(path: Path) -> dict[tuple[str, str, bool], list]:
    """Every value of the recording store: ``(entity, column, static)`` -> the sorted list of
    ``(sim_time, period, value)`` rows (None for the times of static rows). Row ids, which
    differ between any two recordings, are left out; everything else must match."""
    import pyarrow as pa
    from rerun.chunk import RrdReader

    out: dict[tuple[str, str, bool], list] = collections.defaultdict(list)
    for chunk in RrdReader(path).stream():
        if chunk.entity_path.startswith("/__"):  # recording properties (start time)
            continue
        batch = chunk.to_record_batch()
        data = {name: (column.cast(pa.int64()) if pa.types.is_duration(column.type) else column).to_pylist()
                for name, column in zip(batch.schema.names, batch.columns)}  # durations as ns
        n = chunk.num_rows
        times = [data.get(t, [None] * n) for t in TIMELINES]
        for column, values in data.items():
            if column in TIMELINES or column == ROW_ID:
                continue
            out[(chunk.entity_path, column, chunk.is_static)].extend(
                (times[0][i], times[1][i], repr(values[i])) for i in range(n))
    return {key: sorted(rows, key=lambda r: (r[1] is not None, r[1] or 0, r[0] or 0, r[2])) for key, rows in out.items()}


def entity_columns(contents: dict, entity: str, static: bool) -> list[list]:
    """The value columns :func:`rrd_contents` holds for ``entity`` (static, or over time), each its
    list of rows, whatever rerun names the column (``Archetype:field`` in rerun 0.41, its own
    scheme, which has changed between versions)."""
    return [rows for (path, _, is_static), rows in contents.items() if path == entity and is_static == static]
