"""Scenario schema and conversion of the ``contour`` program: lines and arcs run by each method.

The contour is given like G01/G02/G03 blocks in the workpiece frame (mm), in the X/Y plane at a
tool-tip height ``z``, with the tool axis vertical. ``method`` names how the card interpolates
it, or a list of methods to run the same contour several times in one run (one pass each)::

    nurbs            exact NURBS of each element, direct interpolation with the feed planner
    point_by_point   point-by-point comparison, one step per cycle      (older CPLD/8051 cards)
    dda              digital differential analyser, per-iteration steps (older cards)

The step methods work on the pulse lattice: every point is rounded to whole encoder counts, and
an arc's end must be a lattice neighbour of its start's circle (the cards' end-point judgement);
one that is not is refused here, naming both radii, as a CNC refuses G02 with a radius mismatch.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from cnc_twin.core import units
from cnc_twin.core.config import AxisConfig, ContourProgram, LatticeElement
from cnc_twin.core.errors import ScenarioError
from cnc_twin.geometry.contour import Arc, Line, check_contour, element_length, element_nurbs
from cnc_twin.legacy.quadrants import end_is_on_circle
from cnc_twin.scenario.curve import NurbsCurveProgram
from cnc_twin.scenario.curve import convert as convert_curve
from cnc_twin.scenario.schema_base import DAY, FEED_MIN, KeyedValueError, PathLimitsSpec, Strict
from cnc_twin.scenario.validation import validate

Method = Literal["nurbs", "point_by_point", "dda"]


class LineSpec(Strict):
    to: list[float] = Field(min_length=2, max_length=2, description="end point [x, y] [mm]")


class ArcSpec(Strict):
    to: list[float] = Field(min_length=2, max_length=2, description="end point [x, y] [mm]; equal to the start: a full circle")
    center: list[float] = Field(min_length=2, max_length=2, description="[x, y] [mm]")
    direction: Literal["cw", "ccw"] = Field(description="clockwise (G02) or counter-clockwise (G03), seen from +Z")


class ElementSpec(Strict):
    """One block: exactly one of ``line`` or ``arc``."""

    line: LineSpec | None = None
    arc: ArcSpec | None = None

    @model_validator(mode="after")
    def _one(self) -> "ElementSpec":
        if (self.line is None) == (self.arc is None):
            raise KeyedValueError((), "give exactly one of 'line' or 'arc'")
        return self


class ContourProgramSpec(Strict):
    """Lines and arcs in the X/Y plane, run by one or more interpolation methods."""

    type: Literal["contour"]
    start: list[float] = Field(min_length=2, max_length=2, description="[x, y] of the first element's start [mm]")
    z: float = Field(description="tool-tip height in the workpiece frame [mm]")
    elements: list[ElementSpec] = Field(min_length=1)
    feed: float = Field(ge=FEED_MIN, description="programmed feed [mm/min]")
    method: Method | list[Method] = Field(description="one method, or a list: one pass per method, in order")
    chord_tolerance: float = Field(0.001, gt=0, description="nurbs method [mm]")
    limits: PathLimitsSpec = PathLimitsSpec()
    dda_bits: int = Field(0, ge=0, le=30, description="DDA register length [bits]; 0 = the smallest that holds each element")
    C: float = Field(0.0, description="spindle angle held [deg]")
    approach_feed: float | None = Field(None, ge=FEED_MIN, description="X/Y/Z speed cap of the moves to the start [mm/min]")
    dwell: float = Field(0.2, ge=0, le=DAY, description="pause at the start before each pass [s]")
    settle: float = Field(0.3, ge=0, le=DAY, description="time simulated after the last pass [s]")

    @model_validator(mode="after")
    def _methods(self) -> "ContourProgramSpec":
        if isinstance(self.method, list) and not self.method:
            raise KeyedValueError(("method",), "give at least one method")
        return self


def _elements_mm(spec: ContourProgramSpec) -> list[Line | Arc]:
    """The blocks as elements in the workpiece frame [mm], each starting where the last ended."""
    out: list[Line | Arc] = []
    here = (float(spec.start[0]), float(spec.start[1]))
    for e in spec.elements:
        if e.line is not None:
            end = (float(e.line.to[0]), float(e.line.to[1]))
            out.append(Line(start=here, end=end))
        else:
            end = (float(e.arc.to[0]), float(e.arc.to[1]))
            out.append(Arc(start=here, end=end, center=(float(e.arc.center[0]), float(e.arc.center[1])),
                           clockwise=e.arc.direction == "cw"))
        here = end
    return out


def _shifted(el: Line | Arc, scale: float, shift) -> Line | Arc:
    def p(q):
        return (q[0] * scale + shift[0], q[1] * scale + shift[1])

    if isinstance(el, Line):
        return Line(start=p(el.start), end=p(el.end))
    return Arc(start=p(el.start), end=p(el.end), center=p(el.center), clockwise=el.clockwise)


def _lattice(el: Line | Arc, zero, cpu, label: Path, key: str) -> LatticeElement:
    """``el`` (axis space, m) on the pulse lattice; arcs checked with the cards' end judgement."""
    def counts(q):
        return (round((q[0] - zero[0]) * cpu[0]), round((q[1] - zero[1]) * cpu[1]))

    start, end = counts(el.start), counts(el.end)
    if isinstance(el, Line):
        if start == end:
            raise ScenarioError(label, key, "the line is shorter than one pulse")
        return LatticeElement("line", start, end, (0, 0), False)
    if el.start == el.end:
        end = start  # a full circle stays closed after rounding
    center = counts(el.center)
    x0, y0, x1, y1 = start[0] - center[0], start[1] - center[1], end[0] - center[0], end[1] - center[1]
    r2 = x0 * x0 + y0 * y0
    if r2 == 0:
        raise ScenarioError(label, key, "the arc's radius is under one pulse")
    if not end_is_on_circle(r2, x1, y1):
        raise ScenarioError(label, key, f"on the pulse lattice the arc's end is not on its start's circle: radius "
                            f"{math.sqrt(r2) / cpu[0] * 1e3:.4f} mm at the start, "
                            f"{math.hypot(x1, y1) / cpu[0] * 1e3:.4f} mm at the end")
    return LatticeElement("arc", start, end, center, el.clockwise)


