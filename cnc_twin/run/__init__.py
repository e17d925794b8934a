"""One run of the twin: the wiring, the clock, the recording into a trace, fault injection, the
metrics and the run directory.

- :mod:`~cnc_twin.run.twin`           :class:`~cnc_twin.run.twin.Twin`: builds plant, card and planner for a scenario;
  :func:`~cnc_twin.run.twin.run_scenario`
- :mod:`~cnc_twin.run.clock`          the interpolation periods on simulated time: one path, its variants named
- :mod:`~cnc_twin.run.program_kinds`  what each kind of program brings to a run (plant, process models, metrics)
- :mod:`~cnc_twin.run.servo_kernel`, :mod:`~cnc_twin.run.period_kernel`, :mod:`~cnc_twin.run.c_clock`
  a period's servo ticks with their physics and recording, and batches of whole periods, compiled
  with numba (bit for bit the Python card's); a monotonic clock for them
- :mod:`~cnc_twin.run.faults`         injected card and machine faults (encoders, DACs, drives, load cell, obstacles, DSP hang)
- :mod:`~cnc_twin.run.metrics`, :mod:`~cnc_twin.run.path_metrics`, :mod:`~cnc_twin.run.contour_metrics`  figures from the trace
- :mod:`~cnc_twin.run.result`, :mod:`~cnc_twin.run.run_dir`  :class:`~cnc_twin.run.result.RunResult`; the
  atomic run directory
- :mod:`~cnc_twin.run.progress`       the terminal progress bar

May import: every part below it (core, motion, geometry, legacy, whiteboard, dsp, planner,
machine, trace, polishing, view). Imported by: studies, cli.
"""
