"""The drives' dead time: MuJoCo's actuator delay on the compliant machine's current-mode drives,
and the linear model that puts it back (mjd_transitionFD refuses models with delays)."""

from __future__ import annotations

import mujoco
import numpy as np

from cnc_twin import load_scenario
from cnc_twin.machine.model_file import load_model
from cnc_twin.machine.plant import Plant
from cnc_twin.scenario.resources import scenarios_dir
from cnc_twin.studies.linearize import actuator_delays, linear_plant, machine_loop


def _scenario():
    return load_scenario(scenarios_dir() / "jog_axes.yaml")


def test_a_torque_command_reaches_the_current_loop_one_physics_step_late():
    """The MJCF's 0.25 ms on X..B (one step at the bundled timestep), none on C's velocity-mode
    drive: a force command written before a step has moved the current loop's state only after
    the next one."""
    scenario = _scenario()
    assert list(actuator_delays(scenario)[:6]) == [1, 1, 1, 1, 1, 0]
    model = load_model(scenario.model_file)
    model.opt.timestep = scenario.timing.physics_timestep
    data = mujoco.MjData(model)
    y = model.actuator("y_drive")
    data.ctrl[y.id] = 100.0
    mujoco.mj_step(model, data)
    assert data.act[model.actuator_actadr[y.id]] == 0.0
    mujoco.mj_step(model, data)
    assert data.act[model.actuator_actadr[y.id]] > 0.0


def _speeds(delays):
    """Y's motor speed over 60 ms after a 0.02 V step: the linear machine (with ``delays``) and
    the nonlinear one (its own dead time; Coulomb friction and limits off, as linearised)."""
    scenario = _scenario()
    M, N, speed = machine_loop(linear_plant(scenario), "Y", delays=delays)
    plant = Plant(load_model(scenario.model_file), timestep=scenario.timing.physics_timestep,
                  drives=scenario.drives, encoder_mounts=scenario.encoder_mounts)
    plant.model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS | mujoco.mjtDisableBit.mjDSBL_LIMIT
    plant.reset()
    volts = np.zeros(6)
    volts[1] = 0.02
    plant.apply_volts(volts)
    tap = plant.motor_taps[1]
    x = np.zeros(M.shape[0])
    linear, nonlinear = np.empty(240), np.empty(240)
    for k in range(240):
        x = M @ x + N[:, 0] * 0.02
        linear[k] = speed @ x
        plant.step(1)
        nonlinear[k] = plant.data.qvel[tap["dof_adr"]] * tap["scale"]
    return linear, nonlinear


def test_the_linear_machine_with_the_dead_time_follows_the_nonlinear_one():
    """Within 1 % of the response's peak at every step with the dead time put back; without it the
    linear machine runs ahead (its error several times larger)."""
    with_delay, nonlinear = _speeds(actuator_delays(_scenario()))
    peak = np.max(np.abs(nonlinear))
    error = np.max(np.abs(with_delay - nonlinear))
    assert error < 0.01 * peak, error / peak
    without, _ = _speeds(None)
    assert np.max(np.abs(without - nonlinear)) > 3.0 * error
