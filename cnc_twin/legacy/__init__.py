"""Pure algorithms of the older motion cards, in integer pulse units.

1 pulse = 1 encoder count (1 um on a linear axis); callers convert. Nothing here touches the
twin's plant or whiteboard: each module is a generator of steps or per-cycle pulse counts.

- :mod:`~cnc_twin.legacy.quadrants`       circle pieces per quadrant, step-direction table (shared)
- :mod:`~cnc_twin.legacy.point_by_point`  point-by-point comparison interpolation (lines, arcs)
- :mod:`~cnc_twin.legacy.dda`             digital differential analyser (lines, arcs)
- :mod:`~cnc_twin.legacy.motion_chip`     a 4-axis motion chip's per-cycle pulse profiles

May import: motion (a jerk phase evaluated as the S-curve's). Imported by: dsp (step interpolation, the chip), scenario (lattice checks).
"""
