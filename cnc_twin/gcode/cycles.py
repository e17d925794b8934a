"""Canned cycles (G73, G74, G81 .. G89) as LinuxCNC 2.9's interpreter makes them (its
convert_cycle and the cycles of interp_cycles.cc): one cycle block -> its traverses, feeds,
dwells and spindle calls, checked call for call against ``rs274`` (``tests/test_gcode_cycles.py``).

A cycle works in the selected plane (G17 XY, G18 XZ, G19 YZ) along the plane's normal axis (Z,
Y, X): the normal-axis word is the hole's bottom, R the retract plane, and the plane's two axis
words the hole's place. L repeats the cycle (in G91 each repeat moves by the plane's axis words
again); P is a dwell [s], Q a peck [program units], I J K (G87) the back-bore offset and height.
In G91, R is from the level the series of cycles started at and the bottom from R.

The cycle stays the motion mode: a block of axis words alone repeats it at the new place with
the R, bottom, P, Q and I J K of the cycles before (a new cycle code must give them again, but
for G74 / G84's P). The level the series started at (the "old Z" a G98 cycle returns to) is
taken when the first cycle of the series runs, and kept by every cycle after it (of any kind)
until a motion that is no cycle, as LinuxCNC keeps it.

Positions are program coordinates in the program's units (:mod:`~cnc_twin.gcode.state`).
Errors are LinuxCNC's, in its order (a cycle in the G17.1 .. G19.1 planes is one: it would run on
U V W axes); G74 / G84 outside G17 are refused with a reason, as LinuxCNC 2.9 taps with the
plane's axes swapped there.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from cnc_twin.gcode.arcs import PLANE_AXES, glibc_hypot
from cnc_twin.gcode.blocks import Block, BlockError
from cnc_twin.gcode.checks import UNSUPPORTED_MARK
from cnc_twin.gcode.modal import CANNED_CYCLES, G

if TYPE_CHECKING:  # the interpreter owns the runner; only its type is needed here
    from cnc_twin.gcode.interpreter import Interpreter

PECK_CLEARANCE_INCH = 0.010
"""[inch] how far above the last peck's bottom G83 comes back down and G73 backs off (LinuxCNC
2.9's G83_RAPID_DELTA; times 25.4 in a G21 program)"""
UVW_PLANES = {G.G17_1: ("UV", "W"), G.G18_1: ("UW", "V"), G.G19_1: ("VW", "U")}
"""G17.1 / G18.1 / G19.1 -> LinuxCNC's name of the plane and of its normal axis"""
PLANE_NAMES = {G.G17: "xy", G.G18: "xz", G.G19: "yz"}
DWELL_CYCLES = (G.G82, G.G86, G.G88, G.G89)
"""cycles that need a P the first time"""
PECK_CYCLES = (G.G73, G.G83)
"""cycles that need a Q the first time"""
SPINDLE_ENUM = {"cw": 2, "ccw": 3}
"""the spindle's direction as LinuxCNC's CANON_DIRECTION (ORIENT_SPINDLE prints it)"""
SPINDLE_START = {"cw": "START_SPINDLE_CLOCKWISE", "ccw": "START_SPINDLE_COUNTERCLOCKWISE"}


