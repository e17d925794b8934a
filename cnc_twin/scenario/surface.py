"""Scenario schema and conversion of the ``surface_polish`` program (machinist units -> SI).

The workpiece is a NURBS surface given in the workpiece frame (origin at the workpiece top
centre, mm); the path is laid out on it (:mod:`cnc_twin.planner.toolpath`), and every pose of it is
checked for reach and travel here, at load, so an impossible program never starts moving.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from cnc_twin.core import units
from cnc_twin.core.config import AxisConfig, ForceControl, PathLimits, Preston, SurfaceDef, SurfaceProgram
from cnc_twin.core.errors import ScenarioError
from cnc_twin.scenario.schema_base import DAY, FEED_MIN, KeyedValueError, PathLimitsSpec, Strict

REACH_SAMPLES = 2000
"""poses checked per path section at load"""


class SurfaceSpec(Strict):
    """A NURBS surface in the workpiece frame: ``control_net[i][j]`` is the point at u index i, v index j."""

    degree_u: int = Field(ge=1, le=5)
    degree_v: int = Field(ge=1, le=5)
    control_net: list[list[list[float]]] = Field(min_length=2, description="[[[x, y, z], ...], ...] [mm]")
    weights: list[list[float]] | None = Field(None, description="one per control point, > 0; default all 1")
    knots_u: list[float] = Field(description="clamped, len(control_net) + degree_u + 1 values")
    knots_v: list[float] = Field(description="clamped, len(control_net[0]) + degree_v + 1 values")
    tile_size: float = Field(20.0, gt=0, description="edge of the convex collision tiles the solid is cut into [mm]")


class PathSpec(Strict):
    """How the tool covers the surface."""

    pattern: Literal["raster", "spiral"] = "raster"
    direction: Literal["u", "v"] = Field("u", description="raster passes run along u (constant v) or along v")
    step_over: float = Field(gt=0, description="distance between neighbouring passes on the surface [mm]")
    margin: float | None = Field(None, ge=0, description="distance kept from the surface's edges [mm]; default the pad radius")


class ForceLoopSpec(Strict):
    """How the card's grinding-force loop makes contact and holds the force (see
    cnc_twin.dsp.force); the setpoint is the program's."""

    ramp_time: float = Field(0.5, gt=0, description="force ramp after contact and before retract [s]")
    seek_speed: float = Field(2.0, gt=0, description="approach speed along the tool axis until contact [mm/s]")
    standoff: float = Field(2.0, gt=0, description="gap above the surface where the seek starts [mm]")
    contact_threshold: float = Field(2.0, gt=0, description="force that counts as contact [N]")
    kp: float = Field(0.005, ge=0, description="proportional gain [mm/N]")
    ki: float = Field(3.0, ge=0, description="integral gain [mm/(N s)]")
    max_depth: float = Field(8.0, gt=0, description="clamp on the push into the surface [mm]")
    retract_speed: float = Field(10.0, gt=0, description="[mm/s]")
    adapt_threshold: float = Field(0.1, gt=0, description="force error (fraction of the setpoint) that reduces the feed")
    adapt_feed: float = Field(0.5, gt=0, le=1, description="feed fraction while the error is above the threshold")
    adapt_hold: float = Field(0.05, ge=0, description="time below half the threshold before the feed is restored [s]")


class ForceSpec(ForceLoopSpec):
    """The card's grinding-force loop (see cnc_twin.dsp.force)."""

    setpoint: float = Field(gt=0, description="[N]")
    profile: list[list[float]] | None = Field(None, description="[[path length mm, force N], ...] along the path; default the setpoint throughout")

    @model_validator(mode="after")
    def _profile(self) -> "ForceSpec":
        if self.profile is not None:
            for i, point in enumerate(self.profile):
                if len(point) != 2 or point[1] <= 0:
                    raise KeyedValueError(("profile", i), f"expected [path length mm, force N > 0], got {point}")
            lengths = [p[0] for p in self.profile]
            if any(b <= a for a, b in zip(lengths, lengths[1:])) or lengths[0] < 0:
                raise KeyedValueError(("profile",), "path lengths must start at >= 0 and increase")
        return self


class RemovalSpec(Strict):
    """Material removal by Preston's law (see cnc_twin.polishing.removal)."""

    preston_k: float = Field(1.0e-13, gt=0, description="Preston coefficient [1/Pa = m^2/N]")
    pad_modulus: float = Field(0.1, gt=0, description="Winkler foundation modulus of the pad [N/mm^3]")
    grid: float = Field(1.0, gt=0, description="pitch of the removal map on the surface [mm]")
    every: int = Field(4, ge=1, description="removal update interval [interpolation periods]")


