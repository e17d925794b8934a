"""Polishing in compiled batches (cnc_twin/run/period_kernel.py, period_batch.py): surface paths,
the force loop (seek, ramps, TRACK, retract), the spindle and the removal map's updates in the period kernel give
the same trace, removal map and figures as the card's Python task (``batch=False``) and as the
pure-Python reference (``compiled=False``), bit for bit; and the batches carry nearly the whole run.
Cases: the freeform face, the flat plate, a G-code path under M100, a leaning tool with a force
profile, a force limit tripping in the middle of a pass (the retract), the feed adaptation (a
force step). All on the rigid machine (the batches are the card's, the same on either; the pure-Python
reference runs several times faster there); the compliant default's drives' loops in batches
against the reference: tests/test_servo_kernel.py."""

from __future__ import annotations

import numpy as np
import pytest

from cnc_twin import load_scenario
from cnc_twin.polishing import removal_kernel as rk
from cnc_twin.run.twin import Twin
from cnc_twin.scenario.resources import BUNDLED_MACHINES, scenarios_dir

TIMING_KEYS = {"wall_time_s", "real_time_factor", "whiteboard", "path", "memory_mb"}
"""wall-clock figures, different between any two runs"""
RIGID = dict(BUNDLED_MACHINES["rigid"])
SHORT_FREEFORM = {"program.path.margin": 45.0, **RIGID}
"""two passes of the freeform raster (20 s simulated instead of 46), on the rigid machine"""
FIRST_PASS = {**SHORT_FREEFORM, "max_time": 10.0}
"""its first 10 s: the seek, the first pass (the force step of the cases below comes at 6.6 s,
the spike at 8 s) and the move to the second"""


def _same(a, b) -> None:
    """The same trace, metrics (but the clock's), removal map and removal figures (but the cost)."""
    (ra, ta), (rb, tb) = a, b
    cols_a, cols_b = ra.trace.columns(), rb.trace.columns()
    assert cols_a.keys() == cols_b.keys()
    for key in cols_a:
        assert np.array_equal(cols_a[key], cols_b[key]), key
    for key in ra.metrics.keys() - TIMING_KEYS - {"polish"}:
        assert ra.metrics[key] == rb.metrics[key], key
    pa, pb = ra.metrics["polish"], rb.metrics["polish"]
    assert pa["force"] == pb["force"]
    for key in pa["removal"].keys() - {"cost_us_per_update", "cost_fraction_of_run"}:
        assert pa["removal"][key] == pb["removal"][key], key
    assert np.array_equal(ta.removal.model_removal.depth, tb.removal.model_removal.depth)
    keep = [rk.CONTACT_TIME, rk.FORCE_TIME, rk.CALLS, rk.MOST_CONTACTS]
    assert np.array_equal(ta.removal.totals[keep], tb.removal.totals[keep])


def _run(scenario, **kwargs):
    twin = Twin(scenario, **kwargs)
    return twin.run(), twin


def _batched_share(result, twin) -> float:
    return twin.period_batch.periods / len(result.trace.period_signals.per_period("state"))


@pytest.mark.parametrize("name, overrides", [("freeform_polish", SHORT_FREEFORM),
                                             ("flat_plate_polish", {"program.path.step_over": 30.0, **RIGID}),
                                             ("gcode_force", RIGID)])
def test_a_polishing_run_in_batches_is_the_python_task_and_the_reference_bit_for_bit(name, overrides):
    """gcode_force: M100 on a G-code path, the force pushing along a fixed tool axis, program
    line marks per period."""
    scenario = load_scenario(scenarios_dir() / f"{name}.yaml", overrides=overrides)
    batched = _run(scenario)
    _same(batched, _run(scenario, batch=False))
    _same(batched, _run(scenario, compiled=False))
    result, twin = batched
    assert result.status == "complete" and twin.removal.model_removal.depth.max() > 0
    # the passes, the moves between them, the seek, the ramps, the retract, the spindle's run-up
    # and the removal updates run in batches; the periods where something changes state (and
    # the first ones, while the planner still streams) on the Python task
    assert _batched_share(result, twin) > 0.95
    # the planner is woken only when its next record fits: a handful of exchanges, not one per period
    assert result.metrics["whiteboard"]["exchanges"] < 50


def test_a_leaning_tool_with_a_force_profile_in_batches():
    """Lead and tilt (the tool axis off the normal, the kinematics of A and B) and a force that
    changes along the path (the kernel's profile interpolation)."""
    scenario = load_scenario(scenarios_dir() / "freeform_polish.yaml", overrides={
        **FIRST_PASS, "program.lead": 4.0, "program.tilt": -3.0,
        "program.force.profile": [[0.0, 15.0], [60.0, 25.0], [200.0, 18.0]]})
    batched = _run(scenario)
    _same(batched, _run(scenario, compiled=False))
    setpoints = batched[0].trace.period_signals.per_period("force_setpoint")
    assert len(np.unique(setpoints)) > 1000  # the profile was followed period by period
    assert _batched_share(*batched) > 0.8


def test_a_force_limit_in_the_middle_of_a_batch_stops_at_the_same_period():
    """The force steps up along the path beyond the supervisor's maximum: the check that ends the
    batch is the one the card's task makes, so the fault, the retract and the trace are the same."""
    scenario = load_scenario(scenarios_dir() / "freeform_polish.yaml", overrides={
        **SHORT_FREEFORM, "supervisor.max_force": 24.0, "program.force.profile": [[0.0, 20.0], [80.0, 20.0],
                                                                                [90.0, 30.0]]})
    batched = _run(scenario)
    _same(batched, _run(scenario, compiled=False))
    result, twin = batched
    assert result.metrics["fault"]["code"] == "FORCE_LIMIT" and result.metrics["fault"]["stop"] == "retract"
    assert twin.period_batch.periods > 1000  # the pass ran in batches up to the trip


def test_the_feed_adaptation_hands_the_slew_to_the_python_task():
    """A force step makes the error exceed the adaptation threshold: the feed drops to half and
    comes back; the periods where the feed factor changes end their batch."""
    scenario = load_scenario(scenarios_dir() / "freeform_polish.yaml", overrides={
        **FIRST_PASS, "program.force.adapt_threshold": 0.05,
        "program.force.profile": [[0.0, 20.0], [70.0, 20.0], [71.0, 28.0]]})
    batched = _run(scenario)
    _same(batched, _run(scenario, compiled=False))
    assert batched[0].metrics["polish"]["force"]["reduced_feed_s"] > 0
    assert _batched_share(*batched) > 0.7


def test_a_force_spike_runs_the_card_in_python_and_stays_the_reference():
    """An injected force spike (the load cell reads 40 N more for 20 ms mid-pass): injected card
    faults run the card's Python servo, so no batch; the compiled path stepper and removal update
    still run, and the run is the reference's bit for bit, the spike's dip in the force included."""
    scenario = load_scenario(scenarios_dir() / "freeform_polish.yaml", overrides={
        **FIRST_PASS, "faults": [{"type": "force_spike", "at": 8.0, "force": 40.0, "duration": 20.0}]})
    compiled = _run(scenario)
    assert compiled[1].period_batch is None and compiled[1].removal.compiled
    _same(compiled, _run(scenario, compiled=False))
    assert compiled[0].metrics["polish"]["force"]["tracking"]["max_error_pct"] > 50  # the loop backed off
