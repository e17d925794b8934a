"""Typed command records: what the PC streams to the DSP through the FIFO.

Positions in m or rad, absolute machine coordinates. The record kinds (their type numbers, payload
layouts and the header and CRC-16 around them are the wire format, :mod:`cnc_twin.whiteboard.codec`):

==================  ===========================================================================
record              what it carries
==================  ===========================================================================
Move                a synchronised point-to-point move: end position; trapezoid t_acc, t_flat
                    [s], v_peak [1/s], accel [1/s^2]; periods
Probe               a Move stopped when the load cell's force crosses trip_force [N]; kind 2 .. 5
                    (G38.2 .. G38.5)
Dwell               periods to wait
FeedOverride        fraction (1.0 = programmed feed)
ForceSetpoint       force [N]
Spindle             on, speed [rad/s]
EndOfProgram        -
DataBlock           opaque program data (u16 words), e.g. a 4 KB block: 1..MAX_BLOCK_WORDS words
CurveGeometry       a NURBS tool path: control points in X, Y, Z axis space with A, B, C held; or
                    tool-tip positions (world frame) with a tool-axis curve, pivot and tool offset
CurveBlock          one S-curve block of the path's feed plan: length, v0, vp, v1, a_max, j_max
SurfaceGeometry     the surface (world frame, m) the following path sections run on; lead, tilt
                    [rad]; pivot, tool offset
SurfaceCurve        one path section: a (u, v) NURBS on the last SurfaceGeometry; its CurveBlocks
                    follow
ForceControlRecord  force control on or off: setpoint, ramp, seek, gains, adaptation; a profile
                    (path length [m], force [N])
StepContour         a line or arc in X/Y for the step interpolators [counts from power-on],
                    clocked by an S-curve (``STEP_*``)
Mark                a program mark number (0 = none) the trace records
ChipCommand         a motion-chip command (``CHIP_*``): deltas, distance [counts]; speed, creep
                    [counts/s], accel [counts/s^2], jerk [counts/s^3], time [s]
GeometryPart        one piece of a CurveGeometry or SurfaceGeometry too long for one record: the
                    whole record's type, the piece's index and count, its payload words
==================  ===========================================================================
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from cnc_twin.core.config import AxisCurve, ForceControl, SurfaceDef, UvCurve
from cnc_twin.motion.trapezoid import Trapezoid
from cnc_twin.motion.scurve import SCurve


class WireRecord:
    """What every command record shares (each is a frozen dataclass of its own fields)."""

    motion_block: ClassVar[bool] = False
    """the record is one block of motion (a move, a curve block, a step contour): the planner
    counts them"""

    part_of_whole: ClassVar[bool] = False
    """the record is a piece of a longer one: the card joins the pieces
    (:class:`cnc_twin.whiteboard.codec.GeometryJoiner`) and acts on the whole"""


@dataclass(frozen=True)
class Move(WireRecord):
    """Synchronised point-to-point move from the DSP's programmed position to ``end``."""

    end: tuple[float, ...]
    profile: Trapezoid
    periods: int
    motion_block: ClassVar[bool] = True


@dataclass(frozen=True)
class Probe(WireRecord):
    """A probing move: a Move the card stops when the load cell's force crosses ``trip_force``
    [N] (``kind`` 2, 3: rising to it; 4, 5: falling below it), latching the encoders; kinds 2 and
    4 fault when the move ends without crossing, and every kind when the force is already past
    the trip at the start (G38.2 .. G38.5). The status block reports the result."""

    end: tuple[float, ...]
    profile: Trapezoid
    periods: int
    trip_force: float
    kind: int
    motion_block: ClassVar[bool] = True


@dataclass(frozen=True)
class Dwell(WireRecord):
    periods: int


@dataclass(frozen=True)
class FeedOverride(WireRecord):
    fraction: float


@dataclass(frozen=True)
class ForceSetpoint(WireRecord):
    newtons: float


@dataclass(frozen=True)
class Spindle(WireRecord):
    on: bool
    speed: float
    """[rad/s]"""


@dataclass(frozen=True)
class EndOfProgram(WireRecord):
    pass


@dataclass(frozen=True, eq=False)
class DataBlock(WireRecord):
    """Opaque program data moved in bulk (the card's 4 KB block transfers)."""

    words: np.ndarray
    """uint16, 1 to MAX_BLOCK_WORDS words"""

    def __eq__(self, other: object) -> bool:
        return isinstance(other, DataBlock) and np.array_equal(self.words, other.words)

    __hash__ = None  # type: ignore[assignment]


MAX_BLOCK_WORDS = 2048


