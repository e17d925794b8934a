"""Geometry: NURBS curves (and later surfaces) and the machine's kinematics."""
