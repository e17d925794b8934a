"""The simulated motion card: a TMS320F2812-class DSP and its peripherals.

Blocks (one job each, wired in :mod:`cnc_twin.dsp.servo`):

- :mod:`~cnc_twin.dsp.encoder`   QEP quadrature encoder counter, 16-bit hardware + 32-bit software
- :mod:`~cnc_twin.dsp.pid`       position loop in counts with velocity/acceleration feed-forward
- :mod:`~cnc_twin.dsp.dac`       12-bit +/-10 V analog command output
- :mod:`~cnc_twin.dsp.adc`       12-bit load-cell input
- :mod:`~cnc_twin.motion.trapezoid`  trapezoid velocity profile (normalised, period-quantised)
- :mod:`~cnc_twin.dsp.interpolator` per-period setpoints from program segments, fine interpolation per tick
- :mod:`~cnc_twin.dsp.servo`     the servo task: the ordered wiring of the blocks, once per servo tick
"""