class SurfacePolishProgram(Strict):
    """Polish a NURBS surface along a raster or spiral at a controlled force."""

    type: Literal["surface_polish"]
    surface: SurfaceSpec
    path: PathSpec
    feed: float = Field(ge=FEED_MIN, description="programmed feed [mm/min]")
    chord_tolerance: float = Field(0.001, gt=0, description="[mm]")
    limits: PathLimitsSpec = PathLimitsSpec()
    lead: float = Field(0.0, ge=-30, le=30, description="tool axis leaning towards the feed direction [deg]")
    tilt: float = Field(0.0, ge=-30, le=30, description="tool axis leaning sideways [deg]")
    spindle: float = Field(gt=0, description="spindle speed [rpm]")
    force: ForceSpec
    removal: RemovalSpec = RemovalSpec()
    friction: float | None = Field(None, gt=0, description="pad-workpiece sliding friction coefficient; default the model's")
    approach_feed: float | None = Field(None, ge=FEED_MIN, description="X/Y/Z speed cap of the move to the start [mm/min]")
    settle: float = Field(0.2, ge=0, le=DAY, description="time simulated after the program [s]")


def convert(spec: SurfacePolishProgram, axes: tuple[AxisConfig, ...], model_file: Path, label: Path) -> SurfaceProgram:
    """Validate the surface and the path, check every pose, and convert to SI."""
    from cnc_twin.geometry.kinematics import HeadGeometry
    from cnc_twin.machine.model_file import load_model
    from cnc_twin.planner import toolpath
    from cnc_twin.machine.workpiece import pad_radius

    sp = spec.surface
    model = load_model(model_file)
    head = HeadGeometry.from_model(model)
    surface, surface_def = surface_in_world(sp, head.workpiece_origin, label, "program.surface")
    radius = pad_radius(model)
    margin = spec.path.margin * units.MM if spec.path.margin is not None else radius
    step = spec.path.step_over * units.MM
    try:
        if spec.path.pattern == "raster":
            sections = toolpath.raster(surface, step_over=step, margin=margin, direction=spec.path.direction)
        else:
            sections = toolpath.spiral(surface, step_over=step, margin=margin)
    except toolpath.ToolpathError as exc:
        raise ScenarioError(label, f"program.path.{exc.key}", str(exc)) from None
    f = spec.force
    force = force_control(f, f.setpoint, tuple((p[0] * units.MM, p[1]) for p in f.profile) if f.profile else ())
    lim = spec.limits
    c_axis = axes[5]
    program = SurfaceProgram(
        surface=surface_def,
        sections=tuple(sections),
        pattern=spec.path.pattern,
        direction=spec.path.direction,
        lead=spec.lead * units.DEG,
        tilt=spec.tilt * units.DEG,
        spindle_speed=spec.spindle * units.RPM,
        limits=PathLimits(
            feed=spec.feed * units.MM_PER_MIN, chord_tolerance=spec.chord_tolerance * units.MM,
            path_acceleration=lim.path_acceleration * units.MM, path_jerk=lim.path_jerk * units.MM,
            normal_acceleration=lim.normal_acceleration * units.MM, normal_jerk=lim.normal_jerk * units.MM,
            axis_velocity=tuple(c.max_velocity for c in axes[:3]),
            axis_acceleration=tuple(c.max_acceleration for c in axes[:3]),
            axis_jerk=tuple(c.max_jerk for c in axes[:3]),
        ),
        force=force,
        preston=preston_model(spec.removal, radius),
        approach_feed=spec.approach_feed * units.MM_PER_MIN if spec.approach_feed is not None else None,
        settle=spec.settle,
        pivot_home=head.pivot_home,
        tool_offset=head.tool_offset,
        rotary_limits=(tuple(c.max_velocity for c in axes[3:5]), tuple(c.max_acceleration for c in axes[3:5]),
                       tuple(c.max_jerk for c in axes[3:5])),
        spindle_acceleration=c_axis.max_acceleration,
        path_length=0.0,
        surface_tile_size=sp.tile_size * units.MM,
        friction=spec.friction,
    )
    if program.spindle_speed > c_axis.max_velocity:
        raise ScenarioError(label, "program.spindle", f"{spec.spindle:g} rpm exceeds the C axis's "
                            f"{c_axis.max_velocity / units.RPM:g} rpm")
    _check_fits_the_card(program, label)
    length = check_reach(program, axes, head, label)
    from dataclasses import replace

    return replace(program, path_length=length)


