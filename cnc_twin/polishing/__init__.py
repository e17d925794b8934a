"""The polishing process: material removal by Preston's law under a Winkler pad, and the twin's
side of a polishing run.

- :mod:`~cnc_twin.polishing.removal`  the removal grid on the surface, the pad's pressure patch, Preston integration
- :mod:`~cnc_twin.polishing.polish`   the removal tracker during a run, pad friction, force and removal metrics
- :mod:`~cnc_twin.polishing.removal_kernel`  the tracker's update (patch, removal, friction wrench) compiled, bit for bit the reference

May import: core, motion, geometry, dsp (the force loop's states), machine, trace. Imported by: run.
"""
