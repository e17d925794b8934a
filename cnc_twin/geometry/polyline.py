"""Distances to a polyline: the contour error's measure (:mod:`cnc_twin.run.path_metrics`) and
the fitted curve's check against the programmed points (:mod:`cnc_twin.geometry.fit`).

Each point is measured against the segments next to its :data:`NEAREST` nearest vertices (found
with scipy's k-d tree); the segments are measured in one compiled loop
(:func:`segment_distances`): a CAM program's fits ask for millions of points, and numpy's
passes over temporaries cost ten times the arithmetic."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

NEAREST = 4
"""vertices whose segments a point is measured against: the nearest vertex alone can belong to
another part of the curve than the nearest segment (a closed curve's end beside its start, a long
first span's far vertex)"""
CHUNK = 1 << 16
"""points measured at a time (each point's distance is its own)"""


def point_to_polyline(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance of each of ``points`` (shape (n, 3)) to the polyline ``poly`` (shape (m, 3)), same
    units; shape (n,)."""
    from scipy.spatial import cKDTree  # here: only curve and contour runs need it

    points = np.ascontiguousarray(points, dtype=np.float64)
    poly = np.ascontiguousarray(poly, dtype=np.float64)
    tree = cKDTree(poly)
    out = np.empty(len(points))
    for k in range(0, len(points), CHUNK):  # a long run's neighbour lists one piece at a time
        _, nearest = tree.query(points[k:k + CHUNK], k=min(NEAREST, len(poly)))
        nearest = np.ascontiguousarray(np.reshape(nearest, (len(nearest), -1)), dtype=np.int64)
        segment_distances(points[k:k + CHUNK], poly, nearest, out[k:k + CHUNK])
    return out


@njit(cache=True, error_model="numpy")
def segment_distances(points, poly, nearest, out):  # pragma: no cover - compiled
    """``out[i]``: the distance of ``points[i]`` ((n, 3)) to the nearest of the segments of
    ``poly`` ((m, 3), m >= 2) that end or start at the vertices ``nearest[i]`` ((n, k) indices):
    each point's foot on a segment's line clamped to the segment. The arithmetic is numpy's on
    the same arrays, term for term (sums left to right, no fused multiply-add), so the figures
    are its bits; a NaN anywhere stays NaN, as ``np.minimum`` keeps it."""
    m = poly.shape[0]
    for i in range(points.shape[0]):
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        best = np.inf
        for j in range(nearest.shape[1]):
            for offset in (-1, 0):
                i0 = nearest[i, j] + offset
                if i0 < 0:
                    i0 = 0
                elif i0 > m - 2:
                    i0 = m - 2
                ax, ay, az = poly[i0, 0], poly[i0, 1], poly[i0, 2]
                dx, dy, dz = poly[i0 + 1, 0] - ax, poly[i0 + 1, 1] - ay, poly[i0 + 1, 2] - az
                along = (px - ax) * dx + (py - ay) * dy + (pz - az) * dz
                square = dx * dx + dy * dy + dz * dz
                t = along / (square if square > 1e-300 else 1e-300)
                if t < 0.0:
                    t = 0.0
                elif t > 1.0:
                    t = 1.0
                ex, ey, ez = px - (ax + t * dx), py - (ay + t * dy), pz - (az + t * dz)
                d = math.sqrt(ex * ex + ey * ey + ez * ez)
                if d < best or d != d:
                    best = d
        out[i] = best
