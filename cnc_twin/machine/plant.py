"""The machine as MuJoCo sees it: load the MJCF, resolve names to ids once, step, read sensors.

Inputs per servo tick: drive command voltages, shape ``(6,)`` [V], axis order ``X Y Z A B C``.
Outputs: the encoders' positions [m | rad], the pad load-cell force [N, compression positive],
the tool-tip position in the world frame [m].

The servo amplifiers (velocity mode) are MuJoCo ``general`` actuators whose ctrl is the analog
command in volts, so the drive's own velocity loop runs in C at the physics rate. Their scaling
``speed_per_volt`` is read back from the model so the controller and the machine cannot disagree.

Where the encoders are: an axis whose model has a motor rotor hinge (``x_motor``, a compliant
machine: the rotor coupled to the table through the screw's or the harmonic drive's compliance)
is read on the motor, as a rotary encoder on the motor shaft reads it (semi-closed loop): the
hinge's angle times its drive's gear (lead / 2 pi, or 1 / ratio), in axis units. Otherwise the
axis joint itself is read (a rigid machine, where motor and table are one body). Each axis's
reading is one :data:`ENCODER_TAP` (``Plant.encoder_taps``), gathered by :func:`gather_encoders`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from numba import njit

from cnc_twin.core.axes import (
    AXES, HOME_KEYFRAME, SWITCH_HOME, SWITCH_LIMIT_NEG, SWITCH_LIMIT_POS, actuator_name, joint_name, motor_joint_name,
)
from cnc_twin.core.errors import ScenarioError
from cnc_twin.geometry.kinematics import PIVOT_BODY, TOOL_SITE
from cnc_twin.machine.amplifier import any_modelled, drive_amps, reset_amps, setup_amps
from cnc_twin.machine.model_file import OBSTACLE_PARK, PAD_FORCE_SENSOR, TOOL_POS_SENSOR, current_mode
from cnc_twin.machine.screw import screw_stiffness, setup_screws

PAD_JOINT = "pad_joint"
_SWITCH_SENSORS = (("home", SWITCH_HOME, 1.0), ("lim_pos", SWITCH_LIMIT_POS, 1.0), ("lim_neg", SWITCH_LIMIT_NEG, -1.0))


@dataclass(frozen=True)
class ModelInfo:
    """Facts about an MJCF machine the scenario loader checks targets against.

    Attributes
    ----------
    travel
        per axis ``(lo, hi)`` [m | rad], or ``None`` for an unlimited (continuous) joint.
    home
        per axis position at the ``home`` keyframe [m | rad], shape ``(6,)``.
    speed_per_volt
        per axis drive scaling [m/s/V | rad/s/V], shape ``(6,)``; NaN for a
        current-mode drive, whose scaling is the amplifier's (the machine's parameter file).
    current_mode
        per axis, whether the MJCF's drive is a current-mode actuator (force from
        ``ctrl``, lagged by the current loop) whose velocity loop the amplifier closes
        (:mod:`cnc_twin.machine.amplifier`), rather than a velocity-mode one.
    motor_per_axis
        per axis, motor hinge rad per axis m | rad (1 / the drive's gear) where the
        drive turns a motor hinge; 1 on the axis joint.
    """

    travel: tuple[tuple[float, float] | None, ...]
    home: tuple[float, ...]
    speed_per_volt: tuple[float, ...]
    current_mode: tuple[bool, ...] = (False,) * 6
    motor_per_axis: tuple[float, ...] = (1.0,) * 6


BRAKES = {2: 1e7, 3: 1e6, 4: 1e6}
"""holding brakes that close when the drives are disabled: axis index -> damping in axis units
[N s/m | N m s/rad at the axis]. Z's motor has one (it hangs on its counterbalance), and so do
the A/B motors of the tilting head. A brake is modelled as heavy viscous damping rather than
frictionloss: MuJoCo's soft frictionloss lets a load below it creep at a rate independent of
its size, while damping of 1e7 N s/m lets Z's 88 N of unbalance creep under 10 um/s. It acts
on the motor: its hinge on a compliant machine (damping x gear^2 there)."""

ENCODER_TAP = np.dtype([("qpos_adr", np.int64), ("dof_adr", np.int64), ("scale", np.float64)])
"""Where one axis's encoder reads the machine: ``qpos_adr`` / ``dof_adr`` of the joint it sits on
(the motor hinge, or the axis joint) and ``scale``, that joint's units to axis units [m/rad at a
screw, rad/rad at a harmonic drive; 1 on the axis joint]."""


def encoder_taps(model: mujoco.MjModel, mounts=None) -> np.ndarray:
    """Each axis's :data:`ENCODER_TAP`, shape ``(6,)``: on the motor hinge (scale: its drive's gear)
    where the model has one and the axis's ``mounts`` entry is ``motor`` (the default), else on the
    axis joint (scale 1: a linear scale on the table, an encoder on a rotary axis's output)."""
    taps = np.zeros(len(AXES), ENCODER_TAP)
    mounts = mounts or ("motor",) * len(AXES)
    for i, axis in enumerate(AXES):
        motor = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, motor_joint_name(axis))
        if mounts[i] == "table":
            motor = -1
        joint = motor if motor >= 0 else model.joint(joint_name(axis)).id
        taps[i]["qpos_adr"] = model.jnt_qposadr[joint]
        taps[i]["dof_adr"] = model.jnt_dofadr[joint]
        taps[i]["scale"] = model.actuator(actuator_name(axis)).gear[0] if motor >= 0 else 1.0
    return taps


