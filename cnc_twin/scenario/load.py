"""Scenario files: YAML in machinist units -> a validated, frozen :class:`Scenario` in SI.

Loading is the only place units are converted (see :mod:`cnc_twin.core.units`). Every problem is a
:class:`~cnc_twin.core.errors.ScenarioError` naming the file and the key path, e.g.::

    scenarios/bad.yaml: program.moves[1].X: target 900 mm is outside the X travel -400..400 mm

The machine's parameter file (``machine.parameters``, default ``polisher.yaml``) gives every
axis's limits, encoder and servo gains; a scenario's own ``axes:`` / ``force_sensor:`` keys
override any of them, key by key.
"""

from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Annotated, Any, Literal, Union

import mujoco
import yaml
from pydantic import BaseModel, Field, ValidationError, model_validator

from cnc_twin.core import units
from cnc_twin.core.axes import AXES, is_rotary
from cnc_twin.core.errors import ScenarioError, format_key_path
from cnc_twin.machine.plant import ModelInfo, load_model, model_info
from cnc_twin.core.config import (
    AxisConfig,
    AxisCurve,
    ForceSensorConfig,
    Move,
    NurbsProgram,
    PathLimits,
    PlannerConfig,
    PointToPoint,
    Scenario,
    Timing,
    WhiteboardConfig,
)
from cnc_twin.scenario.resources import resolve_model_file
from cnc_twin.scenario.schema_base import KeyedValueError as _KeyedValueError
from cnc_twin.scenario.schema_base import PathLimitsSpec
from cnc_twin.scenario.schema_base import Strict as _Strict
from cnc_twin.scenario.chip import MotionChipProgramSpec
from cnc_twin.scenario.contour import ContourProgramSpec
from cnc_twin.scenario.faults import FAULT_TAGS, FaultSpec, SupervisorSpec, convert_fault, convert_supervisor
from cnc_twin.scenario.surface import SurfacePolishProgram


# --------------------------------------------------------------------------------------------
# Schema, in the units users write. Field descriptions state the unit.
# --------------------------------------------------------------------------------------------
class EncoderSpec(_Strict):
    """Quadrature encoder on the motor shaft (semi-closed loop)."""

    lines_per_rev: int = Field(gt=0, description="encoder lines per motor revolution; the QEP counts 4 edges per line")
    gear_ratio: float = Field(1.0, gt=0, description="motor revolutions per screw (linear) or axis (rotary) revolution")
    pitch: float | None = Field(None, gt=0, description="ball-screw lead [mm per screw revolution]; linear axes only")
    index_offset: float = Field(0.0, description="where one of the index pulses (one per motor revolution) is [mm | deg]")


class ServoSpec(_Strict):
    """Position loop gains in machine terms; the DSP converts them to volts per count."""

    kp: float = Field(ge=0, description="position loop gain [1/s]: commanded speed per unit of following error")
    ki: float = Field(0.0, ge=0, description="integral gain [1/s^2]")
    kd: float = Field(0.0, ge=0, description="derivative gain [-]: speed per unit error rate")
    kvff: float = Field(1.0, ge=0, description="velocity feed-forward [-]; 1 feeds the full commanded speed")
    kaff: float = Field(0.0, ge=0, description="acceleration feed-forward [s]: speed per unit commanded acceleration")
    output_limit: float = Field(10.0, gt=0, le=10.0, description="clamp on the loop output [V]")
    integrator_limit: float = Field(3.0, ge=0, description="clamp on the integrator's contribution [V]")


class PulseSpec(_Strict):
    """Pulse-train output (``command_output: pulse``): the generator's limit and the amplifier
    in position mode."""

    max_rate: float = Field(500.0, gt=0, description="highest step rate of the card and the drive input [kHz]")
    position_gain: float = Field(80.0, gt=0, description="the amplifier's position-loop gain [1/s]")
    velocity_ff: float = Field(1.0, ge=0, le=1.0, description="the amplifier's velocity feed-forward [-]")
    ff_filter: float = Field(1.0, ge=0, description="feed-forward filter time constant [ms]")


