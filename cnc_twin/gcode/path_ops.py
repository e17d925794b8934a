"""What a program's canonical calls become (:mod:`cnc_twin.gcode.toolpath` builds them): feed
elements as rational Bezier chains in workpiece mm, and the operations a machine runs.

- :class:`Traverse`: a coordinated move of all six axes to ``end`` (G0 rapid: ``feed`` None;
  a G1 that turns A, B or C, which the card runs as a linear move in axis space as LinuxCNC does
  without tool-centre-point control; G28 / G30 / G53);
- :class:`FeedPath`: consecutive feed moves with A, B, C held (G1 lines, G2 / G3 arcs and
  helices, G5.2 / G6.2 curves, runs of lines fitted as one curve), each element an exact
  rational Bezier chain;
- :class:`ToolAxisPath`: G1 lines that turn the head as they go (5-axis CAM), fitted as one tip
  curve and one tool-axis curve;
- :class:`Pause` (G4, M0, M1), :class:`SpindleChange` (M3 M4 M5 S), :class:`ForceChange`
  (M100 P / M101).

:func:`programmed_geometry`: a feed path as programmed, as points, for measuring a run against it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from cnc_twin.geometry.bezier import piece_length, piece_points


class ToolpathError(ValueError):
    """A program the machine cannot run although it reads: ``line`` (1-based) and the message."""

    def __init__(self, line: int, message: str):
        super().__init__(message)
        self.line, self.message = line, message

    def __reduce__(self):  # pickled whole (from the paths' helper process), not as its message alone
        return type(self), (self.line, self.message)


@dataclass
class Element:
    """One programmed feed element (or a corner blend) in workpiece mm: its rational Bezier
    ``pieces`` (each ``(degree + 1, 4)`` homogeneous), the program ``line`` that made it."""

    pieces: list[np.ndarray]
    line: int
    kind: str
    """line, arc, curve, blend or fit (a run of lines as one curve)"""
    spans: list[float] | None = None
    """each piece's parameter span relative to the others (a curve's own knot spans); None: equal"""
    nurbs: tuple | None = None
    """a curve as programmed, ``(degree, knots, weights, control points (n, 3) mm)``: a path of
    this one element goes to the card as it is (its pieces would hold about degree x the points)"""
    piece_lines: list[int] | None = None
    """the program line of each piece when they differ (a run of lines fitted as one curve)"""
    deviation: float | None = None
    """a fit's largest distance from its programmed points and segments, as measured [mm]"""

    def __getstate__(self) -> dict:
        # what the joins keep on an element (its turn from the one before it, a reference to that
        # element) stays out of a pickle: it links a whole path (pickle's recursion) and is
        # made again, the same, when asked for
        return {name: value for name, value in self.__dict__.items() if name != "_turn_from"}

    @property
    def start(self) -> np.ndarray:
        q = self.pieces[0][0]
        return q[:3] / q[3]

    @property
    def end(self) -> np.ndarray:
        q = self.pieces[-1][-1]
        return q[:3] / q[3]

    def direction(self, at_end: bool) -> np.ndarray:
        """Unit tangent at the start or the end (the first control point off the end point); a
        line's, the same at both ends, is made once (the joins ask for it again and again)."""
        if self.kind == "line":
            cached = self.__dict__.get("_line_direction")
            if cached is None:
                cached = self.__dict__["_line_direction"] = self._direction(False)
            return cached
        return self._direction(at_end)

    def _direction(self, at_end: bool) -> np.ndarray:
        piece = self.pieces[-1][::-1] if at_end else self.pieces[0]
        xyz = piece[:, :3] / piece[:, 3:4]
        for q in xyz[1:]:
            d = (xyz[0] - q) if at_end else (q - xyz[0])
            norm = math.sqrt(float(d.dot(d)))  # np.linalg.norm's own sum and root, without its checks
            if norm > 1e-12:
                return d / norm
        return np.zeros(3)

    @property
    def length(self) -> float:
        """[mm] along the element (a line's exactly; others by
        :func:`~cnc_twin.geometry.bezier.piece_length`'s chords)."""
        if self.kind == "line":  # most of a CAM program: no need to sample a straight piece
            return float(np.linalg.norm(self.end - self.start))
        return sum(piece_length(p) for p in self.pieces)


@dataclass
class LineChain:
    """Consecutive programmed G1 lines of one feed path, held as one array: ``points`` ((n + 1, 3)
    [mm]; line k from point k to k + 1), ``lines`` (n,) the program line of each, ``turns``
    (n - 1,) [rad] the turn at each inner point (:func:`~cnc_twin.gcode.feed_paths.chain_turns`).
    A CAM program's millions of lines are held so, not as an :class:`Element` each."""

    points: np.ndarray
    lines: list[int]
    turns: list[float]

    @property
    def start(self) -> np.ndarray:
        return self.points[0]

    @property
    def end(self) -> np.ndarray:
        return self.points[-1]

    def part(self, first: int, stop: int) -> "LineChain":
        """Its lines ``first`` ..< ``stop``."""
        return LineChain(self.points[first:stop + 1], self.lines[first:stop], self.turns[first:stop - 1])


@dataclass
class Traverse:
    """A coordinated move of all six axes to ``end`` (G0 rapid: ``feed`` None; a G1 that turns A, B
    or C; G28 / G30 / G53), from program line ``line``."""

    end: tuple[float, ...]
    """X, Y, Z [mm] (tip, workpiece frame), A, B, C [deg]"""
    feed: float | None
    """[mm/min] (X/Y/Z), or [deg/min] for a move of the rotary axes alone; None: rapid"""
    line: int
    rotary_only: bool = False
    """only A, B, C move (the feed is in deg/min)"""