@njit(cache=True)
def gather_encoders(qpos, taps, out):
    """The encoders' positions [m | rad] into ``out`` (shape ``(n,)``) from MuJoCo's ``qpos`` and
    the axes' :data:`ENCODER_TAP` records ``taps``."""
    for i in range(taps.shape[0]):
        out[i] = qpos[taps[i].qpos_adr] * taps[i].scale

def tool_pose_ids(model: mujoco.MjModel) -> np.ndarray:
    """What :func:`tool_pose` reads, shape ``(4,)`` int64: the tool site's id, the head pivot
    body's id, the pad joint's id and its ``qpos`` address."""
    pad = model.joint(PAD_JOINT)
    return np.array([model.site(TOOL_SITE).id, model.body(PIVOT_BODY).id, pad.id, pad.qposadr[0]], dtype=np.int64)


@njit(cache=True)
def tool_pose(site_xpos, xpos, xaxis, qpos, ids, out):
    """The tool's true pose into ``out`` (shape ``(6,)``) [m], world frame: the tool tip (the
    pad face's centre with the pad undeflected: its slide along the pad joint's axis taken off)
    and the head's pivot. Reads MuJoCo's kinematics (``site_xpos``, ``xpos``, ``xaxis``), which
    must be of the current ``qpos`` (``mj_kinematics`` just before); ``ids``: :func:`tool_pose_ids`.

    The machine's every joint is in it (the screws' and the harmonic drives' windup, the bridge's
    rocking), so it is where the tool really is, not where the encoders say."""
    site, body, pad, adr = ids[0], ids[1], ids[2], ids[3]
    slide = qpos[adr]
    for c in range(3):
        out[c] = site_xpos[site, c] - xaxis[pad, c] * slide
        out[3 + c] = xpos[body, c]


def model_info(model: mujoco.MjModel) -> ModelInfo:
    """Travel ranges, home positions and drive scaling of a checked model."""
    key = model.key(HOME_KEYFRAME)
    travel, home, spv, current, ratio = [], [], [], [], []
    for axis in AXES:
        joint = model.joint(joint_name(axis))
        travel.append((float(joint.range[0]), float(joint.range[1])) if joint.limited[0] else None)
        home.append(float(key.qpos[joint.qposadr[0]]))
        act = model.actuator(actuator_name(axis))
        current.append(current_mode(model, act.id))
        spv.append(float("nan") if current[-1] else float(act.gainprm[0] / -act.biasprm[2]))
        on_motor = model.actuator_trnid[act.id, 0] != joint.id
        ratio.append(1.0 / float(act.gear[0]) if on_motor else 1.0)
    return ModelInfo(travel=tuple(travel), home=tuple(home), speed_per_volt=tuple(spv), current_mode=tuple(current),
                     motor_per_axis=tuple(ratio))



