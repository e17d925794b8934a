"""What a run records: every servo tick's and every period's signals in typed columns, and the trace
they make.

- :mod:`~cnc_twin.trace.layout`    the columns, their widths and units
- :mod:`~cnc_twin.trace.recorder`  preallocated columns the servo loop writes into
- :mod:`~cnc_twin.trace.trace`     :class:`Trace` (the run's signals as arrays), :class:`PeriodSamples` (what an export reads)
- :mod:`~cnc_twin.trace.parquet`   a trace as ``trace.parquet``, each field with its unit

May import: core, dsp (the card's per-period fields). Imported by: polishing, view, run, studies.
"""
