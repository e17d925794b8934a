"""The commissioned feed-forward (cnc_twin.studies.feedforward, deflection; the card's side in
cnc_twin.dsp.pid and servo), checked against outside references and the twin's own trace:

- the acceleration feed-forward is the drive's speed loop's inverse on the inertia the MJCF enters
  (kaff = m / kv, its high-pass the drive's integral time tn), and the head's coupling to the table
  is the head's static moment m r_z (the lever its centre of mass hangs on below the tilt axis,
  from the model's bodies, not its mass matrix);
- on the bundled circle at 6 m/min the coupling is what holds the tool's axis still (its tilt read
  off the tool pose in the trace), and the deflection correction is what puts the tip on the
  programmed radius of a fast circle (R 50 at 12 m/min);
- the scenario keys convert with their units, and a wrong axis name is refused.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from cnc_twin import load_scenario, run_scenario
from cnc_twin.core.axes import AXES, joint_name
from cnc_twin.core.errors import ScenarioError
from cnc_twin.machine.model_file import load_model
from cnc_twin.scenario.resources import BUNDLED_MACHINES, scenarios_dir
from cnc_twin.studies.commissioning import entered_rigid_body, identify_rigid_body
from cnc_twin.studies.deflection import fast_circular_traces
from cnc_twin.studies.feedforward import feed_forward

UNCOMMISSIONED = dict(BUNDLED_MACHINES["uncommissioned"])


@pytest.fixture(scope="module")
def identified():
    scenario = load_scenario(scenarios_dir() / "ballbar_xy.yaml", overrides=UNCOMMISSIONED)
    return scenario, feed_forward(scenario, {a: identify_rigid_body(scenario, a) for a in ("X", "Y", "Z", "A", "B")})


def test_the_acceleration_feed_forward_is_the_speed_loop_s_inverse_on_the_entered_inertia(identified):
    scenario, found = identified
    for axis, f in found.items():
        drive = scenario.axis(axis).drive
        assert f.kaff == pytest.approx(entered_rigid_body(scenario, axis).inertia / drive.kp, rel=0.03), axis
        assert f.washout == drive.tn


def _static_moment(model: mujoco.MjModel, data: mujoco.MjData, joint: str, linear: int) -> float:
    """The force on a hinge per unit acceleration of the base along world axis ``linear``: the
    subtree's mass times its centre of mass's lever about the hinge axis [kg m]."""
    j = model.joint(joint)
    body = int(j.bodyid[0])
    mass = float(model.body_subtreemass[body])
    lever = data.subtree_com[body] - data.xanchor[j.id]
    direction = np.zeros(3)
    direction[linear] = 1.0
    return float(mass * np.dot(data.xaxis[j.id], np.cross(lever, direction)))


def test_the_head_s_coupling_is_its_static_moment_over_its_inertia(identified):
    scenario, found = identified
    model = load_model(scenario.model_file)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_forward(model, data)
    for head, table, linear in (("A", "Y", 1), ("B", "X", 0)):
        moment = _static_moment(model, data, joint_name(head), linear)
        assert abs(moment) > 0.5  # the head hangs on a lever: a coupling worth feeding forward
        assert found[head].coupling[table] * found[head].inertia == pytest.approx(moment, rel=0.01), head
    assert "Z" not in found["A"].coupling and "X" not in found["Y"].coupling  # nothing couples there


def _tool_tilt(trace) -> np.ndarray:
    """The tool axis's tilt from its start [rad] per period, from the tool pose (tip, pivot)."""
    axis = trace.tool[:, :3] - trace.tool[:, 3:]
    axis /= np.linalg.norm(axis, axis=1)[:, None]
    return np.arccos(np.clip(axis @ axis[0], -1.0, 1.0))


def test_the_coupling_holds_the_head_still_while_the_table_runs_the_circle():
    default = load_scenario(scenarios_dir() / "nurbs_circle.yaml")
    assert default.axis("A").coupling[AXES.index("Y")] != 0.0  # the bundled default carries it
    with_coupling = _tool_tilt(run_scenario(default).trace).max()
    without = _tool_tilt(run_scenario(load_scenario(scenarios_dir() / "nurbs_circle.yaml", overrides={
        "servo.A.coupling": {}, "servo.B.coupling": {}})).trace).max()
    assert without > 80e-6  # the table's acceleration swings the head by its lever
    assert with_coupling < 0.4 * without


def test_the_coupling_is_what_keeps_the_yz_test_s_reversals_alike_in_both_directions():
    """Y's reversal in the YZ circular test: the head swings on its lever under Y's acceleration one
    way or the other with the direction of travel unless A's drive is fed its coupling."""
    def figures(overrides):
        scenario = load_scenario(scenarios_dir() / "ballbar_yz.yaml", overrides=overrides)
        return run_scenario(scenario).metrics["ballbar"]

    held, swinging = figures({}), figures({"servo.A.coupling": {}})
    assert swinging["hysteresis_um"] > 5.0 >= held["hysteresis_um"]


def _tip_outside_command(trace) -> float:
    """How far the tip runs outside the commanded circle [m]: the mean of the tip's radius less the
    command's about the command's centre (fitted, least squares) over the periods on the circle."""
    tpp = trace.ticks_per_period
    tip = trace.tool[:, :2]
    command = trace.command[tpp - 1::tpp][:len(tip), :2] / trace.counts_per_unit[:2]
    points = command
    for _ in range(4):  # the lead-ins and the approach left out once a centre is known
        basis = np.column_stack([2 * points, np.ones(len(points))])
        (cx, cy, _), *_ = np.linalg.lstsq(basis, (points ** 2).sum(1), rcond=None)
        radius = np.hypot(command[:, 0] - cx, command[:, 1] - cy)
        on = np.abs(radius - 0.05) < 0.5e-3
        points = command[on]
    return float(np.mean(np.hypot(tip[on, 0] - cx, tip[on, 1] - cy) - radius[on]))


def test_the_deflection_correction_puts_the_tip_on_the_commanded_circle_at_12_m_per_min():
    on, off = (fast_circular_traces(overrides, scenarios=scenarios_dir(), planes=("XY",))[0]
               for overrides in ({}, {"servo.X.deflection": {}, "servo.Y.deflection": {}}))
    deflected, corrected = _tip_outside_command(off), _tip_outside_command(on)
    # 0.8 m/s^2 centripetal on the default's deflection (13 - 15 um per m/s^2): about 11 um outward
    assert deflected > 8e-6
    assert abs(corrected) < 0.4 * deflected


def test_the_keys_convert_with_their_units_and_a_wrong_axis_is_refused():
    scenario = load_scenario(scenarios_dir() / "nurbs_circle.yaml", overrides={
        "servo.A.coupling": {"Y": 0.2}, "servo.Y.deflection": {"X": 5.0, "Y": -16.0},
        "servo.X.aff_washout": 20.0, "servo.X.ff_equivalent_time": 0.5})
    a, y, x = scenario.axis("A"), scenario.axis("Y"), scenario.axis("X")
    assert a.coupling[AXES.index("Y")] == pytest.approx(0.2 * np.pi / 180.0 / 1e-3)  # deg per mm -> rad per m
    assert y.deflection[AXES.index("X")] == pytest.approx(5e-6) and y.deflection[AXES.index("Y")] == pytest.approx(-16e-6)
    assert x.aff_washout == pytest.approx(0.02) and x.ff_equivalent_time == pytest.approx(5e-4)
    with pytest.raises(ScenarioError, match="deflection"):
        load_scenario(scenarios_dir() / "nurbs_circle.yaml", overrides={"servo.X.deflection": {"Q": 1.0}})
