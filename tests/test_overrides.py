"""Overrides by dotted path: applied, validated, and failing with a message naming them."""

from __future__ import annotations

import pytest

from cnc_twin import load_scenario
from cnc_twin.core.errors import ScenarioError
from cnc_twin.scenario.overrides import parse_path
from cnc_twin.scenario.resources import default_scenario, scenarios_dir


def test_parse_path():
    assert parse_path("program.moves[2].X") == ["program", "moves", 2, "X"]
    assert parse_path("program.moves.2.X") == ["program", "moves", 2, "X"]
    assert parse_path("servo.X.kp") == ["servo", "X", "kp"]


def test_shorthands_and_plain_paths_reach_the_scenario():
    s = load_scenario(default_scenario(), overrides={
        "servo.X.kp": 60, "axes.A.servo.ki": 500.0, "encoder.Y.lines_per_rev": 5000,
        "planner.feed": 3000, "program.moves[1].dwell": 0.25, "timing.servo_period": 0.5,
    })
    assert s.axis("X").kp == 60 and s.axis("A").ki == 500.0
    assert s.axis("Y").counts_per_unit == pytest.approx(2e6)
    assert all(m.feed == pytest.approx(3000 / 60e3) for m in s.program.moves)
    assert s.program.moves[1].dwell == 0.25 and s.timing.ticks_per_period == 2
    # the machine's other parameters still come from its parameter file
    assert s.axis("X").drive.notches[0].frequency == 66.43 and s.axis("X").max_velocity == pytest.approx(0.4)


def test_planner_feed_on_a_curve_program():
    s = load_scenario(scenarios_dir() / "nurbs_circle.yaml", overrides={"planner.feed": 3000})
    assert s.program.limits.feed == pytest.approx(0.05)


def test_force_gains_of_a_polishing_program():
    s = load_scenario(scenarios_dir() / "flat_plate_polish.yaml", overrides={"force.kp": 0.01, "force.ki": 6})
    assert s.program.force.kp == pytest.approx(1e-5) and s.program.force.ki == pytest.approx(6e-3)
    with pytest.raises(ScenarioError) as info:  # a program without a force loop
        load_scenario(default_scenario(), overrides={"force.ki": 6})
    assert "force.ki" in str(info.value)


@pytest.mark.parametrize("overrides, key, fragment", [
    ({"servo.X.kpp": 1}, "axes.X.servo.kpp", "unknown key"),
    ({"servo.X.kp": "fast"}, "axes.X.servo.kp", ", got 'fast'"),  # ours; "a valid number" is pydantic's
    ({"program.moves[99].X": 1}, "program.moves[99].X", "no item 99"),
    ({"timing.servo_period.value": 1}, "timing.servo_period.value", "is not a mapping"),
    ({"warp": 9}, "warp", "unknown key"),
])
def test_bad_overrides_fail_naming_the_override(overrides, key, fragment):
    with pytest.raises(ScenarioError) as info:
        load_scenario(default_scenario(), overrides=overrides)
    name = next(iter(overrides))
    assert name in str(info.value) and fragment in info.value.message
    assert info.value.key_path in (key, name)


def test_result_dataframe_or_a_clear_import_error():
    from cnc_twin.scenario.load import scenario_from_dict
    from cnc_twin.run.twin import run_scenario

    result = run_scenario(scenario_from_dict({"name": "df", "program": {"type": "point_to_point", "settle": 0.0,
                                                                       "moves": [{"X": 1}]}}))
    try:
        import pandas  # noqa: F401
    except ImportError:
        with pytest.raises(ImportError, match="pip install pandas"):
            result.dataframe()
    else:
        df = result.dataframe()
        assert len(df) == len(result.trace) and "ferr_X" in df.columns
        # units as trace.parquet's metadata gives them, and the encoders' counts per mm or deg
        assert df.attrs["units"]["ferr_X"] == "counts" and df.attrs["units"]["tip_x"] == "m"
        assert set(df.attrs["units"]) == set(df.columns)
        assert df.attrs["counts_per_unit"]["X"] == pytest.approx(1000.0)  # 1 um a count (polisher.yaml)
        assert df.attrs["position_units"]["A"] == "deg"
