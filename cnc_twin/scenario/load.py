"""Scenario files: YAML in machinist units -> a validated, frozen
:class:`~cnc_twin.core.config.Scenario` in SI.

Loading is the only place units are converted (see :mod:`cnc_twin.core.units`). Every problem is a
:class:`~cnc_twin.core.errors.ScenarioError` naming the file and the key path, e.g.::

    scenarios/bad.yaml: program.moves[1].X: target 900 mm is outside the X travel -400..400 mm

The machine's parameter file (``machine.parameters``, default ``polisher.yaml``) gives every
axis's limits, encoder and servo gains; a scenario's own ``axes:`` / ``force_sensor:`` keys
override any of them, key by key.
"""

from __future__ import annotations

import copy
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any, Literal, Union

import mujoco
import yaml
from pydantic import Field, field_validator

from cnc_twin.core import units
from cnc_twin.core.axes import AXES
from cnc_twin.core.config import ForceSensorConfig, PlannerConfig, Scenario, WhiteboardConfig
from cnc_twin.core.errors import ScenarioError, format_key_path
from cnc_twin.machine.model_file import load_model, load_model_with_obstacles
from cnc_twin.machine.plant import model_info
from cnc_twin.scenario import chip, contour, curve, gcode, points, surface
from cnc_twin.scenario.ballbar import BallbarSpec, convert_ballbar
from cnc_twin.scenario.chip import MotionChipProgramSpec
from cnc_twin.scenario.contour import ContourProgramSpec
from cnc_twin.scenario.curve import NurbsCurveProgram
from cnc_twin.scenario.gcode import GcodeProgramSpec
from cnc_twin.scenario.faults import FaultSpec, SupervisorSpec, convert_fault, convert_supervisor
from cnc_twin.scenario.machine import (
    HEARTBEAT_DEFAULT_MS, AxesSpec, ForceSensorSpec, MachineParameters, MachineRef, PlannerSpec, TimingSpec,
    WhiteboardSpec, check_pulse_rates, convert_axes, convert_timing,
)
from cnc_twin.scenario.points import PointToPointProgram
from cnc_twin.scenario.resources import resolve_model_file
from cnc_twin.scenario.schema_base import DAY, Strict
from cnc_twin.scenario.surface import SurfacePolishProgram
from cnc_twin.scenario.validation import validate
from cnc_twin.scenario.yaml_input import MAX_FILE_BYTES, check_structure, parse, read_text, too_large


MAX_NAME_LENGTH = 100
"""[characters] of a scenario name"""
NAME_PATTERN = r"^[^./\\\s]([^/\\]*[^/\\\s])?$"
"""a scenario name as a regular expression (JSON Schema's): no folder separator, not hidden, no
space at either end"""

ProgramSpec = Annotated[Union[PointToPointProgram, NurbsCurveProgram, SurfacePolishProgram, ContourProgramSpec,
                              MotionChipProgramSpec, GcodeProgramSpec],
                        Field(discriminator="type")]


class ScenarioFile(Strict):
    """A whole scenario file, after the machine parameters were merged in."""

    name: str = Field(min_length=1, max_length=MAX_NAME_LENGTH,
                      description="names the default run directory: one file name, printable",
                      # for editors, what _one_file_name checks that a pattern can say (not the printable part)
                      json_schema_extra={"pattern": NAME_PATTERN})
    description: str = Field("", description="what the scenario does: its first sentence is its line in `cnc-twin list`")
    seed: int = Field(0, ge=0, le=2**64 - 1, description="seed for every random source in the run")
    timing: TimingSpec = TimingSpec()
    machine: MachineRef = MachineRef()
    axes: AxesSpec = Field(description="the six axes by name: the machine parameter file's, the scenario's keys over them")
    force_sensor: ForceSensorSpec = Field(description="the load cell: the machine parameter file's, the scenario's keys "
                                                      "over them")
    planner: PlannerSpec = PlannerSpec()
    whiteboard: WhiteboardSpec = WhiteboardSpec()
    faults: list[FaultSpec] = Field(default_factory=list)
    supervisor: SupervisorSpec = SupervisorSpec()
    ballbar: BallbarSpec | None = None
    max_time: float | None = Field(None, gt=0, le=DAY, description="cap on simulated time [s]; default twice the program plus 5 s")
    command_output: Literal["analog", "pulse"] = Field(
        "analog", description="analog: +-10 V from the card's PID, drives in velocity mode; "
                              "pulse: step/direction pulses, drives in position mode")
    program: ProgramSpec

    @field_validator("name")
    @classmethod
    def _one_file_name(cls, name: str) -> str:
        # the name becomes runs/<name>-<time>: it may not climb out of runs/, hide the folder or
        # carry terminal control characters into what the CLI prints
        bad = next((ch for ch in name if not ch.isprintable() or ch in "/\\"), None)
        if bad is not None:
            raise ValueError(f"one file name of printable characters (it names the run directory); "
                             f"{bad!r} is not allowed")
        if name.startswith(".") or name != name.strip():
            raise ValueError("may not start with '.' or start or end with a space (it names the run directory)")
        return name


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
    if path.suffix.lower() in NC_SUFFIXES:
        return _program_scenario(path, overrides)
    text = read_text(path)
    if not overrides:
        return scenario_from_text(text, source_file=path)
    from cnc_twin.scenario.overrides import apply_overrides

    raw = parse(text, path)
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