def force_control(f: ForceLoopSpec, setpoint: float, profile: tuple = ()) -> ForceControl:
    """The force loop's parameters in SI, with ``setpoint`` [N] and ``profile`` ((m, N) pairs)."""
    return ForceControl(
        setpoint=setpoint, profile=profile,
        ramp_time=f.ramp_time, seek_speed=f.seek_speed * units.MM, standoff=f.standoff * units.MM,
        contact_threshold=f.contact_threshold, kp=f.kp * units.MM, ki=f.ki * units.MM,
        max_depth=f.max_depth * units.MM, retract_speed=f.retract_speed * units.MM,
        adapt_threshold=f.adapt_threshold, adapt_feed=f.adapt_feed, adapt_hold=f.adapt_hold,
    )


def preston_model(removal: RemovalSpec, pad_radius: float) -> Preston:
    """The removal model in SI for a pad of ``pad_radius`` [m]."""
    return Preston(k=removal.preston_k, pad_radius=pad_radius, pad_modulus=removal.pad_modulus * 1e9,
                   grid_spacing=removal.grid * units.MM, every=removal.every)


def surface_in_world(sp: SurfaceSpec, origin, label: Path, key: str):
    """The surface of ``sp`` (workpiece frame, mm) in the world frame: ``(NurbsSurface,
    SurfaceDef)``; ``origin``: the workpiece origin [m]. A bad net or knots: ScenarioError at ``key``."""
    from cnc_twin.geometry.nurbs import NurbsError
    from cnc_twin.geometry.surface import NurbsSurface

    rows = {len(r) for r in sp.control_net}
    if len(rows) != 1 or any(len(p) != 3 for r in sp.control_net for p in r):
        raise ScenarioError(label, f"{key}.control_net",
                            "expected a rectangular grid of [x, y, z] points in mm (every row the same length)")
    net = np.asarray(sp.control_net, dtype=np.float64) * units.MM + np.asarray(origin)
    try:
        surface = NurbsSurface(net, sp.weights, sp.knots_u, sp.knots_v, sp.degree_u, sp.degree_v)
    except NurbsError as exc:
        raise ScenarioError(label, f"{key}.{exc.key}", str(exc)) from None
    return surface, SurfaceDef(
        degree_u=sp.degree_u, degree_v=sp.degree_v,
        knots_u=tuple(float(k) for k in sp.knots_u), knots_v=tuple(float(k) for k in sp.knots_v),
        weights=tuple(tuple(float(w) for w in row) for row in surface.weights),
        control_net=tuple(tuple(tuple(float(x) for x in p) for p in row) for row in net))


def _check_fits_the_card(program: SurfaceProgram, label: Path) -> None:
    """The card keeps the surface in its geometry memory (16384 words: about 1000 control points;
    a surface longer than one record goes in parts); refuse a larger one here."""
    from cnc_twin.whiteboard.codec import payload_words
    from cnc_twin.whiteboard.records import SurfaceGeometry

    try:
        payload_words(SurfaceGeometry(surface=program.surface, lead=0.0, tilt=0.0, pivot=(0.0, 0.0, 0.0),
                                      offset=(0.0, 0.0, 0.0)))
    except ValueError as exc:
        raise ScenarioError(label, "program.surface.control_net", str(exc)) from None


def check_reach(program: SurfaceProgram, axes: tuple[AxisConfig, ...], head, label: Path) -> float:
    """Every pose along the path reachable and within travel (including the standoff); returns
    the path's length [m]."""
    from cnc_twin.geometry.kinematics import UnreachablePose
    from cnc_twin.planner.surface_program import section_paths

    total = 0.0
    origin = np.asarray(head.workpiece_origin)
    for k, path in enumerate(section_paths(program)):
        t = np.linspace(*path.domain, REACH_SAMPLES)
        tips = path.point(t)
        axis = path.axes(t, program.lead, program.tilt)
        for lift in (0.0, program.force.standoff):
            try:
                head.inverse(tips + lift * axis, axis, travel=[a.allowed for a in axes[:5]])
            except UnreachablePose as exc:
                where = (tips[exc.index] - origin) / units.MM
                raise ScenarioError(label, "program.path", f"section {k + 1}: the pose at workpiece "
                                    f"({where[0]:.1f}, {where[1]:.1f}, {where[2]:.1f}) mm is unreachable: {exc.reason}") from None
        total += path.arc_length()
    return total
