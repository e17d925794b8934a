"""The PC side: turns a scenario's program into records and streams them to the card, as its own
OS process.

- :mod:`~cnc_twin.planner.job`              what the process is asked to do; :func:`~cnc_twin.planner.job.plan_for`, one
  plan per program kind
- :mod:`~cnc_twin.planner.ptp`              point-to-point moves on synchronised trapezoids
- :mod:`~cnc_twin.planner.curve_program`    a NURBS curve: approach, geometry record, S-curve feed blocks
- :mod:`~cnc_twin.planner.feed`             look-ahead feed planning along a curve, window by window
- :mod:`~cnc_twin.planner.surface_program`, :mod:`~cnc_twin.planner.toolpath`  surface polishing: raster / spiral paths, records
- :mod:`~cnc_twin.planner.contour_program`  contours of lines and arcs, pass by pass with each interpolation method
- :mod:`~cnc_twin.planner.chip_program`     motion-chip commands
- :mod:`~cnc_twin.planner.stream`           feeding planned chunks into the FIFO, go-back-N on rejects
- :mod:`~cnc_twin.planner.faults`           the PC-side injected faults
- :mod:`~cnc_twin.planner.process`          the process's main loop; :mod:`~cnc_twin.planner.launch` starts it, a pool keeps it warm

May import: core, motion, geometry, legacy, whiteboard (never the card: they meet only in the
whiteboard). Imported by: scenario (checks a surface path before any motion), run, studies, cli.
"""