def convert(spec: ContourProgramSpec, axes: tuple[AxisConfig, ...], model, home, label: Path) -> ContourProgram:
    """Check and convert a contour program (mm, mm/min) to SI, in axis space."""
    from cnc_twin.geometry.kinematics import HeadGeometry

    elements_mm = _elements_mm(spec)
    try:
        check_contour([_shifted(e, units.MM, (0.0, 0.0)) for e in elements_mm])
    except ValueError as exc:
        raise ScenarioError(label, "program.elements", str(exc)) from None
    methods = tuple(spec.method) if isinstance(spec.method, list) else (spec.method,)
    cx, cy = axes[0], axes[1]
    if cx.counts_per_unit != cy.counts_per_unit and any(m != "nurbs" for m in methods):
        raise ScenarioError(label, "program.method", "the step methods need X and Y with the same pulse size")

    # Axis space: the tool axis is vertical, so axes = tip + a constant shift.
    head = HeadGeometry.from_model(model)
    tip0 = head.world_from_workpiece(np.array([[0.0, 0.0, spec.z * units.MM]]))
    origin = head.axes_from_tip(tip0, 0.0, 0.0)[0]
    elements = tuple(_shifted(e, units.MM, origin[:2]) for e in elements_mm)

    curves = []
    lattice = []
    feeds = []
    limits_spec = spec.limits
    feed = spec.feed * units.MM_PER_MIN
    for i, (el_mm, el) in enumerate(zip(elements_mm, elements)):
        key = f"program.elements[{i}].{'line' if isinstance(el, Line) else 'arc'}.to"
        degree, knots, weights, points = element_nurbs(el_mm)
        curve_spec = validate(NurbsCurveProgram, {
            "type": "nurbs_curve", "degree": degree, "knots": knots, "weights": weights,
            "control_points": [[x, y, spec.z] for x, y in points], "feed": spec.feed,
            "chord_tolerance": spec.chord_tolerance, "limits": limits_spec.model_dump(), "C": spec.C,
            "settle": 0.0}, label, ("program",))
        try:
            curves.append(convert_curve(curve_spec, axes, model, label))
        except ScenarioError as exc:
            raise ScenarioError(label, key, exc.message) from None
        lattice.append(_lattice(el, home[:2], (cx.counts_per_unit, cy.counts_per_unit), label, key))
        v = min(feed, cx.max_velocity, cy.max_velocity)
        if isinstance(el, Arc):
            radius = math.hypot(el.start[0] - el.center[0], el.start[1] - el.center[1])
            v = min(v, math.sqrt(curves[-1].limits.normal_acceleration * radius))
        feeds.append(v)
    first = curves[0]
    start = (elements[0].start[0], elements[0].start[1], float(origin[2]), *first.hold)
    return ContourProgram(
        methods=methods,
        elements=elements,
        start=tuple(float(x) for x in start),
        limits=first.limits,
        curves=tuple(curves),
        lattice=tuple(lattice),
        element_feeds=tuple(feeds),
        dda_bits=spec.dda_bits,
        approach_feed=spec.approach_feed * units.MM_PER_MIN if spec.approach_feed is not None else None,
        dwell=spec.dwell,
        settle=spec.settle,
    )


def element_lengths(prog: ContourProgram) -> list[float]:
    """Each element's length [m]."""
    return [element_length(e) for e in prog.elements]
