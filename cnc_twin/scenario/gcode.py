"""The G-code program kind (``type: gcode``): an NC program file read as LinuxCNC reads it
(:mod:`cnc_twin.gcode`), its schema in the scenario and its conversion to machine steps in SI.

::

    program:
      type: gcode
      file: part.ngc            # next to the scenario
      blend_tolerance: 0.01     # [mm] corner blends under G64 without P
      chord_tolerance: 0.001    # [mm] the card's chord tolerance on curves (default: G64 P, else 0.001)
      settle: 0.3               # [s] simulated after the program end
      force: {standoff: 2.0}    # how the force loop makes contact (M100 P<newtons> / M101)
      workpiece:                # the surface pressed on and polished (default: the scene's block top)
        surface: {...}          # as a surface_polish program's, workpiece frame [mm]
        removal: {preston_k: 1.0e-12}

X Y Z are the tool tip's in the workpiece frame (origin at the workpiece's top centre, as the
YAML programs'), after the program's work offsets; A B C are the head and spindle angles [deg].
A problem is reported as ``FILE:LINE: message``, the program's own file and line.

The grinding-force loop (M100 P<newtons>, M101): M100 switches it on at the start of the next
feed path (the tool goes to ``force.standoff`` above that start along its axis, seeks contact,
ramps to P newtons) and the feed paths that follow run with the force held along the tool axis;
M101 (or the program end) ramps it down and retracts by the standoff at the end of the last feed
path. Between the two only feed moves, dwells and spindle changes are allowed: a rapid or a
move of A / B / C alone is refused at its line, as is a second M100 or an M100 with no feed move
after it. A program with M100 polishes a workpiece: ``workpiece.surface``, or by default the top
face of the scene's block as a flat plate, with the removal map on it.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field

from cnc_twin.core import units
from cnc_twin.core.config import AxisConfig
from cnc_twin.core.gcode_config import (
    GcodeForce, GcodeMove, GcodePath, GcodePause, GcodeProbe, GcodeProgram, GcodeReference, GcodeSpindle,
    GcodeWorkpiece,
)
from cnc_twin.core.errors import ScenarioError
from cnc_twin.core.packed_text import PackedText
from cnc_twin.gcode.limits import MAX_CALLS
from cnc_twin.scenario.curve import CardMemoryError, NurbsCurveProgram
from cnc_twin.scenario.gcode_read import ProgramStream, Where
from cnc_twin.scenario.gcode_probe import PartTop, ProbeReplay, ProbeSpec, probe_step, reader_answers
from cnc_twin.scenario.gcode_setup import (WORK_SYSTEMS, WorkOffsetSpec, air_clearance, in_units, start_point,
                                           with_placement, work_offset_parameters)
from cnc_twin.scenario.curve import convert as convert_curve
from cnc_twin.scenario.schema_base import DAY, PathLimitsSpec, Strict
from cnc_twin.scenario.surface import ForceLoopSpec, RemovalSpec, SurfaceSpec, force_control, preston_model, surface_in_world
from cnc_twin.scenario.validation import validate

CARD_CONTROL_POINTS = 600
"""control points of one joined curve sent to the card at most: a longer feed path is cut into
curves (an exact stop between them) so each fits the card's geometry memory with room to spare (a
path of one curve block goes whole whenever the memory holds it)"""


DEFAULT_CHORD_TOLERANCE = 0.001
"""[mm] the card's chord tolerance on a path without G64 P, unless the scenario gives one"""


class GcodeWorkpieceSpec(Strict):
    """The workpiece a G-code program presses on (M100) and polishes."""

    surface: SurfaceSpec | None = Field(None, description="NURBS surface, workpiece frame [mm]; default the scene's block top")
    removal: RemovalSpec = RemovalSpec()
    friction: float | None = Field(None, gt=0, description="pad-workpiece sliding friction coefficient; default the model's")


