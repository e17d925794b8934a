"""The motion step of a block, as LinuxCNC's interpreter makes it: the end point from the axis
words (absolute, incremental or, with G53, machine coordinates), then a traverse, a feed, an
arc, a NURBS curve (G5.2 ... G5.3, or the Fanuc-style G6.2), a probing move (G38.2 .. G38.5,
:mod:`~cnc_twin.gcode.probing`), a canned cycle (:mod:`~cnc_twin.gcode.cycles`), a dwell or a
return to a stored position (G28 / G30).

Positions are program coordinates in the program's units (see :mod:`~cnc_twin.gcode.state`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from cnc_twin.gcode.arcs import arc_move, glibc_hypot
from cnc_twin.gcode.blocks import Block, BlockError
from cnc_twin.gcode.cycles import CycleRunner
from cnc_twin.gcode.long_double import extended, pi_long
from cnc_twin.gcode.modal import CANNED_CYCLES, G
from cnc_twin.gcode.probing import PROBE_CODES, straight_probe
from cnc_twin.gcode.state import HOME_PARAMETERS

if TYPE_CHECKING:  # the interpreter owns this runner; only its type is needed here
    from cnc_twin.gcode.interpreter import Interpreter
    from cnc_twin.gcode.nurbs import NurbsBlock

AXIS_LETTERS = "xyzabc"
AXIS_INDEX = {letter: axis for axis, letter in enumerate(AXIS_LETTERS)}
NURBS_STARTS = (G.G5_2, G.G6_2)
"""G5.2 / G6.2 (tenths): their blocks gather into one curve (:mod:`~cnc_twin.gcode.nurbs`, imported with
the first: it brings numpy, which a program without curves never needs)"""
NURBS_END = G.G5_3
"""G5.3 ends a G5.2 curve"""


class MotionRunner:
    """Motion for one :class:`~cnc_twin.gcode.interpreter.Interpreter`; ``nurbs`` is the curve
    being gathered, or None."""

    def __init__(self, interpreter: "Interpreter"):
        self.interpreter = interpreter
        self.state = interpreter.state
        self.nurbs = None
        self.nurbs_kind = None
        self.cycles = CycleRunner(interpreter)

    def ends(self, block: Block, machine: bool = False) -> list[float]:
        """The programmed end point: axes without a word keep the current value."""
        s = self.state
        end = list(s.position)
        for letter, value in block.words.items():  # each axis on its own: their order does not matter
            axis = AXIS_INDEX.get(letter)
            if axis is not None:
                if machine:  # G53: machine coordinates of the tool tip
                    end[axis] = s.from_machine(axis, value)
                elif s.distance == G.G91:
                    end[axis] = s.position[axis] + value
                else:
                    end[axis] = value
        if "@" in block.words or "^" in block.words:
            self._polar(block, end)
        return end

    def _polar(self, block: Block, end: list[float]) -> None:
        """``@`` radius and ``^`` angle (degrees) about the program's XY origin, LinuxCNC's polar
        coordinates (its find_ends): absolute (G90), or in G91 the radius added first and then
        the angle turned, each from the point the step before left."""
        s = self.state
        words = block.words
        if "x" in words or "y" in words:
            raise BlockError("Cannot specify X or Y words with polar coordinate")
        x, y = s.position[0], s.position[1]
        if s.distance == G.G90:
            if "@" in words and "^" in words:
                radius, theta = words["@"], _radians(words["^"])
            elif "@" in words:
                if x == 0 and y == 0:
                    raise BlockError("Must specify angle in polar coordinate if at the origin")
                radius, theta = words["@"], math.atan2(y, x)
            else:
                radius, theta = glibc_hypot(y, x), _radians(words["^"])
            end[0], end[1] = radius * math.cos(theta), radius * math.sin(theta)
            return
        if "@" in words:
            if x == 0 and y == 0:
                raise BlockError("Incremental motion with polar coordinates is indeterminate when at the origin")
            theta = math.atan2(y, x)
            radius = glibc_hypot(y, x) + words["@"]
            x, y = radius * math.cos(theta), radius * math.sin(theta)
        if "^" in words:
            if x == 0 and y == 0:
                raise BlockError("G91 motion with polar coordinates is indeterminate when at the origin")
            theta = math.atan2(y, x) + _radians(words["^"])
            radius = glibc_hypot(y, x)
            x, y = radius * math.cos(theta), radius * math.sin(theta)
        end[0], end[1] = x, y

    def _feed_error(self, words: dict[str, float], missing: str, zero: str) -> str | None:
        """LinuxCNC's refusal of the block's feed (``words``: the block's), or None: ``missing``
        in inverse time without an F, ``zero`` in units per minute at feed 0."""
        s = self.state
        if s.feed_mode == G.G93:
            return missing if "f" not in words else None
        return zero if s.feed <= 0.0 else None

    def move(self, motion: int, block: Block, machine: bool) -> None:
        """The block's motion in mode ``motion`` (tenths: 0, 10, 20, 30, 52, 53, 62)."""
        s = self.state
        emit = self.interpreter.emit
        if self.nurbs is not None and motion not in (self.nurbs_kind, NURBS_END):
            if self.nurbs_kind != G.G5_2:  # the twin's own G6.2 must be complete
                raise BlockError(f"G{self.nurbs_kind / 10:g} curve not ended before another motion")
            self.nurbs = self.nurbs_kind = None  # LinuxCNC drops an unfinished G5.2 curve silently
        if motion in NURBS_STARTS or motion == NURBS_END:
            self._nurbs(motion, block)
            return
        if motion in CANNED_CYCLES:
            self.cycles.run(motion, block)
            return
        if motion in PROBE_CODES:
            straight_probe(self, motion, block)
            return
        end = self.ends(block, machine)
        if motion == G.G0:
            emit("STRAIGHT_TRAVERSE", *end)
        elif motion == G.G1:
            error = self._feed_error(block.words, "F word missing with inverse time g1 move",
                                     "Cannot do g1 with zero feed rate")
            if error:
                raise BlockError(error)
            if s.feed_mode == G.G93:
                self._inverse_time(block.words, straight_length(s.position, end))
            emit("STRAIGHT_FEED", *end)
        else:
            self.arc(motion, block.words, end)
        s.position = end

    def arc(self, motion: int, words: dict[str, float], end: list[float]) -> None:
        """The arc of a G2 / G3 block (``motion``; ``words``: the block's) from the current point to
        ``end`` (x y z a b c, as :meth:`ends` finds it), its checks and refusals; the caller then
        moves the current point to ``end``."""
        s = self.state
        # LinuxCNC checks the feed in the middle of the arc's own checks
        feed_error = self._feed_error(words, "F word missing with inverse time arc move",
                                      "Cannot make arc with zero feed rate")
        start = s.position
        arc = arc_move(s.plane, motion == G.G2, (start[0], start[1], start[2]), (end[0], end[1], end[2]), words,
                       s.ijk_distance == G.G90_1, s.units == G.G21, feed_error=feed_error)
        if s.feed_mode == G.G93:
            self._inverse_time(words, arc_length(s.plane, s.position, arc))
        self.interpreter.emit("ARC_FEED", *end[3:], payload=arc)

    def _inverse_time(self, words: dict[str, float], length: float) -> None:
        """G93: the move's feed in units per minute is its length times F (``words``: the block's;
        at least 0.1)."""
        self.state.feed = max(0.1, length * words["f"])
        self.interpreter.emit("SET_FEED_RATE", self.state.feed)

    def _nurbs(self, motion: int, block: Block) -> None:
        """A block of a NURBS curve. G5.2 points are all relative to the point before the curve
        (LinuxCNC moves its current point only at G5.3); G6.2 points follow one another."""
        from cnc_twin.gcode.nurbs import G52Collector, G62Collector, g53  # see NURBS_STARTS

        s = self.state
        line = block.line
        feed = s.feed if s.feed_mode == G.G94 else None
        if motion == NURBS_END:
            self._finish(g53(self.nurbs, line))
            return
        point = tuple(self.ends(block)[:3])
        if self.nurbs is None or (motion == G.G5_2 and any(round(g * 10) == G.G5_2 for g in block.g)):
            collector = G52Collector if motion == G.G5_2 else G62Collector
            self.nurbs = collector(tuple(s.position[:3]), s.plane, block.words, point, line, feed)
            self.nurbs_kind = motion
        else:
            self.nurbs.add(block.words, point, line, feed)
        if motion == G.G6_2:
            s.position[:3] = list(point)
            if self.nurbs.complete:
                self._finish(self.nurbs.finish(line))

    def _finish(self, curve: "NurbsBlock") -> None:
        self.nurbs = self.nurbs_kind = None
        self.state.position[:3] = list(curve.end)
        self.interpreter.emit("NURBS_FEED", payload=curve)

    def dwell(self, block: Block) -> None:
        """G4: LinuxCNC dwells even a negative time (P-1 alone reads as no P at all)."""
        self.interpreter.emit("DWELL", block.words["p"])

    def home(self, code: int, block: Block, given: list[int]) -> None:
        """G28 / G30: through the programmed point, then to the stored position (#5161.. /
        #5181.., machine coordinates): the named axes, or all of them when none is named."""
        s = self.state
        emit = self.interpreter.emit
        middle = self.ends(block)
        emit("STRAIGHT_TRAVERSE", *middle)
        base = HOME_PARAMETERS[code]
        end = list(middle)
        for axis in (given or range(6)):
            end[axis] = s.home(base, axis)
        emit("STRAIGHT_TRAVERSE", *end)
        s.position = end


def _radians(degrees: float) -> float:
    """LinuxCNC's D2R."""
    return degrees * math.pi / 180.0


PLANE_AXES = {G.G17: (0, 1, 2), G.G18: (2, 0, 1), G.G19: (1, 2, 0)}
"""plane (G17 / G18 / G19 in tenths) -> indices of its first, second and normal axes"""


STRAIGHT_TINY = 1e-7
"""an axis moving less than this does not count in LinuxCNC's inverse-time length"""


def straight_length(start, end) -> float:
    """LinuxCNC's length of a straight move for inverse time: the XYZ distance, or the ABC
    distance (degrees) for a move of rotary axes only."""
    # products, not ** 2: a square past the float range is inf in C (and here), not an exception
    first = 0 if any(abs(start[k] - end[k]) > STRAIGHT_TINY for k in range(3)) else 3
    d = [end[k] - start[k] for k in range(first, first + 3)]
    return math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])


def arc_length(plane: int, start, arc) -> float:
    """LinuxCNC's length of an arc or helix for inverse time (its find_arc_length / find_turn)."""
    first, second, normal = PLANE_AXES[plane]
    x1, y1 = start[first], start[second]
    radius = math.hypot(arc.first_center - x1, arc.second_center - y1)
    turn = arc.rotation
    theta = 0.0
    if turn != 0:
        alpha = math.atan2(y1 - arc.second_center, x1 - arc.first_center)
        beta = math.atan2(arc.second_end - arc.second_center, arc.first_end - arc.first_center)
        # as find_turn writes it: 2 * M_PIl in long double, each result rounded to double
        if turn > 0:
            if beta <= alpha:
                beta = float(beta + 2 * pi_long())
            theta = float(extended(beta - alpha) + (turn - 1) * (2 * pi_long()))
        else:
            if alpha <= beta:
                alpha = float(alpha + 2 * pi_long())
            theta = float(extended(beta - alpha) + (turn + 1) * (2 * pi_long()))
    if arc.axis_end == start[normal]:
        return radius * abs(theta)
    return math.hypot(radius * theta, arc.axis_end - start[normal])
