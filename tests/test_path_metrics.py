"""The contour error's distance to the path (cnc_twin.geometry.polyline.point_to_polyline)."""

import numpy as np

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