class GcodeProgramSpec(Strict):
    """An NC program (RS274/NGC, LinuxCNC's dialect) run on the machine."""

    type: Literal["gcode"]
    file: str = Field(min_length=1, description="the program (.ngc), next to the scenario")
    tool_table: str | None = Field(None, description="LinuxCNC tool table next to the scenario, for G43 H")
    subroutine_path: list[str] = Field(default_factory=list, max_length=10,
                                       description="folders (relative to the scenario) of subroutine files: "
                                       "o<name> call looks for name.ngc beside the program, then in these in order")
    tool_units: Literal["mm", "inch"] = Field("mm", description="units of the tool table's lengths")
    blend_tolerance: float = Field(0.01, gt=0, le=10, description="corner blend tolerance under G64 without P [mm]")
    axis_tolerance: float = Field(0.05, gt=0, le=10, description="how far a fitted tool axis (G1 runs turning A / B "
                                  "under G64 P) may turn from the programmed one [deg]")
    chord_tolerance: float | None = Field(None, gt=0, description="chord tolerance of the card's curve interpolation "
                                          "[mm]; default each path's G64 P, else 0.001")
    limits: PathLimitsSpec = PathLimitsSpec()
    settle: float = Field(0.3, ge=0, le=DAY, description="time simulated after the program end [s]")
    force: ForceLoopSpec = ForceLoopSpec()
    workpiece: GcodeWorkpieceSpec | None = Field(None, description="default: the scene's block top when the program uses M100")
    work_offsets: dict[Literal[WORK_SYSTEMS], WorkOffsetSpec] = Field(
        default_factory=dict, description="where each work system's zero sits in the workpiece frame [mm, deg] (G54: "
        "the program's zero unless it selects another), as LinuxCNC's parameter file holds them after a touch-off")
    probe: ProbeSpec = ProbeSpec()
    max_calls: int = Field(MAX_CALLS, ge=1, le=100_000_000, description="canonical calls the program may make in "
                           "its loops before it is refused as one that does not end (at its innermost open loop's line)")
    in_air: float = Field(0.0, ge=0, le=1000, description="[mm] run the whole program this far above where it is "
                          "written (a dry run: the machine moves as programmed, the pad never reaches the work)")


def _kept_subroutines(files: dict[Path, str], program_folder: Path, names: list[str],
                      folders: list[Path]) -> tuple[tuple[str, str], ...]:
    """The called subroutine files a run directory keeps, by their name beside the program
    there: those beside the program, and those in a ``subroutine_path`` folder named relative
    to the scenario, inside its folder (a folder elsewhere is named as it was, and read again)."""
    kept = []
    for path, text in files.items():
        if path.parent == program_folder:
            kept.append((path.name, text))
            continue
        for name, folder in zip(names, folders):
            relative = Path(name)
            if path.parent == folder and not relative.is_absolute() and ".." not in relative.parts:
                kept.append(((relative / path.name).as_posix(), text))
                break
    return tuple(kept)


def _find(name: str, folder: Path | None, label: Path, key: str, *, is_folder: bool = False) -> Path:
    """The file (or folder) ``name`` the scenario names, relative to its ``folder``."""
    path = Path(name)
    if not path.is_absolute() and folder is not None:
        path = Path(os.path.normpath(folder / path))  # a bundled scenario's ../programs/x.ngc as programs/x.ngc
    if not (path.is_dir() if is_folder else path.is_file()):
        raise ScenarioError(label, key, f"{'folder' if is_folder else 'file'} '{name}' not found next to the scenario")
    return path


