"""The MJCF machine: every scene compiles and steps cleanly; drives, pad and load cell behave."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from cnc_twin.machine.model_file import load_model
from cnc_twin.machine.plant import Plant
from cnc_twin.scenario.resources import models_dir

# every machine and scene; the work cell alone (workcell.xml, included by the scenes) has no machine
SCENES = sorted(p for p in models_dir().glob("*.xml") if p.name != "workcell.xml")


def test_bundled_models_found():
    names = {p.name for p in SCENES}
    assert {"polisher_rigid.xml", "scene_rigid.xml", "polisher.xml", "scene.xml"} <= names


@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.name)
def test_scene_steps_one_second_with_random_controls_without_warnings(path):
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    rng = np.random.default_rng(0)
    lo, hi = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    steps = int(round(1.0 / model.opt.timestep))
    for k in range(steps):
        if k % 40 == 0:  # a new random command every 10 ms, as a servo loop would
            data.ctrl[:] = rng.uniform(lo, hi)
        mujoco.mj_step(model, data)
    counts = {name: data.warning[i].number for i, name in enumerate(mujoco.mjtWarning.__members__)
              if i < len(data.warning)}
    assert not any(counts.values()), counts
    assert np.all(np.isfinite(data.qpos))


def test_every_axis_has_damping_friction_and_travel():
    model = load_model(models_dir() / "scene_rigid.xml")
    for axis in "xyzabc":
        joint = model.joint(f"{axis}_joint")
        assert joint.damping[0] > 0 and joint.frictionloss[0] > 0, axis
        if axis != "c":  # the spindle turns without limit
            assert joint.limited[0] and joint.range[0] < 0 <= joint.range[1], axis
        assert model.actuator(f"{axis}_drive").forcelimited[0]


def test_velocity_mode_drive_runs_at_commanded_speed():
    """A constant command on X settles at speed_per_volt * V, less the friction droop."""
    plant = Plant(load_model(models_dir() / "scene_rigid.xml"), timestep=0.00025)
    volts = [2.0, 0, 0, 0, 0, 0]
    plant.apply_volts(volts)
    plant.step(2000)  # 0.5 s: far longer than the 80 Hz drive loop's time constant
    v = plant.data.qvel[plant.qpos_adr[0]]
    spv = plant.info.speed_per_volt[0]
    assert spv == pytest.approx(0.05)
    # droop = (viscous + Coulomb) / kv = (1500 v + 150) / 450000
    expected = spv * 2.0 - (1500 * spv * 2.0 + 150) / 450000
    assert v == pytest.approx(expected, rel=2e-3)


def test_counterbalance_holds_z_with_drive_at_zero_volts():
    plant = Plant(load_model(models_dir() / "scene_rigid.xml"), timestep=0.00025)
    plant.step(4000)
    assert abs(plant.axis_positions()[2]) < 0.5e-3  # sags less than 0.5 mm in 1 s unpowered


def test_load_cell_reads_contact_force_when_pad_pressed_on_workpiece():
    """Lower Z until the pad touches; at rest the load cell equals the pad spring force."""
    model = load_model(models_dir() / "scene_rigid.xml")
    plant = Plant(model, timestep=0.00025)
    data = plant.data
    z_adr = plant.qpos_adr[2]
    pad = model.joint("pad_joint")
    # Pad face is 290 mm above the workpiece at home: put Z 4 mm lower than touching.
    data.qpos[z_adr] = -0.294
    mujoco.mj_forward(model, data)
    for _ in range(8000):  # 2 s with the drive holding Z (0 V = hold speed 0)
        mujoco.mj_step(model, data)
    compression = data.qpos[pad.qposadr[0]]
    spring = pad.stiffness[0] * compression
    assert compression > 0.003  # the pad is pushed up into the head
    # The load cell carries the pad spring's force; the contact carries that plus the pad's
    # weight (the DSP tares the weight away at servo-on).
    assert plant.pad_force() == pytest.approx(spring, rel=1e-3)
    normal = 0.0
    for i in range(data.ncon):
        wrench = np.zeros(6)
        mujoco.mj_contactForce(model, data, i, wrench)
        normal += wrench[0]
    assert normal == pytest.approx(spring + 0.15 * 9.81, rel=1e-2)
    assert plant.tool_position()[2] == pytest.approx(0.06, abs=0.5e-3)  # on the workpiece top


def test_head_kinematics_match_mujoco_forward_kinematics():
    """Inverse kinematics from the tool tip and axis recover the joint values MuJoCo posed."""
    from cnc_twin.geometry.kinematics import HeadGeometry

    model = load_model(models_dir() / "scene_rigid.xml")
    head = HeadGeometry.from_model(model)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(1)
    for _ in range(20):
        q = np.array([rng.uniform(-0.3, 0.3), rng.uniform(-0.2, 0.2), rng.uniform(-0.3, 0.0),
                      rng.uniform(-1.2, 1.2), rng.uniform(-1.2, 1.2)])
        for name, value in zip(("x_joint", "y_joint", "z_joint", "a_joint", "b_joint"), q):
            data.qpos[model.joint(name).qposadr[0]] = value
        data.qpos[model.joint("pad_joint").qposadr[0]] = 0.0
        mujoco.mj_kinematics(model, data)
        tip, pivot = data.site("tool_site").xpos.copy(), data.body("a_yoke").xpos.copy()
        assert np.allclose(head.axes_from_pose(tip[None], (pivot - tip)[None])[0], q, atol=1e-12)
        assert np.allclose(head.tip_from_axes(q[:3], q[3], q[4]), tip, atol=1e-12)


def test_compiled_models_are_reused_as_copies_and_recompiled_when_a_file_in_the_folder_changes(tmp_path):
    import os
    import shutil

    for name in ("scene_rigid.xml", "polisher_rigid.xml", "workcell.xml"):
        shutil.copy(models_dir() / name, tmp_path / name)
    scene = tmp_path / "scene_rigid.xml"
    first = load_model(scene)
    plant = Plant(first, timestep=0.00025)
    plant.disable_drives()  # a run changes its model: the next load must not see that
    again = load_model(scene)
    assert again is not first and again.actuator_gainprm[0, 0] != 0.0
    assert np.array_equal(again.actuator_gainprm, load_model(scene).actuator_gainprm)
    included = tmp_path / "polisher_rigid.xml"  # an include changes: compiled again
    text = included.read_text()
    assert 'armature="' in text
    included.write_text(text.replace('armature="', 'armature="1', 1))
    stat = included.stat()
    os.utime(included, ns=(stat.st_atime_ns, stat.st_mtime_ns + 1_000_000))
    assert not np.array_equal(load_model(scene).dof_armature, again.dof_armature)


def test_importing_the_twin_and_mujoco_starts_no_opengl_probe():
    """The twin never renders with MuJoCo's OpenGL: `import mujoco` after `import cnc_twin` leaves
    glfw unimported (its import starts a subprocess that asks the GLFW library its version, in
    every process of a run, and prints a traceback when a signal ends the command meanwhile)."""
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    code = "import cnc_twin, mujoco, sys; print('glfw' in sys.modules, hasattr(mujoco, 'MjModel'))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=60)
    assert out.stdout.split() == ["False", "True"], out.stderr
