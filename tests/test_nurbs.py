"""NURBS geometry, S-curve profiles, the curve stepper and the feed planner."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnc_twin.dsp.curve_stepper import CurveStepper
from cnc_twin.motion.scurve import InfeasibleProfile, SCurve
from cnc_twin.geometry.nurbs import NurbsCurve, NurbsError
from cnc_twin.core.config import PathLimits
from cnc_twin.planner.feed import plan_feed

S2 = math.sqrt(2.0) / 2.0
CIRCLE = dict(
    control_points=[[1, 0], [1, 1], [0, 1], [-1, 1], [-1, 0], [-1, -1], [0, -1], [1, -1], [1, 0]],
    weights=[1, S2, 1, S2, 1, S2, 1, S2, 1],
    knots=[0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1],
    degree=2,
)
FREEFORM = dict(  # project test curve (mm -> m): cubic, rational, non-planar
    control_points=np.array([[0, 0, 0], [20, 40, 0], [60, -20, 5], [100, 50, 0], [140, 0, -5], [160, 30, 0],
                             [200, 0, 0]]) * 1e-3,
    weights=[1, 0.8, 1.2, 1, 0.7, 1.1, 1],
    knots=[0, 0, 0, 0, 0.25, 0.5, 0.75, 1, 1, 1, 1],
    degree=3,
)


def cox_de_boor(i: int, p: int, u: float, U) -> float:
    """Independent reference: the textbook basis function recurrence (right-open spans)."""
    if p == 0:
        last = U[i + 1] == U[-1] and U[i] < U[i + 1]
        return 1.0 if (U[i] <= u < U[i + 1]) or (last and u == U[-1]) else 0.0
    left = 0.0 if U[i + p] == U[i] else (u - U[i]) / (U[i + p] - U[i]) * cox_de_boor(i, p - 1, u, U)
    right = 0.0 if U[i + p + 1] == U[i + 1] else (U[i + p + 1] - u) / (U[i + p + 1] - U[i + 1]) * cox_de_boor(i + 1, p - 1, u, U)
    return left + right


def reference_point(P, W, U, p, u):
    P, W = np.asarray(P, float), np.asarray(W, float)
    N = np.array([cox_de_boor(i, p, u, U) for i in range(len(P))])
    return (N * W) @ P / (N @ W)


@pytest.mark.parametrize("spec", [CIRCLE, FREEFORM], ids=["circle", "freeform"])
def test_points_and_derivatives_match_an_independent_evaluation(spec):
    curve = NurbsCurve(**spec)
    u = np.linspace(0, 1, 57)
    ref = np.array([reference_point(spec["control_points"], spec["weights"], spec["knots"], spec["degree"], x) for x in u])
    assert np.allclose(curve.point(u), ref, atol=1e-12)
    # derivatives against central differences of the reference
    h = 1e-6
    inner = u[(u > 2e-3) & (u < 1 - 2e-3) & (np.abs(u * 4 - np.round(u * 4)) > 1e-2)]
    fd1 = np.array([(reference_point(spec["control_points"], spec["weights"], spec["knots"], spec["degree"], x + h)
                     - reference_point(spec["control_points"], spec["weights"], spec["knots"], spec["degree"], x - h)) / (2 * h)
                    for x in inner])
    assert np.allclose(curve.derivatives(inner, 1)[1], fd1, rtol=1e-6, atol=1e-8)
    ev = curve.span_evaluator()
    for x in inner[::5]:
        c, c1, c2 = ev.evaluate(float(x))
        ref0, ref1, ref2 = (d[0] for d in curve.derivatives(x, 2))
        assert np.allclose(c, ref0, atol=1e-14) and np.allclose(c1, ref1) and np.allclose(c2, ref2)


def test_rational_circle_is_exact():
    curve = NurbsCurve(**CIRCLE)
    u = np.linspace(0, 1, 1001)
    assert np.max(np.abs(np.linalg.norm(curve.point(u), axis=1) - 1.0)) < 1e-15
    assert np.allclose(curve.curvature(u), 1.0, atol=1e-12)
    assert curve.arc_length() == pytest.approx(2 * math.pi, rel=1e-14)
    assert curve.arc_length(0, 0.25) == pytest.approx(math.pi / 2, rel=1e-14)


def test_third_derivative_matches_finite_difference():
    curve = NurbsCurve(**FREEFORM)
    u = np.array([0.1, 0.4, 0.6, 0.9])
    h = 1e-5
    fd = (curve.derivatives(u + h, 2)[2] - curve.derivatives(u - h, 2)[2]) / (2 * h)
    assert np.allclose(curve.derivatives(u, 3)[3], fd, rtol=1e-5)


@pytest.mark.parametrize("change, key, fragment", [
    (dict(degree=0), "degree", ">= 1"),
    (dict(weights=[1, 1]), "weights", "weights"),
    (dict(weights=[1, 0, 1, 1, 1, 1, 1, 1, 1]), "weights", "> 0"),
    (dict(knots=[0, 0, 0, 0.5, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1]), "knots", "non-decreasing"),
    (dict(knots=[0, 0, 0.1, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1]), "knots", "clamped"),
    (dict(knots=[0, 0, 0, 1, 1, 1]), "knots", "n + degree + 1"),
    (dict(control_points=[[0, 0], [1, 1]], weights=[1, 1], knots=[0, 0, 0, 1, 1]), "control_points", "at least"),
    (dict(knots=[0, 0, 0, 0.5, 0.5, 0.5, 0.5, 0.75, 0.75, 1, 1, 1]), "knots", "more than degree"),
])
def test_invalid_definitions_are_clear_errors(change, key, fragment):
    with pytest.raises(NurbsError) as info:
        NurbsCurve(**{**CIRCLE, **change})
    assert info.value.key == key and fragment in str(info.value)


@settings(max_examples=60, deadline=None)
@given(length=st.floats(1e-4, 0.5), v0=st.floats(0, 0.2), v1=st.floats(0, 0.2), v_max=st.floats(0.01, 0.4))
def test_scurve_reaches_the_end_state_within_limits(length, v0, v1, v_max):
    a, j = 2.0, 50.0
    try:
        prof = SCurve.plan(length, v0, v1, v_max=v_max, a_max=a, j_max=j)
    except InfeasibleProfile:
        return
    t = np.linspace(0, prof.duration, 4001)
    states = np.array([prof.state(x) for x in t])
    assert states[-1, 0] == pytest.approx(length, rel=1e-9, abs=1e-12)
    end_s, end_v, _ = prof._end
    assert end_s == pytest.approx(length, rel=1e-9, abs=1e-12) and end_v == pytest.approx(v1, abs=1e-9)
    assert np.all(np.diff(states[:, 0]) >= -1e-15)
    assert np.max(states[:, 1]) <= max(v_max, v0, v1) * (1 + 1e-9)
    assert np.max(np.abs(states[:, 2])) <= a * (1 + 1e-9)
    jerk = np.diff(states[:, 2]) / np.diff(t)
    assert np.max(np.abs(jerk)) <= j * (1 + 1e-6)


def _walk(curve, ds, n, correct):
    stepper = CurveStepper(curve.span_evaluator(), 0.0, correct=correct)
    us = [0.0]
    for _ in range(n):
        stepper.step(ds)
        us.append(stepper.u)
    s = np.array([curve.arc_length(a, b) for a, b in zip(us[:-1], us[1:])])
    return np.abs(s - ds) / ds, np.array(us)


@pytest.mark.parametrize("spec", [CIRCLE, FREEFORM], ids=["circle", "freeform"])
def test_stepper_feed_fluctuation_below_1e_6_with_corrector(spec):
    curve = NurbsCurve(**spec)
    # 6000 mm/min for 1 ms on the 229 mm freeform curve; 1 mm steps on the unit (1 m) circle
    ds = 0.1e-3 if spec is FREEFORM else 1e-3
    n = int(curve.arc_length() / ds) - 2
    corrected, us = _walk(curve, ds, n, True)
    taylor, _ = _walk(curve, ds, n, False)
    assert corrected.max() <= 1e-6
    assert taylor.max() > 10 * corrected.max()  # the predictor alone is measurably worse
    # the interpolated points lie on the curve: the stepper's points against the independent evaluation
    stepper = CurveStepper(curve.span_evaluator(), 0.0)
    for k in range(n):
        point = stepper.step(ds)
        if k % 97 == 0:
            ref = reference_point(spec["control_points"], spec["weights"], spec["knots"], spec["degree"], stepper.u)
            assert np.allclose(point, ref, atol=1e-12)


def _check_stepped_plan(curve: NurbsCurve, limits: PathLimits, plan, T: float, length_rel: float = 1e-9) -> None:
    """Step the card's stepper along ``plan`` period by period and check, from the stepped
    points alone: the curve's end reached, the chord error, every axis's velocity, acceleration
    and jerk (finite differences) and the feed, each within 1.01x its limit. ``length_rel``: how
    close the blocks' length and ``curve.arc_length()`` (two quadratures) must agree."""
    assert sum(b.length for b in plan.blocks) == pytest.approx(curve.arc_length(), rel=length_rel)
    assert plan.blocks[0].v0 == 0 and plan.blocks[-1].v1 == 0
    ends = np.cumsum([0] + [b.duration for b in plan.blocks])
    offsets = np.cumsum([0] + [b.length for b in plan.blocks])

    def s_at(t):
        i = min(np.searchsorted(ends, t, "right") - 1, len(plan.blocks) - 1)
        return offsets[i] + plan.blocks[i].state(t - ends[i])[0]

    stepper = CurveStepper(curve.span_evaluator(), curve.domain[0])
    pts, us, prev = [stepper.point], [curve.domain[0]], 0.0
    for k in range(1, int(np.ceil(plan.duration / T)) + 1):
        s = s_at(k * T)
        pts.append(stepper.step(s - prev))
        us.append(stepper.u)
        prev = s
    pts, us = np.array(pts), np.array(us)
    assert np.allclose(pts[-1], curve.point(curve.domain[1])[0], atol=1e-12)
    # chord error of every period: farthest curve point from the chord, by dense sampling
    worst = 0.0
    for k in range(0, len(us) - 1, 7):
        uu = np.linspace(us[k], us[k + 1], 9)
        c = curve.point(uu)
        a, b = pts[k], pts[k + 1]
        d = b - a
        if np.dot(d, d) == 0:
            continue
        proj = a + np.outer(np.clip((c - a) @ d / np.dot(d, d), 0, 1), d)
        worst = max(worst, float(np.max(np.linalg.norm(c - proj, axis=1))))
    assert worst <= limits.chord_tolerance
    v = np.diff(pts, axis=0) / T
    acc = np.diff(v, axis=0) / T
    jerk = np.diff(acc, axis=0) / T
    assert np.all(np.max(np.abs(v), axis=0) <= np.array(limits.axis_velocity) * 1.01)
    assert np.all(np.max(np.abs(acc), axis=0) <= np.array(limits.axis_acceleration) * 1.01)
    assert np.all(np.max(np.abs(jerk), axis=0) <= np.array(limits.axis_jerk) * 1.01)
    assert np.max(np.linalg.norm(v, axis=1)) <= limits.feed * 1.01


