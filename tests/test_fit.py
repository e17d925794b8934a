"""The polyline fit (cnc_twin.geometry.fit): within the tolerance both ways, measured here
independently (dense samples, brute-force segment distances), end points and tangents kept, a
tool axis within its angle."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import BSpline

from cnc_twin.geometry.fit import DEGREE, FitError, fit_polyline


def segment_distance(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Brute force: each point's distance to every segment of ``poly``, the least."""
    a, b = poly[:-1], poly[1:]
    d = b - a
    rel = points[:, None, :] - a[None, :, :]
    t = np.clip(np.einsum("pkj,kj->pk", rel, d) / np.maximum(np.sum(d * d, axis=1), 1e-300), 0.0, 1.0)
    return np.min(np.linalg.norm(rel - t[..., None] * d[None, :, :], axis=2), axis=1)


def cam_polyline(seed: int, chord: float = 0.005, count: int = 300) -> np.ndarray:
    """A CAM-like polyline: a smooth random space curve sampled at uneven steps of 0.05 - 1 mm,
    curved so that its chords stay within ``chord`` [mm] of it (as CAM writes them: curvature
    <= 8 chord / step^2), rounded to 1 um."""
    rng = np.random.default_rng(seed)
    steps = rng.uniform(0.05, 1.0, count)
    s = np.concatenate([[0.0], np.cumsum(steps)])
    k = rng.uniform(0.02, 0.1, 3)
    phase = rng.uniform(0, 2 * np.pi, 3)
    curvature = 8.0 * chord / 1.0 ** 2 / 3.0  # each of three terms a third of it at most
    amp = np.minimum(rng.uniform(1.0, 10.0, 3), curvature / (k * k))
    pts = np.column_stack([s + amp[0] * np.sin(k[0] * s + phase[0]), amp[1] * np.sin(k[1] * s + phase[1]),
                           amp[2] * np.cos(k[2] * s + phase[2])])
    return np.round(pts, 3)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("tolerance", [0.01, 0.002])
def test_the_fit_stays_within_the_tolerance_of_every_point_and_segment(seed, tolerance):
    pts = cam_polyline(seed, chord=tolerance / 2)
    fit = fit_polyline(pts, tolerance)
    curve = BSpline(fit.knots, fit.points, DEGREE)
    dense = curve(np.linspace(fit.knots[0], fit.knots[-1], 8001))
    assert segment_distance(dense, pts).max() <= tolerance * 1.001  # the curve stays by the polyline
    assert segment_distance(pts, dense).max() <= tolerance * 1.001  # and passes by every point
    assert fit.deviation <= tolerance
    assert np.array_equal(fit.points[0], pts[0]) and np.array_equal(fit.points[-1], pts[-1])
    assert fit.spans < len(pts) / 3  # far fewer spans than segments


def test_the_parameter_is_about_the_arc_length():
    pts = cam_polyline(3)
    fit = fit_polyline(pts, 0.005)
    speed = np.linalg.norm(BSpline(fit.knots, fit.points, DEGREE).derivative()(np.linspace(fit.knots[0], fit.knots[-1], 2001)),
                           axis=1)
    assert 0.9 < speed.min() and speed.max() < 1.1


def test_end_tangents_are_kept_at_unit_speed_without_curvature():
    pts = cam_polyline(1)
    t0, t1 = pts[1] - pts[0], pts[-1] - pts[-2]  # along the neighbouring segments
    t0, t1 = t0 / np.linalg.norm(t0), t1 / np.linalg.norm(t1)
    fit = fit_polyline(pts, 0.01, start_tangent=t0, end_tangent=t1)
    d = BSpline(fit.knots, fit.points, DEGREE).derivative()
    assert d(fit.knots[0]) == pytest.approx(t0, abs=1e-12)
    assert d(fit.knots[-1]) == pytest.approx(t1, abs=1e-12)
    dd = d.derivative()  # no curvature at the ends: joined to the lines along t0, t1 it is C2
    assert dd(fit.knots[0]) == pytest.approx(np.zeros(3), abs=1e-9)
    assert dd(fit.knots[-1]) == pytest.approx(np.zeros(3), abs=1e-9)


def test_a_tool_axis_is_fitted_within_its_angle():
    pts = cam_polyline(2)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])  # along the path
    axes = np.column_stack([0.3 * np.sin(s / 40.0), 0.2 * np.cos(s / 25.0), np.ones(len(pts))])  # a smooth tilt
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    tolerance = 2e-4  # rad
    fit = fit_polyline(pts, 0.01, axes=axes, axis_tolerance=tolerance)
    got = BSpline(fit.knots, fit.axis_points, DEGREE)(np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))]))
    got /= np.linalg.norm(got, axis=1, keepdims=True)
    angle = np.arccos(np.clip(np.sum(got * axes, axis=1), -1, 1))
    assert angle.max() <= tolerance and fit.axis_deviation <= tolerance


def test_fewer_than_two_points_is_an_error():
    with pytest.raises(FitError, match="two distinct"):
        fit_polyline(np.array([[1.0, 2.0, 3.0], [1.0, 2.0, 3.0]]), 0.01)


def test_a_turn_too_sharp_for_the_tolerance_is_refused_not_fitted_beyond_it():
    # a zig-zag of 1 mm segments turning 60 deg at every point: no smooth curve stays within
    # 1 um of both its points and its segments
    x = np.arange(40.0)
    pts = np.column_stack([x, 0.866 * (x % 2), np.zeros_like(x)])
    with pytest.raises(FitError, match="too few points"):
        fit_polyline(pts, 0.001)
