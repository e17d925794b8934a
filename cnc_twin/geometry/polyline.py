"""Distances to a polyline: the contour error's measure (:mod:`cnc_twin.run.path_metrics`) and
the fitted curve's check against the programmed points (:mod:`cnc_twin.geometry.fit`)."""

from __future__ import annotations

import numpy as np


def point_to_polyline(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance of each of ``points`` (shape (n, 3)) to the polyline ``poly`` (shape (m, 3)), same
    units; shape (n,)."""
    from scipy.spatial import cKDTree  # here: only curve and contour runs need it

    tree = cKDTree(poly)
    out = np.empty(len(points))
    for k in range(0, len(points), CHUNK):  # a long run's temporaries one piece at a time
        out[k:k + CHUNK] = _nearest_distances(points[k:k + CHUNK], poly, tree)
    return out


CHUNK = 1 << 16
"""points measured at a time (each point's distance is its own)"""


def _nearest_distances(points: np.ndarray, poly: np.ndarray, tree) -> np.ndarray:
    # the segments next to the 4 nearest vertices: the nearest vertex alone can belong to another
    # part of the curve than the nearest segment (a closed curve's end beside its start, a long
    # first span's far vertex)
    _, nearest = tree.query(points, k=min(4, len(poly)))
    best = np.full(len(points), np.inf)
    for idx in nearest.T:
        for offset in (-1, 0):
            i0 = np.clip(idx + offset, 0, len(poly) - 2)
            a, b = poly[i0], poly[i0 + 1]
            d = b - a
            t = np.clip(np.sum((points - a) * d, axis=1) / np.maximum(np.sum(d * d, axis=1), 1e-300), 0.0, 1.0)
            best = np.minimum(best, np.linalg.norm(points - (a + t[:, None] * d), axis=1))
    return best