def test_feed_plan_respects_chord_error_and_every_axis_limit():
    curve = NurbsCurve(**FREEFORM)
    T = 1e-3
    limits = PathLimits(feed=0.1, chord_tolerance=1e-6, path_acceleration=2.0, path_jerk=50.0,
                        normal_acceleration=2.0, normal_jerk=50.0, axis_velocity=(0.4, 0.4, 0.4),
                        axis_acceleration=(1.0, 0.6, 2.0), axis_jerk=(20.0, 10.0, 50.0))
    _check_stepped_plan(curve, limits, plan_feed(curve, limits, period=T), T)


def test_a_curve_of_tight_turns_runs_faster_on_a_share_of_the_tangential_budget(monkeypatch):
    """The butterfly (published, degree 4): its turns bind the jerk term j / (9 A_t |C_ss|), so the
    planner takes a share of the tangential budget and the curve runs >= 10 % faster than on the
    full one, with every limit still held period by period; a curve whose turns do not bind (the
    freeform test curve at 40 mm/s) keeps the full budget and the same plan."""
    import cnc_twin.planner.feed as feed
    from cnc_twin import load_scenario
    from cnc_twin.planner.curve_program import curve_setup
    from cnc_twin.scenario.resources import scenarios_dir

    T = 1e-3
    prog = load_scenario(scenarios_dir() / "published" / "farfalla.yaml").program
    curve, limits = curve_setup(prog)[0], prog.limits
    chosen = plan_feed(curve, limits, period=T)
    calm = NurbsCurve(**FREEFORM)
    calm_limits = PathLimits(feed=0.04, chord_tolerance=1e-6, path_acceleration=2.0, path_jerk=50.0,
                             normal_acceleration=2.0, normal_jerk=50.0, axis_velocity=(0.4, 0.4, 0.4),
                             axis_acceleration=(2.0, 2.0, 2.0), axis_jerk=(50.0, 50.0, 50.0))
    calm_plan = plan_feed(calm, calm_limits, period=T)
    monkeypatch.setattr(feed, "BUDGET_SHARES", (1.0,))
    full = plan_feed(curve, limits, period=T)
    assert chosen.duration < 0.9 * full.duration, (chosen.duration, full.duration)
    assert max(b.a_max for b in chosen.blocks) < limits.tangential_acceleration
    assert max(b.a_max for b in full.blocks) == limits.tangential_acceleration
    _check_stepped_plan(curve, limits, chosen, T, length_rel=1e-5)  # 358 mm, degree 4: quadratures differ by 1.4 um
    assert plan_feed(calm, calm_limits, period=T).blocks == calm_plan.blocks


