"""Motion laws, shared by the PC planner and the card: what both sides must compute the same way.

- :mod:`~cnc_twin.motion.trapezoid`  the trapezoid velocity profile (normalised, period-quantised)
- :mod:`~cnc_twin.motion.scurve`     the jerk-limited S-curve: phases, ramp distances, reachable speeds
- :mod:`~cnc_twin.motion.segments`   planned segments (moves, dwells) before they become records

May import: core. Imported by: legacy (the chip's jerk phases), whiteboard (records carry profiles), dsp, planner, polishing, run, studies.
"""
