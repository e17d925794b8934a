"""Distances to a polyline: the contour error's measure (:mod:`cnc_twin.run.path_metrics`) and
the fitted curve's check against the programmed points (:mod:`cnc_twin.geometry.fit`).

Each point is measured against the segments next to its nearest vertices: the :data:`NEAREST`
nearest and every other vertex as near as the last of them (so that which of equally near
vertices is taken never matters). They are found in a uniform grid of cells about two vertex
spacings wide (:func:`vertex_grid`), searched ring by ring around the point's cell in one compiled
loop (:func:`grid_distances`) until no vertex outside can be nearer. A point the first
:data:`RINGS` rings do not settle (far from the polyline, or beside a long segment between sparse
vertices) is asked of scipy's k-d tree (``_tree_distances``): a CAM program's fits ask for
millions of points close to the polyline, where the tree's query costs several times the grid's.
The segments are measured in one compiled arithmetic (:func:`near_segments`), numpy's term for
term."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

NEAREST = 4
"""nearest vertices whose segments a point is measured against (and those as near as the last):
the nearest vertex alone can belong to another part of the curve than the nearest segment (a
closed curve's end beside its start, a long first span's far vertex)"""
RINGS = 3
"""rings of cells around a point's own searched in the grid before the k-d tree is asked"""
CELL_SPACINGS = 2.0
"""a grid cell's width in mean vertex spacings (the polyline's length over its segments)"""
CELLS_PER_VERTEX = 8
"""the grid's cells at most per vertex (plus :data:`MIN_CELLS`): wider cells beyond it"""
MIN_CELLS = 1 << 16
"""the grid's cells a polyline may have however few its vertices (added to
:data:`CELLS_PER_VERTEX`'s bound)"""
CHUNK = 1 << 16
"""points asked of the k-d tree at a time (each point's distance is its own)"""