NC_SUFFIXES = (".ngc", ".nc", ".gcode", ".tap")
"""files read as an NC program on the bundled machine's defaults, not as a scenario"""


def _program_scenario(path: Path, overrides: dict[str, Any] | None) -> Scenario:
    """``cnc-twin run part.ngc``: the program on the bundled machine, every other key its default.

    The scenario is named after the file (``part``), and written out in the run directory as
    the YAML that would give the same run."""
    stem = path.stem if path.stem and not path.stem.startswith(".") else "program"
    raw: dict[str, Any] = {"name": stem[:MAX_NAME_LENGTH], "program": {"type": "gcode", "file": path.name}}
    if overrides:
        from cnc_twin.scenario.overrides import apply_overrides

        raw = apply_overrides(raw, overrides, label=f"{path} (overrides)")
    return scenario_from_dict(raw, source_file=path, source_text=yaml.safe_dump(raw, sort_keys=False))


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
    raw = parse(text, label)
    return scenario_from_dict(raw, source_file=source_file, source_text=text)


def scenario_from_dict(raw: Any, *, source_file: Path | None = None, source_text: str | None = None) -> Scenario:
    """Validate an already-parsed scenario mapping (e.g. after applying overrides)."""
    label = source_file if source_file is not None else Path("<scenario>")
    if not isinstance(raw, dict):
        raise ScenarioError(label, "", f"expected a mapping of keys at the top level, got {type(raw).__name__}")
    check_structure(raw, label)  # a mapping built in Python (overrides, scripts) gets the file's limits too
    folder = source_file.parent if source_file is not None else None

    machine_raw = raw.get("machine", {})
    machine_ref = validate(MachineRef, machine_raw, label, prefix=("machine",))
    model_path = _resolve(machine_ref.model, folder, label, "machine.model")
    params_path = _resolve(machine_ref.parameters, folder, label, "machine.parameters")
    with _named_by(label, "machine.parameters"):
        params = validate(MachineParameters, parse(read_text(params_path), params_path), params_path)

    merged = dict(raw)
    defaults = params.model_dump()
    merged["axes"] = _deep_merge(defaults["axes"], raw.get("axes", {}))
    merged["force_sensor"] = _deep_merge(defaults["force_sensor"], raw.get("force_sensor", {}))
    spec = validate(ScenarioFile, merged, label)
    for i, fault in enumerate(spec.faults):
        if spec.max_time is not None and fault.at > spec.max_time:
            raise ScenarioError(label, f"faults[{i}].at", f"{fault.at:g} s is after the run's end (max_time {spec.max_time:g} s)")

    timing = convert_timing(spec.timing, label)
    with _named_by(label, "machine.model"):
        if model_path.stat().st_size > MAX_FILE_BYTES:
            raise too_large(model_path)
        model = load_model(model_path)
    block_shift = _block_shift(machine_ref, spec.program, label)
    if any(block_shift):
        try:
            model = load_model_with_obstacles(model_path, [], block_shift)
        except ValueError as exc:
            raise ScenarioError(label, "machine.block_shift", str(exc)) from None
    info = model_info(model)
    axes = convert_axes(spec.axes, info, label, folder)
    if spec.command_output == "pulse":
        check_pulse_rates(axes, label)
    machine_tools = None if params.tool_table is None else params_path.parent / params.tool_table
    program = convert_program(spec.program, axes, model, model_path, info, label, folder, machine_tools, block_shift)
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
            replay=None if spec.planner.replay is None else _pc_stream(spec.planner.replay, folder, label,
                                                                       spec.whiteboard.words),
        ),
        whiteboard=WhiteboardConfig(words=spec.whiteboard.words, chunk_words=spec.whiteboard.chunk // 2,
                                    fifo_interrupt=spec.whiteboard.fifo_interrupt),
        faults=tuple(convert_fault(f) for f in spec.faults),
        supervisor=convert_supervisor(spec.supervisor),
        max_time=spec.max_time,
        command_output=spec.command_output,
        machine={"model": machine_ref.model, "parameters": machine_ref.parameters},
        ballbar=convert_ballbar(spec.ballbar, model),
        block_shift=block_shift,
    )