def convert(spec: GcodeProgramSpec, axes: tuple[AxisConfig, ...], model, label: Path, folder: Path | None,
            machine_tools: Path | None = None, home: tuple[float, ...] | None = None, *, model_file: Path | None = None,
            block_shift=(0.0, 0.0, 0.0), answers=()) -> GcodeProgram:
    """Read the program and turn its operations into machine steps (SI, axis space), with the
    scenario's tool table, else the machine's (``machine_tools``, in mm); the program starts where
    the machine stands at ``home`` (six axes [m | rad]; None: the head's home pose). Its probes
    are answered as rs274 alone answers them, or the first ones by the card's ``answers``
    (:mod:`cnc_twin.scenario.gcode_probe`); a program that probes can be read again at run time
    from ``model_file`` (with the block shifted by ``block_shift`` [m]), else it is refused."""
    from cnc_twin.scenario import program_cache

    path = _find(spec.file, folder, label, "program.file")
    if spec.tool_table:
        table, tool_units = _find(spec.tool_table, folder, label, "program.tool_table"), spec.tool_units
    else:
        table, tool_units = machine_tools, "mm"
    # prepared once: a second load of the same program, with the same machine and code, is read
    # from the cache (an error is not kept: it is found again, in its own words)
    def name() -> str:
        try:
            return program_cache.key((spec.model_dump(mode="json"), tuple(axes), program_cache.model_digest(model),
                                      None if folder is None else str(folder), home, None if model_file is None else
                                      str(model_file), tuple(block_shift), tuple(answers), tool_units, str(label)),
                                     (path, table))
        except OSError as exc:
            raise ScenarioError(label, "program.file", f"cannot read {path} ({exc.strerror})") from None

    return program_cache.cached(name, lambda: _prepare(spec, axes, model, label, folder, path, table, tool_units,
                                                       machine_tools, home, model_file, block_shift, answers))


def _prepare(spec: GcodeProgramSpec, axes, model, label: Path, folder: Path | None, path: Path, table: Path | None,
             tool_units: str, machine_tools: Path | None, home, model_file: Path | None, block_shift,
             answers) -> tuple[GcodeProgram, bool]:
    """:func:`convert`'s work: the program read, shaped and made into steps; and whether it may be
    kept in the cache (not when it opened subroutine files, read by name from folders that may
    change, or probes, read again at run time)."""
    from cnc_twin.gcode import toolpath as tp
    from cnc_twin.gcode.state import MM_PER_INCH
    from cnc_twin.geometry.kinematics import HeadGeometry

    head = HeadGeometry.from_model(model)
    start = start_point(head, home, spec.in_air)  # mm / deg, as the program sees the machine
    # lengths in the machine's units, as LinuxCNC's parameter file and position are: the tool table's
    per_mm = 1.0 / MM_PER_INCH if tool_units == "inch" else 1.0
    start_units = in_units(start, per_mm)
    # G28 / G30 return to where the machine stood (its home), as a machine homed there keeps them
    # in its parameter file; zeros would send the tool to the workpiece frame's origin, on the work
    parameters = {base + k: value for base in (5161, 5181) for k, value in enumerate(start_units)}
    parameters.update(work_offset_parameters(spec.work_offsets, per_mm))
    sub_folders = [_find(name, folder, label, f"program.subroutine_path[{k}]", is_folder=True)
                   for k, name in enumerate(spec.subroutine_path)]
    stream = ProgramStream(path, table, tool_units, label,
                           reader=dict(start=start_units, parameters=parameters, subroutine_path=sub_folders,
                                       probe=reader_answers(answers, head), max_calls=spec.max_calls),
                           shaping=dict(default_blend=spec.blend_tolerance, axis_tolerance=spec.axis_tolerance,
                                        start=start, air=spec.in_air))
    where = stream.where
    # the program read, shaped and made into steps as it is read: held a feed path at a time
    try:
        steps = _machine_steps(_grounded(stream.operations(), spec, path, label), spec, axes, model, label, where,
                               head, _part_top(spec, model, head, label))
    except ScenarioError as exc:
        raise with_placement(exc, stream.box, axes, head) from None
    if not stream.moved:
        raise ScenarioError(label, "program.file", f"{path} moves nothing")
    clearance = air_clearance(stream.lowest, _work_top(spec, model, head, label))
    _check_force_paths(steps, where)
    replay = None
    if any(isinstance(s, GcodeProbe) for s in steps):
        if model_file is None:
            raise ScenarioError(label, "program.file", f"{path} probes (G38.n): give its scenario a machine model file")
        replay = ProbeReplay(convert, spec, tuple(axes), Path(model_file), tuple(block_shift), label, folder, machine_tools,
                             None if home is None else tuple(home))
    workpiece = spec.workpiece
    if workpiece is None and any(isinstance(s, GcodeForce) for s in steps):
        workpiece = GcodeWorkpieceSpec()
    # the scenario's own table goes into the run directory (the machine's is found again by a re-run)
    kept_table = (spec.tool_table, table.read_text(encoding="utf-8", errors="replace")) if spec.tool_table else None
    source, sub_files = stream.source, stream.files
    program = GcodeProgram(file=path, packed_text=PackedText.of(source.text), steps=tuple(steps),
                           lines=len(source.lines), settle=spec.settle, workpiece=_workpiece(workpiece, model, head, label),
                           tool_table=kept_table, air=spec.in_air * units.MM, air_clearance=clearance, after_probe=replay,
                           subroutine_files=_kept_subroutines(sub_files, path.parent, spec.subroutine_path, sub_folders))
    return program, replay is None and not sub_files


