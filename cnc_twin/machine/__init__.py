"""The machine: the MuJoCo plant (axes, drives at the physics rate, load cell, switches), the
workpiece as collision meshes, and the amplifiers in position mode for step-pulse output.

- :mod:`~cnc_twin.machine.plant`      the MJCF model (compiled once per process), names resolved once, lean per-tick accessors
- :mod:`~cnc_twin.machine.workpiece`  a NURBS surface as convex collision tiles via MjSpec
- :mod:`~cnc_twin.machine.screw`      ball screws whose stiffness follows the nut, written before every physics step
- :mod:`~cnc_twin.machine.drive`      the amplifiers' position loops (step pulses in, volts to the speed loop)
- :mod:`~cnc_twin.machine.amplifier`  the amplifiers' own loops (velocity PI, torque filter, notches, torque limit)
- :mod:`~cnc_twin.machine.mujoco_c`   MuJoCo's C ``mj_step`` / ``mj_kinematics`` for compiled kernels

May import: core, geometry, dsp (a position-mode amplifier counts its encoder as the card's QEP
does). Imported by: polishing, view, scenario (the model's travel and home), run, studies.
"""
