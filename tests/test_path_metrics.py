"""The contour error's distance to the path (cnc_twin.geometry.polyline.point_to_polyline)."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from cnc_twin.geometry.polyline import point_to_polyline


def test_distance_to_a_long_segment_whose_nearest_vertex_is_elsewhere():
    # the point sits 0.5 beside the middle of the first, 10-long segment; the polyline's nearest
    # vertex, (5, 3), belongs to its last segment, 2.5 away
    poly = np.array([[0, 0, 0], [10, 0, 0], [10, 3, 0], [5, 3, 0]], float)
    assert point_to_polyline(np.array([[5.0, 0.5, 0.0]]), poly)[0] == 0.5


def test_distance_on_a_closed_curve_near_its_start():
    # a closed circle of radius 1 sampled coarsely at its start, densely elsewhere: the end's vertex
    # coincides with the start's, the nearest segment is the first one
    angle = np.concatenate([[0.0], np.linspace(0.5, 2 * np.pi, 400)])
    poly = np.column_stack([np.cos(angle), np.sin(angle), np.zeros_like(angle)])
    point = np.array([[np.cos(0.25) * 0.9, np.sin(0.25) * 0.9, 0.0]])
    a, b = poly[0], poly[1]
    t = np.dot(point[0] - a, b - a) / np.dot(b - a, b - a)
    expected = np.linalg.norm(point[0] - (a + t * (b - a)))
    assert abs(point_to_polyline(point, poly)[0] - expected) < 1e-12


def _brute_force(points, poly):
    """The distance by its definition, in plain numpy over every vertex: the segments next to the
    four nearest vertices and every vertex as near as the fourth."""
    start, step = poly[:-1], np.diff(poly, axis=0)
    out = []
    for p in points:
        if not np.isfinite(p).all():
            out.append(np.nan)
            continue
        e = poly - p
        square = e[:, 0] * e[:, 0] + e[:, 1] * e[:, 1] + e[:, 2] * e[:, 2]
        near = np.flatnonzero(square <= np.sort(square)[min(4, len(poly)) - 1])
        segments = np.unique(np.clip(np.concatenate([near - 1, near]), 0, len(poly) - 2))
        a, d = start[segments], step[segments]
        along = (p[0] - a[:, 0]) * d[:, 0] + (p[1] - a[:, 1]) * d[:, 1] + (p[2] - a[:, 2]) * d[:, 2]
        length = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]
        t = np.clip(along / np.maximum(length, 1e-300), 0.0, 1.0)
        foot = a + t[:, None] * d
        ex, ey, ez = p[0] - foot[:, 0], p[1] - foot[:, 1], p[2] - foot[:, 2]
        out.append(np.min(np.sqrt(ex * ex + ey * ey + ez * ez)))
    return np.array(out)


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), vertices=st.integers(2, 200), count=st.integers(1, 200),
       kind=st.sampled_from(["cloud", "walk", "lattice", "circle"]), spread=st.floats(-4.0, 2.0))
def test_distances_equal_their_definition_bit_for_bit(seed, vertices, count, kind, spread):
    # the grid's search (and the k-d tree's, for points it leaves: far ones) against every vertex:
    # ties on a lattice (a CAM raster's points), repeated vertices, points far off, a NaN
    rng = np.random.default_rng(seed)
    if kind == "cloud":
        poly = rng.normal(size=(vertices, 3))
    elif kind == "walk":
        poly = np.cumsum(rng.normal(size=(vertices, 3)), axis=0)
    elif kind == "lattice":
        poly = np.round(np.cumsum(rng.integers(-1, 2, size=(vertices, 3)), axis=0) * 0.5, 1)
    else:
        angle = np.linspace(0.0, 4.0 * np.pi, vertices)
        poly = np.column_stack([np.cos(angle), np.sin(angle), np.zeros(vertices)])
    points = poly[rng.integers(0, vertices, count)] + rng.normal(scale=10.0 ** spread, size=(count, 3))
    if kind == "lattice":
        points = np.round(points, 1)
    if seed % 5 == 0:
        points[0, seed % 3] = np.nan
    got, want = point_to_polyline(points, poly), _brute_force(points, poly)
    assert np.array_equal(got, want, equal_nan=True)
