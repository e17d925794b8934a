"""The simulated motion card: a TMS320F2812-class DSP and its peripherals, in Python (the
reference; :mod:`cnc_twin.run` runs compiled twins of its periods, bit for bit the same).

Blocks (one job each, wired in :mod:`cnc_twin.dsp.servo`):

- :mod:`~cnc_twin.dsp.encoder`       QEP quadrature encoder counter, 16-bit hardware + 32-bit software
- :mod:`~cnc_twin.dsp.pid`           position loop in counts with velocity/acceleration feed-forward
- :mod:`~cnc_twin.dsp.dac`           12-bit +/-10 V analog command output
- :mod:`~cnc_twin.dsp.adc`           12-bit load-cell input
- :mod:`~cnc_twin.dsp.step_output`   step/direction pulse generators (``command_output: pulse``)
- :mod:`~cnc_twin.dsp.servo`         the servo task: the ordered wiring of the blocks, once per servo tick

Each servo block is a plain function over a typed record (its interface), compiled with numba;
the Python path and the compiled kernels call the same functions on the same records.

Once per interpolation period:

- :mod:`~cnc_twin.dsp.task`          the period task: exchange, records from the FIFO, state, feed hold, stops
- :mod:`~cnc_twin.dsp.supervisor`    fault checks (following error, limits, DAC saturation, force) and stops
- :mod:`~cnc_twin.dsp.interpolator`  per-period setpoints from the records, fine interpolation per tick
- :mod:`~cnc_twin.dsp.path_blocks`   what the interpolator runs on curve and surface paths, one class per record kind
- :mod:`~cnc_twin.dsp.curve_stepper`  NURBS direct interpolation (one compiled function)
- :mod:`~cnc_twin.dsp.force`         the grinding-force loop: seek, ramp, track, retract; feed adaptation
- :mod:`~cnc_twin.dsp.step_interpolator`, :mod:`~cnc_twin.dsp.chip`  the older cards: step interpolation, motion-chip commands

May import: core, motion, geometry, legacy, whiteboard (the card never imports the PC planner:
they meet in the whiteboard). Imported by: machine, trace, polishing, run.
"""
