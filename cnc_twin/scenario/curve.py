"""The NURBS curve program (``type: nurbs_curve``): a tool-tip curve with a held or varying tool
axis; its schema in machinist units and its conversion to SI (checked against the head's reach)."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field

from cnc_twin.core import units
from cnc_twin.core.config import AxisConfig, AxisCurve, NurbsProgram, PathLimits
from cnc_twin.core.errors import ScenarioError
from cnc_twin.scenario.schema_base import DAY, FEED_MIN, PathLimitsSpec, Strict


class ToolAxisSpec(Strict):
    """The tool axis, held fixed along the curve, as head angles."""

    A: float = Field(0.0, description="[deg]")
    B: float = Field(0.0, description="[deg]")


class AxisCurveSpec(Strict):
    """The tool axis along the path as a NURBS of direction vectors (workpiece frame, pointing
    from the tip up the tool), on the same parameter range as the tip curve."""

    degree: int = Field(ge=1, le=9)
    control_points: list[list[float]] = Field(min_length=2, description="[[i, j, k], ...] directions")
    weights: list[float] | None = None
    knots: list[float]


class NurbsCurveProgram(Strict):
    """A tool-tip NURBS curve in the workpiece frame (origin at the workpiece top centre, mm)."""

    type: Literal["nurbs_curve"]
    degree: int = Field(ge=1, le=9)
    control_points: list[list[float]] = Field(min_length=2, description="[[x, y, z], ...] [mm]")
    weights: list[float] | None = Field(None, description="one per control point, > 0; default all 1")
    knots: list[float] = Field(description="clamped knot vector, n + degree + 1 values")
    feed: float = Field(ge=FEED_MIN, description="programmed feed [mm/min]")
    chord_tolerance: float = Field(0.001, gt=0, description="[mm]")
    limits: PathLimitsSpec = PathLimitsSpec()
    tool_axis: ToolAxisSpec = ToolAxisSpec()
    tool_axis_curve: AxisCurveSpec | None = Field(None, description="tool axis varying along the path (replaces tool_axis)")
    C: float = Field(0.0, description="spindle angle held along the curve [deg]")
    approach_feed: float | None = Field(None, ge=FEED_MIN, description="X/Y/Z speed cap of the move to the start [mm/min]")
    settle: float = Field(0.3, ge=0, le=DAY, description="dwell after the approach move, before the curve starts, "
                                                 "and time simulated after the curve [s]")


def convert(spec: NurbsCurveProgram, axes: tuple[AxisConfig, ...], model, label: Path, lines: tuple = ()) -> NurbsProgram:
    """The curve in SI, checked against the head's reach, travel and the card's memory (with the
    ``(u, line)`` marks a G-code path's record carries too)."""
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
    program = NurbsProgram(
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
    _check_fits_the_card(program, label, lines)
    return program


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


class CardMemoryError(ScenarioError):
    """A curve larger than the card's geometry memory (a caller that can cut it catches this)."""


def _check_fits_the_card(program: NurbsProgram, label: Path, lines: tuple = ()) -> None:
    """The card keeps a curve's geometry in its geometry memory (16384 words: about 800 control
    points of a 3D curve with their weights and knots; a curve longer than one record goes in
    parts); refuse a larger one here, before any motion. ``lines``: the ``(u, line)`` marks a
    G-code path's record carries too."""
    import dataclasses

    from cnc_twin.planner.curve_program import curve_setup
    from cnc_twin.whiteboard.codec import payload_words

    try:
        payload_words(dataclasses.replace(curve_setup(program)[4], lines=tuple(lines)))
    except ValueError as exc:
        raise CardMemoryError(label, "program.control_points", f"{exc}: split the curve") from None