@dataclass(frozen=True)
class CurveGeometry(WireRecord):
    """A NURBS tool path: in axis space (X/Y/Z, m) with A, B, C held [rad]; or, with ``axis``
    given, tool-tip positions in the world frame plus a NURBS of tool directions on the same
    parameter, ``pivot`` and ``offset`` being the head geometry the card's kinematics needs."""

    degree: int
    knots: tuple[float, ...]
    weights: tuple[float, ...]
    control_points: tuple[tuple[float, float, float], ...]
    hold: tuple[float, float, float]
    axis: AxisCurve | None = None
    """the tool-axis curve (directions), or None when A/B are held"""
    pivot: tuple[float, float, float] = (0.0, 0.0, 0.0)
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    lines: tuple[tuple[float, int], ...] = ()
    """``(u, line)``, u increasing: from parameter ``u`` on the curve runs program line ``line``
    (a G-code path joins several blocks into one curve; the card shows the line in ``mark``)"""


@dataclass(frozen=True)
class CurveBlock(WireRecord):
    """One S-curve block of the path's feed plan."""

    profile: SCurve
    motion_block: ClassVar[bool] = True


@dataclass(frozen=True)
class SurfaceGeometry(WireRecord):
    """The surface the following path sections run on, and the tool axis's lead and tilt [rad]."""

    surface: SurfaceDef
    lead: float
    tilt: float
    pivot: tuple[float, float, float]
    offset: tuple[float, float, float]


@dataclass(frozen=True)
class SurfaceCurve(WireRecord):
    """One section of a surface path: a (u, v) NURBS on the last SurfaceGeometry."""

    curve: UvCurve


@dataclass(frozen=True)
class ForceControlRecord(WireRecord):
    """Force control on (seek, ramp up, then let the path run) or off (ramp down, retract)."""

    on: bool
    params: ForceControl



@dataclass(frozen=True)
class StepContour(WireRecord):
    """A line or arc in the X/Y plane for the older cards' step interpolators, in pulses.

    ``method`` is ``STEP_POINT_BY_POINT`` or ``STEP_DDA``; ``kind`` ``STEP_LINE`` or ``STEP_ARC``.
    Points are lattice points [counts from the encoders' power-on position]; ``start == end`` on
    an arc is a full circle. ``profile`` is the rest-to-rest S-curve over the element's length
    [m] that clocks the interpolator (its cycles follow the profile's path position).
    ``dda_bits`` is the register length, 0 = the smallest that holds the element.
    """

    method: int
    kind: int
    start: tuple[int, int]
    end: tuple[int, int]
    center: tuple[int, int]
    clockwise: bool
    profile: SCurve
    dda_bits: int = 0
    motion_block: ClassVar[bool] = True


STEP_POINT_BY_POINT, STEP_DDA = 1, 2
STEP_LINE, STEP_ARC = 1, 2


@dataclass(frozen=True)
class Mark(WireRecord):
    """A program mark (like an N number): the card shows it in the trace from here on."""

    number: int


@dataclass(frozen=True)
class ChipCommand(WireRecord):
    """A motion-chip command (the 4-axis chip's own profiles, in pulses; see
    :mod:`cnc_twin.dsp.chip`). ``op`` is one of ``CHIP_*``; ``profile`` ``CHIP_CONSTANT`` (no
    ramps), ``CHIP_TRAPEZOID`` (``accel``) or ``CHIP_S_CURVE`` (``accel`` and ``jerk``).

    index:  ``distance`` pulses on ``axis`` at ``speed``;  linear: ``deltas`` (X, Y, Z) along a line at ``speed``;
    jog:    at ``speed`` (signed) for ``time`` seconds, then stop;
    home:   to the home switch at ``speed``, off it at ``creep``, on to the encoder index, latch, return.
    """

    op: int
    axis: int
    profile: int
    deltas: tuple[int, int, int]
    speed: float
    distance: int = 0
    creep: float = 0.0
    accel: float = 0.0
    jerk: float = 0.0
    time: float = 0.0


@dataclass(frozen=True, eq=False)
class GeometryPart(WireRecord):
    """Piece ``index`` of ``count`` of a geometry record's payload (``kind`` = that record's wire
    type). A curve or surface longer than one record goes as consecutive parts; the card joins
    them (:class:`cnc_twin.whiteboard.codec.GeometryJoiner`) and acts on the whole record when the
    last part arrives."""

    kind: int
    index: int
    count: int
    words: np.ndarray
    """uint16, this piece of the whole record's payload"""

    part_of_whole: ClassVar[bool] = True

    def __eq__(self, other: object) -> bool:
        return (isinstance(other, GeometryPart) and (self.kind, self.index, self.count) == (other.kind, other.index, other.count)
                and np.array_equal(self.words, other.words))

    __hash__ = None  # type: ignore[assignment]


CHIP_INDEX, CHIP_LINEAR, CHIP_JOG, CHIP_HOME = 1, 2, 3, 4
CHIP_CONSTANT, CHIP_TRAPEZOID, CHIP_S_CURVE = 0, 1, 2


Record = (Move | Probe | Dwell | FeedOverride | ForceSetpoint | Spindle | EndOfProgram | DataBlock | CurveGeometry | CurveBlock | SurfaceGeometry
          | SurfaceCurve | ForceControlRecord | StepContour | Mark | ChipCommand | GeometryPart)