def test_windowed_planning_commits_the_same_blocks_as_the_whole_plan():
    curve = NurbsCurve(**FREEFORM)
    limits = PathLimits(feed=0.1, chord_tolerance=1e-6, path_acceleration=2.0, path_jerk=50.0,
                        normal_acceleration=2.0, normal_jerk=50.0, axis_velocity=(0.4, 0.4, 0.4),
                        axis_acceleration=(2.0, 2.0, 2.0), axis_jerk=(50.0, 50.0, 50.0))
    whole = plan_feed(curve, limits, period=1e-3)
    windowed = plan_feed(curve, limits, period=1e-3, window=0.03)
    assert sum(b.length for b in windowed.blocks) == pytest.approx(curve.arc_length(), rel=1e-9)
    assert windowed.blocks[0].v0 == 0 and windowed.blocks[-1].v1 == 0
    # same profile: the duration differs only by blocks split at window boundaries (none here
    # change speed), well within a millisecond on a 2.5 s curve
    assert windowed.duration == pytest.approx(whole.duration, abs=1e-3)
    for a, b in zip(windowed.blocks[:-1], windowed.blocks[1:]):
        assert a.v1 == pytest.approx(b.v0)  # continuous speed across every block boundary


def test_a_keyed_window_plan_is_kept_and_handed_out_again(monkeypatch):
    """plan_feed_windows(key=...): a plan completed under a key is handed out again, the same
    blocks without sampling the curve again; another key plans; a plan left half-way keeps nothing."""
    from cnc_twin.planner import feed

    curve = NurbsCurve(**FREEFORM)
    limits = PathLimits(feed=0.1, chord_tolerance=1e-6, path_acceleration=2.0, path_jerk=50.0,
                        normal_acceleration=2.0, normal_jerk=50.0, axis_velocity=(0.4, 0.4, 0.4),
                        axis_acceleration=(2.0, 2.0, 2.0), axis_jerk=(50.0, 50.0, 50.0))
    sampled = []
    real_sample = feed._sample
    monkeypatch.setattr(feed, "_sample", lambda *args: sampled.append(1) or real_sample(*args))
    monkeypatch.setattr(feed, "_PLANS", type(feed._PLANS)())
    key = feed.plan_key("freeform", limits, 1e-3, 0.03)
    first = list(feed.plan_feed_windows(curve, limits, period=1e-3, window=0.03, key=key))
    again = list(feed.plan_feed_windows(curve, limits, period=1e-3, window=0.03, key=key))
    assert len(sampled) == 1 and len(first) > 1
    assert all(a is b for wa, wb in zip(first, again) for a, b in zip(wa, wb))
    other = feed.plan_key("freeform", limits, 1e-3, 0.05)
    next(iter(feed.plan_feed_windows(curve, limits, period=1e-3, window=0.05, key=other)))  # left half-way
    assert len(sampled) == 2 and other not in feed._PLANS
    list(feed.plan_feed_windows(curve, limits, period=1e-3, window=0.05, key=other))
    assert len(sampled) == 3 and other in feed._PLANS and feed.plan_key("freeform", limits, 1e-3, 0.05) == other
    # the samples a curve program takes before its windows: kept under their key as well
    monkeypatch.setattr(feed, "_SAMPLES", type(feed._SAMPLES)())
    taken = feed.sample_limits(curve, limits, period=1e-3, key=key)
    assert feed.sample_limits(curve, limits, period=1e-3, key=key) is taken and len(sampled) == 4
    assert feed.sample_limits(curve, limits, period=1e-3) is not taken and len(sampled) == 5


def test_arc_lengths_of_many_stretches_are_each_stretchs_arc_length_bit_for_bit():
    """One evaluation for a curve's stretches (the G-code metrics measure hundreds) gives what
    one quadrature per stretch gives, to the last bit; inside one knot span too, and empty."""
    rng = np.random.default_rng(7)
    for _ in range(40):
        degree = int(rng.integers(2, 4))
        n = int(rng.integers(degree + 1, 25))
        knots = np.concatenate([np.zeros(degree + 1), np.sort(rng.random(n - degree - 1)), np.ones(degree + 1)])
        curve = NurbsCurve(rng.normal(size=(n, 3)), rng.uniform(0.5, 2.0, n), knots, degree)
        u = np.sort(rng.random((30, 2)), axis=1)
        u[0, 1] = u[0, 0]  # an empty stretch
        each = np.array([curve.arc_length(a, b) for a, b in u])
        assert np.array_equal(curve.arc_lengths(u[:, 0], u[:, 1]), each)