def _grounded(ops, spec: GcodeProgramSpec, path: Path, label: Path):
    """``ops`` as they come, refusing a program that presses on the workpiece (M100) in a run in
    the air."""
    from cnc_twin.gcode import toolpath as tp

    for op in ops:
        if spec.in_air and isinstance(op, tp.ForceChange) and op.setpoint is not None:
            raise ScenarioError(label, "program.in_air", f"the program presses on the workpiece (M100 at {path.name} "
                                f"line {op.line}): a run in the air cannot; leave in_air out to polish")
        yield op


def _machine_steps(ops, spec: GcodeProgramSpec, axes, model, label: Path, where: Where, head, part=None) -> list:
    """The program's operations as machine steps (SI, axis space), refusing at its line what the
    machine cannot run."""
    from cnc_twin.gcode import toolpath as tp

    steps = []
    force_on = None  # the M100 op while the force loop is on
    for op in ops:
        if isinstance(op, tp.Traverse):
            if force_on is not None:
                raise where(op.line, f"a rapid or a move of A / B / C alone while the grinding-force loop is on (M100 at "
                            f"line {force_on.line}): switch it off with M101 first")
            steps.append(_move(op, axes, head, where))
        elif isinstance(op, tp.FeedPath):
            steps += _paths(op, spec, axes, model, label, where, head)
        elif isinstance(op, tp.ToolAxisPath):
            if force_on is not None:
                raise where(op.line, f"G1 moves turning A / B while the grinding-force loop is on (M100 at line "
                            f"{force_on.line}): not in this version; hold A / B, or M101 first")
            steps += _tool_axis_paths(op, spec, axes, model, label, where, head)
        elif isinstance(op, tp.Probe):
            end = _move(tp.Traverse(op.end, op.feed, op.line), axes, head, where)
            steps.append(probe_step(op, end, spec.probe, head, where, force_on=force_on, air=spec.in_air, part=part))
        elif isinstance(op, tp.Pause):
            steps.append(GcodePause(op.seconds, op.line))
        elif isinstance(op, tp.SpindleChange):
            asked = op.rpm * units.RPM
            # as LinuxCNC's motion holds a spindle command to [SPINDLE_0]MAX_FORWARD_VELOCITY:
            # the spindle (C) turns at its limit, and the run says so at load
            top = axes[5].max_velocity
            steps.append(GcodeSpindle(max(-top, min(top, asked)), op.line, asked if abs(asked) > top else None))
        elif op.setpoint is not None:
            if force_on is not None:
                raise where(op.line, f"M100 while the grinding-force loop is on (M100 at line {force_on.line}): "
                            "M101 first")
            force_on = op
            steps.append(GcodeForce(force_control(spec.force, op.setpoint), op.line))
        elif force_on is not None:  # M101 (one while the loop is off changes nothing)
            force_on = None
            steps.append(GcodeForce(None, op.line))
    if force_on is not None:  # the program end switches the loop off, as it stops the spindle
        steps.append(GcodeForce(None, steps[-1].line))
    return steps


