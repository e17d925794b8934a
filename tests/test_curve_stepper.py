"""The curve stepper compiled agrees with its own Python source (numba's ``py_func``) bit for bit,
and keeps the feed within 1e-6 where the parametrisation is hard (arc lengths from scipy's
B-splines, :meth:`NurbsCurve.arc_length`). The stepper's accuracy on ordinary curves is in
``tests/test_nurbs.py``."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from cnc_twin.dsp.curve_stepper import CurveStepper
from cnc_twin.geometry.nurbs import NurbsCurve

FREEFORM = NurbsCurve(np.array([[0, 0, 0], [20, 40, 0], [60, -20, 5], [100, 50, 0], [140, 0, -5], [160, 30, 0],
                                [200, 0, 0]]) * 1e-3, [1, 0.8, 1.2, 1, 0.7, 1.1, 1],
                      [0, 0, 0, 0, 0.25, 0.5, 0.75, 1, 1, 1, 1], 3)
r = math.sqrt(0.5)
CIRCLE = NurbsCurve(np.array([[1, 0, 0], [1, 1, 0], [0, 1, 0], [-1, 1, 0], [-1, 0, 0], [-1, -1, 0], [0, -1, 0],
                              [1, -1, 0], [1, 0, 0]]) * 0.03, [1, r, 1, r, 1, r, 1, r, 1],
                    [0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1], 2)
PLANAR = NurbsCurve([[0, 0], [0.01, 0.02], [0.03, -0.01], [0.05, 0.0]], None, [0, 0, 0, 0.4, 1, 1, 1], 2)


def _walk_both(curve, steps, correct):
    ev = curve.span_evaluator()
    python, compiled = CurveStepper(ev, curve.domain[0], correct=correct, compiled=False), \
        CurveStepper(ev, curve.domain[0], correct=correct)
    assert python.u == compiled.u and python.point == compiled.point
    for ds in steps:
        a, b = python.step(ds), compiled.step(ds)
        assert (python.u, a) == (compiled.u, b), ds
    return python.u


@pytest.mark.parametrize("curve", [FREEFORM, CIRCLE, PLANAR], ids=["freeform", "circle", "planar"])
@pytest.mark.parametrize("correct", [True, False], ids=["corrector", "taylor"])
def test_the_compiled_stepper_is_its_python_source_to_the_end_of_the_curve(curve, correct):
    length = curve.arc_length()
    steps = [length / 700.0 * (1.0 + 0.5 * math.sin(0.1 * k)) for k in range(1000)]  # runs past the end
    assert _walk_both(curve, [0.0, *steps, -1.0, 1e-6], correct) == curve.domain[1]


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(min_value=1e-7, max_value=3e-3), min_size=1, max_size=60))
def test_any_arc_lengths_give_the_same_parameters_and_points(steps):
    _walk_both(FREEFORM, steps, True)
    _walk_both(CIRCLE, steps, True)


def test_a_poor_prediction_gets_a_second_newton_step_in_both_steppers():
    """The dolphin's sharp corner near u = 28.5: |C'| is tiny and changes fast, the Taylor predictor
    is off by about 0.5 % of its step, and one Newton step left relative feed errors of 2.5e-6.
    With the second step the error stays within 1e-6, compiled and not, bit for bit."""
    from cnc_twin import load_scenario
    from cnc_twin.geometry.tip_path import tip_curve
    from cnc_twin.scenario.resources import scenarios_dir

    curve = tip_curve(load_scenario(scenarios_dir() / "published" / "delfino.yaml").program)
    ev = curve.span_evaluator()
    python, compiled = CurveStepper(ev, 28.25, compiled=False), CurveStepper(ev, 28.25)
    errors = []
    for ds in np.geomspace(3e-7, 5e-8, 60):  # slowing into the corner, as the planned feed does
        u0 = python.u
        a, b = python.step(ds), compiled.step(ds)
        assert (python.u, a) == (compiled.u, b)
        errors.append(abs(curve.arc_length(u0, python.u) - ds) / ds)
    assert max(errors) <= 1e-6, max(errors)


# two periods of the scroll (Scroll F) at 2400 mm/min, 1 ms, as the run stepped them: start
# parameter, arc length; one Simpson panel left relative feed errors of 1.03e-6 and 1.39e-6
SCROLL_STEPS = [(493.6431642628107, 1.3569259715560346e-05), (494.66062523814486, 1.356383184602088e-05)]


@pytest.mark.parametrize("rough", [2e-3, math.inf], ids=["refined", "one-panel"])
def test_a_slow_tight_bend_gets_a_refined_length_in_both_steppers(rough, monkeypatch):
    """The degree-5 scroll near u = 494, at the 13.6 mm/s the planner slows to there: the
    prediction is good (the first Newton correction is small) but one Simpson panel misjudges the
    length by up to 1.4e-6 of the step, because |C'| bends over it. Measured by how much |C'|
    bends, the step gets one refined Newton step; without it (ROUGH_SIMPSON = inf, seen by the
    Python source; the compiled stepper has the constant compiled in) the error is back."""
    from cnc_twin import load_scenario
    from cnc_twin.dsp import curve_stepper
    from cnc_twin.geometry.tip_path import tip_curve
    from cnc_twin.scenario.resources import scenarios_dir

    monkeypatch.setattr(curve_stepper, "ROUGH_SIMPSON", rough)
    curve = tip_curve(load_scenario(scenarios_dir() / "published" / "scroll_f.yaml").program)
    ev = curve.span_evaluator()
    errors = []
    for u0, ds in SCROLL_STEPS:
        python = CurveStepper(ev, u0, compiled=False)
        python.step(ds)
        errors.append(abs(curve.arc_length(u0, python.u) - ds) / ds)
        if rough != math.inf:
            compiled = CurveStepper(ev, u0)
            assert (compiled.step(ds), compiled.u) == (python.point, python.u)
    if rough == math.inf:
        assert max(errors) > 1e-6, errors
    else:
        assert max(errors) <= 2e-7, errors