def point_to_polyline(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance of each of ``points`` (shape (n, 3)) to the polyline ``poly`` (shape (m, 3), m >=
    2), same units; shape (n,): to the nearest of the segments next to the :data:`NEAREST` nearest
    vertices and every vertex as near. A point with a NaN is NaN away."""
    points = np.ascontiguousarray(points, dtype=np.float64)
    poly = np.ascontiguousarray(poly, dtype=np.float64)
    out = np.full(len(points), np.nan)
    nearest = min(NEAREST, len(poly))
    if np.isfinite(poly).all():
        origin, width, shape, starts, order = vertex_grid(poly)
        settled = np.zeros(len(points), dtype=np.bool_)
        grid_distances(points, poly, nearest, origin, width, shape, starts, order, out, settled)
        rest = np.flatnonzero(~settled)
    else:  # vertices a grid cannot place
        rest = np.flatnonzero(np.isfinite(points).all(axis=1))
    if len(rest):
        out[rest] = _tree_distances(points[rest], poly, nearest)
    return out


def vertex_grid(poly: np.ndarray) -> tuple[np.ndarray, float, np.ndarray, np.ndarray, np.ndarray]:
    """A uniform grid over the finite vertices ``poly`` ((m, 3), m >= 2): its ``origin`` (3,), cell
    ``width`` (same units), ``shape`` (3,) cells per axis, and the vertices cell by cell: cell
    ``c`` (flat, C order) holds ``order[starts[c]:starts[c + 1]]``, increasing indices."""
    origin, extent, length = _bounds(poly)
    width = CELL_SPACINGS * length / (len(poly) - 1)
    if not width > 0.0:  # every vertex in one place
        width = 1.0
    most = CELLS_PER_VERTEX * len(poly) + MIN_CELLS
    while True:
        shape = (extent // width).astype(np.int64) + 1
        if np.prod(shape.astype(np.float64)) <= most:
            break
        width *= 2.0
    starts, order = _sort_into_cells(poly, origin, width, shape)
    return origin, width, shape, starts, order


def _tree_distances(points: np.ndarray, poly: np.ndarray, nearest: int) -> np.ndarray:
    """:func:`point_to_polyline` of the finite ``points`` ((n, 3)) with scipy's k-d tree: the
    ``nearest`` nearest vertices, then every vertex as near (a ball query, filtered in
    :func:`listed_distances`'s arithmetic)."""
    from scipy.spatial import cKDTree  # here: only points the grid leaves need it

    tree = cKDTree(poly)
    out = np.empty(len(points))
    for k in range(0, len(points), CHUNK):  # a long run's neighbour lists one piece at a time
        chunk = points[k:k + CHUNK]
        _, found = tree.query(chunk, k=nearest)
        reach = _reach(chunk, poly, np.ascontiguousarray(np.reshape(found, (len(chunk), -1)), dtype=np.int64))
        # a little wider than the reach: the tree's arithmetic may round the other way
        balls = tree.query_ball_point(chunk, np.sqrt(reach) * (1.0 + 1e-9), return_sorted=False)
        starts = np.zeros(len(chunk) + 1, dtype=np.int64)
        np.cumsum(np.fromiter((len(b) for b in balls), dtype=np.int64, count=len(balls)), out=starts[1:])
        listed = np.fromiter((v for b in balls for v in b), dtype=np.int64, count=int(starts[-1]))
        listed_distances(chunk, poly, reach, starts, listed, out[k:k + CHUNK])
    return out


@njit(cache=True, inline="always")
def _square(q0, q1, q2, poly, v):  # pragma: no cover - compiled
    """Squared distance of the point (``q0``, ``q1``, ``q2``) to vertex ``v`` of ``poly``."""
    e0, e1, e2 = poly[v, 0] - q0, poly[v, 1] - q1, poly[v, 2] - q2
    return e0 * e0 + e1 * e1 + e2 * e2


@njit(cache=True, error_model="numpy")
def near_segments(px, py, pz, poly, v, best):  # pragma: no cover - compiled
    """``best`` lowered to the distance of the point (``px``, ``py``, ``pz``) to the segments of
    ``poly`` ((m, 3), m >= 2) ending and starting at vertex ``v``: the point's foot on a
    segment's line clamped to the segment. The arithmetic is numpy's on the same arrays, term for
    term (sums left to right, no fused multiply-add), so the figures are its bits; a NaN stays
    NaN, as ``np.minimum`` keeps it."""
    m = poly.shape[0]
    for offset in (-1, 0):
        i0 = v + offset
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
    return best


@njit(cache=True, error_model="numpy")
def _reach(points, poly, found):  # pragma: no cover - compiled
    """Per point of ``points`` ((n, 3)): the largest squared distance to its vertices ``found``
    ((n, k) indices); shape (n,)."""
    reach = np.empty(points.shape[0])
    for i in range(points.shape[0]):
        most = 0.0
        for j in range(found.shape[1]):
            most = max(most, _square(points[i, 0], points[i, 1], points[i, 2], poly, found[i, j]))
        reach[i] = most
    return reach


@njit(cache=True, error_model="numpy")
def listed_distances(points, poly, reach, starts, listed, out):  # pragma: no cover - compiled
    """``out[i]``: the distance of ``points[i]`` ((n, 3)) to the segments next to the vertices
    ``listed[starts[i]:starts[i + 1]]`` within squared distance ``reach[i]`` (:func:`near_segments`)."""
    for i in range(points.shape[0]):
        q0, q1, q2 = points[i, 0], points[i, 1], points[i, 2]
        best = np.inf
        for s in range(starts[i], starts[i + 1]):
            if _square(q0, q1, q2, poly, listed[s]) <= reach[i]:
                best = near_segments(q0, q1, q2, poly, listed[s], best)
        out[i] = best


@njit(cache=True, error_model="numpy")
def grid_distances(points, poly, nearest, origin, width, shape, starts, order, out, settled):  # pragma: no cover - compiled
    """For each of ``points`` ((n, 3)): its ``nearest`` nearest vertices of ``poly`` found in the
    grid (:func:`vertex_grid`'s ``origin``, ``width``, ``shape``, ``starts``, ``order``), ring by
    ring of cells around its own; once no vertex outside the rings searched can be nearer than
    the last of them (within :data:`RINGS` rings), ``out[i]``: its distance to the segments next
    to every vertex as near (:func:`near_segments`), and ``settled[i]`` set. A point with a NaN
    is settled as NaN (any segment's distance to it is)."""
    best = np.empty(nearest)  # the nearest squared distances found, increasing
    margin = 1e-9 * width  # a cell's face in floats against a vertex's cell: rounding never hides a vertex
    for i in range(points.shape[0]):
        q0, q1, q2 = points[i, 0], points[i, 1], points[i, 2]
        if q0 != q0 or q1 != q1 or q2 != q2:
            out[i] = np.nan
            settled[i] = True
            continue
        c0 = _cell(q0, origin[0], width, shape[0])
        c1 = _cell(q1, origin[1], width, shape[1])
        c2 = _cell(q2, origin[2], width, shape[2])
        found = 0
        for ring in range(RINGS + 1):
            for a in range(max(c0 - ring, 0), min(c0 + ring, shape[0] - 1) + 1):
                for b in range(max(c1 - ring, 0), min(c1 + ring, shape[1] - 1) + 1):
                    for c in range(max(c2 - ring, 0), min(c2 + ring, shape[2] - 1) + 1):
                        if max(abs(a - c0), abs(b - c1), abs(c - c2)) != ring:
                            continue  # searched in an earlier ring
                        cell = (a * shape[1] + b) * shape[2] + c
                        for s in range(starts[cell], starts[cell + 1]):
                            found = _keep(_square(q0, q1, q2, poly, order[s]), best, found)
            # how near a vertex outside the searched box of cells can be
            bound = np.inf
            bound = _face(bound, c0 - ring > 0, q0 - (origin[0] + (c0 - ring) * width))
            bound = _face(bound, c0 + ring < shape[0] - 1, origin[0] + (c0 + ring + 1) * width - q0)
            bound = _face(bound, c1 - ring > 0, q1 - (origin[1] + (c1 - ring) * width))
            bound = _face(bound, c1 + ring < shape[1] - 1, origin[1] + (c1 + ring + 1) * width - q1)
            bound = _face(bound, c2 - ring > 0, q2 - (origin[2] + (c2 - ring) * width))
            bound = _face(bound, c2 + ring < shape[2] - 1, origin[2] + (c2 + ring + 1) * width - q2)
            if found == nearest and (bound == np.inf or (bound > margin and best[nearest - 1] < (bound - margin) ** 2)):
                # every vertex as near as the last found lies in the box searched
                reach, d = best[nearest - 1], np.inf
                for a in range(max(c0 - ring, 0), min(c0 + ring, shape[0] - 1) + 1):
                    for b in range(max(c1 - ring, 0), min(c1 + ring, shape[1] - 1) + 1):
                        for c in range(max(c2 - ring, 0), min(c2 + ring, shape[2] - 1) + 1):
                            cell = (a * shape[1] + b) * shape[2] + c
                            for s in range(starts[cell], starts[cell + 1]):
                                if _square(q0, q1, q2, poly, order[s]) <= reach:
                                    d = near_segments(q0, q1, q2, poly, order[s], d)
                out[i] = d
                settled[i] = True
                break


@njit(cache=True, inline="always")
def _keep(square, best, found):  # pragma: no cover - compiled
    """``square`` kept in the increasing list ``best`` of the smallest found (``found`` of them
    so far, at most its length) if it is among them; the count now held."""
    k = found
    if found == best.shape[0]:
        if square >= best[found - 1]:
            return found
        k = found - 1
    else:
        found += 1
    while k > 0 and best[k - 1] > square:
        best[k] = best[k - 1]
        k -= 1
    best[k] = square
    return found


@njit(cache=True, inline="always")
def _cell(q, origin, width, cells):  # pragma: no cover - compiled
    """The cell along one axis holding coordinate ``q`` (clamped into the grid)."""
    at = (q - origin) / width
    if at < 0.0:
        return 0
    if at >= cells - 1:
        return cells - 1
    return int(at)


@njit(cache=True, inline="always")
def _face(bound, beyond, distance):  # pragma: no cover - compiled
    """``bound`` lowered to ``distance`` when cells lie ``beyond`` that face of the searched box."""
    return min(bound, distance) if beyond else bound


@njit(cache=True, error_model="numpy")
def _bounds(poly):  # pragma: no cover - compiled
    """The lowest corner (3,) and the extent (3,) of the box around ``poly`` ((m, 3)), and the
    polyline's length: one pass (numpy's reductions along the short axis cost ten times more)."""
    low = poly[0].copy()
    high = poly[0].copy()
    length = 0.0
    for v in range(1, poly.shape[0]):
        for d in range(3):
            low[d] = min(low[d], poly[v, d])
            high[d] = max(high[d], poly[v, d])
        e0, e1, e2 = poly[v, 0] - poly[v - 1, 0], poly[v, 1] - poly[v - 1, 1], poly[v, 2] - poly[v - 1, 2]
        length += math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    return low, high - low, length


@njit(cache=True, error_model="numpy")
def _sort_into_cells(poly, origin, width, shape):  # pragma: no cover - compiled
    """The vertices ``poly`` ((m, 3)) sorted into the grid's cells (a counting sort: increasing
    indices in each cell): ``starts`` (cells + 1,) and ``order`` (m,), as :func:`vertex_grid`."""
    m = poly.shape[0]
    cells = np.empty(m, dtype=np.int64)
    starts = np.zeros(shape[0] * shape[1] * shape[2] + 1, dtype=np.int64)
    for v in range(m):
        cell = ((_cell(poly[v, 0], origin[0], width, shape[0]) * shape[1]
                 + _cell(poly[v, 1], origin[1], width, shape[1])) * shape[2]
                + _cell(poly[v, 2], origin[2], width, shape[2]))
        cells[v] = cell
        starts[cell + 1] += 1
    for c in range(1, starts.shape[0]):
        starts[c] += starts[c - 1]
    filled = starts[:-1].copy()
    order = np.empty(m, dtype=np.int64)
    for v in range(m):
        order[filled[cells[v]]] = v
        filled[cells[v]] += 1
    return starts, order