def _block_shift(machine_ref: MachineRef, program, label: Path) -> tuple[float, float, float]:
    """``machine.block_shift`` in m; refused for a program that brings its own surface."""
    shift = tuple(v * units.MM for v in machine_ref.block_shift)
    if not any(shift):
        return (0.0, 0.0, 0.0)
    own = isinstance(program, SurfacePolishProgram) or (
        isinstance(program, GcodeProgramSpec) and program.workpiece is not None and program.workpiece.surface is not None)
    if own:
        raise ScenarioError(label, "machine.block_shift", "the program's own surface replaces the block: place the "
                            "surface where it is instead")
    return shift


def convert_program(spec, axes, model, model_path: Path, info, label: Path, folder: Path | None = None,
                    machine_tools: Path | None = None, block_shift=(0.0, 0.0, 0.0)):
    """The program in SI, by its kind: the one place a program kind's schema meets the loader
    (``folder``: the scenario's, where files it names are looked for; ``machine_tools``: the
    machine's tool table, for an NC program that names none)."""
    if isinstance(spec, PointToPointProgram):
        return points.convert(spec, axes, info, label)
    if isinstance(spec, NurbsCurveProgram):
        return curve.convert(spec, axes, model, label)
    if isinstance(spec, SurfacePolishProgram):
        return surface.convert(spec, axes, model_path, label)
    if isinstance(spec, ContourProgramSpec):
        return contour.convert(spec, axes, model, info.home, label)
    if isinstance(spec, MotionChipProgramSpec):
        def has_home_switch(i: int) -> bool:
            return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SENSOR, f"{AXES[i].lower()}_home") >= 0

        return chip.convert(spec, axes, has_home_switch, label)
    if isinstance(spec, GcodeProgramSpec):
        return gcode.convert(spec, axes, model, label, folder, machine_tools, info.home, model_file=model_path,
                             block_shift=block_shift)
    raise TypeError(f"no converter for {type(spec).__name__}")  # pragma: no cover - ProgramSpec lists them all


@contextmanager
def _named_by(label: Path, key: str):
    """A problem in a file the scenario names (the model, the parameters) is reported at the
    scenario's key that names it, with the file and what is wrong there."""
    try:
        yield
    except ScenarioError as exc:
        inner = f"{exc.file}: {exc.key_path}" if exc.key_path else exc.file
        raise ScenarioError(label, key, f"{inner}: {exc.message}") from None


def _pc_stream(name: str, folder: Path | None, label: Path, words: int):
    """``planner.replay``'s stream, read and checked (a ScenarioError at that key otherwise)."""
    from cnc_twin.whiteboard.capture import PcStream

    path = Path(name) if folder is None else folder / name
    try:
        stream = PcStream.read(path)
    except OSError as exc:
        raise ScenarioError(label, "planner.replay", f"cannot read '{name}': {exc.strerror}") from None
    except ValueError as exc:
        raise ScenarioError(label, "planner.replay", f"'{name}': {exc}") from None
    if stream.layout_words != words:
        raise ScenarioError(label, "planner.replay", f"'{name}' was written on a whiteboard of {stream.layout_words} "
                            f"words, this scenario's has {words} (whiteboard.words)")
    return stream


def _resolve(name: str, folder: Path | None, label: Path, key: str) -> Path:
    found = resolve_model_file(name, folder)
    if found is None:
        raise ScenarioError(label, key, f"file '{name}' not found next to the scenario or in the bundled models")
    return found


WHOLE_KEYS = frozenset({"compensation", "deflection", "coupling"})
"""mappings a scenario's value replaces whole instead of key by key: an axis's compensation is one
measurement (a comp file's columns and the backlash together), and so are a servo's deflection
and coupling (one fit over the axes; ``{}`` turns them off)"""


def _deep_merge(base: Any, override: Any) -> Any:
    """``override`` on top of ``base``, key by key (but :data:`WHOLE_KEYS`, replaced whole);
    non-mapping overrides replace (and get validated)."""
    if not isinstance(base, dict) or not isinstance(override, dict):
        return copy.deepcopy(override)
    out = copy.deepcopy(base)
    for key, value in override.items():
        out[key] = _deep_merge(out[key], value) if key in out and key not in WHOLE_KEYS else copy.deepcopy(value)
    return out
