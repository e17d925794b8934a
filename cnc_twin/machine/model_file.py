"""An MJCF machine file, compiled and checked: what the twin drives and reads is in it.

Its own module, without numba or the plant's compiled kernels, so that a process that only
needs the model (the recording process draws the machine from it) does not pay for them.
"""

from __future__ import annotations

import copy
import os
from pathlib import Path

import mujoco

from cnc_twin.core.axes import AXES, HOME_KEYFRAME, actuator_name, joint_name
from cnc_twin.core.errors import ScenarioError

PAD_FORCE_SENSOR = "pad_force"
TOOL_POS_SENSOR = "tool_pos"
BLOCK_GEOM = "workpiece_collision"
"""the scene's workpiece block (a box)"""

_COMPILED: dict[tuple, mujoco.MjModel] = {}
"""checked models compiled in this process, by file and the state of its folder (see load_model)"""
_COMPILED_MAX = 8


def folder_state(path: Path) -> tuple:
    """What a compiled model depends on: the file and everything next to it (includes, meshes),
    by name, size and modification time."""
    try:
        entries = sorted((entry.name, entry.stat().st_mtime_ns, entry.stat().st_size)
                         for entry in os.scandir(path.parent) if entry.is_file())
    except OSError:
        return (str(path), None)
    return (str(path.resolve()), tuple(entries))


def load_model(path: Path) -> mujoco.MjModel:
    """Compile an MJCF file and check it has what the twin drives and reads.

    Returns a model of its own (a run changes gains and timestep): a copy of the one compiled for
    the same file earlier in this process while neither it nor anything in its folder changed
    (a copy takes 3 ms, compiling 20 ms).

    Raises
    ------
    ScenarioError
        If the file does not compile or lacks a required joint, actuator, sensor or keyframe.
    """
    key = folder_state(Path(path))
    compiled = _COMPILED.get(key)
    if compiled is None:
        try:
            compiled = mujoco.MjModel.from_xml_path(str(path))
        except ValueError as exc:
            reason = " ".join(line.strip() for line in str(exc).splitlines() if line.strip()) or "no reason given"
            raise ScenarioError(path, "", f"MJCF does not compile: {reason}") from None
        _require(compiled, path)
        if len(_COMPILED) >= _COMPILED_MAX:
            _COMPILED.clear()
        _COMPILED[key] = compiled
    return copy.copy(compiled)


def _require(model: mujoco.MjModel, path: Path) -> None:
    def has(obj_type: mujoco.mjtObj, name: str) -> bool:
        return mujoco.mj_name2id(model, obj_type, name) >= 0

    for axis in AXES:
        if not has(mujoco.mjtObj.mjOBJ_JOINT, joint_name(axis)):
            raise ScenarioError(path, "", f"MJCF lacks joint '{joint_name(axis)}' for axis {axis}")
        if not has(mujoco.mjtObj.mjOBJ_ACTUATOR, actuator_name(axis)):
            raise ScenarioError(path, "", f"MJCF lacks actuator '{actuator_name(axis)}' for axis {axis}")
        act = model.actuator(actuator_name(axis))
        if not (act.biasprm[2] < 0 and act.gainprm[0] > 0) and not current_mode(model, act.id):
            raise ScenarioError(
                path, "", f"actuator '{act.name}' is neither a velocity-mode drive (gainprm[0] > 0, biasprm[2] < 0) "
                          "nor a current-mode one (dyntype filterexact, gainprm[0] 1, no bias)"
            )
    for sensor in (PAD_FORCE_SENSOR, TOOL_POS_SENSOR):
        if not has(mujoco.mjtObj.mjOBJ_SENSOR, sensor):
            raise ScenarioError(path, "", f"MJCF lacks sensor '{sensor}'")
    if not has(mujoco.mjtObj.mjOBJ_KEY, HOME_KEYFRAME):
        raise ScenarioError(path, "", f"MJCF lacks keyframe '{HOME_KEYFRAME}'")
    problem = screw_chain_problem(model)
    if problem is not None:
        raise ScenarioError(path, "", problem)


def place_block(spec: mujoco.MjSpec, shift) -> None:
    """Move the scene's workpiece block by ``shift`` (x y z [m], world frame) in ``spec``, the
    work frame staying where the scene puts it: a part set up off its drawn place, or thicker or
    thinner than drawn (``machine.block_shift``), as a program that probes finds it. Edited in the
    spec, not the compiled model: MuJoCo bounds a static body's geoms when it compiles, and a
    geom moved afterwards is not found in contact above its old bounds. ValueError for a scene
    without the block."""
    block = spec.geom(BLOCK_GEOM)
    if block is None:
        raise ValueError(f"the scene has no block '{BLOCK_GEOM}' to shift")
    block.pos = [p + d for p, d in zip(block.pos, shift)]


