"""Legacy step interpolators: point-by-point comparison and DDA, lines and arcs, in pulses.

Every lattice point within one pulse of the ideal path, the end reached exactly, the step counts
of the old cards' end-point counters, and no step backwards along the path.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnc_twin.legacy import dda
from cnc_twin.legacy import point_by_point as pbp
from cnc_twin.legacy.point_by_point import trace
from cnc_twin.legacy.quadrants import arc_pieces, end_is_on_circle

TOL = 1e-9


def rot(p: tuple[int, int], quarter_turns: int) -> tuple[int, int]:
    """Rotate a lattice point by 90 degrees CCW ``quarter_turns`` times."""
    x, y = p
    for _ in range(quarter_turns % 4):
        x, y = -y, x
    return x, y


def line_distance(points: np.ndarray, dx: int, dy: int) -> np.ndarray:
    """Distance of each point to the infinite line through (0, 0) and (dx, dy)."""
    return np.abs(dy * points[:, 0] - dx * points[:, 1]) / math.hypot(dx, dy)


def radial_error(points: np.ndarray, r2: int) -> np.ndarray:
    return np.abs(np.hypot(points[:, 0], points[:, 1]) - math.sqrt(r2))


def axis_radius(r2: int) -> int:
    """Where an arc crosses an axis, as documented: ceil(sqrt(R2 - 1)), at least 1."""
    return max(1, math.ceil(math.sqrt(r2 - 1) - 1e-12))


def expected_arc_steps(start, end, crossings: int, *, clockwise: bool) -> int:
    """Manhattan length of start -> the axis points crossed -> end, from the direction table."""
    x0, y0 = start
    a = axis_radius(x0 * x0 + y0 * y0)
    q = quadrant_of(start, clockwise)
    if clockwise:
        axis_points = [rot((a, 0), q - i) for i in range(crossings)]
    else:
        axis_points = [rot((0, a), q + i) for i in range(crossings)]
    pts = [start, *axis_points, end]
    return sum(abs(p[0] - q_[0]) + abs(p[1] - q_[1]) for p, q_ in zip(pts, pts[1:]))


def quadrant_of(p, clockwise: bool) -> int:
    """Quadrant 0..3 (I..IV) of a point strictly inside one."""
    x, y = p
    assert x != 0 and y != 0
    return {(True, True): 0, (False, True): 1, (False, False): 2, (True, False): 3}[(x > 0, y > 0)]


def lattice_end(r2: int, angle: float) -> tuple[int, int]:
    """A valid arc end near ``angle``: round onto the lattice, then step the larger coordinate
    towards the circle until it is a lattice neighbour of it (valid by construction)."""
    r = math.sqrt(r2)
    x, y = round(r * math.cos(angle)), round(r * math.sin(angle))
    while not end_is_on_circle(r2, x, y):
        outside = x * x + y * y > r2
        if abs(x) >= abs(y):
            x += (-1 if x > 0 else 1) if outside else (1 if x >= 0 else -1)
        else:
            y += (-1 if y > 0 else 1) if outside else (1 if y >= 0 else -1)
    return x, y


def arc_steps(module, start, end, *, clockwise: bool, **kw) -> np.ndarray:
    """The arc's steps as an (n, 2) array, with a bounded iteration so that a generator that
    hangs (an axis owing steps it can never make) fails the test instead of stalling it."""
    r2 = start[0] ** 2 + start[1] ** 2
    budget = 5 * 4 * 2 ** (axis_radius(r2).bit_length() + dda.GUARD_BITS) + 16
    steps = list(itertools.islice(module.arc(*start, *end, clockwise=clockwise, **kw), budget + 1))
    assert len(steps) <= budget, "arc did not finish"
    return np.array(steps, dtype=np.int64).reshape(-1, 2)


def check_arc_path(points: np.ndarray, steps: np.ndarray, r2: int, end, *, clockwise: bool) -> None:
    """End exact, within one pulse of the circle, never a step against the direction of motion."""
    assert tuple(points[-1]) == tuple(end)
    assert radial_error(points, r2).max() <= 1.0 + TOL
    # cross(p, step) >= 0 for CCW: each step has no component going back along the arc.
    cross = points[:-1, 0] * steps[:, 1] - points[:-1, 1] * steps[:, 0]
    assert np.all(cross <= 0) if clockwise else np.all(cross >= 0)


# --- point-by-point: lines -------------------------------------------------------------------

OCTANTS = [(sx * big, sy * small) for sx in (1, -1) for sy in (1, -1) for big, small in ((17, 6), (6, 17))]


@pytest.mark.parametrize("dx, dy", OCTANTS + [(9, 0), (-9, 0), (0, 9), (0, -9), (7, 7), (-7, 7), (1, 1)])
def test_pbp_line_steps_one_axis_at_a_time_ends_exactly_within_one_pulse(dx, dy):
    steps = np.array(list(pbp.line(dx, dy)))
    assert len(steps) == abs(dx) + abs(dy)
    assert np.all(np.abs(steps).sum(axis=1) == 1)                  # exactly one axis, +-1
    assert np.all(steps[:, 0] * np.sign(dx) >= 0) and np.all(steps[:, 1] * np.sign(dy) >= 0)
    points = trace(steps)
    assert tuple(points[-1]) == (dx, dy)
    assert line_distance(points, dx, dy).max() <= 1.0 + TOL


def test_pbp_line_matches_the_textbook_sequence():
    # (5, 3): deviation judgement gives X Y X Y X X Y X, ending on F = 0.
    steps = list(pbp.line(5, 3))
    assert "".join("X" if sx else "Y" for sx, _ in steps) == "XYXYXXYX"


def test_pbp_zero_line_has_no_steps():
    assert list(pbp.line(0, 0)) == []
    assert trace([]).tolist() == [[0, 0]]


@settings(max_examples=300, deadline=None)
@given(st.integers(-300, 300), st.integers(-300, 300))
def test_pbp_random_lines(dx, dy):
    steps = list(pbp.line(dx, dy))
    points = trace(steps, start=(0, 0))
    assert len(steps) == abs(dx) + abs(dy)
    assert tuple(points[-1]) == (dx, dy)
    if dx or dy:
        assert line_distance(points, dx, dy).max() <= 1.0 + TOL
    # inside the bounding box: no axis overshoots its end
    assert np.all(np.abs(points[:, 0]) <= abs(dx)) and np.all(np.abs(points[:, 1]) <= abs(dy))


def test_trace_from_a_start_point():
    assert trace([(1, 0), (0, -1)], start=(5, 5)).tolist() == [[5, 5], [6, 5], [6, 4]]


# --- point-by-point and DDA: arcs --------------------------------------------------------------

# R = 25 circle: (24, 7) at 16 deg and (15, 20) at 53 deg, so both lie in the same quadrant.
CASES = [(q, k, cw) for q in range(4) for k in range(4) for cw in (False, True)]


def quadrant_case(q: int, k: int, clockwise: bool):
    """Start in quadrant q, end k quadrant boundaries further along the motion."""
    if clockwise:
        return rot((15, 20), q), rot((24, 7), q - k)
    return rot((24, 7), q), rot((15, 20), q + k)


@pytest.mark.parametrize("q, k, clockwise", CASES)
@pytest.mark.parametrize("module", [pbp, dda], ids=["pbp", "dda"])
def test_arc_from_each_quadrant_crossing_0_to_3_boundaries(module, q, k, clockwise):
    start, end = quadrant_case(q, k, clockwise)
    steps = arc_steps(module, start, end, clockwise=clockwise)
    points = trace(steps, start)
    check_arc_path(points, steps, 625, end, clockwise=clockwise)
    assert np.abs(steps).sum() == expected_arc_steps(start, end, k, clockwise=clockwise)
    assert len(arc_pieces(*start, *end, clockwise=clockwise)) == k + 1
    if module is pbp:
        assert np.all(np.abs(steps).sum(axis=1) == 1)
    else:
        assert np.all(np.abs(steps) <= 1)


@pytest.mark.parametrize("start", [(25, 0), (24, 7), (0, -25), (-15, 20), (3, 4), (1, 0), (11, 5), (-7, -3)])
@pytest.mark.parametrize("clockwise", [False, True])
@pytest.mark.parametrize("module", [pbp, dda], ids=["pbp", "dda"])
def test_full_circle_returns_to_start_in_8a_steps(module, start, clockwise):
    r2 = start[0] ** 2 + start[1] ** 2
    steps = arc_steps(module, start, start, clockwise=clockwise)
    points = trace(steps, start)
    check_arc_path(points, steps, r2, start, clockwise=clockwise)
    # every axis sweeps 0..a..0..-a..0: 4a steps each, whichever the start
    assert np.abs(steps).sum() == 8 * axis_radius(r2)
    assert {tuple(p) for p in points} >= {rot((axis_radius(r2), 0), i) for i in range(4)}


def test_pbp_quarter_circle_textbook():
    # R = 5 from (5, 0) to (0, 5) CCW: F = 0 steps -X first (inward), then F < 0 steps +Y.
    points = trace(pbp.arc(5, 0, 0, 5, clockwise=False), (5, 0))
    assert points[:4].tolist() == [[5, 0], [4, 0], [4, 1], [4, 2]]
    assert len(points) - 1 == 10


@pytest.mark.parametrize("module", [pbp, dda], ids=["pbp", "dda"])
def test_arc_rejects_ends_off_the_circle_and_zero_radius(module):
    with pytest.raises(ValueError, match="lattice circle"):
        module.arc(10, 0, 0, 12, clockwise=False)
    with pytest.raises(ValueError, match="lattice circle"):  # R + 1 outside: the band is -(2m+1)..2m-2
        module.arc(10, 0, 0, 11, clockwise=False)
    with pytest.raises(ValueError, match="lattice circle"):
        module.arc(10, 0, 0, 0, clockwise=True)
    with pytest.raises(ValueError, match="radius 0"):
        module.arc(0, 0, 1, 0, clockwise=True)
    module.arc(10, 0, 0, 9, clockwise=False)  # lattice neighbours are accepted
    module.arc(10, 0, 1, 10, clockwise=False)


arc_params = dict(
    radius=st.integers(1, 120),
    a0=st.floats(0.0, 2 * math.pi, allow_nan=False),
    a1=st.floats(0.0, 2 * math.pi, allow_nan=False),
    clockwise=st.booleans(),
)


def random_arc(radius, a0, a1):
    x0, y0 = round(radius * math.cos(a0)), round(radius * math.sin(a0))
    if x0 == 0 and y0 == 0:  # radius 1 rounds the diagonal to the centre: take the axis point
        x0 = 1
    r2 = x0 * x0 + y0 * y0
    return (x0, y0), lattice_end(r2, a1), r2


def check_pieces(pieces, start, end, steps) -> None:
    """The quadrant pieces chain start -> end and their |dx| + |dy| add up to the step count."""
    assert pieces[0].start == start and pieces[-1].end == end
    assert all(p.end == n.start for p, n in zip(pieces, pieces[1:]))
    for p in pieces:  # each piece stays in one closed quadrant
        xs, ys = (p.start[0], p.end[0]), (p.start[1], p.end[1])
        assert (min(xs) >= 0 or max(xs) <= 0) and (min(ys) >= 0 or max(ys) <= 0)
    assert np.abs(steps).sum() == sum(sum(p.steps) for p in pieces)


@settings(max_examples=200, deadline=None)
@given(**arc_params)
def test_pbp_random_arcs(radius, a0, a1, clockwise):
    start, end, r2 = random_arc(radius, a0, a1)
    steps = arc_steps(pbp, start, end, clockwise=clockwise)
    points = trace(steps, start)
    check_arc_path(points, steps, r2, end, clockwise=clockwise)
    check_pieces(arc_pieces(*start, *end, clockwise=clockwise), start, end, steps)


@settings(max_examples=100, deadline=None)
@given(**arc_params)
def test_dda_random_arcs(radius, a0, a1, clockwise):
    start, end, r2 = random_arc(radius, a0, a1)
    steps = arc_steps(dda, start, end, clockwise=clockwise)
    assert np.all(np.abs(steps) <= 1)
    points = trace(steps, start)
    check_arc_path(points, steps, r2, end, clockwise=clockwise)
    check_pieces(arc_pieces(*start, *end, clockwise=clockwise), start, end, steps)


# --- DDA: lines and registers --------------------------------------------------------------------

@pytest.mark.parametrize("dx, dy", OCTANTS + [(9, 0), (0, -9), (-1, 0), (5, 5), (-8, 8), (1000, -3)])
@pytest.mark.parametrize("half_load", [False, True])
def test_dda_line_2n_iterations_ends_exactly_within_one_pulse(dx, dy, half_load):
    steps = np.array(list(dda.line(dx, dy, half_load=half_load)))
    n = max(abs(dx), abs(dy)).bit_length()
    assert len(steps) == 2**n                                       # one pass of the accumulators
    assert np.all(np.abs(steps) <= 1)
    assert np.all(steps[:, 0] * np.sign(dx) >= 0) and np.all(steps[:, 1] * np.sign(dy) >= 0)
    points = trace(steps)
    assert tuple(points[-1]) == (dx, dy)
    assert line_distance(points, dx, dy).max() < 1.0
    # each axis is within one pulse (half a pulse half-loaded) of the ideal point at t = k / 2^n
    ideal = np.outer(np.arange(2**n + 1) / 2**n, [dx, dy])
    assert np.abs(points - ideal).max() <= (0.5 if half_load else 1.0 - 1e-12)


def test_dda_line_overflow_is_a_step():
    # 2-bit registers, dx = 3: accumulator 3, 6-4=2, 5-4=1, 4-4=0 -> steps on iterations 2, 3, 4.
    assert [sx for sx, _ in dda.line(3, 1, bits=2)] == [0, 1, 1, 1]
    assert [sy for _, sy in dda.line(3, 1, bits=2)] == [0, 0, 0, 1]


def test_dda_line_register_width():
    assert len(list(dda.line(5, 2, bits=6))) == 64
    assert trace(dda.line(5, 2, bits=6))[-1].tolist() == [5, 2]
    with pytest.raises(ValueError, match="bits"):
        dda.line(8, 1, bits=3)
    assert list(dda.line(0, 0)) == []


@settings(max_examples=200, deadline=None)
@given(st.integers(-2000, 2000), st.integers(-2000, 2000), st.booleans())
def test_dda_random_lines(dx, dy, half_load):
    steps = list(dda.line(dx, dy, half_load=half_load))
    points = trace(steps)
    assert tuple(points[-1]) == (dx, dy)
    if dx or dy:
        assert line_distance(points, dx, dy).max() < 1.0


def test_dda_arc_default_registers_beat_the_zero_cleared_card():
    # The textbook zero-cleared n-bit DDA circle spirals outwards (module docstring); the
    # default half-loaded registers with guard bits keep within one pulse.
    start, end = (1000, 0), (0, 1000)
    classic = trace(arc_steps(dda, start, end, clockwise=False, bits=10, half_load=False), start)
    default = trace(arc_steps(dda, start, end, clockwise=False), start)
    assert radial_error(classic, 10**6).max() > 1.0
    assert radial_error(default, 10**6).max() <= 1.0
    assert tuple(classic[-1]) == tuple(default[-1]) == end   # both end exactly (per-axis counters)
    with pytest.raises(ValueError, match="bits"):
        dda.arc(*start, *end, clockwise=False, bits=9)


@pytest.mark.parametrize("start", [(2, 5), (3, 3), (6, 4), (-6, 7)])
@pytest.mark.parametrize("clockwise", [False, True])
def test_dda_arc_does_not_hang_when_an_integrand_reaches_zero(start, clockwise):
    # These circles leave the outward axis a step short at an axis point, with its integrand 0.
    r2 = start[0] ** 2 + start[1] ** 2
    steps = arc_steps(dda, start, start, clockwise=clockwise)
    check_arc_path(trace(steps, start), steps, r2, start, clockwise=clockwise)