class CycleRunner:
    """The canned cycles of one :class:`~cnc_twin.gcode.interpreter.Interpreter`, with what
    LinuxCNC keeps between cycle blocks: the series' starting level, the last bottom word, R,
    P, Q and I J K (program units, as written: increments in G91)."""

    def __init__(self, interpreter: "Interpreter"):
        self.interpreter = interpreter
        self.state = interpreter.state
        self.initial_level = 0.0
        self.bottom = 0.0
        self.r = 0.0
        self.p = 0.0
        self.q = 0.0
        self.ijk = [0.0, 0.0, 0.0]

    def run(self, motion: int, block: Block) -> None:
        """The cycle ``motion`` (tenths) of ``block``; the state's motion mode is still the one
        before the block (LinuxCNC sets it once the cycle has run)."""
        s = self.state
        words = block.words
        repeat = s.motion == motion
        if s.feed == 0.0:
            raise BlockError("Cannot feed with zero feed rate")
        if s.feed_mode == G.G93:
            raise BlockError("Cannot use inverse time feed with canned cycles")
        if "r" in words:
            r_word = words["r"]
        elif repeat:
            r_word = self.r
        else:
            raise BlockError("R clearance plane unspecified in cycle")
        repeats = round(words.get("l", 1.0))  # read as a whole number of at least 0
        if repeats == 0:
            raise BlockError("Cannot do zero repeats of cycle")
        if s.plane in UVW_PLANES:
            self._uvw_plane(repeat, words)
        if motion in (G.G74, G.G84) and s.plane != G.G17:
            raise BlockError(f"G{motion // 10} in the G{s.plane / 10:g} plane is {UNSUPPORTED_MARK}'s machine "
                             "(LinuxCNC 2.9 taps with the plane's axes swapped there)")
        first, second, normal = PLANE_AXES[s.plane]
        letters = "xyz"
        if not repeat and letters[normal] not in words:
            raise BlockError(f"{letters[normal].upper()} value unspecified in {PLANE_NAMES[s.plane]} plane "
                             "canned cycle")
        bottom_word = words.get(letters[normal], self.bottom)
        if s.motion not in CANNED_CYCLES:  # the first cycle of a series: its starting level
            self.initial_level = s.position[normal]
        old = self.initial_level  # the level G98 returns to
        here = s.position[normal]  # the normal axis's level now
        step = (0.0, 0.0, 0.0, 0.0)  # G91: first, second axis, polar radius, angle [rad] per repeat
        if s.distance == G.G90:
            r, bottom = r_word, bottom_word
            a, b = self._absolute_place(words, first, second)
        else:
            step = (words.get(letters[first], 0.0), words.get(letters[second], 0.0),
                    words.get("@", 0.0) if s.plane == G.G17 else 0.0,
                    _radians(words["^"]) if s.plane == G.G17 and "^" in words else 0.0)
            r = r_word + old
            bottom = r + bottom_word
            a, b = s.position[first], s.position[second]
        if r < bottom:
            raise BlockError(f"R less than {letters[normal]} in cycle in {PLANE_NAMES[s.plane]} plane")
        if old < r:  # below the R plane: straight up to it first
            self._traverse_normal(normal, r)
            old = here = r
        clear = r if s.retract == G.G99 else old
        control = s.control
        if control[0] != "CANON_EXACT_PATH":
            self.interpreter.emit("SET_MOTION_CONTROL_MODE", "CANON_EXACT_PATH")
        axes = (first, second, normal)
        move = self._mover(axes)
        cycle = self._body(motion, block, repeat, bottom, r, clear, axes, move)
        for k in range(repeats):
            a, b = self._next_place(a, b, step)
            if k == 0 and here > r:  # from above R: over to the hole at this level, down to R
                move("STRAIGHT_TRAVERSE", a, b, here)
                move("STRAIGHT_TRAVERSE", a, b, r)
            else:  # from the clearance level the last hole left (LinuxCNC assumes it is there)
                move("STRAIGHT_TRAVERSE", a, b, clear)
                if clear > r:
                    move("STRAIGHT_TRAVERSE", a, b, r)
            cycle(a, b)
        s.position[first], s.position[second], s.position[normal] = a, b, clear
        self.bottom, self.r = bottom_word, r_word
        if control[0] != "CANON_EXACT_PATH":
            self.interpreter.emit("SET_MOTION_CONTROL_MODE", *control)
            self.interpreter.emit("SET_NAIVECAM_TOLERANCE", s.naivecam)

    # -- the place of the hole ---------------------------------------------------------------
    def _uvw_plane(self, repeat: bool, words: dict[str, float]) -> None:
        """G17.1 .. G19.1: LinuxCNC runs the cycle on U V W, which this machine has not: it
        refuses X Y Z words and a first cycle without the normal axis's word."""
        name, axis = UVW_PLANES[self.state.plane]
        for letter in "xyz":
            if letter in words:
                article = "an" if letter == "x" else "a"
                raise BlockError(f"Cannot put {article} {letter.upper()} in a canned cycle in the {name} plane")
        if not repeat:
            raise BlockError(f"G{self.state.plane / 10:g} canned cycle is not possible on a machine without "
                             f"{axis} axis")
        # a repeat there would need polar words, which LinuxCNC refuses outside G17 before this
        raise BlockError(f"canned cycles in the G{self.state.plane / 10:g} plane (U V W axes) are "
                         f"{UNSUPPORTED_MARK}'s machine")

    def _absolute_place(self, words: dict[str, float], first: int, second: int) -> tuple[float, float]:
        """G90: the plane's axis words, or (XY plane) the polar radius ``@`` and angle ``^``
        [deg] about the origin, each missing one taken from the current point."""
        s = self.state
        if s.plane == G.G17 and ("@" in words or "^" in words):
            x, y = s.position[0], s.position[1]
            radius = words["@"] if "@" in words else glibc_hypot(y, x)
            theta = _radians(words["^"]) if "^" in words else math.atan2(y, x)
            return radius * math.cos(theta), radius * math.sin(theta)
        letters = "xyz"
        return (words.get(letters[first], self.state.position[first]),
                words.get(letters[second], self.state.position[second]))

    @staticmethod
    def _next_place(a: float, b: float, step: tuple[float, float, float, float]) -> tuple[float, float]:
        """The place of the next repeat in G91: moved by the axis words, then the polar radius
        lengthened and the angle turned about the origin."""
        a, b = a + step[0], b + step[1]
        if step[2]:
            if a == 0 and b == 0:
                raise BlockError("Incremental motion with polar coordinates is indeterminate when at the origin")
            theta = math.atan2(b, a)
            radius = glibc_hypot(b, a) + step[2]
            a, b = radius * math.cos(theta), radius * math.sin(theta)
        if step[3]:
            if a == 0 and b == 0:
                raise BlockError("Incremental motion with polar coordinates is indeterminate when at the origin")
            theta = math.atan2(b, a) + step[3]
            radius = glibc_hypot(b, a)
            a, b = radius * math.cos(theta), radius * math.sin(theta)
        return a, b

    # -- the moves ---------------------------------------------------------------------------
    def _traverse_normal(self, normal: int, level: float) -> None:
        end = list(self.state.position)
        end[normal] = level
        self.interpreter.emit("STRAIGHT_TRAVERSE", *end)

    def _mover(self, axes: tuple[int, int, int]):
        """``move(name, a, b, c)``: a straight call to the plane's point (a, b) at level c of
        the normal axis, the other axes where they are."""
        emit = self.interpreter.emit
        base = self.state.position
        first, second, normal = axes

        def move(name: str, a: float, b: float, c: float) -> None:
            end = list(base)
            end[first], end[second], end[normal] = a, b, c
            emit(name, *end)
        return move

    def _body(self, motion: int, block: Block, repeat: bool, bottom: float, r: float, clear: float,
              axes: tuple[int, int, int], move):
        """The words the cycle ``motion`` needs, checked and kept as LinuxCNC checks them (after
        the cycle's path mode is set); the cycle at one place, ``cycle(a, b)``, from R down to
        ``bottom`` and back to ``clear`` (levels of the normal axis)."""
        s = self.state
        emit = self.interpreter.emit
        words = block.words
        code = f"g{motion // 10}"
        if motion in DWELL_CYCLES or motion in (G.G74, G.G84):
            p = words.get("p", -1.0)  # LinuxCNC's "no P" is P -1
            if p == -1.0 and not repeat and motion in DWELL_CYCLES:
                raise BlockError(f"Dwell time p word missing with {code}")
            self.p = self.p if p == -1.0 else p
        if motion in PECK_CYCLES:
            q = words.get("q", -1.0)
            if q == -1.0 and not repeat:
                raise BlockError(f"Q word missing with {code}")
            self.q = self.q if q == -1.0 else q
        height = 0.0
        if motion == G.G87:
            if not repeat:
                for letter in "ijk":
                    if letter not in words:
                        raise BlockError(f"{letter.upper()} word missing with g87")
            self.ijk = [words.get(letter, value) for letter, value in zip("ijk", self.ijk)]
            first, second, normal = axes
            height = self.ijk[normal] + (bottom if s.distance == G.G91 else 0.0)
        dwell, delta = self.p, self.q
        direction = s.spindle
        peck_clearance = PECK_CLEARANCE_INCH * (25.4 if s.units == G.G21 else 1.0)

        def spindle_on() -> None:
            emit(SPINDLE_START[direction], 0)

        def turning() -> None:
            if direction == "stop":
                raise BlockError(f"Spindle not turning in {code}")

        def cycle(a: float, b: float) -> None:
            if motion in PECK_CYCLES:
                if delta <= 0.0:
                    raise BlockError("Negative or zero q value used")
                depth = r - delta
                while depth > bottom:
                    move("STRAIGHT_FEED", a, b, depth)
                    if motion == G.G83:  # out to R to clear the chips; G73 only backs off
                        move("STRAIGHT_TRAVERSE", a, b, r)
                    move("STRAIGHT_TRAVERSE", a, b, depth + peck_clearance)
                    depth = depth - delta
                move("STRAIGHT_FEED", a, b, bottom)
                move("STRAIGHT_TRAVERSE", a, b, clear)
            elif motion in (G.G81, G.G82):
                move("STRAIGHT_FEED", a, b, bottom)
                if motion == G.G82:
                    emit("DWELL", dwell)
                move("STRAIGHT_TRAVERSE", a, b, clear)
            elif motion in (G.G74, G.G84):
                self._tap(motion, direction, move, a, b, bottom, clear, dwell)
            elif motion == G.G85:
                move("STRAIGHT_FEED", a, b, bottom)
                move("STRAIGHT_FEED", a, b, r)
                move("STRAIGHT_TRAVERSE", a, b, clear)
            elif motion == G.G86:
                turning()
                move("STRAIGHT_FEED", a, b, bottom)
                emit("DWELL", dwell)
                emit("STOP_SPINDLE_TURNING", 0)
                move("STRAIGHT_TRAVERSE", a, b, clear)
                spindle_on()
            elif motion == G.G87:
                turning()
                first, second, _ = axes
                off_a, off_b = a + self.ijk[first], b + self.ijk[second]
                move("STRAIGHT_TRAVERSE", off_a, off_b, r)
                emit("STOP_SPINDLE_TURNING", 0)
                emit("ORIENT_SPINDLE", 0, 0.0, SPINDLE_ENUM[direction])
                move("STRAIGHT_TRAVERSE", off_a, off_b, bottom)
                move("STRAIGHT_TRAVERSE", a, b, bottom)
                spindle_on()
                move("STRAIGHT_FEED", a, b, height)
                move("STRAIGHT_FEED", a, b, bottom)
                emit("STOP_SPINDLE_TURNING", 0)
                emit("ORIENT_SPINDLE", 0, 0.0, SPINDLE_ENUM[direction])
                move("STRAIGHT_TRAVERSE", off_a, off_b, bottom)
                move("STRAIGHT_TRAVERSE", off_a, off_b, clear)
                move("STRAIGHT_TRAVERSE", a, b, clear)
                spindle_on()
            elif motion == G.G88:  # the operator takes the tool out by hand at the stop
                turning()
                move("STRAIGHT_FEED", a, b, bottom)
                emit("DWELL", dwell)
                emit("STOP_SPINDLE_TURNING", 0)
                emit("PROGRAM_STOP")
                spindle_on()
            else:  # G89
                move("STRAIGHT_FEED", a, b, bottom)
                emit("DWELL", dwell)
                move("STRAIGHT_FEED", a, b, clear)
        return cycle

    def _tap(self, motion: int, direction: str, move, a: float, b: float, bottom: float, clear: float,
             dwell: float) -> None:
        """G84 (right-hand, spindle clockwise) / G74 (left-hand): a floating-chuck tap, in at
        the feed, the spindle reversed for the way out, overrides off meanwhile."""
        emit = self.interpreter.emit
        name = f"G{motion // 10}"
        if direction == "stop":
            raise BlockError(f"Spindle not turning in {name}")
        if direction == "cw" and motion == G.G74:
            raise BlockError("Spindle turning clockwise in G74")
        if direction == "ccw" and motion == G.G84:
            raise BlockError("Spindle turning counterclockwise in G84")
        reverse = "ccw" if direction == "cw" else "cw"
        emit("DISABLE_FEED_OVERRIDE")
        emit("DISABLE_SPEED_OVERRIDE", 0)
        move("STRAIGHT_FEED", a, b, bottom)
        emit("STOP_SPINDLE_TURNING", 0)
        emit(SPINDLE_START[reverse], 0)
        emit("DWELL", dwell)
        move("STRAIGHT_FEED", a, b, clear)
        emit("STOP_SPINDLE_TURNING", 0)
        emit(SPINDLE_START[direction], 0)
        emit("ENABLE_FEED_OVERRIDE")
        emit("ENABLE_SPEED_OVERRIDE", 0)


def _radians(degrees: float) -> float:
    """LinuxCNC's D2R."""
    return degrees * math.pi / 180.0
