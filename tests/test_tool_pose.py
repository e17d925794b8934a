"""The tool's true pose in the trace (``tip_*``, ``pivot_*``: MuJoCo's kinematics of every joint at
each period's last tick) against the encoders and against outside references.

- Rigid machine: the true axis positions (the pose through the head's inverse kinematics) and
  the encoders agree within the encoders' one count (they truncate), every period of a jog at
  0.4 m/s (400 counts a period): a pose recorded a tick early or late would be off by 100.
- Compliant machine, encoders on the motors: what the card sees and where the tool is part by
  the drive train's windup. Cruising, the screw carries the guideway's friction and damping:
  ``(F_c + b v) / k``. Accelerating at ``a``, it also carries the moving mass, and the bridge,
  pushed by its own inertia, rocks on its hinge and carries the head back:
  ``(m a + F_c + b v) / k + M a h_com h_pivot / k_rock`` (small angles, quasi-static). ``k`` is the
  published screw stiffness (80 N/um, ../shared/data/machine-dynamics.md); masses, friction,
  damping and the rocking stiffness as the MJCF enters them.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from cnc_twin import load_scenario, run_scenario
from cnc_twin.geometry.kinematics import HeadGeometry
from cnc_twin.scenario.resources import BUNDLED_MACHINES, scenarios_dir

SCREW_K_X = 80e6
"""[N/m] X's ball-screw drive train, the published figure (machine-dynamics reference: 80 N/um)"""


def _true_and_encoder_axes(result):
    """Per period ``(true X..B, encoders' X..B, commanded X..B)`` [m | rad], each (periods, 5)."""
    trace, scenario = result.trace, result.scenario
    tpp = trace.ticks_per_period
    head = HeadGeometry.from_model(result.model)
    tip, pivot = trace.tool[:, :3], trace.tool[:, 3:]
    true = head.axes_from_pose(tip, pivot - tip)
    home = np.asarray(scenario.home)
    encoders = (trace.actual[tpp - 1::tpp] / trace.counts_per_unit + home)[:, :5]
    command = (trace.command[tpp - 1::tpp] / trace.counts_per_unit + home)[:, :5]
    n = min(len(true), len(encoders))
    return true[:n], encoders[:n], command[:n]


def test_on_the_rigid_machine_the_tool_is_where_the_encoders_say_within_a_count():
    scenario = load_scenario(scenarios_dir() / "jog_axes.yaml", overrides={"max_time": 2.0, **BUNDLED_MACHINES["rigid"]})
    result = run_scenario(scenario)
    true, encoders, command = _true_and_encoder_axes(result)
    assert np.ptp(command[:, 0]) > 0.15  # X moved
    counts = (true - encoders) * result.trace.counts_per_unit[:5]
    assert counts.min() > -1e-6 and counts.max() < 1.0 + 1e-6, (counts.min(axis=0), counts.max(axis=0))


def test_on_the_compliant_machine_the_encoders_and_the_tool_part_by_the_windup():
    scenario = load_scenario(scenarios_dir() / "jog_axes.yaml", overrides={
        "max_time": 2.0, "axes.X.servo.kp": 130.0, "axes.X.servo.ki": 0.0})  # the tuner's gains: no ringing
    result = run_scenario(scenario)
    model = result.model
    true, encoders, command = _true_and_encoder_axes(result)
    period = scenario.timing.interpolation_period
    velocity = np.gradient(command[:, 0], period)
    acceleration = np.gradient(velocity, period)
    windup = encoders[:, 0] - true[:, 0]
    half_count = 0.5 / result.trace.counts_per_unit[0]  # the encoders truncate: half a count low on average
    joint = model.joint("x_joint")
    friction, damping = float(model.dof_frictionloss[joint.dofadr[0]]), float(model.dof_damping[joint.dofadr[0]])
    index = np.arange(len(windup))

    v_cruise = velocity.max()
    at_speed = np.abs(velocity - v_cruise) < 1e-6 * v_cruise
    cruise = at_speed & (index > np.argmax(at_speed) + 50)  # the ringing of the arrival gone
    assert cruise.sum() > 100
    expected = (friction + damping * v_cruise) / SCREW_K_X - half_count
    assert windup[cruise].mean() == pytest.approx(expected, abs=0.5e-6)  # 4.0 um

    a = acceleration.max()
    accelerating = (np.abs(acceleration - a) < 1e-6) & (velocity > 0) & (index > 60)
    assert accelerating.sum() > 100
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_forward(model, data)
    bridge, rock = model.body("x_bridge").id, model.joint("x_rock")
    hinge_z = data.xanchor[rock.id][2]
    moving_mass = model.body_subtreemass[model.body("x_carriage").id]
    screw = (moving_mass * a + friction + damping * velocity[accelerating].mean()) / SCREW_K_X
    rocking = (model.body_subtreemass[bridge] * a * (data.subtree_com[bridge][2] - hinge_z)
               * (data.body("a_yoke").xpos[2] - hinge_z) / model.jnt_stiffness[rock.id])
    assert windup[accelerating].mean() == pytest.approx(screw + rocking - half_count, rel=0.05)  # 30.5 um
