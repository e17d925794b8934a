"""Trapezoid profile and point-to-point planning: limits held, synchronised arrival, whole periods."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnc_twin.motion.trapezoid import Trapezoid
from cnc_twin.planner.ptp import plan_move, plan_point_to_point
from cnc_twin.motion.segments import DwellSegment, MoveSegment
from cnc_twin.scenario.load import scenario_from_dict

T = 0.001


@settings(max_examples=200)
@given(st.floats(1e-3, 1e3), st.floats(1e-3, 1e4))
def test_trapezoid_reaches_one_within_limits_in_whole_periods(v_max, a_max):
    fastest = Trapezoid.fastest(v_max, a_max)
    prof, n = fastest.quantised(T)
    assert n * T == pytest.approx(prof.duration, rel=1e-12)
    assert prof.duration >= fastest.duration - 1e-12
    assert prof.v_peak <= v_max * (1 + 1e-12) and prof.accel <= a_max * (1 + 1e-12)
    t = np.linspace(0.0, prof.duration, 2001)
    s, sd, sdd = np.array([prof.evaluate(x) for x in t]).T
    assert s[0] == 0.0 and s[-1] == pytest.approx(1.0, abs=1e-12)
    assert np.all(np.diff(s) >= -1e-12)              # monotonic
    assert np.max(np.abs(sd)) <= v_max * (1 + 1e-9)
    assert np.max(np.abs(sdd)) <= a_max * (1 + 1e-9)
    # velocity is continuous: no jump larger than a_max * dt between samples
    assert np.max(np.abs(np.diff(sd))) <= a_max * (t[1] - t[0]) * (1 + 1e-6) + 1e-12


def test_triangle_when_cruise_speed_is_not_reached():
    prof = Trapezoid.fastest(10.0, 4.0)  # v^2/a = 25 > 1
    assert prof.t_flat == 0.0 and prof.duration == pytest.approx(1.0)


@pytest.fixture(scope="module")
def axes():
    raw = {"name": "t", "program": {"type": "point_to_point", "moves": [{"X": 1}]}}
    return scenario_from_dict(raw).axes


def test_all_axes_arrive_together_and_within_their_limits(axes):
    start = (0.0,) * 6
    end = (0.2, -0.1, -0.05, math.radians(30), math.radians(-10), math.radians(720))
    seg = plan_move(start, end, axes, feed=None, period=T)
    assert isinstance(seg, MoveSegment) and seg.periods * T == pytest.approx(seg.profile.duration)
    for cfg, p0, p1 in zip(axes, start, end):
        d = abs(p1 - p0)
        assert seg.profile.v_peak * d <= cfg.max_velocity * (1 + 1e-9)
        assert seg.profile.accel * d <= cfg.max_acceleration * (1 + 1e-9)
    # at least one axis is at one of its limits (the move is as fast as allowed, up to quantisation)
    ratios = [max(seg.profile.v_peak * abs(p1 - p0) / c.max_velocity, seg.profile.accel * abs(p1 - p0) / c.max_acceleration)
              for c, p0, p1 in zip(axes, start, end)]
    assert max(ratios) > 0.98


def test_feed_caps_the_xyz_path_speed(axes):
    start, end = (0.0,) * 6, (0.3, 0.4, 0.0, 0.0, 0.0, 0.0)  # 0.5 m in XY
    seg = plan_move(start, end, axes, feed=0.1, period=T)   # 6000 mm/min
    assert seg.profile.v_peak * 0.5 <= 0.1 * (1 + 1e-12)
    assert seg.profile.v_peak * 0.5 > 0.099


def test_plan_adds_dwells_and_settle_and_skips_null_moves(axes):
    raw = {"name": "t", "program": {"type": "point_to_point", "settle": 0.25,
                                    "moves": [{"X": 10, "dwell": 0.1}, {"X": 10}, {"Y": 5}]}}
    sc = scenario_from_dict(raw)
    segs = plan_point_to_point(sc.program, sc.axes, start=sc.home, period=T)
    kinds = [type(s) for s in segs]
    assert kinds == [MoveSegment, DwellSegment, MoveSegment, DwellSegment]
    assert segs[1].periods == 100 and segs[-1].periods == 250
    assert segs[2].start[0] == pytest.approx(0.01) and segs[2].end[1] == pytest.approx(0.005)
