"""A whole RS274/NGC program run as LinuxCNC's interpreter runs it, into canonical calls
(:mod:`~cnc_twin.gcode.canon`), checked call for call against LinuxCNC's ``rs274``
(``tests/test_gcode_corpus.py``).

Each line is read (:mod:`~cnc_twin.gcode.blocks`), its parameter settings applied, its codes
sorted into modal groups (:mod:`~cnc_twin.gcode.modal`) and its words checked; then the block
runs in LinuxCNC's order of execution: comment, feed mode, F, S, T, M6 / M61, spindle, coolant,
force-control M codes, dwell, plane, units, cutter radius compensation off, tool length offset,
work system, path control, distance modes, retract mode, G10 / G28 / G30 / G92, motion, stops.
O-word lines go to :mod:`~cnc_twin.gcode.flow`.

What the twin's machine does not have is refused in one line naming it (probing, cutter radius
compensation, canned cycles, threading, lathe modes...), never read differently: the reader
either makes the calls LinuxCNC makes or says why it will not. A refused or wrong program raises
:class:`ProgramError` with the line and LinuxCNC's wording; nothing of it reaches the machine,
because the whole program is read before any motion.
"""

from __future__ import annotations

from dataclasses import dataclass

from cnc_twin.gcode.blocks import Block, BlockError, apply_assignments, read_block
from cnc_twin.gcode.canon import Call
from cnc_twin.gcode.comments import CALLS, read_comment
from cnc_twin.gcode.expressions import INTEGER_TOLERANCE, Parameters
from cnc_twin.gcode.flow import Flow
from cnc_twin.gcode.modal import modal_codes
from cnc_twin.gcode.motion import MotionRunner
from cnc_twin.gcode.source import Source
from cnc_twin.gcode.state import (G92_PARAMETER, HOME_PARAMETERS, SYSTEM_CODES, SYSTEM_PARAMETER, State,
                                  ToolTable)

UNSUPPORTED_MARK = "not supported by cnc-twin"
"""every refusal of a feature the machine does not have says this"""
UNSUPPORTED_G = {
    50: "G5 (cubic spline)", 51: "G5.1 (quadratic spline)", 70: "G7 (lathe diameter mode)",
    330: "G33 (spindle-synchronised motion)", 331: "G33.1 (rigid tapping)", 382: "G38.2 (probing)",
    383: "G38.3 (probing)", 384: "G38.4 (probing)", 385: "G38.5 (probing)", 410: "G41 (cutter radius compensation)",
    411: "G41.1 (cutter radius compensation)", 420: "G42 (cutter radius compensation)",
    421: "G42.1 (cutter radius compensation)", 432: "G43.2 (additional tool length offset)",
    730: "G73 (canned cycle)", 740: "G74 (canned cycle)", 760: "G76 (threading cycle)", 950: "G95 (feed per revolution)",
    960: "G96 (constant surface speed)",
    **{c: f"G{c / 10:g} (lathe cycle)" for c in (700, 710, 711, 712, 720, 721, 722)}, **{c: f"G{c // 10} (canned cycle)" for c in range(810, 900, 10)},
}
"""G codes (tenths) the twin's machine cannot run -> what they are, for the refusal"""
UNSUPPORTED_M = {19: "M19 (spindle orientation)", 48: "M48 (override switches)", 49: "M49 (override switches)",
                 50: "M50 (feed override control)", 51: "M51 (spindle override control)",
                 52: "M52 (adaptive feed)", 53: "M53 (feed stop control)", 62: "M62 (digital output)",
                 63: "M63 (digital output)", 64: "M64 (digital output)", 65: "M65 (digital output)",
                 66: "M66 (input wait)", 67: "M67 (analog output)", 68: "M68 (analog output)",
                 70: "M70 (modal state save)", 71: "M71 (modal state save)", 72: "M72 (modal state restore)",
                 73: "M73 (modal state save)", 61: "M61 (tool number without a change)"}