class AxisSpec(_Strict):
    """One axis: limits (mm or deg based), encoder, servo gains."""

    max_velocity: float = Field(gt=0, description="[mm/min] linear, [deg/min] rotary")
    max_acceleration: float = Field(gt=0, description="[mm/s^2] linear, [deg/s^2] rotary")
    max_jerk: float = Field(gt=0, description="[mm/s^3] linear, [deg/s^3] rotary")
    encoder: EncoderSpec
    servo: ServoSpec
    pulse: PulseSpec = PulseSpec()
    following_error_limit: float = Field(0.0, ge=0, description="the supervisor's following-error limit [mm | deg]; 0 = off")
    soft_limits: list[float] | None = Field(None, min_length=2, max_length=2,
                                            description="[low, high] the supervisor keeps the axis within [mm | deg]; "
                                                        "default: the hard travel of the MJCF")

    @model_validator(mode="after")
    def _ordered_limits(self) -> "AxisSpec":
        if self.soft_limits is not None and not self.soft_limits[0] < self.soft_limits[1]:
            raise _KeyedValueError(("soft_limits",), f"expected [low, high] with low < high, got {self.soft_limits}")
        return self


class AxesSpec(_Strict):
    X: AxisSpec
    Y: AxisSpec
    Z: AxisSpec
    A: AxisSpec
    B: AxisSpec
    C: AxisSpec

    @model_validator(mode="after")
    def _pitch_only_on_linear_axes(self) -> "AxesSpec":
        for axis in AXES:
            enc = getattr(self, axis).encoder
            if is_rotary(axis) and enc.pitch is not None:
                raise _KeyedValueError((axis, "encoder", "pitch"), "rotary axes have no screw pitch; remove the key")
            if not is_rotary(axis) and enc.pitch is None:
                raise _KeyedValueError((axis, "encoder", "pitch"), "linear axes need the screw pitch [mm/rev]")
        return self


class ForceSensorSpec(_Strict):
    """Load cell between head and pad, read by the DSP's ADC."""

    range: list[float] = Field(min_length=2, max_length=2, description="[N] force at ADC code 0 and at full scale")
    bits: int = Field(12, ge=8, le=16, description="ADC resolution [bits]")

    @model_validator(mode="after")
    def _ordered(self) -> "ForceSensorSpec":
        if not self.range[0] < self.range[1]:
            raise _KeyedValueError(("range",), f"expected [low, high] with low < high, got {self.range}")
        return self


class MachineParameters(_Strict):
    """A machine parameter file (e.g. ``models/polisher.yaml``)."""

    axes: AxesSpec
    force_sensor: ForceSensorSpec


class TimingSpec(_Strict):
    """The three rates; each period must be an integer multiple of the next."""

    interpolation_period: float = Field(1.0, gt=0, description="PC <-> DSP exchange and interpolation period [ms]")
    servo_period: float = Field(0.25, gt=0, description="DSP servo interrupt period [ms]")
    physics_timestep: float = Field(0.25, gt=0, description="MuJoCo timestep [ms]")
    mode: Literal["lockstep", "realtime"] = Field(
        "lockstep",
        description="lockstep: the DSP waits for every exchange (deterministic); "
        "realtime: the DSP is paced to the wall clock and never waits (late answers are missed exchanges)",
    )


class MachineRef(_Strict):
    model: str = Field("scene.xml", description="MJCF file, relative to the scenario or bundled in models/")
    parameters: str = Field("polisher.yaml", description="machine parameter file, same lookup as model")


HEARTBEAT_DEFAULT_MS = {"realtime": 1000.0, "lockstep": 10000.0}


class PlannerSpec(_Strict):
    """The PC planner process."""

    lookahead: float = Field(0.0, ge=0, description="motion kept queued on the card ahead of execution [ms]; 0 = no limit")
    heartbeat_timeout: float | None = Field(
        None, gt=0, description="wall-clock time without planner heartbeat before it counts as lost [ms]; "
        "default 1000 in realtime mode, 10000 in lockstep (where the card waits anyway, and a busy machine "
        "running a sweep must not pass for a hung planner)")
    start_timeout: float = Field(60.0, gt=0, description="wall-clock time for the planner process to start [s]")


