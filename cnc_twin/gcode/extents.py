"""How far a program reaches: the box around every point its operations can take the tool tip
to (:mod:`~cnc_twin.gcode.toolpath`), in the machine frame [mm]. Lines and traverses by their
ends; arcs, curves and fitted runs by their control points, whose box holds the curve (a rational
Bezier or B-spline with positive weights stays in the hull of its control points), so the box
may be a little larger than the path, never smaller. What a user reads before placing a program
on the workpiece (``cnc-twin gcode``), and what the beyond-travel refusal points at."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from cnc_twin.gcode.path_ops import FeedPath, Operation, Probe, ToolAxisPath, Traverse


def operation_points(op: Operation) -> np.ndarray | None:
    """(k, 3) [mm] points whose box holds everywhere ``op`` takes the tool tip; None for an
    operation that does not move it (a pause, a spindle or force change)."""
    if isinstance(op, Traverse):
        return np.asarray([op.end[:3]], dtype=float)
    if isinstance(op, FeedPath):
        pieces = [np.asarray(q, dtype=float) for element in op.elements for q in element.pieces]
        return np.vstack([q[:, :3] / q[:, 3:4] for q in pieces])
    if isinstance(op, ToolAxisPath):
        return np.asarray(op.points, dtype=float)[:, :3]
    if isinstance(op, Probe):  # as far as its end when it does not trip
        return np.asarray([op.start[:3], op.end[:3]], dtype=float)
    return None


def extents(ops: Iterable[Operation]) -> tuple[np.ndarray, np.ndarray] | None:
    """``(low, high)`` (each (3,) [mm]): the box of every point the operations reach (taken one
    at a time: a stream of them is never held); None when nothing moves."""
    low = high = None
    for op in ops:
        points = operation_points(op)
        if points is None:
            continue
        lo, hi = points.min(axis=0), points.max(axis=0)
        low, high = (lo, hi) if low is None else (np.minimum(low, lo), np.maximum(high, hi))
    return None if low is None else (low, high)


def describe(box: tuple[np.ndarray, np.ndarray]) -> str:
    """The box as a line of text. For example ``X -12.5 .. 80 Y 0 .. 40 Z -2 .. 5 mm``."""
    low, high = box
    return " ".join(f"{name} {lo:.4g} .. {hi:.4g}" for name, lo, hi in zip("XYZ", low, high)) + " mm"