def _check_force_paths(steps: list, where: Where) -> None:
    """Every M100 has a feed path after it before its M101 (the loop switches on at its start)."""
    for k, step in enumerate(steps):
        if isinstance(step, GcodeForce) and step.control is not None:
            following = steps[k + 1:]
            end = next((j for j, s in enumerate(following) if isinstance(s, GcodeForce)), len(following))
            if not any(isinstance(s, GcodePath) for s in following[:end]):
                raise where(step.line, "M100: no feed move follows before M101 or the program end (the force loop "
                            "switches on at the start of the next feed path)")


def _workpiece(spec: GcodeWorkpieceSpec | None, model, head, label: Path) -> GcodeWorkpiece | None:
    """The workpiece in SI: the given surface, or the top face of the scene's block as a flat plate."""
    from cnc_twin.machine.workpiece import pad_radius

    if spec is None:
        return None
    surface = spec.surface if spec.surface is not None else _block_top(model, head, label)
    _, surface_def = surface_in_world(surface, head.workpiece_origin, label, "program.workpiece.surface")
    return GcodeWorkpiece(surface=surface_def, preston=preston_model(spec.removal, pad_radius(model)),
                          friction=spec.friction, tile_size=surface.tile_size * units.MM)


def _part_top(spec: GcodeProgramSpec, model, head, label: Path) -> PartTop | None:
    """Where a probe can touch the part: the scene block's top as set up; None with a surface of
    the program's own or no block."""
    from cnc_twin.machine.workpiece import pad_radius

    if spec.workpiece is not None and spec.workpiece.surface is not None:
        return None
    try:
        net = _block_top(model, head, label).control_net
    except ScenarioError:
        return None
    xs, ys = [p[0] for row in net for p in row], [p[1] for row in net for p in row]
    return PartTop((min(xs), max(xs)), (min(ys), max(ys)), net[0][0][2], pad_radius(model) / units.MM)


def _work_top(spec: GcodeProgramSpec, model, head, label: Path) -> float | None:
    """[mm] the scene block's top in the workpiece frame, for a run in the air; None otherwise."""
    if not spec.in_air:
        return None
    try:
        return _block_top(model, head, label).control_net[0][0][2]
    except ScenarioError:
        return None


def _block_top(model, head, label: Path) -> SurfaceSpec:
    """The scene block's top face as a flat degree-1 surface in the workpiece frame [mm]."""
    import mujoco

    from cnc_twin.machine.workpiece import BLOCK_GEOM

    try:
        geom = model.geom(BLOCK_GEOM)
    except KeyError:
        raise ScenarioError(label, "program.workpiece.surface", f"the scene has no block '{BLOCK_GEOM}': give the "
                            "workpiece's surface") from None
    if model.geom_type[geom.id] != mujoco.mjtGeom.mjGEOM_BOX:
        raise ScenarioError(label, "program.workpiece.surface", f"the scene's '{BLOCK_GEOM}' is not a box: give the "
                            "workpiece's surface")
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    centre = data.geom_xpos[geom.id] - np.asarray(head.workpiece_origin)
    hx, hy, hz = model.geom_size[geom.id]
    x0, x1, y0, y1 = ((centre[0] - hx) / units.MM, (centre[0] + hx) / units.MM, (centre[1] - hy) / units.MM,
                      (centre[1] + hy) / units.MM)
    z = (centre[2] + hz) / units.MM
    return SurfaceSpec(degree_u=1, degree_v=1, knots_u=[0, 0, 1, 1], knots_v=[0, 0, 1, 1],
                       control_net=[[[x0, y0, z], [x0, y1, z]], [[x1, y0, z], [x1, y1, z]]])