class WhiteboardSpec(_Strict):
    """The emulated dual-port RAM."""

    words: int = Field(8192, description="size [16-bit words]; a power of two from 2048 to 32768")
    chunk: int = Field(4096, ge=64, description="most bytes of records the planner writes per exchange [bytes]")

    @model_validator(mode="after")
    def _power_of_two(self) -> "WhiteboardSpec":
        if not (2048 <= self.words <= 32768 and self.words & (self.words - 1) == 0):
            raise _KeyedValueError(("words",), f"expected a power of two from 2048 to 32768, got {self.words}")
        return self


_UNION_TAGS = FAULT_TAGS | {"point_to_point", "nurbs_curve", "surface_polish", "contour", "motion_chip"}


class MoveSpec(_Strict):
    """One point-to-point move: absolute targets; axes not named keep their position."""

    X: float | None = Field(None, description="[mm]")
    Y: float | None = Field(None, description="[mm]")
    Z: float | None = Field(None, description="[mm]")
    A: float | None = Field(None, description="[deg]")
    B: float | None = Field(None, description="[deg]")
    C: float | None = Field(None, description="[deg]")
    feed: float | None = Field(None, gt=0, description="cap on the tool's X/Y/Z path speed [mm/min]; default: rapid")
    dwell: float = Field(0.0, ge=0, description="pause after arriving [s]")


class PointToPointProgram(_Strict):
    """Moves executed in turn, each on a synchronised trapezoid profile (all axes arrive together)."""

    type: Literal["point_to_point"]
    moves: list[MoveSpec] = Field(min_length=1)
    settle: float = Field(0.3, ge=0, description="time simulated after the last move [s]")


class ToolAxisSpec(_Strict):
    """The tool axis, held fixed along the curve, as head angles."""

    A: float = Field(0.0, description="[deg]")
    B: float = Field(0.0, description="[deg]")


class AxisCurveSpec(_Strict):
    """The tool axis along the path as a NURBS of direction vectors (workpiece frame, pointing
    from the tip up the tool), on the same parameter range as the tip curve."""

    degree: int = Field(ge=1, le=9)
    control_points: list[list[float]] = Field(min_length=2, description="[[i, j, k], ...] directions")
    weights: list[float] | None = None
    knots: list[float]


class NurbsCurveProgram(_Strict):
    """A tool-tip NURBS curve in the workpiece frame (origin at the workpiece top centre, mm)."""

    type: Literal["nurbs_curve"]
    degree: int = Field(ge=1, le=9)
    control_points: list[list[float]] = Field(min_length=2, description="[[x, y, z], ...] [mm]")
    weights: list[float] | None = Field(None, description="one per control point, > 0; default all 1")
    knots: list[float] = Field(description="clamped knot vector, n + degree + 1 values")
    feed: float = Field(gt=0, description="programmed feed [mm/min]")
    chord_tolerance: float = Field(0.001, gt=0, description="[mm]")
    limits: PathLimitsSpec = PathLimitsSpec()
    tool_axis: ToolAxisSpec = ToolAxisSpec()
    tool_axis_curve: AxisCurveSpec | None = Field(None, description="tool axis varying along the path (replaces tool_axis)")
    C: float = Field(0.0, description="spindle angle held along the curve [deg]")
    approach_feed: float | None = Field(None, gt=0, description="X/Y/Z speed cap of the move to the start [mm/min]")
    settle: float = Field(0.3, ge=0, description="time simulated after the curve [s]")


ProgramSpec = Annotated[Union[PointToPointProgram, NurbsCurveProgram, SurfacePolishProgram, ContourProgramSpec,
                              MotionChipProgramSpec],
                        Field(discriminator="type")]


class ScenarioFile(_Strict):
    """A whole scenario file, after the machine parameters were merged in."""

    name: str = Field(min_length=1)
    description: str = ""
    seed: int = Field(0, ge=0, description="seed for every random source in the run")
    timing: TimingSpec = TimingSpec()
    machine: MachineRef = MachineRef()
    axes: AxesSpec
    force_sensor: ForceSensorSpec
    planner: PlannerSpec = PlannerSpec()
    whiteboard: WhiteboardSpec = WhiteboardSpec()
    faults: list[FaultSpec] = Field(default_factory=list)
    supervisor: SupervisorSpec = SupervisorSpec()
    max_time: float | None = Field(None, gt=0, description="cap on simulated time [s]; default twice the program plus 5 s")
    command_output: Literal["analog", "pulse"] = Field(
        "analog", description="analog: +-10 V from the card's PID, drives in velocity mode; "
                              "pulse: step/direction pulses, drives in position mode")
    program: ProgramSpec