OBSTACLE_PARK = (0.0, 0.0, -50.0)
"""where an obstacle waits until its time comes [m]: far below the table"""


def add_obstacles(spec: mujoco.MjSpec, boxes: list[tuple[tuple[float, float, float], tuple[float, float, float]]]
                  ) -> None:
    """Add one mocap body per obstacle box (``(centre, half sizes)`` [m], world frame) to ``spec``,
    parked at :data:`OBSTACLE_PARK`; :meth:`~cnc_twin.machine.plant.Plant.place_obstacle` puts one
    in place. Their geoms collide with the head and pad as the workpiece does (contype 1,
    conaffinity 2)."""
    for n, (_, size) in enumerate(boxes):
        body = spec.worldbody.add_body(name=f"obstacle_{n}", mocap=True, pos=list(OBSTACLE_PARK))
        body.add_geom(name=f"obstacle_{n}", type=mujoco.mjtGeom.mjGEOM_BOX, size=list(size), contype=1,
                      conaffinity=2, group=3, rgba=[0.85, 0.2, 0.2, 1.0], density=0.0)


def load_model_with_obstacles(path: Path, boxes, block_shift=(0.0, 0.0, 0.0)) -> mujoco.MjModel:
    """:func:`load_model` plus obstacle boxes (see :func:`add_obstacles`), the workpiece block
    moved by ``block_shift`` [m] (:func:`place_block`)."""
    model = load_model(path)  # checks the file first, with its clear errors
    if not boxes and not any(block_shift):
        return model
    spec = mujoco.MjSpec.from_file(str(path))
    add_obstacles(spec, boxes)
    if any(block_shift):
        place_block(spec, block_shift)
    return spec.compile()


def current_mode(model: mujoco.MjModel, actuator: int) -> bool:
    """Whether ``actuator`` is a current-mode drive: force = its lagged ``ctrl`` (the current
    loop, ``dyntype="filterexact"``, gain 1, no bias)."""
    return (model.actuator_dyntype[actuator] == mujoco.mjtDyn.mjDYN_FILTEREXACT
            and model.actuator_gainprm[actuator, 0] == 1.0 and model.actuator_biastype[actuator] == 0)


def chain_name(axis: str) -> str:
    """The custom numeric that gives ``axis``'s ball-screw chain (``x_screw_chain``; see
    :mod:`cnc_twin.machine.screw`)."""
    return f"{axis.lower()}_screw_chain"


def chain_stiffness(k_rest: float, ea: float, a0: float, side: float, q: float) -> float:
    """A ball-screw chain's stiffness [N/m] with the table at ``q`` [m]: the rest of the chain
    ``k_rest`` [N/m] in series with the shaft between the fixed bearing and the nut, ``ea`` [N]
    over its length ``a0 + side q`` [m] (:mod:`cnc_twin.machine.screw`)."""
    return 1.0 / (1.0 / k_rest + (a0 + side * q) / ea)


def screw_chain_problem(model: mujoco.MjModel) -> str | None:
    """What is wrong with the model's ball-screw chains, in a sentence, or None: each needs its
    ``<axis>_screw`` tendon, four values (k_rest > 0 [N/m], EA > 0 [N], a0 [m], side +-1), the nut
    clear of the fixed bearing (a > 0) over the table's whole travel, and the tendon's stiffness
    the chain's at the home keyframe (within 1e-6: the model as compiled is right at home)."""
    home = model.key(HOME_KEYFRAME).qpos
    for axis in AXES:
        name = chain_name(axis)
        numeric = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_NUMERIC, name)
        if numeric < 0:
            continue
        data = [float(v) for v in model.numeric(numeric).data]
        tendon = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TENDON, f"{axis.lower()}_screw")
        if tendon < 0:
            return f"numeric {name}: the model has no tendon {axis.lower()}_screw for it"
        if len(data) != 4 or not (data[0] > 0 and data[1] > 0 and abs(abs(data[3]) - 1.0) < 1e-12):
            return f"numeric {name}: expected 4 values: k_rest > 0 [N/m], EA > 0 [N], a0 [m], side +1 or -1"
        k_rest, ea, a0, side = data
        joint = model.joint(joint_name(axis))
        for q in joint.range:
            if a0 + side * q <= 0.0:
                return f"numeric {name}: the nut reaches the fixed bearing at {q:g} m (a0 + side q <= 0)"
        at_home = chain_stiffness(k_rest, ea, a0, side, float(home[joint.qposadr[0]]))
        entered = float(model.tendon_stiffness[tendon])
        if abs(entered - at_home) > 1e-6 * at_home:
            return (f"tendon {axis.lower()}_screw: stiffness {entered:.7g} N/m, but {name} gives {at_home:.7g} "
                    "at the home keyframe")
    return None