@njit(cache=True)
def switch_bits(switches, sensordata, out):
    """The switch inputs per axis into ``out`` (shape ``(6,)``, bits ``SWITCH_*``): a switch is on
    when its dog is past it (the coordinate along the axis >= 0, <= 0 for a - switch).
    ``switches``: :attr:`Plant.switches`."""
    out[:] = 0
    for r in range(switches.shape[0]):
        if switches[r, 3] * sensordata[switches[r, 2]] >= 0.0:
            out[switches[r, 0]] |= switches[r, 1]

class Plant:
    """A MuJoCo machine with named accessors resolved once and a lean per-tick path.

    Parameters
    ----------
    model
        a model checked by :func:`~cnc_twin.machine.model_file.load_model`; its ``opt.timestep`` is
        set to ``timestep``.
    timestep
        physics step [s].
    drives
        per axis the amplifier's own loops (:class:`~cnc_twin.core.axis_config.DriveConfig`) for a
        current-mode drive of the MJCF, else None (the default: every drive velocity-mode).
    encoder_mounts
        per axis ``motor`` or ``table``: where the card's encoder reads the machine
        (the default: on the motors, where the model has them).
    """

    def __init__(self, model: mujoco.MjModel, *, timestep: float, drives=None, encoder_mounts=None):
        self.model = model
        self.model.opt.timestep = timestep
        self.data = mujoco.MjData(model)
        self.info = model_info(model)
        drives = tuple(drives) if drives is not None else (None,) * len(AXES)
        for axis, drive, current in zip(AXES, drives, self.info.current_mode):
            if current != (drive is not None):
                raise ScenarioError("<model>", f"axes.{axis}.drive",
                                    "the MJCF's drive is current-mode: the parameter file must give the amplifier's "
                                    "loops" if current else "the MJCF's drive is velocity-mode: it takes no drive loops")
        self.qpos_adr = np.array([model.joint(joint_name(a)).qposadr[0] for a in AXES], dtype=np.intp)
        """the axis joints' addresses in ``qpos`` (the table and head positions)"""
        self.actuator_ids = np.array([model.actuator(actuator_name(a)).id for a in AXES], dtype=np.intp)
        if not np.array_equal(self.actuator_ids, np.arange(len(AXES))):
            raise ScenarioError("<model>", "", "drive actuators must be the first six actuators, in X Y Z A B C order")
        self.encoder_taps = encoder_taps(model, encoder_mounts)
        """where each axis's encoder reads the machine (:data:`ENCODER_TAP`, shape ``(6,)``)"""
        self.encoders = np.zeros(len(AXES))
        """the encoders' positions [m | rad], shape ``(6,)``: :meth:`encoder_positions` fills it"""
        self.motor_taps = encoder_taps(model)
        """each axis's motor (its axis joint on a rigid machine): where its drive reads the speed and
        its brake holds, whatever the card's encoder reads"""
        self.amps = setup_amps(drives, self.motor_taps, timestep)
        """the amplifiers (:data:`~cnc_twin.machine.amplifier.AMP`, shape ``(6,)``)"""
        self.amps_modelled = any_modelled(self.amps)
        """whether any amplifier runs its loops here (then every physics step updates ``ctrl``)"""
        self.screws = setup_screws(model)
        """the ball screws whose stiffness follows their nut (:data:`~cnc_twin.machine.screw.SCREW`;
        none on a rigid machine): every physics step writes it into ``model.tendon_stiffness``"""
        self.per_step = self.amps_modelled or self.screws.size > 0
        """whether anything runs before every physics step (amplifiers' loops, screws' stiffness)"""
        for i, drive in enumerate(drives):
            if drive is not None:  # the current loop's lag and the torque limit are the drive's
                act = self.actuator_ids[i]
                model.actuator_dynprm[act, 0] = 1.0 / (2.0 * np.pi * drive.current_bandwidth)
                model.actuator_ctrlrange[act] = (-drive.force_limit, drive.force_limit)
                model.actuator_forcerange[act] = (-drive.force_limit, drive.force_limit)
        self.volts = np.zeros(len(AXES))
        """the drives' command voltages [V], shape ``(6,)``: the DACs' outputs, held"""
        force = model.sensor(PAD_FORCE_SENSOR)
        # z of the force sensor, in the pad site frame (tool axis); see pad_force().
        self._force_z_adr = int(force.adr[0]) + 2
        tool = model.sensor(TOOL_POS_SENSOR)
        self._tool_adr = slice(int(tool.adr[0]), int(tool.adr[0]) + 3)
        # Views into MjData kept once: no attribute lookups on the hot path.
        self._qpos = self.data.qpos
        self._ctrl = self.data.ctrl
        self._sensordata = self.data.sensordata
        self._n_drives = len(AXES)
        self.drives_enabled = True
        """False once :meth:`disable_drives` was called"""
        # Switches (optional in a model): framepos of the axis's dog in the switch's frame; the
        # switch is on when the dog is past it: coordinate along the axis >= 0 (<= 0 for -limit).
        rows = []
        for i, axis in enumerate(AXES[:3]):
            for suffix, bit, sign in _SWITCH_SENSORS:
                sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, f"{axis.lower()}_{suffix}")
                if sid >= 0:
                    rows.append((i, bit, int(model.sensor_adr[sid]) + i, sign))
        self.switches = np.array(rows, dtype=np.int64).reshape(-1, 4)
        """the model's switches, one row each: axis, its ``SWITCH_*`` bit, the address in
        ``data.sensordata`` of the dog's coordinate, the side (+1, -1) (:func:`switch_bits`)"""
        self._inputs = np.zeros(self._n_drives, np.int64)
        self.tool_ids = tool_pose_ids(model)
        """what :func:`tool_pose` reads (:func:`tool_pose_ids`)"""
        self.reset()

    def reset(self) -> None:
        """Put the machine at the ``home`` keyframe at rest, drives at 0 V."""
        mujoco.mj_resetDataKeyframe(self.model, self.data, self.model.key(HOME_KEYFRAME).id)
        self.data.ctrl[:] = 0.0
        self.volts[:] = 0.0
        reset_amps(self.amps)
        self.update_screws()
        mujoco.mj_forward(self.model, self.data)

    def move_axis(self, axis: int, distance: float) -> None:
        """Move axis ``axis`` (index) by ``distance`` [m | rad] at rest, as if jogged there and
        settled: its joint and its motor hinge (``distance`` / the drive's gear) together, so the
        screw's or the harmonic drive's windup stays; the screws' stiffness and MuJoCo's derived
        quantities follow."""
        qpos = self._qpos
        qpos[self.qpos_adr[axis]] += distance
        motor = self.motor_taps[axis]
        if motor["qpos_adr"] != self.qpos_adr[axis]:
            qpos[motor["qpos_adr"]] += distance / motor["scale"]
        self.update_screws()
        mujoco.mj_forward(self.model, self.data)

    def update_screws(self) -> None:
        """The ball screws' stiffness where their tables are now (:mod:`cnc_twin.machine.screw`);
        :meth:`step` does it before every physics step, a caller that sets ``qpos`` itself calls it."""
        screw_stiffness(self.screws, self._qpos, self.model.tendon_stiffness)

    @property
    def encoder_home(self) -> tuple[float, ...]:
        """The encoders' positions at the ``home`` keyframe [m | rad], shape ``(6,)``: where they
        count from at power-on (the axis positions on a rigid machine)."""
        out = np.zeros(len(AXES))
        gather_encoders(self.model.key(HOME_KEYFRAME).qpos, self.encoder_taps, out)
        return tuple(out.tolist())

    # --- lean per-tick path -------------------------------------------------------------
    def axis_positions(self) -> list[float]:
        """The axis joints' positions [m | rad] (table, head), as a list of 6 floats."""
        return self._qpos[self.qpos_adr].tolist()

    def encoder_positions(self) -> np.ndarray:
        """The encoders' positions now [m | rad], shape ``(6,)`` (:attr:`encoders`, overwritten
        by the next call)."""
        gather_encoders(self._qpos, self.encoder_taps, self.encoders)
        return self.encoders

    def sample_tool_pose(self, out: np.ndarray) -> None:
        """The tool's true pose now into ``out`` (shape ``(6,)``) [m]: tip and pivot, world frame
        (:func:`tool_pose`). Runs MuJoCo's kinematics for the current ``qpos``; the next physics
        step computes them again, so the motion is the same with or without it."""
        data = self.data
        mujoco.mj_kinematics(self.model, data)
        tool_pose(data.site_xpos, data.xpos, data.xaxis, self._qpos, self.tool_ids, out)

    def apply_volts(self, volts: list[float]) -> None:
        """Set the six drive command voltages [V] (held until the next call)."""
        self.volts[:] = volts
        if not self.amps_modelled:  # velocity-mode drives: the voltage is MuJoCo's control
            self._ctrl[: self._n_drives] = volts

    def step(self, n: int) -> None:
        """Advance the physics ``n`` steps of ``timestep`` (before each, the screws' stiffness where
        their nuts are and the amplifiers' loops)."""
        if not self.per_step:
            mujoco.mj_step(self.model, self.data, nstep=n)
            return
        model, data, amps, volts, ctrl = self.model, self.data, self.amps, self.volts, self._ctrl
        qpos, qvel, screws, stiffness = data.qpos, data.qvel, self.screws, model.tendon_stiffness
        for _ in range(n):
            screw_stiffness(screws, qpos, stiffness)
            drive_amps(amps, volts, qpos, qvel, ctrl)
            mujoco.mj_step(model, data)

    def pad_force(self) -> float:
        """Load-cell force between head and pad along the tool axis [N], compression positive.

        The sensor reports the force the spindle exerts on the pad in the pad frame; pressing the
        pad onto the workpiece makes that force point down the tool axis (negative z), so the sign
        is flipped. With no contact it reads minus the pad's weight (about -1.5 N) when vertical.
        """
        return -float(self._sensordata[self._force_z_adr])

    @property
    def force_sensor_adr(self) -> int:
        """Index in ``data.sensordata`` of the load cell's z (see :meth:`pad_force`)."""
        return self._force_z_adr

    def switch_inputs(self) -> list[int]:
        """Home and limit switch states per axis, shape ``(6,)``: bits ``SWITCH_*`` (0 without switches)."""
        switch_bits(self.switches, self._sensordata, self._inputs)
        return self._inputs.tolist()

    # --- faults and stops ----------------------------------------------------------------
    def disable_drives(self) -> None:
        """Amplifier enable off: the six drives make no force from now on (gains zeroed), and
        the holding brakes (:data:`BRAKES`) close. Once is enough; later calls do nothing."""
        if not self.drives_enabled:
            return
        self.drives_enabled = False
        model = self.model
        ids = self.actuator_ids
        model.actuator_gainprm[ids, 0] = 0.0
        model.actuator_biasprm[ids, 2] = 0.0
        self._ctrl[: self._n_drives] = 0.0
        self.volts[:] = 0.0
        for axis, damping in BRAKES.items():
            tap = self.motor_taps[axis]
            model.dof_damping[tap["dof_adr"]] = damping * tap["scale"] ** 2

    def scale_force_limit(self, axis: int, fraction: float) -> None:
        """The drive of ``axis`` can deliver only ``fraction`` of its force range from now on."""
        self.model.actuator_forcerange[self.actuator_ids[axis]] *= fraction

    def place_obstacle(self, index: int, centre: tuple[float, float, float]) -> None:
        """Move obstacle ``index`` (see :func:`~cnc_twin.machine.model_file.add_obstacles`) to
        ``centre`` [m], world frame."""
        body = self.model.body(f"obstacle_{index}")
        self.data.mocap_pos[body.mocapid[0]] = centre

    def tool_position(self) -> np.ndarray:
        """Tool-tip (pad face centre) position in the world frame [m], shape ``(3,)``."""
        return self._sensordata[self._tool_adr].copy()

    @property
    def time(self) -> float:
        """Simulated time [s]."""
        return float(self.data.time)

    def warnings(self) -> dict[str, int]:
        """MuJoCo warnings raised so far, by name, only those with a non-zero count."""
        out = {}
        for i, name in enumerate(mujoco.mjtWarning.__members__):
            if i >= len(self.data.warning):
                break
            if self.data.warning[i].number:
                out[name] = int(self.data.warning[i].number)
        return out