# --------------------------------------------------------------------------------------------
# Loading.
# --------------------------------------------------------------------------------------------
def load_scenario(path: str | Path, *, overrides: dict[str, Any] | None = None) -> Scenario:
    """Read, validate and convert a scenario file, with optional overrides by dotted path
    (see :mod:`cnc_twin.scenario.overrides`: ``{"servo.X.kp": 60, "program.settle": 0.5}``).

    Raises
    ------
    ScenarioError
        For any problem, naming the file and the key path (an override's problem names the
        override too).
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ScenarioError(path, "", "no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(path, "", f"cannot read: {exc}") from None
    if not overrides:
        return scenario_from_text(text, source_file=path)
    from cnc_twin.scenario.overrides import apply_overrides

    raw = _parse_yaml(text, path)
    if not isinstance(raw, dict):
        raise ScenarioError(path, "", f"expected a mapping of keys at the top level, got {type(raw).__name__}")
    changed = apply_overrides(raw, overrides, label=f"{path} (overrides)")
    try:
        return scenario_from_dict(changed, source_file=path,
                                  source_text=yaml.safe_dump(changed, sort_keys=False))
    except ScenarioError as exc:
        hit = _override_for(exc.key_path, overrides)
        if hit is None:
            raise
        raise ScenarioError(f"{path} (override {hit!r})", exc.key_path, exc.message) from None


def _override_for(key_path: str, overrides: dict[str, Any]) -> str | None:
    """The override whose expanded path is ``key_path``, lies under it (a mapping the override
    created, e.g. ``program.force`` for ``force.ki`` on a program without a force loop), or holds
    it (a value the override set), if any."""
    from cnc_twin.scenario.overrides import expand

    def under(path: str, top: str) -> bool:
        return path == top or path.startswith(top + ".") or path.startswith(top + "[")

    for name in overrides:
        for target in expand(name, {}):
            shown = format_key_path(tuple(target))
            if under(key_path, shown) or under(shown, key_path):
                return name
    return None


def scenario_from_text(text: str, *, source_file: Path | None = None) -> Scenario:
    """Validate scenario YAML ``text``; relative model paths resolve against ``source_file``'s folder."""
    label = source_file if source_file is not None else Path("<scenario>")
    raw = _parse_yaml(text, label)
    return scenario_from_dict(raw, source_file=source_file, source_text=text)


