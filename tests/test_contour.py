"""Line/arc contours: exact NURBS, lengths, point-to-contour distances and validation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import BSpline
from scipy.spatial import cKDTree

from cnc_twin.geometry.contour import (Arc, Line, arc_sweep, check_contour, contour_distance, element_length,
                                       element_nurbs, elements_length)
from cnc_twin.geometry.nurbs import NurbsCurve

HALF_PI, TWO_PI = math.pi / 2, 2 * math.pi


def make_arc(center, r: float, a0: float, sweep: float, clockwise: bool) -> Arc:
    """Arc of radius r [m] starting at polar angle a0 [rad] and turning ``sweep`` [rad]; a sweep of
    exactly 2 pi gives a full circle (end is the very same tuple as start)."""
    cx, cy = center
    start = (cx + r * math.cos(a0), cy + r * math.sin(a0))
    if sweep == TWO_PI:
        return Arc(start, start, center, clockwise)
    a1 = a0 - sweep if clockwise else a0 + sweep
    return Arc(start, (cx + r * math.cos(a1), cy + r * math.sin(a1)), center, clockwise)


def eval_nurbs(nurbs, u: np.ndarray) -> np.ndarray:
    """Independent evaluation: polynomial B-spline of the homogeneous points [w P, w], projected."""
    degree, knots, weights, points = nurbs
    w = np.asarray(weights, float)
    homogeneous = np.column_stack([w[:, None] * np.asarray(points, float), w])
    a = BSpline(np.asarray(knots, float), homogeneous, degree)(u)
    return a[:, :2] / a[:, 2:]


def polyline_length(points: np.ndarray) -> float:
    return float(np.sum(np.hypot(*np.diff(points, axis=0).T)))


def travel_angles(points: np.ndarray, center) -> np.ndarray:
    """Signed angle [rad] turned about ``center`` between successive points, shape (m - 1,)."""
    v = points - np.asarray(center, float)
    cross = v[:-1, 0] * v[1:, 1] - v[:-1, 1] * v[1:, 0]
    dot = np.einsum("md,md->m", v[:-1], v[1:])
    return np.arctan2(cross, dot)


def sample_elements(elements, spacing: float) -> tuple[np.ndarray, float]:
    """Points exactly on the elements, at most ``spacing`` [m] apart along each element (the
    first and last included); returns the points (m, 2) and the largest chord between them."""
    chunks, widest = [], 0.0
    for el in elements:
        n = max(2, math.ceil(element_length(el) / spacing) + 1)
        s = np.linspace(0.0, 1.0, n)
        if isinstance(el, Line):
            a, b = np.asarray(el.start), np.asarray(el.end)
            pts = a + s[:, None] * (b - a)
        else:
            r = math.hypot(el.start[0] - el.center[0], el.start[1] - el.center[1])
            a0 = math.atan2(el.start[1] - el.center[1], el.start[0] - el.center[0])
            t = a0 + (-1 if el.clockwise else 1) * arc_sweep(el) * s
            pts = np.asarray(el.center) + r * np.column_stack([np.cos(t), np.sin(t)])
        chunks.append(pts)
        widest = max(widest, float(np.max(np.hypot(*np.diff(pts, axis=0).T))))
    return np.vstack(chunks), widest


def assert_matches_brute_force(points, elements, spacing: float) -> None:
    """The exact distance can only undercut the sampled one, by at most half a sample chord."""
    samples, chord = sample_elements(elements, spacing)
    brute, _ = cKDTree(samples).query(points)
    exact = contour_distance(points, elements)
    assert np.all(exact <= brute + 1e-12)
    assert np.all(brute - exact <= chord / 2 + 1e-12)


# A closed keyhole-like contour with lines, CCW and CW arcs of several sweeps (m).
CONTOUR = [
    Line((0.0, 0.0), (0.04, 0.0)),
    Arc((0.04, 0.0), (0.04, 0.02), (0.04, 0.01), clockwise=False),  # half circle, r 10 mm
    Line((0.04, 0.02), (0.02, 0.02)),
    Arc((0.02, 0.02), (0.01, 0.03), (0.01, 0.02), clockwise=False),  # quarter, r 10 mm
    Line((0.01, 0.03), (0.0, 0.03)),
    Arc((0.0, 0.03), (0.0, 0.0), (0.0, 0.015), clockwise=True),  # half circle bulging inwards
]
CONTOUR_LENGTH = 0.04 + math.pi * 0.01 + 0.02 + HALF_PI * 0.01 + 0.01 + math.pi * 0.015

# (sweep, pieces) for the NURBS cases: whole quarter turns and arbitrary sweeps
SWEEPS = [(HALF_PI, 1), (math.pi, 2), (3 * HALF_PI, 3), (TWO_PI, 4), (0.3, 1), (1.7, 2), (4.0, 3),
          (5.0, 4), (TWO_PI - 1e-3, 4)]


# --- sweep and length ---------------------------------------------------------------------------

@pytest.mark.parametrize("clockwise, expected", [(False, HALF_PI), (True, 3 * HALF_PI)])
def test_arc_sweep_follows_the_direction(clockwise, expected):
    arc = Arc((0.01, 0.0), (0.0, 0.01), (0.0, 0.0), clockwise)
    assert arc_sweep(arc) == pytest.approx(expected, rel=1e-15)
    assert element_length(arc) == pytest.approx(0.01 * expected, rel=1e-15)


@pytest.mark.parametrize("clockwise", [False, True])
def test_equal_start_and_end_is_a_full_circle(clockwise):
    arc = Arc((0.3, -0.2), (0.3, -0.2), (0.25, -0.2), clockwise)
    assert arc_sweep(arc) == TWO_PI
    assert element_length(arc) == pytest.approx(TWO_PI * 0.05, rel=1e-15)


def test_contour_length_is_the_sum_of_exact_element_lengths():
    assert element_length(CONTOUR[0]) == pytest.approx(0.04, rel=1e-15)
    assert elements_length(CONTOUR) == pytest.approx(CONTOUR_LENGTH, rel=1e-14)
    assert elements_length([]) == 0.0


@pytest.mark.parametrize("el", [
    Line((0.01, -0.02), (0.13, 0.07)),
    make_arc((0.1, 0.05), 0.02, 0.4, 0.3, False),
    make_arc((0.1, 0.05), 0.02, -2.0, 4.0, True),
    make_arc((-0.2, 0.1), 0.15, 1.0, TWO_PI, True),
    make_arc((0.0, 0.0), 0.003, 3.0, math.pi, False),
], ids=["line", "arc_0.3", "arc_4.0_cw", "full_circle_cw", "half"])
def test_length_equals_the_numerical_length_of_the_nurbs(el):
    nurbs = element_nurbs(el)
    dense = eval_nurbs(nurbs, np.linspace(0.0, 1.0, 200_000))
    assert element_length(el) == pytest.approx(polyline_length(dense), rel=1e-8)
    # and the project's NURBS curve accepts the definition and agrees to quadrature accuracy
    degree, knots, weights, points = nurbs
    curve = NurbsCurve(control_points=points, weights=weights, knots=knots, degree=degree)
    assert curve.arc_length() == pytest.approx(element_length(el), rel=1e-12)


# --- NURBS --------------------------------------------------------------------------------------

def test_line_nurbs_is_the_segment_at_uniform_speed():
    line = Line((0.02, -0.01), (-0.03, 0.05))
    degree, knots, weights, points = nurbs = element_nurbs(line)
    assert degree == 2 and knots == [0, 0, 0, 1, 1, 1] and weights == [1, 1, 1]
    assert points[0] == line.start and points[-1] == line.end
    u = np.linspace(0, 1, 101)
    expected = np.asarray(line.start) + u[:, None] * (np.asarray(line.end) - np.asarray(line.start))
    assert np.allclose(eval_nurbs(nurbs, u), expected, rtol=0, atol=1e-16)


def assert_exact_arc(arc: Arc, nurbs, pieces: int, sweep: float, n_eval: int) -> None:
    """Structure of the NURBS, and its dense evaluation lies on the arc, in the right direction,
    from start to end, turning through ``sweep``."""
    degree, knots, weights, points = nurbs
    assert degree == 2 and len(points) == 2 * pieces + 1 and len(weights) == len(points)
    assert len(knots) == len(points) + degree + 1
    assert knots[:3] == [0, 0, 0] and knots[-3:] == [1, 1, 1] and np.all(np.diff(knots) >= 0)
    assert np.allclose(knots[3:-3], np.repeat(np.arange(1, pieces) / pieces, 2), rtol=0, atol=1e-15)
    assert weights[::2] == [1.0] * (pieces + 1)
    assert np.allclose(weights[1::2], math.cos(sweep / pieces / 2), rtol=1e-14)
    assert points[0] == tuple(arc.start) and points[-1] == tuple(arc.end)

    r = math.hypot(arc.start[0] - arc.center[0], arc.start[1] - arc.center[1])
    pts = eval_nurbs(nurbs, np.linspace(0.0, 1.0, n_eval))
    radius = np.hypot(*(pts - np.asarray(arc.center)).T)
    assert np.max(np.abs(radius - r)) <= 1e-12 * r
    assert np.allclose(pts[0], arc.start, rtol=0, atol=1e-15) and np.allclose(pts[-1], arc.end, rtol=0, atol=1e-15)
    turns = travel_angles(pts, arc.center)
    assert np.all(turns < 0) if arc.clockwise else np.all(turns > 0)
    assert abs(np.sum(turns)) == pytest.approx(arc_sweep(arc), rel=1e-12)
    assert arc_sweep(arc) == pytest.approx(sweep, rel=1e-12)


@pytest.mark.parametrize("clockwise", [False, True], ids=["ccw", "cw"])
@pytest.mark.parametrize("sweep, pieces", SWEEPS, ids=[f"{s:.4g}" for s, _ in SWEEPS])
def test_arc_nurbs_is_exact(sweep, pieces, clockwise):
    arc = make_arc((0.12, -0.05), 0.025, 0.7 if clockwise else -2.9, sweep, clockwise)
    assert_exact_arc(arc, element_nurbs(arc), pieces, sweep, 20_001)


@pytest.mark.parametrize("clockwise", [False, True])
def test_whole_quarter_turns_from_rounded_end_points_keep_their_piece_count(clockwise):
    # End points from cos/sin of exact k quarter turns: the sweep lands a hair either side of
    # k pi/2, and one rounded up must not add a needless (near-zero) piece.
    rounded_up = 0
    for k in (1, 2, 3):
        for a0 in np.round(np.linspace(-3.1, 3.1, 621), 4):
            arc = make_arc((0.0, 0.0), 0.01, float(a0), k * HALF_PI, clockwise)
            assert arc_sweep(arc) == pytest.approx(k * HALF_PI, rel=1e-14)
            rounded_up += arc_sweep(arc) > k * HALF_PI
            assert len(element_nurbs(arc)[3]) == 2 * k + 1
    assert rounded_up > 0  # the case the test is about does occur


def test_arc_sweep_stays_in_range_for_a_degenerate_arc():
    # distinct end points at the same polar angle (mismatched radii): a full turn, never 0
    assert arc_sweep(Arc((0.01, 0.0), (0.02, 0.0), (0.0, 0.0), clockwise=False)) == TWO_PI
    assert arc_sweep(Arc((0.01, 0.0), (0.02, 0.0), (0.0, 0.0), clockwise=True)) == TWO_PI


@settings(max_examples=60, deadline=None)
@given(cx=st.floats(-0.2, 0.2), cy=st.floats(-0.2, 0.2), r=st.floats(1e-3, 0.5), a0=st.floats(-math.pi, math.pi),
       sweep=st.one_of(st.floats(1e-3, TWO_PI), st.just(TWO_PI)), clockwise=st.booleans())
def test_random_arc_nurbs_is_exact(cx, cy, r, a0, sweep, clockwise):
    arc = make_arc((cx, cy), r, a0, sweep, clockwise)
    pieces = max(1, math.ceil(arc_sweep(arc) / HALF_PI - 1e-9))
    assert_exact_arc(arc, element_nurbs(arc), pieces, sweep, 2_001)


# --- distances ----------------------------------------------------------------------------------

def test_points_on_the_contour_are_at_zero_distance():
    on = np.vstack([eval_nurbs(element_nurbs(el), np.linspace(0, 1, 97)) for el in CONTOUR])
    assert np.max(contour_distance(on, CONTOUR)) < 1e-15


def test_line_distance_is_perpendicular_inside_and_to_the_end_outside():
    line = [Line((0.0, 0.0), (0.03, 0.04))]  # length 50 mm along (0.6, 0.8)
    normal, along = np.array([-0.8, 0.6]), np.array([0.6, 0.8])
    pts = np.array([0.02 * along + 0.007 * normal, 0.05 * along - 0.003 * normal,
                    0.06 * along + 0.004 * normal, -0.01 * along])
    assert contour_distance(pts, line) == pytest.approx([0.007, 0.003, math.hypot(0.01, 0.004), 0.01], rel=1e-13)


@pytest.mark.parametrize("clockwise", [False, True])
def test_radial_offset_from_an_arc_is_the_distance(clockwise):
    arc = make_arc((0.05, -0.02), 0.01, 0.5, 2.0, clockwise)
    sign = -1 if clockwise else 1
    theta = 0.5 + sign * np.linspace(0.01, 1.99, 23)  # strictly inside the angular extent
    d = np.linspace(-0.0095, 0.02, 31)
    t, dd = (a.ravel() for a in np.meshgrid(theta, d))
    pts = np.array(arc.center) + ((0.01 + dd) * np.array([np.cos(t), np.sin(t)])).T
    assert np.allclose(contour_distance(pts, [arc]), np.abs(dd), rtol=1e-9, atol=1e-15)


def test_point_near_the_centre_outside_the_extent_goes_to_the_nearer_end():
    p = np.array([[-0.001, -0.002]])  # polar angle about 243 deg, 2.2 mm from the centre
    quarter_ccw = Arc((0.01, 0.0), (0.0, 0.01), (0.0, 0.0), clockwise=False)
    quarter_cw = Arc((0.0, 0.01), (0.01, 0.0), (0.0, 0.0), clockwise=True)  # the same point set
    for arc in (quarter_ccw, quarter_cw):
        assert contour_distance(p, [arc])[0] == pytest.approx(math.hypot(0.011, 0.002), rel=1e-14)
    # the other way round the point is inside the 270 deg extent: the radial distance
    three_quarter = Arc((0.01, 0.0), (0.0, 0.01), (0.0, 0.0), clockwise=True)
    assert contour_distance(p, [three_quarter])[0] == pytest.approx(0.01 - math.hypot(0.001, 0.002), rel=1e-14)


def test_full_circle_distance_is_radial_everywhere():
    circle = [Arc((0.02, 0.0), (0.02, 0.0), (0.0, 0.0), clockwise=True)]
    pts = np.random.default_rng(1).uniform(-0.05, 0.05, (500, 2))
    assert np.allclose(contour_distance(pts, circle), np.abs(np.hypot(*pts.T) - 0.02), rtol=1e-12, atol=1e-16)


def test_contour_distance_matches_brute_force_on_a_mixed_contour():
    rng = np.random.default_rng(7)
    spread = rng.uniform([-0.03, -0.03], [0.08, 0.06], (3000, 2))
    # and points within 1 mm of the contour, where the angular-extent decisions matter most
    on, _ = sample_elements(CONTOUR, 1e-4)
    near = on + rng.uniform(-1e-3, 1e-3, on.shape)
    assert_matches_brute_force(np.vstack([spread, near]), CONTOUR, spacing=2e-5)


@pytest.mark.parametrize("clockwise", [False, True])
def test_distance_just_past_the_arc_ends_is_the_chord_to_the_end(clockwise):
    r, a0, sweep, delta = 0.01, 0.3, 1.2, 1e-6
    arc = make_arc((0.0, 0.0), r, a0, sweep, clockwise)
    sign = -1 if clockwise else 1
    t = np.array([a0 - sign * delta, a0 + sign * (sweep + delta),  # just outside either end
                  a0 + sign * delta, a0 + sign * (sweep - delta)])  # just inside
    pts = r * np.column_stack([np.cos(t), np.sin(t)])
    chord = 2 * r * math.sin(delta / 2)
    assert np.allclose(contour_distance(pts, [arc]), [chord, chord, 0, 0], rtol=1e-6, atol=1e-17)


@settings(max_examples=40, deadline=None)
@given(cx=st.floats(-0.1, 0.1), cy=st.floats(-0.1, 0.1), r=st.floats(1e-3, 0.05), a0=st.floats(-math.pi, math.pi),
       sweep=st.one_of(st.floats(1e-2, TWO_PI), st.just(TWO_PI)), clockwise=st.booleans(),
       seed=st.integers(0, 2**32 - 1))
def test_random_arc_distance_matches_brute_force(cx, cy, r, a0, sweep, clockwise, seed):
    arc = make_arc((cx, cy), r, a0, sweep, clockwise)
    pts = np.array([cx, cy]) + np.random.default_rng(seed).uniform(-2 * r, 2 * r, (300, 2))
    assert_matches_brute_force(pts, [arc], spacing=r * 2e-3)


def test_distance_input_shapes():
    assert contour_distance(np.zeros((0, 2)), CONTOUR).shape == (0,)
    assert np.all(np.isinf(contour_distance([[0.0, 0.0]], [])))
    with pytest.raises(ValueError, match=r"shape \(m, 2\)"):
        contour_distance([0.0, 0.0], CONTOUR)


# --- validation ---------------------------------------------------------------------------------

def test_valid_contours_pass():
    check_contour(CONTOUR)
    check_contour([Arc((0.02, 0.0), (0.02, 0.0), (0.0, 0.0), clockwise=False)])
    nudged = [CONTOUR[0], Line((0.04 + 5e-13, 0.0), (0.05, 0.0))]  # gap below 1e-12 m
    check_contour(nudged)
    # radius mismatch within 1e-9 m + 1e-9 relative: 1.01e-9 m at r = 10 mm, 2e-9 m at r = 1 m
    check_contour([Arc((0.01, 0.0), (0.0, 0.01 + 0.9e-9), (0.0, 0.0), clockwise=False)])
    check_contour([Arc((1.0, 0.0), (0.0, 1.0 + 1.5e-9), (0.0, 0.0), clockwise=False)])


@pytest.mark.parametrize("elements, pattern", [
    ([CONTOUR[0], Line((0.04, 0.0), (0.04, 0.0))], r"element 1: zero-length line"),
    ([Arc((0.01, 0.0), (0.0, 0.010001), (0.0, 0.0), clockwise=False)],
     r"element 0: arc start radius 10 mm and end radius 10\.001 mm differ"),
    ([Arc((0.01, 0.0), (0.0, 0.01 + 1.2e-9), (0.0, 0.0), clockwise=True)],
     r"start radius 10 mm and end radius 10\.0000012 mm"),
    ([Arc((1.0, 0.0), (0.0, 1.0 + 2.5e-9), (0.0, 0.0), clockwise=True)],
     r"start radius 1000 mm and end radius 1000\.0000025 mm"),
    ([Arc((0.01, 0.0), (0.02, 0.0), (0.01, 0.0), clockwise=False)], r"element 0: arc radius is zero"),
    (CONTOUR[:3] + [Line((0.02, 0.02 + 1e-9), (0.0, 0.02))], r"element 3 starts at .* but element 2 ends at"),
    ([CONTOUR[0], Line((0.05, 0.0), (0.06, 0.0))], r"element 1 .*do not join \(gap 10 mm\)"),
    ([Line((0.0, float("nan")), (0.01, 0.0))], r"element 0: coordinates must be finite"),
])
def test_invalid_contours_are_clear_errors(elements, pattern):
    with pytest.raises(ValueError, match=pattern):
        check_contour(elements)


def test_unknown_element_type_is_rejected():
    with pytest.raises(TypeError, match="Line or an Arc"):
        check_contour([((0, 0), (1, 0))])
    with pytest.raises(TypeError, match="Line or an Arc"):
        element_length("G01")
