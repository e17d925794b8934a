"""Legacy motion chip: per-cycle pulse profiles within their limits, ending exactly on target."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnc_twin.legacy.motion_chip import IndexMove, Jog, linear_move, rest_to_rest

DT = 1e-3
REL = 1e-9

# (distance, v_max, a_max, j_max): v_max and a_max reached; a_max not reached; v_max not reached
SCURVE_CASES = [(200_000, 50_000.0, 400_000.0, 8e6), (5_000, 50_000.0, 400_000.0, 8e6),
                (30_000, 1e6, 400_000.0, 8e6), (-77_777, 30_000.0, 1e5, 1e6), (3, 1e4, 1e5, 1e7)]


def assert_pulses_follow_profile(move: IndexMove) -> None:
    """Sum exact, one sign, cumulative within half a pulse of the continuous position."""
    assert move.pulses.dtype == np.int64
    assert int(move.pulses.sum()) == move.distance
    assert np.all(move.pulses * np.sign(move.distance) >= 0)
    assert list(move) == move.pulses.tolist()
    if move.distance == 0:
        assert len(move) == 0
        return
    assert np.abs(np.cumsum(move.pulses) - move.position[1:]).max() <= 0.5 + 1e-6


@pytest.mark.parametrize("distance, v_max, a_max, j_max", SCURVE_CASES)
def test_scurve_jerk_bounded_and_acceleration_continuous(distance, v_max, a_max, j_max):
    move = IndexMove(distance, v_max, a_max, j_max, DT)
    assert_pulses_follow_profile(move)
    assert np.abs(move.jerk).max() <= j_max * (1 + REL)
    # continuous acceleration: per-cycle change no more than j_max dt, from rest to rest
    assert np.abs(np.diff(move.acceleration)).max() <= j_max * DT * (1 + REL)
    assert move.acceleration[0] == 0.0 and abs(move.acceleration[-1]) <= 1e-6 * a_max
    assert np.abs(move.acceleration).max() <= a_max * (1 + REL)
    assert np.abs(move.velocity).max() <= v_max * (1 + REL)
    assert np.abs(np.diff(move.velocity)).max() <= a_max * DT * (1 + REL)
    assert move.velocity[0] == 0.0 and move.velocity[-1] == 0.0
    assert len(move) == math.ceil(move.duration / DT - 1e-9)


def test_scurve_reaches_its_limits_on_a_long_move():
    move = IndexMove(200_000, 50_000.0, 400_000.0, 8e6, DT)
    assert np.abs(move.velocity).max() == pytest.approx(50_000.0)
    assert np.abs(move.acceleration).max() == pytest.approx(400_000.0, rel=1e-3)
    assert move.pulses.max() == 50   # cruise: v_max dt pulses per cycle


@pytest.mark.parametrize("distance, v_max, a_max", [(100_000, 40_000.0, 2e5), (1_000, 40_000.0, 2e5),
                                                     (-12_345, 8_000.0, 1e6), (1, 100.0, 1e3)])
def test_trapezoid_acceleration_bounded(distance, v_max, a_max):
    move = IndexMove(distance, v_max, a_max, None, DT)
    assert_pulses_follow_profile(move)
    assert np.abs(move.acceleration).max() <= a_max * (1 + REL)
    assert np.abs(np.diff(move.velocity)).max() <= a_max * DT * (1 + REL)
    assert np.abs(move.velocity).max() <= v_max * (1 + REL)
    peak = min(v_max, math.sqrt(abs(distance) * a_max))        # triangle when v_max is not reached
    assert np.abs(move.velocity).max() == pytest.approx(peak, rel=1e-2, abs=a_max * DT)


def test_constant_speed_emits_v_dt_each_cycle():
    move = IndexMove(10_007, 25_000.0, None, None, DT)
    assert_pulses_follow_profile(move)
    assert set(move.pulses[:-1].tolist()) == {25}
    assert move.pulses[-1] == 10_007 - 25 * (len(move) - 1)
    # a fractional rate carries the remainder: 2.5 pulses per cycle alternate 2 and 3 (half up)
    move = IndexMove(1_000, 2_500.0, None, None, DT)
    assert move.pulses.sum() == 1_000 and set(move.pulses.tolist()) == {2, 3}


def test_zero_distance_and_bad_limits():
    assert len(IndexMove(0, 1e3, 1e4, 1e5, DT)) == 0
    for args in [(10, 0.0, 1e4, None, DT), (10, 1e3, -1.0, None, DT), (10, 1e3, None, 1e5, DT),
                 (10, 1e3, 1e4, 1e5, 0.0)]:
        with pytest.raises(ValueError):
            IndexMove(*args)


kinds = st.sampled_from(["constant", "trapezoid", "scurve"])


@settings(max_examples=250, deadline=None)
@given(distance=st.integers(-200_000, 200_000), v_max=st.floats(1e4, 1e6), a_max=st.floats(1e4, 1e7),
       j_max=st.floats(1e5, 1e10), kind=kinds, dt=st.sampled_from([2.5e-4, 5e-4, 1e-3, 2e-3]))
def test_index_moves_end_exactly_on_target(distance, v_max, a_max, j_max, kind, dt):
    move = IndexMove(distance, v_max, None if kind == "constant" else a_max,
                     j_max if kind == "scurve" else None, dt)
    assert_pulses_follow_profile(move)
    assert move.position[-1] == distance
    if distance == 0:
        return
    if kind != "constant":
        assert np.abs(move.acceleration).max() <= a_max * (1 + REL)
    if kind == "scurve":
        assert np.abs(np.diff(move.acceleration)).max() <= j_max * dt * (1 + REL)


def test_rest_to_rest_profile_covers_its_length():
    for limits in [(5e4, None, None), (5e4, 4e5, None), (5e4, 4e5, 8e6)]:
        profile = rest_to_rest(12_345.0, *limits)
        s, v, a, _ = profile.state(profile.duration)
        assert s == 12_345.0 and v == 0.0 and a == 0.0
        # integrating the sampled velocity gives the length back (no jump in position); the
        # constant-speed profile's velocity step costs up to half a sample interval at v_max
        t = np.linspace(0.0, profile.duration, 200_001)
        v = profile.sample(t)[1]
        assert np.trapezoid(v, t) == pytest.approx(12_345.0, abs=5e4 * (t[1] - t[0]))


# --- jog --------------------------------------------------------------------------------------

JOG_LIMITS = [(None, None), (2e5, None), (2e5, 5e6)]


@pytest.mark.parametrize("a_max, j_max", JOG_LIMITS)
@pytest.mark.parametrize("v", [30_000.0, -30_000.0])
def test_jog_reaches_its_speed_and_stops_within_the_braking_distance(v, a_max, j_max):
    jog = Jog(v, a_max, j_max, DT)
    cruise = list(itertools.islice(jog, 400))       # ramps take at most 0.15 + 0.04 s here
    assert jog.velocity == pytest.approx(v)
    assert cruise[-50:] == [int(v * DT)] * 50      # 30 pulses per cycle, signed
    braking = jog.braking_distance()
    expected = 0.0 if a_max is None else v * v / (2 * a_max) + (0.0 if j_max is None else abs(v) * a_max / (2 * j_max))
    assert braking == pytest.approx(expected, rel=1e-9)   # symmetric ramp down from cruise
    before = jog.position
    jog.stop()
    rest = list(jog)                                 # ends once the axis is at rest
    assert jog.velocity == 0.0
    travelled = jog.position - before
    assert sum(rest) == travelled and travelled * np.sign(v) >= 0
    assert abs(travelled) <= braking + 1.0           # rounding: half a pulse at each end
    assert abs(travelled) >= braking - 1.0
    assert all(p * np.sign(v) >= 0 for p in rest)


@pytest.mark.parametrize("cycles", [5, 12, 20, 33])
def test_scurve_jog_stopped_while_accelerating_keeps_acceleration_continuous(cycles):
    a_max, j_max = 2e5, 5e6  # ramp: 40 ms jerk up, 110 ms at a_max, 40 ms jerk down
    jog = Jog(40_000.0, a_max, j_max, DT)
    accel = [jog.acceleration]
    for _ in itertools.islice(jog, cycles):
        accel.append(jog.acceleration)
    braking = jog.braking_distance()
    before = jog.position
    jog.stop()
    for _ in jog:
        accel.append(jog.acceleration)
        assert jog.velocity >= -1e-6                  # never reverses
    assert np.abs(np.diff(accel)).max() <= j_max * DT * (1 + REL)
    assert np.abs(accel).max() <= a_max * (1 + REL)
    assert abs(jog.position - before - braking) <= 1.0


def test_constant_speed_jog_stops_at_once():
    jog = Jog(-12_000.0, None, None, DT)
    assert list(itertools.islice(jog, 3)) == [-12, -12, -12]
    jog.stop()
    assert list(jog) == [0] and jog.position == -36


# --- multi-axis linear interpolation ------------------------------------------------------------

def check_linear(deltas, pulses: np.ndarray) -> None:
    d = np.array(deltas, dtype=float)
    assert pulses.dtype == np.int64 and pulses.shape[1] == len(deltas)
    assert pulses.sum(axis=0).tolist() == list(deltas)
    points = np.vstack([np.zeros(len(deltas)), np.cumsum(pulses, axis=0)])
    # distance of each lattice point to the infinite line through 0 and d
    u = d / np.linalg.norm(d)
    off = points - np.outer(points @ u, u)
    assert np.linalg.norm(off, axis=1).max() <= 1.0 + 1e-9
    # and along it, between the ends: no axis runs backwards
    assert np.all(pulses * np.sign(d) >= 0)


@pytest.mark.parametrize("deltas", [(1000, -300, 7, 0), (5, 5, 5, 5), (-40_000,), (0, 123), (17, -4_000, 2_999)])
@pytest.mark.parametrize("a_path, j_path", [(None, None), (1e5, None), (1e5, 1e7)])
def test_linear_move_ends_exactly_and_stays_on_the_line(deltas, a_path, j_path):
    pulses = linear_move(deltas, 20_000.0, a_path, j_path, DT)
    check_linear(deltas, pulses)
    # the path speed stays within v_path (plus one pulse of rounding per axis per cycle)
    path_step = np.linalg.norm(pulses, axis=1)
    assert path_step.max() <= 20_000.0 * DT + math.sqrt(len(deltas))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(-50_000, 50_000), min_size=1, max_size=4), st.floats(5e3, 1e6),
       st.floats(1e4, 1e7), st.floats(1e5, 1e10), kinds)
def test_random_linear_moves(deltas, v_path, a_path, j_path, kind):
    a = None if kind == "constant" else a_path
    j = j_path if kind == "scurve" else None
    pulses = linear_move(tuple(deltas), v_path, a, j, DT)
    if not any(deltas):
        assert pulses.shape == (0, len(deltas))
        return
    check_linear(deltas, pulses)


def test_linear_move_has_at_most_four_axes():
    with pytest.raises(ValueError, match="axes"):
        linear_move((1, 2, 3, 4, 5), 1e3, None, None, DT)
    with pytest.raises(ValueError, match="32-bit"):
        linear_move((1 << 31, 0), 1e3, None, None, DT)