def scenario_from_dict(raw: Any, *, source_file: Path | None = None, source_text: str | None = None) -> Scenario:
    """Validate an already-parsed scenario mapping (e.g. after applying overrides)."""
    label = source_file if source_file is not None else Path("<scenario>")
    if not isinstance(raw, dict):
        raise ScenarioError(label, "", f"expected a mapping of keys at the top level, got {type(raw).__name__}")
    folder = source_file.parent if source_file is not None else None

    machine_raw = raw.get("machine", {})
    machine_ref = _validate(MachineRef, machine_raw, label, prefix=("machine",))
    model_path = _resolve(machine_ref.model, folder, label, "machine.model")
    params_path = _resolve(machine_ref.parameters, folder, label, "machine.parameters")
    params_raw = _parse_yaml(_read(params_path), params_path)
    params = _validate(MachineParameters, params_raw, params_path)

    merged = dict(raw)
    defaults = params.model_dump()
    merged["axes"] = _deep_merge(defaults["axes"], raw.get("axes", {}))
    merged["force_sensor"] = _deep_merge(defaults["force_sensor"], raw.get("force_sensor", {}))
    spec = _validate(ScenarioFile, merged, label)

    timing = _convert_timing(spec.timing, label)
    model = load_model(model_path)
    info = model_info(model)
    axes = _convert_axes(spec.axes, info, label)
    if spec.command_output == "pulse":
        _check_pulse_rates(axes, label)
    if isinstance(spec.program, SurfacePolishProgram):
        from cnc_twin.scenario import surface as scenario_surface

        program = scenario_surface.convert(spec.program, axes, model_path, label)
    elif isinstance(spec.program, NurbsCurveProgram):
        program = _convert_nurbs(spec.program, axes, model, label)
    elif isinstance(spec.program, ContourProgramSpec):
        from cnc_twin.scenario import contour as scenario_contour

        program = scenario_contour.convert(spec.program, axes, model, info.home, label)
    elif isinstance(spec.program, MotionChipProgramSpec):
        from cnc_twin.scenario import chip as scenario_chip

        def has_home_switch(i: int) -> bool:
            return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, f"{AXES[i].lower()}_home") >= 0

        program = scenario_chip.convert(spec.program, axes, has_home_switch, label)
    else:
        program = _convert_program(spec.program, axes, info, label)
    if source_text is None:
        source_text = yaml.safe_dump(raw, sort_keys=False)
    return Scenario(
        name=spec.name,
        description=spec.description,
        seed=spec.seed,
        source_file=source_file,
        source_text=source_text,
        timing=timing,
        model_file=model_path,
        axes=axes,
        force_sensor=ForceSensorConfig(spec.force_sensor.range[0], spec.force_sensor.range[1], spec.force_sensor.bits),
        program=program,
        home=info.home,
        planner=PlannerConfig(
            lookahead=spec.planner.lookahead * units.MS,
            heartbeat_timeout=(spec.planner.heartbeat_timeout if spec.planner.heartbeat_timeout is not None
                               else HEARTBEAT_DEFAULT_MS[spec.timing.mode]) * units.MS,
            start_timeout=spec.planner.start_timeout,
        ),
        whiteboard=WhiteboardConfig(words=spec.whiteboard.words, chunk_words=spec.whiteboard.chunk // 2),
        faults=tuple(convert_fault(f) for f in spec.faults),
        supervisor=convert_supervisor(spec.supervisor),
        max_time=spec.max_time,
        command_output=spec.command_output,
    )


def _read(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(path, "", f"cannot read: {exc}") from None


_SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
"""PyYAML's safe loader, in C when libyaml is there (7x faster; the same safe subset)"""


def _parse_yaml(text: str, label: Path) -> Any:
    try:
        return yaml.load(text, Loader=_SAFE_LOADER)  # noqa: S506 - a safe loader, never the full one
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ScenarioError(label, where, f"not valid YAML: {problem}") from None


def _resolve(name: str, folder: Path | None, label: Path, key: str) -> Path:
    found = resolve_model_file(name, folder)
    if found is None:
        raise ScenarioError(label, key, f"file '{name}' not found next to the scenario or in the bundled models")
    return found


def _deep_merge(base: Any, override: Any) -> Any:
    """``override`` on top of ``base``, key by key; non-mapping overrides replace (and get validated)."""
    if not isinstance(base, dict) or not isinstance(override, dict):
        return copy.deepcopy(override)
    out = copy.deepcopy(base)
    for key, value in override.items():
        out[key] = _deep_merge(out[key], value) if key in out else copy.deepcopy(value)
    return out


def _validate(model_cls: type[BaseModel], data: Any, label: Path, prefix: tuple = ()) -> Any:
    try:
        return model_cls.model_validate(data)
    except ValidationError as exc:
        raise _first_error(exc, label, prefix) from None


def _first_error(exc: ValidationError, label: Path, prefix: tuple) -> ScenarioError:
    errors = exc.errors(include_url=False)
    err = errors[0]
    loc = prefix + tuple(part for part in err["loc"] if part not in _UNION_TAGS)
    cause = err.get("ctx", {}).get("error")
    if isinstance(cause, _KeyedValueError):
        loc = loc + cause.loc
        message = str(cause)
    elif err["type"] == "extra_forbidden":
        message = "unknown key"
    elif err["type"] == "missing":
        message = "required key is missing"
    else:
        message = f"{err['msg'][0].lower()}{err['msg'][1:]}, got {err['input']!r}"
    more = len(errors) - 1
    if more:
        message += f" (and {more} more problem{'s' if more > 1 else ''})"
    return ScenarioError(label, format_key_path(loc), message)


def _whole_multiple(spec: TimingSpec, longer: str, shorter: str, label: Path) -> int:
    """How many ``shorter`` periods fit in ``longer``; an error unless a whole number >= 1."""
    numerator, denominator = getattr(spec, longer), getattr(spec, shorter)
    ratio = numerator / denominator
    nearest = round(ratio)
    if nearest >= 1 and abs(ratio - nearest) <= 1e-9 * ratio:
        return int(nearest)
    raise ScenarioError(
        label,
        f"timing.{shorter}",
        f"{longer} {numerator} ms must be an integer multiple (>= 1) of {shorter} {denominator} ms",
    )


def _convert_timing(spec: TimingSpec, label: Path) -> Timing:
    ticks = _whole_multiple(spec, "interpolation_period", "servo_period", label)
    substeps = _whole_multiple(spec, "servo_period", "physics_timestep", label)
    return Timing(
        interpolation_period=spec.interpolation_period * units.MS,
        servo_period=spec.servo_period * units.MS,
        physics_timestep=spec.physics_timestep * units.MS,
        ticks_per_period=ticks,
        substeps_per_tick=substeps,
        mode=spec.mode,
    )


def _counts_per_unit(axis: str, enc: EncoderSpec) -> float:
    counts_per_motor_rev = 4.0 * enc.lines_per_rev
    if is_rotary(axis):
        return counts_per_motor_rev * enc.gear_ratio / (2.0 * math.pi)
    return counts_per_motor_rev * enc.gear_ratio / (enc.pitch * units.MM)


def _index_period(axis: str, enc: EncoderSpec) -> float:
    """One motor revolution at the axis [m | rad]: the distance between index pulses."""
    if is_rotary(axis):
        return 2.0 * math.pi / enc.gear_ratio
    return enc.pitch * units.MM / enc.gear_ratio


def _convert_axes(spec: AxesSpec, info: ModelInfo, label: Path) -> tuple[AxisConfig, ...]:
    out = []
    for i, axis in enumerate(AXES):
        a: AxisSpec = getattr(spec, axis)
        rotary = is_rotary(axis)
        out.append(
            AxisConfig(
                name=axis,
                rotary=rotary,
                max_velocity=a.max_velocity * units.velocity_factor(rotary),
                max_acceleration=a.max_acceleration * units.position_factor(rotary),
                max_jerk=a.max_jerk * units.position_factor(rotary),
                counts_per_unit=_counts_per_unit(axis, a.encoder),
                kp=a.servo.kp,
                ki=a.servo.ki,
                kd=a.servo.kd,
                kvff=a.servo.kvff,
                kaff=a.servo.kaff,
                output_limit=a.servo.output_limit,
                integrator_limit=a.servo.integrator_limit,
                travel=info.travel[i],
                speed_per_volt=info.speed_per_volt[i],
                pulse_max_rate=a.pulse.max_rate * 1e3,
                drive_position_gain=a.pulse.position_gain,
                drive_velocity_ff=a.pulse.velocity_ff,
                drive_ff_filter=a.pulse.ff_filter * units.MS,
                index_period=_index_period(axis, a.encoder),
                index_offset=a.encoder.index_offset * units.position_factor(rotary),
                following_error_limit=a.following_error_limit * units.position_factor(rotary),
                soft_limits=_soft_limits(axis, a, info.travel[i], label),
            )
        )
    return tuple(out)


def _soft_limits(axis: str, spec: AxisSpec, travel: tuple[float, float] | None, label: Path
                 ) -> tuple[float, float] | None:
    """The soft limits in SI, checked to lie within the hard travel."""
    if spec.soft_limits is None:
        return None
    f = units.position_factor(is_rotary(axis))
    lo, hi = spec.soft_limits[0] * f, spec.soft_limits[1] * f
    if travel is not None and not (travel[0] <= lo and hi <= travel[1]):
        unit = units.position_unit(is_rotary(axis))
        raise ScenarioError(label, f"axes.{axis}.soft_limits",
                            f"{spec.soft_limits[0]:g}..{spec.soft_limits[1]:g} {unit} must lie within the "
                            f"{axis} travel {travel[0] / f:g}..{travel[1] / f:g} {unit}")
    return lo, hi


def _check_pulse_rates(axes: tuple[AxisConfig, ...], label: Path) -> None:
    """Pulse output: every axis's top speed must fit its pulse rate limit (the planner plans up to it)."""
    for cfg in axes:
        needed = cfg.max_velocity * cfg.counts_per_unit
        if needed > cfg.pulse_max_rate * (1.0 + 1e-9):
            speed = cfg.max_velocity * cfg.display_factor * 60.0
            raise ScenarioError(label, f"axes.{cfg.name}.pulse.max_rate",
                                f"{cfg.name}'s max_velocity {speed:g} {cfg.display_unit}/min needs "
                                f"{needed / 1e3:g} kHz of step pulses; the limit is {cfg.pulse_max_rate / 1e3:g} kHz "
                                f"(raise it or lower max_velocity)")


def _convert_nurbs(spec: NurbsCurveProgram, axes: tuple[AxisConfig, ...], model, label: Path) -> NurbsProgram:
    import numpy as np

    from cnc_twin.geometry.kinematics import HeadGeometry, rotation_ab
    from cnc_twin.geometry.nurbs import NurbsCurve, NurbsError

    for i, point in enumerate(spec.control_points):
        if len(point) != 3:
            raise ScenarioError(label, f"program.control_points[{i}]", f"expected [x, y, z] in mm, got {point}")
    a, b = spec.tool_axis.A * units.DEG, spec.tool_axis.B * units.DEG
    head = HeadGeometry.from_model(model)
    tip_world = head.world_from_workpiece(np.array(spec.control_points) * units.MM)
    axis_curve = None
    if spec.tool_axis_curve is not None:
        if "tool_axis" in spec.model_fields_set:
            raise ScenarioError(label, "program.tool_axis", "give either tool_axis (held) or tool_axis_curve, not both")
        axis_curve, curve, poses = _oriented_path(spec, tip_world, head, label)
        a, b = float(poses[0, 3]), float(poses[0, 4])
        axis_points = tip_world  # tip space: the card solves the kinematics per period
        checks = zip(axes[:5], poses.T, ("control_points",) * 3 + ("tool_axis_curve",) * 2)
    else:
        axis_points = head.axes_from_tip(tip_world, a, b)
        try:
            curve = NurbsCurve(axis_points, spec.weights, spec.knots, spec.degree)
        except NurbsError as exc:
            raise ScenarioError(label, f"program.{exc.key}", str(exc)) from None
        u = np.linspace(*curve.domain, 4001)
        path = curve.point(u)
        checks = zip(axes[:3], path.T, ("control_points",) * 3)
    hold = (a, b, spec.C * units.DEG)
    held = zip(axes[3:], hold, ("tool_axis.A", "tool_axis.B", "C"))
    for cfg, value, name in held if axis_curve is None else list(held)[2:]:
        if cfg.allowed is not None and not cfg.allowed[0] <= value <= cfg.allowed[1]:
            lo, hi = (v * cfg.display_factor for v in cfg.allowed)
            raise ScenarioError(label, f"program.{name}", f"{value * cfg.display_factor:g} deg is outside the "
                                f"{cfg.name} {cfg.allowed_name} {lo:g}..{hi:g} deg")
    for cfg, values, key in checks:
        lo, hi = cfg.allowed
        bad = np.flatnonzero((values < lo) | (values > hi))
        if bad.size:
            f, unit = cfg.display_factor, cfg.display_unit
            raise ScenarioError(label, f"program.{key}",
                                f"the path leaves the {cfg.name} {cfg.allowed_name} {lo * f:g}..{hi * f:g} {unit} "
                                f"(reaches {values[bad[0]] * f:g} {unit})")
    limits = spec.limits
    path_limits = PathLimits(
        feed=spec.feed * units.MM_PER_MIN,
        chord_tolerance=spec.chord_tolerance * units.MM,
        path_acceleration=limits.path_acceleration * units.MM,
        path_jerk=limits.path_jerk * units.MM,
        normal_acceleration=limits.normal_acceleration * units.MM,
        normal_jerk=limits.normal_jerk * units.MM,
        axis_velocity=tuple(c.max_velocity for c in axes[:3]),
        axis_acceleration=tuple(c.max_acceleration for c in axes[:3]),
        axis_jerk=tuple(c.max_jerk for c in axes[:3]),
    )
    shift = np.asarray(head.pivot_home) + rotation_ab(a, b) @ np.asarray(head.tool_offset)
    return NurbsProgram(
        degree=spec.degree,
        knots=tuple(float(k) for k in spec.knots),
        weights=tuple(float(w) for w in curve.weights),
        control_points=tuple(tuple(float(x) for x in p) for p in axis_points),
        hold=hold,
        limits=path_limits,
        approach_feed=spec.approach_feed * units.MM_PER_MIN if spec.approach_feed is not None else None,
        settle=spec.settle,
        tip_shift=tuple(float(x) for x in shift),
        tool_offset=tuple(float(x) for x in head.tool_offset),
        pivot_home=tuple(float(x) for x in head.pivot_home),
        axis_curve=axis_curve,
        rotary_limits=None if axis_curve is None else (
            tuple(c.max_velocity for c in axes[3:5]), tuple(c.max_acceleration for c in axes[3:5]),
            tuple(c.max_jerk for c in axes[3:5])),
    )


def _oriented_path(spec: NurbsCurveProgram, tip_world, head, label: Path):
    """Tip curve (world), axis curve, and sampled poses X/Y/Z/A/B, shape (4001, 5)."""
    import numpy as np

    from cnc_twin.geometry.nurbs import NurbsCurve, NurbsError

    ac = spec.tool_axis_curve
    for i, point in enumerate(ac.control_points):
        if len(point) != 3 or not any(point):
            raise ScenarioError(label, f"program.tool_axis_curve.control_points[{i}]",
                                f"expected a non-zero direction [i, j, k], got {point}")
    try:
        curve = NurbsCurve(tip_world, spec.weights, spec.knots, spec.degree)
    except NurbsError as exc:
        raise ScenarioError(label, f"program.{exc.key}", str(exc)) from None
    try:
        directions = NurbsCurve(ac.control_points, ac.weights, ac.knots, ac.degree)
    except NurbsError as exc:
        raise ScenarioError(label, f"program.tool_axis_curve.{exc.key}", str(exc)) from None
    if directions.domain != curve.domain:
        raise ScenarioError(label, "program.tool_axis_curve.knots",
                            f"parameter range {directions.domain} must equal the tip curve's {curve.domain}")
    u = np.linspace(*curve.domain, 4001)
    n = directions.point(u)
    if np.min(np.linalg.norm(n, axis=1)) < 1e-9:
        raise ScenarioError(label, "program.tool_axis_curve", "the tool axis curve passes through zero")
    if np.min(n[:, 2] / np.linalg.norm(n, axis=1)) <= 0.0:
        raise ScenarioError(label, "program.tool_axis_curve", "the tool must point down: every direction needs k > 0")
    poses = head.axes_from_pose(curve.point(u), n)
    axis_curve = AxisCurve(degree=ac.degree, knots=tuple(float(k) for k in ac.knots),
                           weights=tuple(float(w) for w in directions.weights),
                           control_points=tuple(tuple(float(x) for x in p) for p in ac.control_points))
    return axis_curve, curve, poses


def _convert_program(spec: PointToPointProgram, axes: tuple[AxisConfig, ...], info: ModelInfo, label: Path) -> PointToPoint:
    moves = []
    for m_index, move in enumerate(spec.moves):
        targets: list[float | None] = []
        for cfg in axes:
            value = getattr(move, cfg.name)
            if value is None:
                targets.append(None)
                continue
            si = value * units.position_factor(cfg.rotary)
            if cfg.allowed is not None and not (cfg.allowed[0] <= si <= cfg.allowed[1]):
                lo, hi = (v * cfg.display_factor for v in cfg.allowed)
                raise ScenarioError(
                    label,
                    f"program.moves[{m_index}].{cfg.name}",
                    f"target {value:g} {cfg.display_unit} is outside the {cfg.name} {cfg.allowed_name} "
                    f"{lo:g}..{hi:g} {cfg.display_unit}",
                )
            targets.append(si)
        feed = move.feed * units.MM_PER_MIN if move.feed is not None else None
        moves.append(Move(targets=tuple(targets), feed=feed, dwell=move.dwell))
    return PointToPoint(moves=tuple(moves), settle=spec.settle)
