"""Commissioning on the circular test (cnc_twin.studies.commission, reversal_tuning,
``cnc-twin commission``), checked against outside references and the twin's own trace:

- two axes with different position-loop gains and no feed-forward draw the 45 deg ellipse whose
  radial amplitude is v (1/kv_x - 1/kv_y) / 2 (the servo-mismatch formula of the ballbar's
  literature, shared/data/commissioning.md), and commissioning reads the lag difference from it;
  matched gains draw none;
- the bundled default machine (models/polisher.yaml, what ``cnc-twin commission`` wrote from
  polisher_uncommissioned.yaml) keeps its circular-test figures, and turning its reversal
  compensation off brings the spikes back;
- the first reversal setting is the drive's (A = 2 c / kp, T = tn); the parameter file is written
  with its comments and every value as set; bad input is refused with exit 2 and one line.

The bundled commissioned machine meets the acceptance in every plane (G <= 10, spikes <= 5,
H <= 5 um), and is held to it.
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest
import yaml

from cnc_twin import load_scenario, run_scenario
from cnc_twin.run.ballbar import ballbar_passes
from cnc_twin.scenario.resources import BUNDLED_MACHINES, models_dir, scenarios_dir
from cnc_twin.studies import commission, reversal_tuning
from tests.conftest import run_cli

pytestmark = pytest.mark.slow
COMMISSIONED = dict(BUNDLED_MACHINES["compliant"])  # the default


def _passes(overrides, plane="xy"):
    scenario = load_scenario(scenarios_dir() / f"ballbar_{plane}.yaml", overrides=overrides)
    result = run_scenario(scenario)
    return result, ballbar_passes(result.trace, scenario.ballbar, scenario.timing.interpolation_period)


@pytest.mark.parametrize("kv_y", [42.28, 33.77])
def test_mismatched_gains_without_feed_forward_draw_the_45_degree_ellipse_of_the_formula(kv_y):
    kv_x = 33.77
    no_ff = {"servo.X.kvff": 0, "servo.Y.kvff": 0, "servo.X.kaff": 0, "servo.Y.kaff": 0,
             "servo.X.kp": kv_x, "servo.Y.kp": kv_y,
             # the rapids lag v / kv without feed-forward: 12 mm at 24 m/min
             "axes.X.following_error_limit": 20, "axes.Y.following_error_limit": 20}
    result, passes = _passes(no_ff)
    assert {p.direction for p in passes} == {"ccw", "cw"}
    for p in passes:
        expected = p.feed * (1 / kv_x - 1 / kv_y) / 2 * 1e6  # um; 149 um at 3 m/min for 33.77 / 42.28
        measured = commission.ellipse_45(p)
        if expected:
            assert abs(measured) == pytest.approx(expected, rel=0.2), (p.direction, measured, expected)
        else:  # matched: no ellipse beyond a tenth of the mismatched one's
            assert abs(measured) < 15.0, (p.direction, measured)
    test = reversal_tuning.CircularTest(result.metrics["ballbar"], passes, None)
    difference = commission.equivalent_time_difference(test)  # what commissioning reads of it
    if kv_y != kv_x:
        assert difference == pytest.approx(1 / kv_x - 1 / kv_y, rel=0.2)  # 5.96 ms: X lags longer
    else:
        assert abs(difference) < commission.MISMATCH_LIMIT


def _spikes(figures):
    return [abs(v) for d in ("ccw", "cw") for v in figures[d]["reversal_spikes_um"].values()]


# [um] G, the largest spike, H: the acceptance asked for, G <= 10, spikes <= 5, H <= 5 in every plane
# (the bundled default, commissioned, measures XY 4.9 / 2.3 / 2.3, XZ 6.3 / 2.3 / 3.0, YZ 7.9 / 2.5 /
# 2.9: docs/tuning.md)
HELD = {"xy": (10.0, 5.0, 5.0), "xz": (10.0, 5.0, 5.0), "yz": (10.0, 5.0, 5.0)}


@pytest.mark.parametrize("plane", sorted(HELD))
def test_the_default_machine_holds_its_commissioned_circular_test(plane):
    f = _passes(COMMISSIONED, plane)[0].metrics["ballbar"]
    g, spike, h = HELD[plane]
    assert max(f[d]["circular_deviation_um"] for d in ("ccw", "cw")) <= g
    assert max(_spikes(f)) <= spike
    assert f["hysteresis_um"] <= h
    before = _passes(dict(BUNDLED_MACHINES["uncommissioned"]), plane)[0].metrics["ballbar"]
    assert max(_spikes(before)) >= 3 * max(_spikes(f))  # what commissioning bought


def test_the_reversal_compensation_is_what_holds_the_spikes():
    off = {**COMMISSIONED, **{f"servo.{a}.reversal_amplitude": 0 for a in "XY"}}
    with_comp = _spikes(_passes(COMMISSIONED)[0].metrics["ballbar"])
    without = _spikes(_passes(off)[0].metrics["ballbar"])
    assert max(without) >= 25.0 and max(without) >= 3 * max(with_comp), (with_comp, without)


def _circle_tip_error(overrides) -> tuple[float, float]:
    """The 6 m/min circle (``nurbs_circle``, R 40 mm) run with ``overrides``: the tool tip's largest
    distance [um] from the program's circle in its plane (the centre the command's, fitted; the
    radius the program's 40 mm) over the periods on the curve, and the run's own contour error."""
    result = run_scenario(load_scenario(scenarios_dir() / "nurbs_circle.yaml", overrides=overrides))
    trace = result.trace
    tpp = trace.ticks_per_period
    on = trace.periods["path_u"][:len(trace.tool)] >= 0.0
    command = trace.command[tpp - 1::tpp][:len(trace.tool), :2] / trace.counts_per_unit[:2]
    basis = np.column_stack([2 * command[on], np.ones(on.sum())])
    (cx, cy, _), *_ = np.linalg.lstsq(basis, (command[on] ** 2).sum(1), rcond=None)
    tip = trace.tool[on, :2]
    radial = np.hypot(tip[:, 0] - cx, tip[:, 1] - cy) - 0.040
    return float(np.abs(radial).max() * 1e6), result.metrics["path"]["contour_error_um"]["max"]


def test_the_6_m_per_min_circle_holds_10_um_by_the_stops_and_starts_and_the_adaptation():
    """Heidenhain's "several um" with feed-forward: the commissioned machine's tip stays within
    10 um of the circle from its start after the approach to its stop; without the pulse's share at
    stops and starts, or without its adaptation to the acceleration, it does not."""
    held, reported = _circle_tip_error(COMMISSIONED)
    assert held <= 10.0 and reported <= 10.0
    no_standstill, _ = _circle_tip_error({**COMMISSIONED, **{f"servo.{a}.reversal_standstill": 0 for a in "XYZ"}})
    no_adaptation, _ = _circle_tip_error({**COMMISSIONED, **{f"servo.{a}.reversal_adapt_amplitude": 0 for a in "XYZ"}})
    assert no_standstill > held + 3.0 and no_adaptation > held + 0.5, (held, no_standstill, no_adaptation)


def test_the_first_setting_is_twice_the_friction_through_the_drive_gain_for_its_integral_time():
    scenario = load_scenario(scenarios_dir() / "ballbar_xy.yaml")
    drive = scenario.axis("X").drive
    s = reversal_tuning.first_setting(scenario, "X", coulomb=248.5)
    assert s.amplitude == pytest.approx(2 * 248.5 / drive.kp) and s.time == drive.tn and s.lead == 0.0
    # identified on the twin's own signals: the MJCF's 60 N guides + 0.3 N m motor through the 10 mm screw
    identified = reversal_tuning.first_setting(scenario, "X")
    assert identified.amplitude == pytest.approx(s.amplitude, rel=0.05)


def test_the_commissioned_file_is_the_source_with_the_settings_and_its_comments(tmp_path):
    source = models_dir() / "polisher_uncommissioned.yaml"
    settings = {"servo.Y.kp": 33.77, "servo.Z.reversal_amplitude": 219.5, "servo.Z.reversal_lead": 7.5,
                "axes.Z.compensation.backlash": 0.00196, "axes.X.compensation.backlash": 0.0}
    out = commission.write_parameters(source, settings, tmp_path / "p.yaml")
    text = out.read_text()
    comments = [line for line in source.read_text().splitlines() if line.lstrip().startswith("#")]
    assert all(line in text.splitlines() for line in comments)  # the comments kept
    before, after = yaml.safe_load(source.read_text()), yaml.safe_load(text)
    assert after["axes"]["Y"]["servo"]["kp"] == 33.77
    assert after["axes"]["Z"]["servo"]["reversal_amplitude"] == 219.5
    assert after["axes"]["Z"]["servo"]["reversal_lead"] == 7.5
    assert after["axes"]["Z"]["compensation"] == {"backlash": 0.00196}  # added, in decimals YAML reads back
    assert "compensation" not in after["axes"]["X"]  # a zero adds nothing
    for axis in "XYZABC":  # nothing else changed
        assert set(after["axes"][axis]) - set(before["axes"][axis]) <= {"compensation"}
        for key, value in before["axes"][axis]["servo"].items():
            if f"servo.{axis}.{key}" not in settings:
                assert after["axes"][axis]["servo"][key] == value, (axis, key)
    assert {k: v for k, v in after.items() if k != "axes"} == {k: v for k, v in before.items() if k != "axes"}


def test_a_commissioned_mapping_is_written_inside_the_servo_mapping_and_replaced_whole(tmp_path):
    source = models_dir() / "polisher_uncommissioned.yaml"
    first = commission.write_parameters(source, {"servo.A.coupling": {"Y": 0.22144}, "servo.A.kaff": 0.0038,
                                                 "servo.Y.deflection": {"X": 5.3, "Y": -16.5}}, tmp_path / "a.yaml")
    second = commission.write_parameters(first, {"servo.A.coupling": {"X": -0.1, "Y": 0.3}, "servo.A.kp": 40.0,
                                                 "servo.Y.deflection": {}}, tmp_path / "b.yaml")
    before, a, b = (yaml.safe_load(p.read_text()) for p in (source, first, second))
    assert a["axes"]["A"]["servo"]["coupling"] == {"Y": 0.22144} and a["axes"]["A"]["servo"]["kaff"] == 0.0038
    assert a["axes"]["Y"]["servo"]["deflection"] == {"X": 5.3, "Y": -16.5}
    assert b["axes"]["A"]["servo"]["coupling"] == {"X": -0.1, "Y": 0.3} and b["axes"]["A"]["servo"]["kp"] == 40.0
    assert b["axes"]["Y"]["servo"]["deflection"] == {}
    for key, value in before["axes"]["A"]["servo"].items():  # the keys after a nested mapping kept
        if key not in ("kp", "kaff"):
            assert b["axes"]["A"]["servo"][key] == value, key
    shutil.copy(models_dir() / "polisher.tbl", tmp_path)  # the file's tool table, beside it
    load_scenario(scenarios_dir() / "ballbar_xy.yaml", overrides={"machine.parameters": str(second)})  # it loads


def test_the_bundled_default_differs_from_the_uncommissioned_file_only_in_the_commissioned_keys():
    default = yaml.safe_load((models_dir() / "polisher_uncommissioned.yaml").read_text())
    done = yaml.safe_load((models_dir() / "polisher.yaml").read_text())
    # the dynamics matched already (equivalent times within 0.06 ms with the feed-forward): each
    # axis kept the gain its margins allow
    for axis in commission.INTERPOLATING:
        assert done["axes"][axis]["servo"]["kp"] == default["axes"][axis]["servo"]["kp"]
    for axis in commission.COMPENSATED:
        assert done["axes"][axis]["servo"]["reversal_amplitude"] > 0
    for axis in "XYZABC":
        for key in set(default["axes"][axis]) | set(done["axes"][axis]):
            if key not in ("servo", "compensation"):
                assert done["axes"][axis][key] == default["axes"][axis][key], (axis, key)


def test_bad_input_is_refused_with_exit_2_and_one_line(tmp_path):
    code, out, err = run_cli("commission", tmp_path / "missing.yaml", "--out", tmp_path / "o")
    assert code == 2 and len(err.strip().splitlines()) == 1 and not (tmp_path / "o").exists()
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("")
    code, out, err = run_cli("commission", "--out", tmp_path / "full")
    assert code == 2 and len(err.strip().splitlines()) == 1
    (tmp_path / "bad.yaml").write_text("axes: [1, 2]\n")
    code, out, err = run_cli("commission", tmp_path / "bad.yaml", "--out", tmp_path / "o2")
    assert code == 2 and len(err.strip().splitlines()) == 1


def test_a_sweep_of_a_compensation_tabulates_the_circular_test_per_direction(tmp_path):
    y = yaml.safe_load((models_dir() / "polisher.yaml").read_text())["axes"]["Y"]["servo"]["reversal_amplitude"]
    code, out, err = run_cli("sweep", "ballbar_xy", "--param", f"servo.Y.reversal_amplitude=0,{y}",
                             "--workers", "1", "--out", tmp_path / "sweep")
    assert code == 0, err
    import pandas as pd

    rows = pd.read_csv(tmp_path / "sweep" / "sweep.csv").set_index("servo.Y.reversal_amplitude")
    for column in ("ballbar_G_ccw_um", "ballbar_G_cw_um", "ballbar_G_um", "ballbar_spike_ccw_um",
                   "ballbar_spike_cw_um", "ballbar_H_um"):
        assert rows[column].notna().all(), column
    off, on = rows.loc[0.0], rows.loc[y]
    assert off["ballbar_spike_ccw_um"] >= 3 * abs(on["ballbar_spike_ccw_um"])  # Y's spike, outward, is back
    assert off["ballbar_G_um"] == max(off["ballbar_G_ccw_um"], off["ballbar_G_cw_um"]) > on["ballbar_G_um"]
    assert "best by ballbar_G_um" in out


@pytest.mark.parametrize("axis", ["X", "Y", "Z", "A", "B"])
def test_the_default_gains_keep_the_margins_on_each_axis_s_measured_response(axis):
    """On each axis's mechanics as measured on the twin (mid-way, clear of the work) with its
    drive's velocity loop, the default machine's position loop keeps 45 deg / 6 dB."""
    from cnc_twin.studies import drive_tuning
    from cnc_twin.studies.commissioning import commissioning_positions, measure_mechanics

    scenario = load_scenario(scenarios_dir() / "jog_axes.yaml")
    cfg, dt = scenario.axis(axis), scenario.timing.physics_timestep
    positions = commissioning_positions(scenario, axis)
    measured = measure_mechanics(scenario, axis, at=positions[len(positions) // 2])
    velocity = drive_tuning.current_velocity_loop(measured, cfg.drive, dt)
    m = drive_tuning.position_margins(measured, velocity, cfg, scenario.timing.servo_period, dt)
    assert m.phase_margin_deg >= 45.0 and m.gain_margin_db >= 6.0, m