@dataclass
class FeedPath:
    """Consecutive feed moves with A, B, C held (``hold``), each element an exact rational Bezier
    chain (see the module docstring)."""

    elements: list[Element]
    feed: float
    """[mm/min]"""
    hold: tuple[float, float, float]
    """A, B, C [deg]"""
    line: int
    tolerance: float | None = None
    """the path's G64 P [mm] (its corner blends' tolerance, and the card's chord tolerance on it);
    None under G61 / G61.1 or a G64 without P"""
    program: list[Element | LineChain] = field(default_factory=list)
    """the elements as programmed, before corner blends and fits (what the run is measured
    against), the lines in chains"""

    @property
    def start(self) -> np.ndarray:
        return self.elements[0].start

    @property
    def end(self) -> np.ndarray:
        return self.elements[-1].end


@dataclass
class Pause:
    seconds: float
    line: int
    """G4 P seconds; M0 / M1 pause the twin 0 s (an exact stop: no operator to press start)"""


@dataclass
class SpindleChange:
    rpm: float
    """signed: + M3 (clockwise), - M4; 0 stopped"""
    line: int


@dataclass
class ForceChange:
    setpoint: float | None
    """[N]; None: the force loop off (M101)"""
    line: int


@dataclass
class ToolAxisPath:
    """G1 lines that turn the head as they go (5-axis CAM), fitted as one tip curve and one
    tool-axis curve on the same knots (``knots``; ``points``, ``axis_points`` (n, 3): tip [mm],
    axis directions), run rest to rest at ``feed`` [mm/min] with C held at ``c`` [deg]."""

    knots: np.ndarray
    points: np.ndarray
    axis_points: np.ndarray
    feed: float
    c: float
    line: int
    span_lines: list[tuple[float, int]]
    """``(u, line)``: from parameter ``u`` on, the curve runs program line ``line``"""
    tolerance: float
    """G64 P [mm]"""
    deviation: float
    """the fit's own measured distance from the programmed points and segments [mm]"""
    axis_deviation: float
    """its largest angle from the programmed tool axis [rad]"""
    program_points: np.ndarray
    """(m, 3) [mm] the programmed tip points"""
    program_axes: np.ndarray
    """(m, 3) unit tool axes there (from the programmed A, B)"""
    program_lines: list[int]
    """(m - 1,) the program line of each programmed move"""
    axis_tolerance: float
    """[rad] how far the fitted tool axis may turn from the programmed one"""


@dataclass
class Probe:
    """A straight probing move (G38.2 .. G38.5) from ``start`` to ``end`` (machine points: tip,
    workpiece frame [mm], A B C [deg]) at ``feed`` [mm/min]; ``stop``, where the machine stopped
    as the reader was answered (:mod:`cnc_twin.gcode.probing`); ``offset`` (x y z [mm], a b c
    [deg]) and ``scale`` [mm per program unit]: the program's frame at the probe."""

    start: tuple[float, ...]
    end: tuple[float, ...]
    stop: tuple[float, ...]
    feed: float
    kind: int
    """2 .. 5 for G38.2 .. G38.5"""
    line: int
    offset: tuple[float, ...]
    scale: float


Operation = Traverse | FeedPath | Pause | SpindleChange | ForceChange | ToolAxisPath | Probe


# -- element geometry ---------------------------------------------------------------------------

def line_element(start: np.ndarray, end: np.ndarray, line: int) -> Element:
    """A line from ``start`` to ``end`` (each (3,) [mm]): one degree-1 piece of weights 1 (made
    directly: :func:`~cnc_twin.geometry.bezier.homogeneous`'s general path costs a CAM line most
    of its conversion, and multiplying by a weight of 1 changes no bit)."""
    piece = np.empty((2, 4))
    piece[0, :3], piece[1, :3], piece[:, 3] = start, end, 1.0
    return Element([piece], line, "line")


REFERENCE_STEP = 0.05
"""[mm] between the samples of a programmed arc or curve in :func:`programmed_geometry` (a 20 mm
radius's chord then strays 0.016 um from it)"""


def programmed_geometry(elements: list[Element | LineChain]) -> tuple[np.ndarray, np.ndarray]:
    """The programmed path as a polyline ((k, 3) mm: lines by their ends, arcs and curves sampled
    every :data:`~cnc_twin.gcode.path_ops.REFERENCE_STEP`) and its vertices ((m, 3) mm: each
    element's ends); a path of lines alone gives the same array for both."""
    points, vertices = [elements[0].start[None]], [elements[0].start[None]]
    for e in elements:
        if isinstance(e, LineChain):
            points.append(e.points[1:])
            vertices.append(e.points[1:])
            continue
        if e.kind != "line":
            for q in e.pieces:
                t = np.linspace(0.0, 1.0, max(8, math.ceil(piece_length(q) / REFERENCE_STEP)) + 1)[1:]
                points.append(np.asarray(piece_points(q, t)))
        else:
            points.append(e.end[None])
        vertices.append(e.end[None])
    polyline = np.concatenate(points)
    if all(isinstance(e, LineChain) or e.kind == "line" for e in elements):
        return polyline, polyline
    return polyline, np.concatenate(vertices)
