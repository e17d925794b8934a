"""What a run records: every servo tick's and every period's signals in typed columns, and the trace
they make.

- :mod:`~cnc_twin.trace.layout`    the columns, their widths and units
- :mod:`~cnc_twin.trace.recorder`  preallocated columns the servo loop writes into (a long run's: a window)
- :mod:`~cnc_twin.trace.trace`     :class:`~cnc_twin.trace.trace.Trace` (the run's signals as arrays),
  :class:`~cnc_twin.trace.trace.PeriodSamples` (what an export and the path metrics read: the signals at each
  period's end)
- :mod:`~cnc_twin.trace.parquet`   a trace as ``trace.parquet``, each field with its unit, written whole or
  piece by piece while a long run runs (:class:`~cnc_twin.trace.parquet.TraceWriter`)
- :mod:`~cnc_twin.trace.trace_file` a long run's trace read back from its file
  (:class:`~cnc_twin.trace.trace_file.TraceFile`)

May import: core, dsp (the card's per-period fields). Imported by: polishing, view, run, studies.
"""
