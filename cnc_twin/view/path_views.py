"""Plane views of the tool-tip path as a machine-tool engineer draws them: commanded and actual in
XY (and XZ / YZ where the program moves there), the actual path's distance from the commanded
one magnified by a stated round factor, and the 3D camera framed on the path.

Magnifying the *contour* error, not the following error: each actual point is moved away from
its nearest point on the commanded polyline (in the plane) by ``factor`` times its distance, so
a lag along the path (which every servo has) does not draw as a deviation. The nearest point is
searched among the commanded segments within ``LAG_WINDOW`` samples of the same instant, which
covers any lag the machine can have at the 4 ms sampling of the recorded paths.
"""

from __future__ import annotations

import numpy as np
from numba import njit

PLANES = {"XY": (0, 1), "XZ": (0, 2), "YZ": (1, 2)}
"""plane name -> the tip coordinates (world x, y, z) drawn across and up"""
LAG_WINDOW = 64
"""samples each side of the same instant searched for an actual point's nearest commanded segment"""
MAGNIFIED_SHARE = 0.05
"""the magnified largest contour error spans at most this share of the path's extent in the plane"""
MOVES_IN_PLANE = 0.1
"""a plane other than XY is drawn when the path's extent along its second axis is at least this
share of the path's largest extent (and at least ``MIN_EXTENT``)"""
MIN_EXTENT = 1e-4
"""[m] extents below this count as no motion"""


def nearest_on_path(command: np.ndarray, actual: np.ndarray, window: int = LAG_WINDOW) -> np.ndarray:
    """For each actual point, its nearest point on the commanded polyline, searched among the
    segments within ``window`` samples of the same index (the first of equally near ones).
    ``command``, ``actual``: shape (n, d), sampled at the same instants; returns shape (n, d).
    Compiled (a cam raster's 3 planes took 0.5 s in numpy passes, the last wait of a run's
    recording); ``tests/test_path_views.py`` holds it to the numpy form of the definition."""
    command = np.ascontiguousarray(command, dtype=np.float64)
    actual = np.ascontiguousarray(actual, dtype=np.float64)
    if len(command) < 2:
        return command.copy()
    return _nearest_in_window(command, actual, window)


@njit(cache=True, error_model="numpy")
def _nearest_in_window(command, actual, window):  # pragma: no cover - compiled
    n, d = command.shape
    nearest = command.copy()
    foot = np.empty(d)
    for i in range(n):
        best = np.inf
        for offset in range(-window, window + 1):
            k = min(max(i + offset, 0), n - 2)
            length2 = 0.0
            along = 0.0
            for j in range(d):
                ab = command[k + 1, j] - command[k, j]
                length2 += ab * ab
                along += (actual[i, j] - command[k, j]) * ab
            t = min(max(along / (length2 if length2 > 0 else 1.0), 0.0), 1.0)
            distance2 = 0.0
            for j in range(d):
                foot[j] = command[k, j] + t * (command[k + 1, j] - command[k, j])
                gap = actual[i, j] - foot[j]
                distance2 += gap * gap
            distance = np.sqrt(distance2)
            if distance < best:
                best = distance
                nearest[i] = foot
    return nearest


def warm_up() -> None:
    """Load the compiled search (from numba's cache) now, not at the end of a run."""
    nearest_on_path(np.zeros((2, 2)), np.zeros((2, 2)))


def round_factor(largest_error: float, extent: float) -> int:
    """The largest of 1, 2, 5, 10, 20, 50, ... whose magnified ``largest_error`` spans at most
    ``MAGNIFIED_SHARE`` of ``extent`` (1 when the error is nil or already that large)."""
    if largest_error <= 0 or extent <= 0:
        return 1
    limit = MAGNIFIED_SHARE * extent / largest_error
    factor = 1
    for decade in range(0, 9):
        for mantissa in (1, 2, 5):
            candidate = mantissa * 10 ** decade
            if candidate <= limit:
                factor = candidate
    return factor


def planes_moved(command_tips: np.ndarray) -> list[str]:
    """The planes worth drawing: XY always, XZ / YZ where the path (tips [m], shape (n, 3)) moves
    along Z there."""
    extent = np.ptp(command_tips, axis=0) if len(command_tips) else np.zeros(3)
    largest = max(float(extent.max()), MIN_EXTENT)
    planes = ["XY"]
    if extent[2] >= max(MOVES_IN_PLANE * largest, MIN_EXTENT):
        planes += [name for name in ("XZ", "YZ") if extent[PLANES[name][0]] >= MIN_EXTENT]
    return planes


def program_strips(command_tips: np.ndarray, actual_tips: np.ndarray, on_path: np.ndarray
                   ) -> list[tuple[np.ndarray, np.ndarray]]:
    """The stretches worth drawing, as (commanded, actual) tip arrays [m], shape (n, 3) each: the
    runs of samples on the program's path (``on_path``: the trace's ``path_u >= 0``, curve and
    G-code feed paths), without the approach and the rapids between them; the whole path for a
    program that has none (point to point)."""
    if not on_path.any():
        return [(command_tips, actual_tips)] if len(command_tips) else []
    edges = np.flatnonzero(np.diff(np.concatenate([[0], on_path.astype(np.int8), [0]])))
    return [(command_tips[a:b], actual_tips[a:b]) for a, b in zip(edges[::2], edges[1::2]) if b - a >= 2]


def plane_paths(strips: list[tuple[np.ndarray, np.ndarray]], plane: str
                ) -> tuple[list[np.ndarray], list[np.ndarray], int, float]:
    """One plane's drawing in mm: (commanded strips (n, 2), actual strips with their contour error
    magnified, the factor, the largest contour error in the plane [mm]). ``strips``: from
    :func:`program_strips`, tips [m]."""
    across_up = list(PLANES[plane])
    commands = [command[:, across_up] * 1e3 for command, _ in strips]
    actuals = [actual[:, across_up] * 1e3 for _, actual in strips]
    nearest = [nearest_on_path(c, a) for c, a in zip(commands, actuals)]
    deviations = [a - n for a, n in zip(actuals, nearest)]
    largest = max((float(np.linalg.norm(d, axis=1).max()) for d in deviations if len(d)), default=0.0)
    every = np.vstack(commands) if commands else np.zeros((0, 2))
    extent = float(np.ptp(every, axis=0).max()) if len(every) else 0.0
    factor = round_factor(largest, extent)
    return commands, [n + factor * d for n, d in zip(nearest, deviations)], factor, largest


def camera_on(points: np.ndarray, *, smallest: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """A 3D camera (eye position, look target) [m] that frames ``points`` (shape (n, 3), world):
    from the front, to the side and above, far enough to see their bounding box (at least
    ``smallest`` metres across) whole."""
    low, high = points.min(axis=0), points.max(axis=0)
    target = (low + high) / 2
    size = max(float(np.linalg.norm(high - low)), smallest)
    direction = np.array([0.55, -1.0, 0.6])
    return target + 2.0 * size * direction / np.linalg.norm(direction), target
