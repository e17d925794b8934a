"""The compiled knot insertion (:func:`cnc_twin.geometry.bezier.bezier_pieces`) gives the pieces
Boehm's insertion gives on numpy's rows, bit for bit, for random clamped NURBS of degree 1 to 5
with repeated interior knots; and the pieces are the curve (scipy's B-spline at the cuts)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import BSpline

from cnc_twin.geometry.bezier import bezier_pieces, homogeneous


def _boehm_on_rows(points, weights, knots, degree):
    """The reference: one knot at a time, each new point a numpy row sum (The NURBS Book A5.1)."""
    Pw = homogeneous(points, weights)
    U = np.asarray(knots, dtype=np.float64)
    p = int(degree)
    for u in np.unique(U[p + 1:len(U) - p - 1]):
        for _ in range(p - int(np.count_nonzero(U == u))):
            k = int(np.searchsorted(U, u, side="right")) - 1
            out = np.empty((len(Pw) + 1, 4))
            out[:k - p + 1] = Pw[:k - p + 1]
            out[k + 1:] = Pw[k:]
            for i in range(k - p + 1, k + 1):
                alpha = (u - U[i]) / (U[i + p] - U[i])
                out[i] = alpha * Pw[i] + (1.0 - alpha) * Pw[i - 1]
            Pw, U = out, np.insert(U, k + 1, u)
    return [Pw[i * p:i * p + p + 1].copy() for i in range(len(Pw) // p) if i * p + p < len(Pw)]


@st.composite
def nurbs(draw):
    degree = draw(st.integers(1, 5))
    spans = draw(st.lists(st.integers(1, 3), min_size=1, max_size=8))  # each interior knot's multiplicity
    breaks = np.cumsum([0.0] + draw(st.lists(st.floats(0.01, 10.0), min_size=len(spans), max_size=len(spans))))
    inner = [b for b, r in zip(breaks[1:-1], spans) for _ in range(min(r, degree))]
    knots = [breaks[0]] * (degree + 1) + inner + [breaks[-1]] * (degree + 1)
    n = len(knots) - degree - 1
    points = np.array(draw(st.lists(st.tuples(*[st.floats(-100, 100)] * 3), min_size=n, max_size=n)))
    weights = np.array(draw(st.lists(st.floats(0.2, 5.0), min_size=n, max_size=n)))
    return points, weights, np.array(knots), degree


@settings(max_examples=150, deadline=None)
@given(curve=nurbs())
def test_the_compiled_insertion_is_boehm_on_numpy_rows_bit_for_bit(curve):
    points, weights, knots, degree = curve
    ours, theirs = bezier_pieces(points, weights, knots, degree), _boehm_on_rows(points, weights, knots, degree)
    assert len(ours) == len(theirs) == len(np.unique(knots)) - 1
    for a, b in zip(ours, theirs):
        assert a.shape == (degree + 1, 4) and a.tobytes() == b.tobytes()
    # the pieces are the curve: each piece's ends are the NURBS at its span's ends
    curve_h = BSpline(knots, homogeneous(points, weights), degree)
    for piece, (u0, u1) in zip(ours, zip(np.unique(knots)[:-1], np.unique(knots)[1:])):
        np.testing.assert_allclose(piece[0], curve_h(u0), rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(piece[-1], curve_h(u1 - 1e-12 * (u1 - u0)), rtol=1e-6, atol=1e-6)