"""M codes the twin's machine cannot run"""
FORCE_ON, FORCE_OFF = 100, 101
"""the machine's own M codes: M100 P<newtons> switches the grinding-force loop on with that
setpoint, M101 switches it off (LinuxCNC's user M-code range)"""
MOTION_CALLS = frozenset(("STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "ARC_FEED", "NURBS_FEED"))
AXIS_LETTERS = "xyzabc"
MOVE_WORDS = AXIS_LETTERS + "@^"
"""words that make a block move (``@`` / ``^`` polar radius and angle)"""


class ProgramError(ValueError):
    """A program the reader refuses: ``line`` (1-based; 0 for the file as a whole), the message
    in LinuxCNC's wording where it has one, and ``calls`` made before it (for comparisons)."""

    def __init__(self, line: int, message: str, calls: list[Call] | None = None, printed: list[str] | None = None):
        self.line = line
        self.message = message
        self.calls = calls or []
        self.printed = printed or []
        super().__init__(f"line {line}: {message}")


@dataclass
class Reading:
    """A program read whole: its calls in order and what ``(print,...)`` comments printed."""

    calls: list[Call]
    printed: list[str]


class Interpreter:
    """Runs one program; see :func:`read_program`."""

    def __init__(self, source: Source, tools: ToolTable):
        self.source = source
        self.params = Parameters()
        self.state = State(self.params, tools)
        self.flow = Flow(source, self.params)
        self.calls: list[Call] = []
        self.printed: list[str] = []
        self.motion = MotionRunner(self)
        self._line, self._number = 0, None
        self.state.install_live_parameters(lambda: self._line)

    def emit(self, name: str, *values, payload=None) -> None:
        self.calls.append(Call(name, values, self._line, self._number, payload))
        if name in MOTION_CALLS:
            self.state.tool_shift = [0.0] * 6

    # -- the program -------------------------------------------------------------------------
    def run(self) -> Reading:
        self._preamble()
        index = self.source.first
        try:
            while True:
                if index >= self.source.end:
                    if self.source.percent_end:
                        self._line, self._number = 0, None
                        self.emit("FINISH")
                        break
                    self._line = index  # the last line read (a skipped subroutine's endsub too)
                    raise BlockError("File ended with no percent sign or program end")
                self._line, self._number = index + 1, None
                if index in self.source.o_lines:
                    index = self.flow.step(index)
                    continue
                block = read_block(self.source.lines[index], index + 1, self.params)
                if block.o_word is not None:
                    raise BlockError("Unknown control command in o word")
                apply_assignments(block, self.params)
                if self._execute(block):
                    break
                index += 1
        except BlockError as exc:
            line = getattr(exc, "line", self._line)
            self._reset()
            raise ProgramError(line, str(exc), self.calls, self.printed) from None
        self._reset()
        return Reading(self.calls, self.printed)

    def _preamble(self) -> None:
        s = self.state
        self.emit("USE_LENGTH_UNITS", s.units)
        self.emit("SET_G5X_OFFSET", s.system, *s.g5x)
        self.emit("SET_G92_OFFSET", *s.g92)
        self.emit("SET_XY_ROTATION", 0.0)
        self.emit("SET_FEED_REFERENCE", "CANON_XYZ")
        self.emit("ON_RESET")

    def _reset(self) -> None:
        self._line, self._number = 0, None
        self.emit("ON_RESET")
        self.emit("ON_RESET")

    # -- one block ---------------------------------------------------------------------------
    def _execute(self, block: Block) -> bool:
        """Run ``block``; True when it ends the program."""
        if block.number is not None:
            self._number = _n_text(self.source.lines[block.line - 1])
        g, m = modal_codes(block)
        self._refuse_unsupported(block, g, m)
        # axis words move in the current motion mode unless a code of the block owns them
        owned = g.get(0) in (100, 280, 300, 920) or g.get(8) == 431
        motion = g.get(1, self.state.motion if any(a in block.words for a in MOVE_WORDS) and not owned else None)
        self._check_words(block, g, m, motion)
        s = self.state
        if block.comments:
            self._comment(block.comments[-1])
        if 5 in g:
            self._feed_mode(g[5])
        if "f" in block.words:
            s.feed = block.words["f"]
            if s.feed_mode != 930:  # in inverse time each move sets its own rate
                self.emit("SET_FEED_RATE", s.feed)
        if "s" in block.words:
            s.speed = block.words["s"]
            self.emit("SET_SPINDLE_SPEED", s.speed)
        if "t" in block.words:
            self._select_tool(block.words["t"])
        if m.get(6) == 6:
            self.emit("START_CHANGE")
            self.emit("STOP_SPINDLE_TURNING", 0)
            s.spindle = "stop"
            self.emit("CHANGE_TOOL", s.selected_tool)
            s.tool_in_spindle = s.tool_data = s.selected_tool
        elif m.get(6) == 61:
            self._set_tool_number(block)
        if 7 in m:
            self._spindle(m[7])
        if 8 in m:
            self._coolant(m[8])
        if 10 in m:
            self._force_control(m[10], block)
        if g.get(0) == 40:
            self.motion.dwell(block)
        if 2 in g:
            s.plane = g[2]
            self.emit("SELECT_PLANE", g[2])
        if 6 in g:
            s.change_units(g[6])
            self.emit("USE_LENGTH_UNITS", g[6])
        if g.get(7) == 400:
            self.emit("COMMENT", "interpreter: cutter radius compensation off")
        if 8 in g:
            self._tool_length(g[8], block)
        if 12 in g:
            self._work_system(SYSTEM_CODES[g[12]])
        if 13 in g:
            self._path_control(g[13], block)
        if 3 in g and g[3] != s.distance:
            s.distance = g[3]
            self.emit("COMMENT", "interpreter: distance mode changed to " +
                      ("absolute" if g[3] == 900 else "incremental"))
        if 4 in g and g[4] != s.ijk_distance:
            s.ijk_distance = g[4]
            self.emit("COMMENT", "interpreter: IJK distance mode changed to " +
                      ("absolute" if g[4] == 901 else "incremental"))
        # G8 (group 15), radius mode, is what a mill always is: nothing to do (G7 is refused)
        if 10 in g:
            s.retract = g[10]
            self.emit("COMMENT", "interpreter: retract mode set to " + ("old_z" if g[10] == 980 else "r_plane"))
        if g.get(0) in (100, 280, 281, 300, 301, 920, 921, 922, 923):
            self._non_modal(g[0], block)
        if g.get(1) == 800:
            s.motion = 800
            self.emit("COMMENT", "interpreter: motion mode set to none")
        if motion is not None and motion != 800:
            s.motion = motion
            self.motion.move(motion, block, g.get(0) == 530)
        if m.get(6) == 6:
            s.resynchronise()
        return self._stop(m.get(4))

    def _refuse_unsupported(self, block: Block, g: dict[int, int], m: dict[int, int]) -> None:
        for code in g.values():
            if code in UNSUPPORTED_G:
                raise BlockError(f"{UNSUPPORTED_G[code]} is {UNSUPPORTED_MARK}'s machine")
        for code in m.values():
            if code in UNSUPPORTED_M:
                raise BlockError(f"{UNSUPPORTED_M[code]} is {UNSUPPORTED_MARK}'s machine")
            if 100 <= code <= 199 and code not in (FORCE_ON, FORCE_OFF):
                raise BlockError(f"Unknown m code used: M{code}")
        if g.get(0) == 100 and round(block.words.get("l", 0)) not in (2, 20):
            raise BlockError("G10 L1 / L10 / L11 (tool table edits) are not supported by cnc-twin: give tool "
                             "data in the tool table")
        for letter in "uvw":
            if letter in block.words:
                raise BlockError(f"Bad character '{letter}' used")
        if "e" in block.words:
            raise BlockError(f"E word (lathe threading) is {UNSUPPORTED_MARK}'s machine")

    def _check_words(self, block: Block, g: dict[int, int], m: dict[int, int], motion: int | None) -> None:
        words = block.words
        arc = motion in (20, 30)
        g0 = g.get(0)
        user_m = 10 in m
        if ("i" in words or "j" in words) and not arc:
            letter = "I" if "i" in words else "J"
            raise BlockError(f"{letter} word with no G2, G3, G5, G5.1, G10, G33.1, G76, or G87 to use it")
        if "k" in words and not (arc or motion == 62):
            raise BlockError("K word with no G2, G3, G33, G33.1, G76, or G87 to use it")
        if "r" in words and not (arc or g0 == 100 or motion == 62):
            raise BlockError("R word with no g code that uses it")
        if "p" in words and not (arc or g0 in (40, 100) or g.get(13) == 640 or user_m or motion in (52, 62)):
            raise BlockError("P word with no G2 G3 G4 G10 G64 G5 G5.2 G76 G82 G86 G88 G89 or M50 M51 M52 M53 "
                             "M62 M63 M64 M65 M66 M98 or user M code to use it")
        if "q" in words and not (g.get(13) == 640 or g0 == 100 or user_m or m.get(6) == 61 or motion == 62):
            raise BlockError("Q word with no G5, G10, G64, G73, G76, G83, M19, M66, M67, M68 or user M code "
                             "that uses it")
        if "h" in words and g.get(8) != 430:
            raise BlockError("H word with no G43 or G76 to use it")
        if "l" in words and not (g0 == 100 or motion in (52, 62)):
            raise BlockError("L word with no G10, cutter compensation, canned cycle, digital/analog input, M98 "
                             "or NURBS code")
        if "d" in words:
            raise BlockError("D word with no G41, G41.1, G42, G42.1, G71, G71.1, G71.2 or G96 to use it")
        if g0 == 40 and "p" not in words:
            raise BlockError("Dwell time missing with g4")
        if g0 == 530 and motion not in (0, 10):
            raise BlockError("Must use G0 or G1 with G53")
        if g0 == 530 and (g.get(3) == 910 or (3 not in g and self.state.distance == 910)):
            raise BlockError("Cannot use G53 incremental")

    # -- the steps ---------------------------------------------------------------------------
    def _comment(self, text: str) -> None:
        kind, body = read_comment(text, self.params)
        if kind == "comment":
            self.emit("COMMENT", body)
        elif kind == "print":
            self.printed.append(body)
        elif kind == "logclose":
            self.emit("LOGCLOSE")
        else:
            self.emit(CALLS[kind], body)

    def _feed_mode(self, code: int) -> None:
        s = self.state
        if code == 930:
            self.emit("COMMENT", "interpreter: feed mode set to inverse time")
            self.emit("SET_FEED_MODE", 0)
        else:
            self.emit("COMMENT", "interpreter: feed mode set to units per minute")
            self.emit("SET_FEED_MODE", 0)
            s.feed = 0.0
            self.emit("SET_FEED_RATE", 0.0)
        s.feed_mode = code

    def _tool_number(self, value: float) -> int:
        number = round(value)
        if abs(value - number) >= INTEGER_TOLERANCE:
            raise BlockError("Non integer value for integer")
        if number < 0:
            raise BlockError("Negative tool id used")
        if number != 0 and number not in self.state.tools.lengths:
            raise BlockError(f"Requested tool {number} not found in the tool table")
        return number

    def _select_tool(self, value: float) -> None:
        self.state.selected_tool = self._tool_number(value)
        self.emit("SELECT_TOOL", self.state.selected_tool)

    def _set_tool_number(self, block: Block) -> None:
        if "q" not in block.words:
            raise BlockError("Q word missing with M61")
        number = self._tool_number(block.words["q"])
        self.emit("CHANGE_TOOL_NUMBER", number)
        self.state.tool_in_spindle = number

    def _spindle(self, code: int) -> None:
        s = self.state
        if code == 3:
            s.spindle = "cw"
            self.emit("START_SPINDLE_CLOCKWISE", 0)
        elif code == 4:
            s.spindle = "ccw"
            self.emit("START_SPINDLE_COUNTERCLOCKWISE", 0)
        else:
            s.spindle = "stop"
            self.emit("STOP_SPINDLE_TURNING", 0)

    def _coolant(self, code: int) -> None:
        s = self.state
        if code == 7:
            s.mist = True
            self.emit("MIST_ON")
        elif code == 8:
            s.flood = True
            self.emit("FLOOD_ON")
        else:
            s.mist = s.flood = False
            self.emit("MIST_OFF")
            self.emit("FLOOD_OFF")

    def _force_control(self, code: int, block: Block) -> None:
        if code == FORCE_ON:
            if "p" not in block.words or not block.words["p"] > 0:
                raise BlockError("M100 needs P<force setpoint in newtons> greater than 0")
            self.emit("FORCE_CONTROL_ON", block.words["p"])
        else:
            self.emit("FORCE_CONTROL_OFF")

    def _tool_length(self, code: int, block: Block) -> None:
        s = self.state
        offsets = [0.0] * 9
        if code == 430:
            number = s.tool_data if "h" not in block.words else self._tool_number(block.words["h"])
            scale = s.length_scale(s.tools.units)
            for axis, value in enumerate(s.tools.lengths.get(number, (0.0, 0.0, 0.0))):
                offsets[axis] = value * scale
        elif code == 431:
            for axis, letter in enumerate(AXIS_LETTERS):
                offsets[axis] = block.words.get(letter, 0.0)
        s.set_tool_offset(offsets)
        self.emit("USE_TOOL_LENGTH_OFFSET", *offsets)

    def _work_system(self, system: int) -> None:
        s = self.state
        if system == s.system:
            self.emit("COMMENT", "interpreter: continuing to use same coordinate system")
            return
        s.select_system(system)
        self.emit("SET_G5X_OFFSET", system, *s.g5x)
        self.emit("SET_G92_OFFSET", *s.g92)
        self.emit("SET_XY_ROTATION", 0.0)

    def _path_control(self, code: int, block: Block) -> None:
        s = self.state
        if code == 610:
            s.control = ("CANON_EXACT_PATH",)
        elif code == 611:
            s.control = ("CANON_EXACT_STOP",)
        else:
            tolerance = max(block.words.get("p", 0.0), 0.0)
            s.control = ("CANON_CONTINUOUS", tolerance)
        self.emit("SET_MOTION_CONTROL_MODE", *s.control)
        if code == 640:
            self.emit("SET_NAIVECAM_TOLERANCE", block.words.get("q", s.control[1]))

    def _non_modal(self, code: int, block: Block) -> None:
        s = self.state
        words = block.words
        given = [k for k, letter in enumerate(AXIS_LETTERS) if letter in words]
        if code == 100:
            self._g10(block, given)
        elif code in (280, 300):
            self.motion.home(code, block, given)
        elif code in (281, 301):
            base = HOME_PARAMETERS[code - 1]
            for axis in range(6):
                self.params.numbered[base + axis] = s.to_machine(axis, s.position[axis])
        elif code == 920:
            if not given:
                raise BlockError("All axes missing with G92")
            offsets = list(s.g92)
            for axis in given:
                offsets[axis] = s.position[axis] + s.g92[axis] - words[AXIS_LETTERS[axis]]
            s.set_g92(offsets, save=True)
            self.params.numbered[5210] = 1.0
            self.emit("SET_G92_OFFSET", *s.g92)
        elif code in (921, 922):
            s.set_g92([0.0] * 6, save=code == 921)
            if code == 921:
                self.params.numbered[5210] = 0.0
            self.emit("SET_G92_OFFSET", *s.g92)
        elif code == 923:
            s.set_g92([self.params.number(G92_PARAMETER + axis) for axis in range(6)], save=False)
            self.emit("SET_G92_OFFSET", *s.g92)

    def _g10(self, block: Block, given: list[int]) -> None:
        s = self.state
        words = block.words
        if "p" not in words:
            raise BlockError("P word missing with G10")
        system = round(words["p"])
        if abs(words["p"] - system) >= INTEGER_TOLERANCE:
            raise BlockError("Non integer value for integer")
        if not 0 <= system <= 9:
            raise BlockError("P value out of range with G10 L2")
        if words.get("r", 0.0) != 0.0:
            raise BlockError(f"G10 L2 R (rotated work coordinates) is {UNSUPPORTED_MARK}")
        system = system or s.system
        base = SYSTEM_PARAMETER + 20 * system
        for axis in given:
            value = words[AXIS_LETTERS[axis]]
            if round(words["l"]) == 20:
                # L20: the current point becomes `value` in that system
                value = s.position[axis] + s.g5x[axis] - value
            self.params.numbered[base + axis] = value
        if system == s.system:
            s.reload_active_system()
            self.emit("SET_G5X_OFFSET", system, *s.g5x)
            self.emit("SET_XY_ROTATION", 0.0)
        else:
            self.emit("COMMENT", "interpreter: setting coordinate system origin")

    def _stop(self, code: int | None) -> bool:
        if code == 0:
            self.emit("PROGRAM_STOP")
        elif code == 1:
            self.emit("OPTIONAL_PROGRAM_STOP")
        elif code == 60:
            self.emit("PALLET_SHUTTLE")
            self.emit("PROGRAM_STOP")
        elif code in (2, 30):
            self._program_end(code)
            return True
        return False

    def _program_end(self, code: int) -> None:
        s = self.state
        if s.system != 1:
            s.select_system(1)
        self.emit("SET_G5X_OFFSET", 1, *s.g5x)
        self.emit("SET_XY_ROTATION", 0.0)
        if s.plane != 170:
            s.plane = 170
            self.emit("SELECT_PLANE", 170)
        s.distance = 900
        s.feed_mode, s.feed = 940, 0.0
        self.emit("SET_FEED_MODE", 0)
        self.emit("SET_FEED_RATE", 0.0)
        self.emit("STOP_SPINDLE_TURNING", 0)
        s.spindle = "stop"
        self.emit("SET_SPINDLE_MODE", 0.0)
        s.motion = 10
        if s.mist:
            s.mist = False
            self.emit("MIST_OFF")
        if s.flood:
            s.flood = False
            self.emit("FLOOD_OFF")
        if code == 30:
            self.emit("PALLET_SHUTTLE")
        self.emit("PROGRAM_END")


def _n_text(raw: str) -> str:
    """The N word's digits as written (``N0030`` -> ``0030``), for the call lines."""
    text = raw.lstrip(" \t/")[1:]
    digits = []
    for c in text:
        if c.isdigit():
            digits.append(c)
        elif c not in " \t":
            break
    return "".join(digits)


def read_program(source: Source, tools: ToolTable) -> Reading:
    """Run ``source`` with ``tools``; :class:`ProgramError` if it is refused."""
    return Interpreter(source, tools).run()
