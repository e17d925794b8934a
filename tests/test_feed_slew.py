"""Holds, resumes and override changes on a curve are jerk-limited: checked on the transition
itself and on the commanded axis positions of a published curve (finite differences)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnc_twin.dsp import feed_slew
from cnc_twin.dsp.interpolator import SegmentInterpolator
from cnc_twin.planner.curve_program import CurvePlan
from cnc_twin.scenario.resources import scenarios_dir
from cnc_twin import load_scenario
from cnc_twin.whiteboard.records import CurveBlock, CurveGeometry, EndOfProgram

A, J = 1.0, 20.0  # [m/s^2], [m/s^3]


@settings(max_examples=300, deadline=None)
@given(sigma0=st.floats(0, 0.2), sigma1=st.floats(0, 0.2), alpha0=st.floats(-A, A), alpha1=st.floats(-A, A))
def test_a_transition_ends_on_its_target_within_the_limits(sigma0, sigma1, alpha0, alpha1):
    plan = feed_slew.transition(sigma0, alpha0, sigma1, alpha1, A, J)
    assert abs(plan[0]) == J and abs(plan[3]) == J and min(plan[1:3] + plan[4:]) >= 0.0
    end = feed_slew.duration(plan)
    _, sigma, alpha = feed_slew.follow(sigma0, alpha0, plan, end)
    assert sigma == pytest.approx(sigma1, abs=1e-12) and alpha == pytest.approx(alpha1, abs=1e-12)
    # the acceleration is piecewise linear: its extremes are at the phase ends
    corners = np.cumsum([0.0, plan[1], plan[2], plan[4]])
    peaks = [abs(feed_slew.follow(sigma0, alpha0, plan, t)[2]) for t in corners]
    assert max(peaks) <= max(A, abs(alpha0), abs(alpha1)) * (1 + 1e-12)


@settings(max_examples=300, deadline=None)
@given(speed=st.floats(0, 0.2), alpha=st.floats(-A, A))
def test_a_stop_fits_in_the_stopping_distance(speed, alpha):
    if alpha < 0.0 and speed < alpha * alpha / (2 * J):  # decelerating too hard to end at rest
        return
    plan = feed_slew.transition(speed, alpha, 0.0, 0.0, A, J)
    covered, _, _ = feed_slew.follow(speed, alpha, plan, feed_slew.duration(plan))
    assert covered <= feed_slew.stop_distance(speed, alpha, A, J, 0.0) / feed_slew.STOP_MARGIN * (1 + 1e-12) + 1e-15


T = 0.0005  # [s] half a millisecond: the finite differences see a jerk step hardest at short periods


@pytest.fixture(scope="module")
def farfalla():
    scenario = load_scenario(scenarios_dir() / "published" / "farfalla.yaml", overrides={"timing.interpolation_period": T * 1e3})
    plan = CurvePlan(scenario.program, scenario.axes, scenario.home, T, window=0.05)
    chunks = plan.chunks()
    records = [r for r in next(chunks)[0] if isinstance(r, CurveGeometry)]
    windows = [[r for r in chunk if isinstance(r, CurveBlock)] for chunk, _ in chunks]
    return scenario, records + windows[0], [b for w in windows[1:] for b in w]


def _commanded(interp: SegmentInterpolator, periods: int, step=None) -> list[np.ndarray]:
    out = []
    for k in range(periods):
        if step is not None:
            step(k)
        out.append(np.asarray(interp._position_of(interp.next_period())))
        if interp.finished:
            break
    return out


def _peaks_within_limits(positions: list[np.ndarray], scenario) -> dict[str, float]:
    """Each axis's largest |velocity|, |acceleration|, |jerk| by finite differences of the commanded
    positions, over its limit (asserted <= 1.01); the worst ratios by kind."""
    q = np.array(positions)[:, :3]
    worst = {}
    for order, kind in ((1, "velocity"), (2, "acceleration"), (3, "jerk")):
        d = np.abs(np.diff(q, order, axis=0)).max(axis=0) / T**order
        limits = np.array([getattr(c, f"max_{kind}") for c in scenario.axes[:3]])
        worst[kind] = float(np.max(d / limits))
        assert worst[kind] <= 1.01, (kind, d / limits)
    return worst


def test_a_starved_curve_holds_and_resumes_within_every_axis_limit(farfalla):
    """Only the first 50 mm window reaches the card: it runs dry at speed, stops inside the path it
    has, and resumes when the rest comes; jerk included (it was 12-18x the limit)."""
    scenario, first, rest = farfalla
    interp = SegmentInterpolator(axes=scenario.axes, power_on=scenario.home, period=T)
    seq = 0
    for seq, record in enumerate(first, 1):
        interp.push(seq, record)
    held, late = [], rest + [EndOfProgram()]

    def deliver_late(k):
        if interp.holding_for_data:
            held.append(k)
            if interp.override == 0.0 and len(held) > 200 and late:  # at rest a while: the rest arrives
                for i, record in enumerate(late, seq + 1):
                    interp.push(i, record)
                late.clear()

    positions = _commanded(interp, 200_000, deliver_late)
    assert interp.finished and len(held) > 200
    worst = _peaks_within_limits(positions, scenario)
    assert worst["jerk"] > 0.1  # the check sees real motion


def test_a_feed_hold_mid_curve_stops_and_resumes_within_every_axis_limit(farfalla):
    scenario, first, rest = farfalla
    interp = SegmentInterpolator(axes=scenario.axes, power_on=scenario.home, period=T)
    for seq, record in enumerate(first + rest + [EndOfProgram()], 1):
        interp.push(seq, record)
    overrides = []

    def operator(k):
        interp.hold = 3000 <= k < 5000
        overrides.append(interp.override)

    positions = _commanded(interp, 200_000, operator)
    assert interp.finished and min(overrides[3000:5000]) == 0.0 and overrides[-1] == 1.0
    _peaks_within_limits(positions, scenario)
