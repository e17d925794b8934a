"""NURBS interpolator cost per period (``python -m pytest benchmarks/ --benchmark-only``).

Target (issue #4): <= 15 us per period in Python on the 2-core development machine (embedded C
implementations report 3-4 us). ``test_stepper_taylor_only`` is the predictor without the
corrector, for comparison; ``test_coarse_period_on_circle`` is the DSP's whole coarse
interpolation period on a curve (S-curve feed, stepper, axis setpoints). Each runs with the
stepper's Python source and compiled (:mod:`cnc_twin.dsp.curve_stepper`), which the twin uses.
"""

from __future__ import annotations

import numpy as np
import pytest

from cnc_twin.dsp.curve_stepper import CurveStepper
from cnc_twin.dsp.interpolator import SegmentInterpolator
from cnc_twin.geometry.nurbs import NurbsCurve
from cnc_twin.planner.job import PlannerJob, build_program
from cnc_twin.scenario.resources import scenarios_dir
from cnc_twin.scenario.load import load_scenario

FREEFORM = NurbsCurve(np.array([[0, 0, 0], [20, 40, 0], [60, -20, 5], [100, 50, 0], [140, 0, -5], [160, 30, 0],
                                [200, 0, 0]]) * 1e-3, [1, 0.8, 1.2, 1, 0.7, 1.1, 1],
                      [0, 0, 0, 0, 0.25, 0.5, 0.75, 1, 1, 1, 1], 3)


STEPPERS = {"python": False, "compiled": True}
"""the stepper's Python source (numba's py_func) or compiled"""


def _stepper(correct: bool, kind: str):
    compiled = STEPPERS[kind]
    stepper = CurveStepper(FREEFORM.span_evaluator(), 0.0, correct=correct, compiled=compiled)

    def step():
        if stepper.u > 0.99:
            stepper.__init__(FREEFORM.span_evaluator(), 0.0, correct=correct, compiled=compiled)
        stepper.step(1e-4)  # 6 m/min for 1 ms

    return step


@pytest.mark.parametrize("kind", list(STEPPERS))
def test_stepper_with_corrector(benchmark, kind):
    benchmark(_stepper(True, kind))


@pytest.mark.parametrize("kind", list(STEPPERS))
def test_stepper_taylor_only(benchmark, kind):
    benchmark(_stepper(False, kind))


@pytest.fixture(scope="module")
def circle():
    sc = load_scenario(scenarios_dir() / "nurbs_circle.yaml")
    job = PlannerJob(program=sc.program, axes=sc.axes, home=sc.home, period=sc.timing.interpolation_period,
                     layout_words=8192, chunk_words=2048, lookahead_periods=0)
    records, _, _ = build_program(job)
    return sc, records


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "python"])
def test_coarse_period_on_circle(benchmark, circle, compiled):
    sc, records = circle

    def fresh():
        interp = SegmentInterpolator(axes=sc.axes, power_on=sc.home, period=sc.timing.interpolation_period,
                                     compiled=compiled)
        for seq, record in enumerate(records, 1):
            interp.push(seq, record)
        while interp.path_u < 0:
            interp.next_period()
        return interp

    state = {"interp": fresh()}

    def period():
        if state["interp"].path_u > 0.95:
            state["interp"] = fresh()
        state["interp"].next_period()

    benchmark(period)


def test_planning_time_per_block(benchmark):
    from cnc_twin.planner.feed import plan_feed

    sc = load_scenario(scenarios_dir() / "nurbs_freeform.yaml")
    curve = NurbsCurve(sc.program.control_points, sc.program.weights, sc.program.knots, sc.program.degree)
    plan = benchmark.pedantic(plan_feed, args=(curve, sc.program.limits), kwargs={"period": 1e-3}, rounds=3)
    per_block = benchmark.stats.stats.min / len(plan.blocks)
    execution = plan.duration / len(plan.blocks)
    benchmark.extra_info.update(blocks=len(plan.blocks), planning_s_per_block=per_block,
                                execution_s_per_block=execution)
    print(f"\n{len(plan.blocks)} blocks: planning {per_block * 1e3:.1f} ms per block, "
          f"execution {execution * 1e3:.1f} ms per block ({execution / per_block:.1f}x ahead)")