def _move(op, axes: tuple[AxisConfig, ...], head, where: Where) -> GcodeMove:
    """A traverse: the tip's point through the ``head`` kinematics at the target A / B."""
    a, b, c = (v * units.DEG for v in op.end[3:])
    tip = head.world_from_workpiece(np.array([op.end[:3]]) * units.MM)
    xyz = head.axes_from_tip(tip, a, b)[0]
    end = (*(float(v) for v in xyz), a, b, c)
    for cfg, value in zip(axes, end):
        if cfg.allowed is not None and not cfg.allowed[0] <= value <= cfg.allowed[1]:
            lo, hi = (v * cfg.display_factor for v in cfg.allowed)
            raise where(op.line, f"the move takes {cfg.name} to {value * cfg.display_factor:g} {cfg.display_unit}, "
                        f"outside its {cfg.allowed_name} {lo:g}..{hi:g} {cfg.display_unit}")
    feed = None
    if op.feed is not None:
        feed = op.feed * (units.DEG if op.rotary_only else units.MM) / 60.0
    return GcodeMove(end=end, feed=feed, rotary_only=op.rotary_only, line=op.line)


def _pieces_in_cards(path) -> list[list[tuple]]:
    """The path's Bezier pieces, ``(piece, span, line)``, cut into lists that each fit one card
    curve. The spans keep the parameter speed continuous where elements join tangentially (each
    element's spans scaled so it starts as fast as the last one ended): the card's stepper then
    meets no jump in ``|dC/du|`` at a join."""
    from cnc_twin.geometry.bezier import end_speed

    degree = max(len(q) - 1 for e in path.elements for q in e.pieces)
    per_curve = max(1, (CARD_CONTROL_POINTS - 1) // degree)
    flat: list[tuple] = []
    speed = None  # |dC/du| where the last element ended
    for e in path.elements:
        relative = e.spans or [1.0] * len(e.pieces)
        start = end_speed(e.pieces[0], False) / relative[0]
        if speed is None or start <= 0.0 or speed <= 0.0:
            scale = max(e.length, 1e-6) / sum(relative)  # about unit speed
        else:
            scale = start / speed
        spans = [r * scale for r in relative]
        lines = e.piece_lines or [e.line] * len(e.pieces)
        flat += list(zip(e.pieces, spans, lines))
        speed = end_speed(e.pieces[-1], True) / spans[-1]
    return [flat[k:k + per_curve] for k in range(0, len(flat), per_curve)]


def _paths(op, spec: GcodeProgramSpec, axes, model, label: Path, where: Where, head) -> list[GcodePath]:
    """A feed path as one or more card curves: a lone curve block as programmed when the card's
    memory holds it, else the path's Bezier pieces joined (:func:`_pieces_in_cards`)."""
    from cnc_twin.geometry.bezier import join

    out = []
    if op.feed <= 0.0:
        raise where(op.line, "feed rate 0")
    reference = _reference(op, head)
    whole = op.elements[0].nurbs if len(op.elements) == 1 else None
    if whole is not None:  # one curve block: to the card as programmed, when its memory holds it
        degree, knots, weights, points = whole
        try:
            lines = ((float(knots[0]), op.line),)
            curve = _card_curve(op, spec, degree, knots, weights, points.tolist(), axes, model, label, where, lines)
            return [GcodePath(curve=curve, lines=lines, line=op.line, reference=reference)]
        except CardMemoryError:  # too large for the card's memory: cut into pieces below
            pass
    for chunk in _pieces_in_cards(op):
        spans = [h for _, h, _ in chunk]
        degree, knots, weights, points = join([q for q, _, _ in chunk], spans)
        u = np.concatenate([[0.0], np.cumsum(spans)])
        lines: list[tuple[float, int]] = []
        for k, (_, _, line) in enumerate(chunk):
            if not lines or lines[-1][1] != line:
                lines.append((float(u[k]), line))
        curve = _card_curve(op, spec, degree, knots, weights, points, axes, model, label, where, tuple(lines),
                            chunk[0][2])
        out.append(GcodePath(curve=curve, lines=tuple(lines), line=chunk[0][2], reference=reference))
    return out


def _reference(op, head) -> GcodeReference:
    """The feed path as programmed, in the world frame [m], with its fits' figures."""
    from cnc_twin.gcode.toolpath import programmed_geometry

    polyline, vertices = programmed_geometry(op.program or op.elements)
    origin = np.asarray(head.workpiece_origin)
    fits = [e for e in op.elements if e.kind == "fit"]
    world = polyline * units.MM + origin  # a path of lines: its vertices are its polyline, held once
    return GcodeReference.of(
        world, world if vertices is polyline else vertices * units.MM + origin,
        tolerance=None if op.tolerance is None else op.tolerance * units.MM, fits=len(fits),
        fit_spans=sum(len(e.pieces) for e in fits), fit_deviation=max((e.deviation for e in fits), default=0.0) * units.MM)


def _tool_axis_paths(op, spec: GcodeProgramSpec, axes, model, label: Path, where: Where, head) -> list[GcodePath]:
    """A run of G1 lines turning the head, fitted (tip and tool-axis curves on one knot vector),
    as one card curve with its tool-axis curve; cut in halves, each fitted again, while the card's
    memory cannot hold it (a stop between them)."""
    from cnc_twin.gcode.line_fit import split_tool_axis_path
    from cnc_twin.geometry.fit import FitError

    try:
        return [_tool_axis_path(op, spec, axes, model, label, where, head)]
    except CardMemoryError as exc:
        try:
            halves = split_tool_axis_path(op)
        except FitError:
            raise where(op.line, exc.message) from None
    return [p for half in halves for p in _tool_axis_paths(half, spec, axes, model, label, where, head)]


def _tool_axis_path(op, spec: GcodeProgramSpec, axes, model, label: Path, where: Where, head) -> GcodePath:
    """One fitted run as one card curve (CardMemoryError when the card cannot hold it)."""
    curve_spec = validate(NurbsCurveProgram, {
        "type": "nurbs_curve", "degree": 3, "knots": op.knots.tolist(), "control_points": op.points.tolist(),
        "feed": op.feed, "chord_tolerance": _chord_tolerance(spec, op), "limits": spec.limits.model_dump(),
        "tool_axis_curve": {"degree": 3, "knots": op.knots.tolist(), "control_points": op.axis_points.tolist()},
        "C": op.c, "settle": 0.0}, label, ("program",))
    try:
        curve = convert_curve(curve_spec, axes, model, label, tuple(op.span_lines))
    except CardMemoryError:  # the caller cuts the run
        raise
    except ScenarioError as exc:
        raise where(op.line, exc.message) from None
    origin = np.asarray(head.workpiece_origin)
    points = op.program_points * units.MM + origin
    reference = GcodeReference.of(points, points, tolerance=op.tolerance * units.MM, fits=1,
                               fit_spans=len(np.unique(op.knots)) - 1, fit_deviation=op.deviation * units.MM,
                               axes=op.program_axes, axis_tolerance=op.axis_tolerance)
    return GcodePath(curve=curve, lines=tuple(op.span_lines), line=op.line, reference=reference)


def _chord_tolerance(spec: GcodeProgramSpec, op) -> float:
    """The card's chord tolerance on a feed path [mm]: the scenario's, else the path's G64 P."""
    if spec.chord_tolerance is not None:
        return spec.chord_tolerance
    return op.tolerance if op.tolerance is not None else DEFAULT_CHORD_TOLERANCE


def _card_curve(op, spec: GcodeProgramSpec, degree, knots, weights, points, axes, model, label: Path, where: Where,
                lines: tuple, line: int | None = None):
    """One card curve of a feed path, checked against travel and the card's memory (with its
    program-line marks ``lines``) at ``line``."""
    curve_spec = validate(NurbsCurveProgram, {
        "type": "nurbs_curve", "degree": degree, "knots": knots, "weights": weights, "control_points": points,
        "feed": op.feed, "chord_tolerance": _chord_tolerance(spec, op), "limits": spec.limits.model_dump(),
        "tool_axis": {"A": op.hold[0], "B": op.hold[1]}, "C": op.hold[2], "settle": 0.0}, label, ("program",))
    try:
        return convert_curve(curve_spec, axes, model, label, lines)
    except ScenarioError as exc:
        if line is None and isinstance(exc, CardMemoryError):  # the whole curve block: the caller cuts it
            raise
        raise where(op.line if line is None else line, exc.message) from None
