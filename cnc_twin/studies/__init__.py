"""What users do with the twin beyond one run: measure it, sweep it, tune it, stress it.

- :mod:`~cnc_twin.studies.bench`, :mod:`~cnc_twin.studies.bench_whiteboard`, :mod:`~cnc_twin.studies.bench_replay`  speed figures (``cnc-twin bench``; the replayed physics of a run in contact)
- :mod:`~cnc_twin.studies.bench_startup`  whole commands timed beside the floor, phase by phase (``cnc-twin bench --startup``)
- :mod:`~cnc_twin.studies.bench_command`, :mod:`~cnc_twin.studies.sweep_command`, :mod:`~cnc_twin.studies.tune_command`  the commands' handlers
- :mod:`~cnc_twin.studies.sweep`          grids and random draws of overrides, local processes or Dask
- :mod:`~cnc_twin.studies.linearize`, :mod:`~cnc_twin.studies.tuning`  the linear loop (python-control) and gain proposals checked on the twin
- :mod:`~cnc_twin.studies.fault_catalog`  one run per fault kind -> docs/faults.md
- :mod:`~cnc_twin.studies.soak`           the long soak run

May import: every part below it. Imported by: cli.
"""
