"""The motion chip on the twin: home return repeatability, limit switches, events, bad programs."""

from __future__ import annotations

import numpy as np
import pytest

from cnc_twin.dsp.chip import IndexMarks
from cnc_twin.core.errors import ScenarioError
from cnc_twin.scenario.load import load_scenario, scenario_from_dict
from cnc_twin.run.twin import run_scenario
from conftest import REPO


@pytest.fixture(scope="module")
def shipped():
    scenario = load_scenario(REPO / "scenarios" / "home_and_index.yaml")
    return scenario, run_scenario(scenario)


def _events(result, name, axis=None):
    return [e for e in result.metrics["events"] if e["event"] == name and (axis is None or e["axis"] == axis)]


def test_home_return_latches_the_same_count_from_different_starts(shipped):
    scenario, result = shipped
    assert result.metrics["final_state"] == "FINISHED"
    homes = _events(result, "home_found", "X")
    assert len(homes) == 3
    assert {e["count"] for e in homes} == {365000}  # the index mark at 365 mm, to the count
    # ... although the switch tripped at different places: where each search stopped differs
    trace = result.trace
    stops = []
    t = np.asarray(trace.time)
    since = 0.0
    for e in homes:
        stops.append(trace.command[(t >= since) & (t < e["time_s"]), 0].max())
        since = e["time_s"]
    # the searches started from 0, 341.287 and 303.671 mm and overran the switch by different amounts
    assert len({round(s) for s in stops}) == 3
    # and the axis stands on its home after each return
    for e in _events(result, "motion_done", "X")[::2][:3]:
        assert e["count"] == 365000


def test_z_home_starts_on_its_switch_and_clears_it_first(shipped):
    _, result = shipped
    (home,) = _events(result, "home_found", "Z")
    assert home["count"] == -25000  # switch at -20 mm; first index pulse below it at -25 mm


def test_a_jog_into_a_limit_switch_stops_the_axis_and_says_so(shipped):
    _, result = shipped
    (hit,) = _events(result, "limit_pos", "Y")
    assert 290.0 <= hit["position"] <= 290.2  # the + limit switch at 290 mm, sampled once a period
    done = [e for e in _events(result, "motion_done", "Y") if e["time_s"] > hit["time_s"]]
    assert done and done[0]["position"] < 292.0  # stopped within the profile's braking distance


def test_events_are_in_the_trace_and_the_linear_move_ends_on_its_counts(shipped):
    _, result = shipped
    bits = result.trace.period_signals["events"]
    home_x = np.flatnonzero((bits >> 0) & 2)  # axis X (shift 0), HOME_FOUND bit
    assert len(np.unique(result.trace.period[home_x])) == 3
    linear = [e for e in result.metrics["events"] if e["event"] == "motion_done" and 28.0 < e["time_s"] < 28.2]
    assert {(e["axis"], e["count"]) for e in linear} == {("X", 325000), ("Y", 25000), ("Z", -35000)}


def test_index_marks_in_counts():
    marks = IndexMarks(1e6, 0.01, 0.005, power_on=0.0)
    assert marks.count_of(36) == 365000
    assert marks.mark_of(365000) == 36 and marks.mark_of(364999) == 35
    shifted = IndexMarks(1e6, 0.01, 0.005, power_on=0.1234567)
    assert shifted.count_of(36) == 365000 - 123456


def _chip(*commands, **extra) -> dict:
    return {"name": "chip", "program": {"type": "motion_chip", "commands": list(commands), **extra}}


@pytest.mark.parametrize("commands, key, message", [
    ([{"home": {"axis": "A"}}], "program.commands[0].home.axis", ""),
    ([{"home": {"axis": "X", "speed": 100, "creep": 200}}], "program.commands[0].home.creep", "creep"),
    ([{"jog": {"axis": "Y", "speed": 99999, "time": 1}}], "program.commands[0].jog.speed", "max_velocity"),
    ([{"index": {"axis": "X", "distance": 0.0001, "speed": 100}}], "program.commands[0].index.distance", "pulse"),
    ([{"linear": {"speed": 100}}], "program.commands[0].linear", "moves no axis"),
    ([{"dwell": 1, "jog": {"axis": "X", "speed": 10, "time": 1}}], "program.commands[0]", "exactly one"),
])
def test_bad_chip_programs_are_refused_with_the_key_path(commands, key, message):
    with pytest.raises(ScenarioError) as info:
        scenario_from_dict(_chip(*commands))
    assert info.value.key_path.startswith(key)
    assert message in info.value.message


@pytest.mark.parametrize("profile", ["constant", "trapezoid", "s_curve"])
def test_index_moves_end_exactly_on_their_counts_with_every_profile(profile):
    scenario = scenario_from_dict(_chip({"index": {"axis": "X", "distance": 12.3456, "speed": 3000}},
                                        {"index": {"axis": "B", "distance": -7.5, "speed": 1800}},
                                        profile=profile, settle=0.05))
    result = run_scenario(scenario)
    assert result.metrics["final_state"] == "FINISHED"
    done = _events(result, "motion_done")
    assert [(e["axis"], e["count"]) for e in done] == [
        ("X", 12346), ("B", round(-7.5 * np.pi / 180 * scenario.axes[4].counts_per_unit))]
