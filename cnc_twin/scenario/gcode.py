"""The G-code program kind (``type: gcode``): an NC program file read as LinuxCNC reads it
(:mod:`cnc_twin.gcode`), its schema in the scenario and its conversion to machine steps in SI.

::

    program:
      type: gcode
      file: part.ngc            # next to the scenario
      blend_tolerance: 0.01     # [mm] corner blends under G64 without P
      chord_tolerance: 0.001    # [mm] the card's chord tolerance on curves
      settle: 0.3               # [s] simulated after the program end

X Y Z are the tool tip's in the workpiece frame (origin at the workpiece's top centre, as the
YAML programs'), after the program's work offsets; A B C are the head and spindle angles [deg].
A problem is reported as ``FILE:LINE: message``, the program's own file and line.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field

from cnc_twin.core import units
from cnc_twin.core.config import AxisConfig
from cnc_twin.core.gcode_config import GcodeMove, GcodePath, GcodePause, GcodeProgram, GcodeSpindle
from cnc_twin.core.errors import ScenarioError
from cnc_twin.scenario.curve import CardMemoryError, NurbsCurveProgram
from cnc_twin.scenario.curve import convert as convert_curve
from cnc_twin.scenario.schema_base import DAY, PathLimitsSpec, Strict
from cnc_twin.scenario.validation import validate

CARD_CONTROL_POINTS = 600
"""control points of one joined curve sent to the card at most: a longer feed path is cut into
curves (an exact stop between them) so each fits the card's geometry memory with room to spare (a
path of one curve block goes whole whenever the memory holds it)"""


class GcodeProgramSpec(Strict):
    """An NC program (RS274/NGC, LinuxCNC's dialect) run on the machine."""

    type: Literal["gcode"]
    file: str = Field(min_length=1, description="the program (.ngc), next to the scenario")
    tool_table: str | None = Field(None, description="LinuxCNC tool table next to the scenario, for G43 H")
    tool_units: Literal["mm", "inch"] = Field("mm", description="units of the tool table's lengths")
    blend_tolerance: float = Field(0.01, gt=0, le=10, description="corner blend tolerance under G64 without P [mm]")
    chord_tolerance: float = Field(0.001, gt=0, description="chord tolerance of the card's curve interpolation [mm]")
    limits: PathLimitsSpec = PathLimitsSpec()
    settle: float = Field(0.3, ge=0, le=DAY, description="time simulated after the program end [s]")


class _Where:
    """Errors at a program line: ``FILE:LINE: message`` (exit 2 in the CLI)."""

    def __init__(self, path: Path):
        self.path = path

    def __call__(self, line: int, message: str) -> ScenarioError:
        return ScenarioError(f"{self.path}:{line}", "", message)


def read_calls(path: Path, tool_table: Path | None, tool_units: str, label: Path):
    """The canonical calls of the program at ``path`` and its :class:`~cnc_twin.gcode.source.Source`,
    or a ScenarioError at its line."""
    from cnc_twin.gcode.interpreter import ProgramError, read_program
    from cnc_twin.gcode.listing import read_tool_table
    from cnc_twin.gcode.source import Source, SourceError

    try:
        tools = read_tool_table(tool_table, tool_units)
    except ValueError as exc:
        raise ScenarioError(label, "program.tool_table", str(exc)) from None
    try:
        source = Source.read(path)
    except SourceError as exc:
        raise (_Where(path)(exc.line, str(exc)) if exc.line else ScenarioError(path, "", str(exc))) from None
    except OSError as exc:
        raise ScenarioError(label, "program.file", f"cannot read {path} ({exc.strerror})") from None
    try:
        return read_program(source, tools).calls, source
    except ProgramError as exc:
        raise _Where(path)(exc.line, exc.message) from None


def _find(name: str, folder: Path | None, label: Path, key: str) -> Path:
    path = Path(name)
    if not path.is_absolute() and folder is not None:
        path = folder / path
    if not path.is_file():
        raise ScenarioError(label, key, f"file '{name}' not found next to the scenario")
    return path


def convert(spec: GcodeProgramSpec, axes: tuple[AxisConfig, ...], model, label: Path, folder: Path | None) -> GcodeProgram:
    """Read the program and turn its operations into machine steps (SI, axis space)."""
    from cnc_twin.gcode import toolpath as tp
    from cnc_twin.geometry.kinematics import HeadGeometry

    path = _find(spec.file, folder, label, "program.file")
    table = _find(spec.tool_table, folder, label, "program.tool_table") if spec.tool_table else None
    calls, source = read_calls(path, table, spec.tool_units, label)
    where = _Where(path)
    try:
        ops = tp.operations(calls, default_blend=spec.blend_tolerance)
    except tp.ToolpathError as exc:
        raise where(exc.line, exc.message) from None
    if not any(isinstance(op, (tp.Traverse, tp.FeedPath)) for op in ops):
        raise ScenarioError(label, "program.file", f"{path} moves nothing")
    head = HeadGeometry.from_model(model)
    steps = []
    for op in ops:
        if isinstance(op, tp.Traverse):
            steps.append(_move(op, axes, head, where))
        elif isinstance(op, tp.FeedPath):
            steps += _paths(op, spec, axes, model, label, where)
        elif isinstance(op, tp.Pause):
            steps.append(GcodePause(op.seconds, op.line))
        elif isinstance(op, tp.SpindleChange):
            steps.append(GcodeSpindle(op.rpm * 2.0 * math.pi / 60.0, op.line))
        else:
            raise where(op.line, "M100 / M101 (the grinding-force loop) need a workpiece to press on; a G-code "
                        "program runs without one in this version: polish with a surface_polish scenario")
    return GcodeProgram(file=path, text="\n".join(source.lines) + "\n", steps=tuple(steps), lines=len(source.lines),
                        settle=spec.settle)


def _move(op, axes: tuple[AxisConfig, ...], head, where: _Where) -> GcodeMove:
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
        flat += [(q, h, e.line) for q, h in zip(e.pieces, spans)]
        speed = end_speed(e.pieces[-1], True) / spans[-1]
    return [flat[k:k + per_curve] for k in range(0, len(flat), per_curve)]


def _paths(op, spec: GcodeProgramSpec, axes, model, label: Path, where: _Where) -> list[GcodePath]:
    """A feed path as one or more card curves: a lone curve block as programmed when the card's
    memory holds it, else the path's Bezier pieces joined (:func:`_pieces_in_cards`)."""
    from cnc_twin.geometry.bezier import join

    out = []
    if op.feed <= 0.0:
        raise where(op.line, "feed rate 0")
    whole = op.elements[0].nurbs if len(op.elements) == 1 else None
    if whole is not None:  # one curve block: to the card as programmed, when its memory holds it
        degree, knots, weights, points = whole
        try:
            curve = _card_curve(op, spec, degree, knots, weights, points.tolist(), axes, model, label, where)
            return [GcodePath(curve=curve, lines=((float(knots[0]), op.line),), line=op.line)]
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
        curve = _card_curve(op, spec, degree, knots, weights, points, axes, model, label, where, chunk[0][2])
        out.append(GcodePath(curve=curve, lines=tuple(lines), line=chunk[0][2]))
    return out


def _card_curve(op, spec: GcodeProgramSpec, degree, knots, weights, points, axes, model, label: Path, where: _Where,
                line: int | None = None):
    """One card curve of a feed path, checked against travel and the card's memory at ``line``."""
    curve_spec = validate(NurbsCurveProgram, {
        "type": "nurbs_curve", "degree": degree, "knots": knots, "weights": weights, "control_points": points,
        "feed": op.feed, "chord_tolerance": spec.chord_tolerance, "limits": spec.limits.model_dump(),
        "tool_axis": {"A": op.hold[0], "B": op.hold[1]}, "C": op.hold[2], "settle": 0.0}, label, ("program",))
    try:
        return convert_curve(curve_spec, axes, model, label)
    except ScenarioError as exc:
        if line is None and isinstance(exc, CardMemoryError):  # the whole curve block: the caller cuts it
            raise
        raise where(op.line if line is None else line, exc.message) from None
