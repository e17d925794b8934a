"""Geometry: NURBS curves and surfaces, contours of lines and arcs, paths on surfaces, and the
head's kinematics. Pure functions and evaluators in SI; nothing here runs the machine.

- :mod:`~cnc_twin.geometry.nurbs`         NURBS curves (scipy B-splines in homogeneous coordinates), span evaluators for the card
- :mod:`~cnc_twin.geometry.surface`       NURBS surfaces, their span evaluators, parameter scales
- :mod:`~cnc_twin.geometry.surface_path`  tool paths on a surface as (u, v) curves
- :mod:`~cnc_twin.geometry.contour`       lines and arcs as exact NURBS; distances to them
- :mod:`~cnc_twin.geometry.kinematics`    the A/B head: forward, inverse, reach
- :mod:`~cnc_twin.geometry.tip_path`      the programmed tool-tip path of a curve program

May import: core. Imported by: dsp, planner, machine, polishing, view, scenario, run.
"""
