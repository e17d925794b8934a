"""Every row of docs/faults.md, run: each injected fault is detected as the table says (or, for
those the card cannot see, the run finishes), the machine ends at rest, and nothing is left
behind (planner process, whiteboard segment, partial run directory)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cnc_twin.studies.fault_catalog import CASES, markdown, run_case
from cnc_twin.scenario.load import scenario_from_dict
from cnc_twin.run.twin import run_scenario


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_fault_case(case):
    row = run_case(case)
    assert row.leftovers == []
    assert (row.code, row.stop) == (case.expect_code, case.expect_stop), row.message
    if case.expect_code == "NONE":
        assert row.final_state == "FINISHED"
    else:
        assert row.final_state == "FAULT", "the machine must come to rest in FAULT"
        assert 0.0 <= row.detected_ms <= case.within_ms
        assert row.at_rest_ms >= row.detected_ms
    assert row.ok
    if case.expect_code == "FORCE_LIMIT":
        assert row.extra["retract_mm"] == pytest.approx(5.0, abs=0.1)
    if case.fault is not None and case.fault["type"] == "encoder_loss" and case.expect_code == "NONE":
        assert row.extra["x_off_mm"] == pytest.approx(0.1, abs=0.005)  # 100 counts of 1 um


def test_markdown_has_a_row_per_case():
    rows = [run_case(CASES[0])] * len(CASES)
    assert len(markdown(rows).splitlines()) == len(CASES) + 2


JOG = {"name": "jog", "program": {"type": "point_to_point", "moves": [{"X": 200, "Y": 100, "feed": 12000},
                                                                     {"X": 0, "Y": 0}]}}


def test_soft_limit_at_run_time_clamps_the_command_and_stops():
    """The load check refuses programs beyond the soft limits; with limits tightened after
    loading (as a force loop's depth or an override could do it) the card clamps and stops."""
    sc = scenario_from_dict(JOG)
    x = dataclasses.replace(sc.axes[0], soft_limits=(-0.05, 0.05))
    sc = dataclasses.replace(sc, axes=(x, *sc.axes[1:]))
    result = run_scenario(sc)
    fault = result.metrics["fault"]
    assert (fault["code"], fault["stop"]) == ("SOFT_LIMIT", "controlled")
    assert result.metrics["final_state"] == "FAULT"
    command = np.asarray(result.trace.columns()["command_X"])
    limit_counts = (0.05 - sc.home[0]) * sc.axes[0].counts_per_unit
    assert command.max() <= limit_counts + 1e-6
    assert command.max() == pytest.approx(limit_counts)


def test_encoder_noise_is_seeded():
    raw = {**JOG, "faults": [{"type": "encoder_noise", "at": 0.2, "axis": "Y", "amplitude": 20, "duration": 0.1}]}
    a = run_scenario(scenario_from_dict(raw)).trace.columns()
    b = run_scenario(scenario_from_dict(raw)).trace.columns()
    c = run_scenario(scenario_from_dict({**raw, "seed": 1})).trace.columns()
    assert all(np.array_equal(a[k], b[k]) for k in a)
    assert not np.array_equal(a["actual_Y"], c["actual_Y"])


def test_a_harsher_fault_escalates_the_stop():
    """A controlled stop (planner killed) followed by a dead DAC: the following error then
    disables the drives, and both faults are listed."""
    raw = {**JOG, "faults": [{"type": "planner_kill", "at": 0.3}, {"type": "dac_stuck", "at": 0.301, "axis": "X"}]}
    result = run_scenario(scenario_from_dict(raw))
    codes = [(f["code"], f["stop"]) for f in result.metrics["faults"]]
    assert codes[0] == ("PLANNER_LOST", "controlled")
    assert ("FOLLOWING_ERROR", "disable") in codes
    assert result.metrics["fault"]["code"] == "PLANNER_LOST"
    assert result.metrics["final_state"] == "FAULT"


@pytest.mark.parametrize("fault, key, fragment", [
    ({"type": "encoder_loss", "at": 0.1, "axis": "W", "counts": 5}, "faults[0].axis", "X"),
    ({"type": "collision", "position": [0, 0, 0], "size": [1, 0, 1]}, "faults[0].size", "> 0"),
    ({"type": "torque_drop", "at": 0.1, "axis": "X", "fraction": 1.5}, "faults[0].fraction", "less than 1"),
    ({"type": "dsp_hang", "at": 0.1}, "faults[0].duration", "missing"),
])
def test_bad_fault_specs_name_the_key(fault, key, fragment):
    from cnc_twin.core.errors import ScenarioError

    with pytest.raises(ScenarioError) as info:
        scenario_from_dict({**JOG, "faults": [fault]})
    assert info.value.key_path == key and fragment in info.value.message


def test_soft_limits_must_lie_within_the_travel():
    from cnc_twin.core.errors import ScenarioError

    with pytest.raises(ScenarioError) as info:
        scenario_from_dict({**JOG, "axes": {"X": {"soft_limits": [-450, 100]}}})
    assert info.value.key_path == "axes.X.soft_limits" and "travel -400..400 mm" in info.value.message
