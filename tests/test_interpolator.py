"""The DSP's record queue and coarse interpolator: feed override, hold and resume within limits."""

from __future__ import annotations

import numpy as np
import pytest

from cnc_twin.dsp.interpolator import SegmentInterpolator
from cnc_twin.planner.ptp import plan_move
from cnc_twin.scenario.load import scenario_from_dict
from cnc_twin.whiteboard.records import EndOfProgram, FeedOverride, Move

T = 0.001


@pytest.fixture(scope="module")
def scenario():
    return scenario_from_dict({"name": "i", "program": {"type": "point_to_point", "moves": [{"X": 1}]}})


def _move(scenario, x_end: float) -> Move:
    seg = plan_move((0.0,) * 6, (x_end, 0, 0, 0, 0, 0), scenario.axes, feed=None, period=T)
    return Move(end=seg.end, profile=seg.profile, periods=seg.periods)


def _run(interp: SegmentInterpolator, periods: int, *, hold_at=None, resume_at=None) -> np.ndarray:
    xs = []
    for k in range(periods):
        if hold_at is not None and k == hold_at:
            interp.hold = True
        if resume_at is not None and k == resume_at:
            interp.hold = False
        xs.append(interp.next_period()[0])
    return np.array(xs) / interp.counts_per_unit[0]


def _limits_held(x: np.ndarray, cfg) -> None:
    v = np.diff(x) / T
    a = np.diff(v) / T
    assert np.max(np.abs(v)) <= cfg.max_velocity * 1.001
    assert np.max(np.abs(a)) <= cfg.max_acceleration * 1.02


def test_feed_override_half_takes_twice_as_long_within_limits(scenario):
    move = _move(scenario, 0.2)
    full = SegmentInterpolator(axes=scenario.axes, power_on=scenario.home, period=T)
    full.push(1, move)
    full.push(2, EndOfProgram())
    half = SegmentInterpolator(axes=scenario.axes, power_on=scenario.home, period=T)
    half.push(1, FeedOverride(fraction=0.5))
    half.push(2, move)
    half.push(3, EndOfProgram())
    x_full = _run(full, 3 * move.periods)
    x_half = _run(half, 3 * move.periods)
    t_full = np.argmax(x_full >= 0.2 - 1e-12)
    t_half = np.argmax(x_half >= 0.2 - 1e-12)
    assert t_half == pytest.approx(2 * t_full, abs=2)
    assert x_half[-1] == pytest.approx(0.2) and half.finished and half.last_seq_executed == 3
    _limits_held(x_half, scenario.axis("X"))


def test_hold_stops_along_the_path_within_limits_and_resume_finishes(scenario):
    move = _move(scenario, 0.3)
    interp = SegmentInterpolator(axes=scenario.axes, power_on=scenario.home, period=T)
    interp.push(1, move)
    hold_at = move.periods // 2  # cruising at full speed
    x = _run(interp, 3 * move.periods, hold_at=hold_at, resume_at=hold_at + 400)
    _limits_held(x, scenario.axis("X"))
    v = np.diff(x) / T
    stopped = np.flatnonzero(np.abs(v[hold_at:hold_at + 400]) < 1e-12)
    assert len(stopped) > 100                      # it came to rest while held ...
    assert 0.0 < x[hold_at + 300] < 0.3           # ... part way along the path
    assert x[-1] == pytest.approx(0.3)             # and finished exactly on target after resuming
    assert interp.last_seq_executed == 1
