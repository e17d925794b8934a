"""A whole RS274/NGC program run as LinuxCNC's interpreter runs it, into canonical calls
(:mod:`~cnc_twin.gcode.canon`), checked call for call against LinuxCNC's ``rs274``
(``tests/test_gcode_corpus.py``).

Each line is read (:mod:`~cnc_twin.gcode.blocks`), its parameter settings applied, its codes
sorted into modal groups (:mod:`~cnc_twin.gcode.modal`) and its words checked
(:mod:`~cnc_twin.gcode.checks`); then the block
runs in LinuxCNC's order of execution: comment, feed mode, F, S, T, M6 / M61, spindle, coolant,
force-control M codes, dwell, plane, units, cutter radius compensation off, tool length offset,
work system, path control, distance modes, retract mode, G10 / G28 / G30 / G92, motion, stops.
O-word lines go to :mod:`~cnc_twin.gcode.flow`.

What the twin's machine does not have is refused in one line naming it (cutter radius compensation,
threading, lathe modes...), never read differently: the reader either makes the calls LinuxCNC makes or
says why it will not. A refused or wrong program raises :class:`~cnc_twin.gcode.outcome.ProgramError`
with the line and LinuxCNC's wording; nothing of it reaches the machine, because the whole program is
read before any motion (its calls handed out in batches as made: :meth:`Interpreter.stream`).
"""

from __future__ import annotations

import bisect
import gc
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

from cnc_twin.gcode.blocks import Block, BlockError, apply_assignments
from cnc_twin.gcode.canon import Call
from cnc_twin.gcode.checks import (AXIS_CODES, AXIS_LETTERS, FORCE_ON, MOVE_WORDS, UNSUPPORTED_MARK,
                                   check_words, refuse_unsupported)
from cnc_twin.gcode.comments import CALLS, read_comment
from cnc_twin.gcode.common_lines import run_common_lines
from cnc_twin.gcode.expressions import INTEGER_TOLERANCE, Parameters
from cnc_twin.gcode.flow import Flow
from cnc_twin.gcode.limits import MAX_CALLS
from cnc_twin.gcode.modal import CANNED_CYCLES, G, GGroup, M, MGroup, modal_codes
from cnc_twin.gcode.motion import MotionRunner
from cnc_twin.gcode.outcome import ProgramError, Reading
from cnc_twin.gcode.probing import Probe, standalone_probe
from cnc_twin.gcode.reading import read_line
from cnc_twin.gcode.source import O_NAME, Source
from cnc_twin.gcode.subfiles import SubroutineFiles
from cnc_twin.gcode.state import ACTIVE_SYSTEM, HOME_PARAMETERS, SYSTEM_CODES, State, ToolTable
from cnc_twin.gcode.tool_edits import TOOL_EDITS, edit_tool_table

MOTION_CALLS = frozenset(("STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "ARC_FEED", "NURBS_FEED"))
PLAIN_WORDS = frozenset(AXIS_LETTERS + "f")
"""a block with no codes, no comment and no words but these only moves in the current mode"""
COMMON_LINES = True
"""run a CAM program's common lines on the fast path (:mod:`~cnc_twin.gcode.common_lines`); off only
in the tests that compare it with the full path"""
NON_MODAL_STEPS = (G.G10, G.G28, G.G28_1, G.G30, G.G30_1, G.G92, G.G92_1, G.G92_2, G.G92_3)
"""the group 0 codes run in the G10 / G28 / G30 / G92 step (G4 and G53 have steps of their own)"""


class Interpreter:
    """Runs one program; see :func:`read_program`."""

    def __init__(self, source: Source, tools: ToolTable, *, start: Sequence[float] | None = None,
                 parameters: Mapping[int, float] | None = None, probe: Probe | None = None,
                 subroutine_path: Sequence[Path] = (), max_calls: int = MAX_CALLS):
        self.probe: Probe = probe or standalone_probe
        self.params = Parameters()
        self.params.numbered.update(parameters or {})
        self.state = State(self.params, tools)
        self.state.begin(start)
        folder = source.path.parent if source.path is not None else None
        self.flow = Flow(source, self.params, files=SubroutineFiles(folder, subroutine_path), max_passes=max_calls)
        self.calls: list[Call] = []
        self.printed: list[str] = []
        self.motion = MotionRunner(self)
        self._line, self._number = 0, None
        self.state.install_live_parameters(lambda: self._line)
        self.max_calls = max_calls

    @property
    def source(self) -> Source:
        """The file being run: the program's, or a subroutine file's while it runs."""
        return self.flow.source

    def at(self, line: int, number: str | None) -> None:
        """The line being run (1-based) and its N word as written: its calls and refusal name them."""
        self._line, self._number = line, number

    def emit(self, name: str, *values, payload=None) -> None:
        self.calls.append(Call(name, values, self._line, self._number, payload))
        if name in MOTION_CALLS:
            self.state.tool_shift = [0.0] * 6

    # -- the program -------------------------------------------------------------------------
    def run(self) -> Reading:
        """The program read whole (:func:`read_program`)."""
        for _ in self.stream(None):
            pass
        return Reading(self.calls, self.printed, self.flow.files.texts())

    def stream(self, batch: int | None):
        """Run the program, handing out its calls as it goes: each time ``batch`` calls or more are
        made, at a line's end, they are yielded (a list) and no longer kept; the rest, at its end, as
        the last list (``batch`` None: all of them, also left in ``calls``). A refused program raises
        :class:`~cnc_twin.gcode.outcome.ProgramError` with the calls made since the last batch."""
        if self.source.too_long[:1] == [0]:  # LinuxCNC reads the first line on opening, before its reset
            self._preamble(opening=True)
            raise ProgramError(1, "Command too long", self.calls, self.printed)
        self._preamble()
        index = self.source.first
        try:
            looped, seen = 0, len(self.calls)  # calls made while a loop was open; calls counted
            while True:
                if self.flow.loops:  # only a loop can run on: a program's own lines end with its file
                    looped += len(self.calls) - seen
                    if looped > self.max_calls:
                        self._runaway()
                if batch is not None and len(self.calls) >= batch:
                    yield self.calls
                    self.calls = []
                seen = len(self.calls)
                if COMMON_LINES:
                    most = self.max_calls + 1 - looped if self.flow.loops else None
                    if batch is not None:  # a line makes a call or a few: the batch stays about its size
                        most = batch if most is None else min(most, batch)
                    index = run_common_lines(self, index, most)
                if index >= self.source.end:
                    if self.source.percent_end:
                        self._line, self._number = 0, None
                        self.emit("FINISH")
                        break
                    self._line = index  # the last line read (a skipped subroutine's endsub too)
                    raise BlockError(self.source.eof_message)
                self._line, self._number = index + 1, None
                self._check_length(index, index + 1)
                if index in self.source.o_lines:
                    after = self.flow.step(index)
                    if isinstance(after, int):  # the lines a jump forward passes over are read too
                        self._check_length(index + 1, after)
                    index = after
                    continue
                block = read_line(self.source, index, self.params, in_call=bool(self.flow.frames))
                if block.o_word is not None:
                    if re.fullmatch(O_NAME, block.o_word):  # "/O0001": a program number, passed over
                        index += 1
                        continue
                    raise BlockError("Unknown control command in o word")
                apply_assignments(block, self.params)
                if self._execute(block):
                    break
                index += 1
        except BlockError as exc:
            line = getattr(exc, "line", self._line)
            self._reset()
            file = None if self.source is self.flow.main else (self.source.path or Path(self.source.name))
            raise ProgramError(line, str(exc), self.calls, self.printed, file) from None
        self._reset()
        yield self.calls

    def _runaway(self) -> None:
        """Refuse a program past ``max_calls`` calls made in loops, at the line of the loop that
        runs on (the innermost open one)."""
        loop = self.flow.loops[-1]
        self._line = loop.start + 1
        raise BlockError(f"more than {self.max_calls} canonical calls in loops: the {loop.kind} loop o{loop.name} here "
                         "runs on (the bound: program.max_calls, gcode --max-calls)")

    def _check_length(self, start: int, stop: int) -> None:
        """Refuse the first line in ``start`` ..< ``stop`` (0-based) that is too long to read."""
        long = self.source.too_long
        k = bisect.bisect_left(long, start)
        if k < len(long) and long[k] < stop:
            self._line = long[k] + 1
            raise BlockError("Command too long")

    def _preamble(self, opening: bool = False) -> None:
        """The calls before the first line; ``opening``: only those made before the file is opened."""
        s = self.state
        self.emit("USE_LENGTH_UNITS", int(s.units))
        self.emit("SET_G5X_OFFSET", s.system, *s.g5x)
        self.emit("SET_G92_OFFSET", *s.g92)
        self.emit("SET_XY_ROTATION", 0.0)
        self.emit("SET_FEED_REFERENCE", "CANON_XYZ")
        if not opening:
            self.emit("ON_RESET")

    def _reset(self) -> None:
        self._line, self._number = 0, None
        self.emit("ON_RESET")
        self.emit("ON_RESET")

    # -- one block ---------------------------------------------------------------------------
    def _execute(self, block: Block) -> bool:
        """Run ``block``; True when it ends the program."""
        if block.number is not None:
            self._number = block.number_text
        if (not (block.g or block.m or block.comments) and PLAIN_WORDS.issuperset(block.words)
                and self.state.motion not in CANNED_CYCLES):  # a cycle's words are checked whole
            return self._plain_move(block)
        g, m = modal_codes(block)
        refuse_unsupported(block, g, m)
        # axis words move in the current motion mode unless a code of the block owns them
        owned = g.get(GGroup.NON_MODAL) in AXIS_CODES or g.get(GGroup.TOOL_LENGTH_OFFSET) == G.G43_1
        motion = g.get(GGroup.MOTION,
                       self.state.motion if any(a in block.words for a in MOVE_WORDS) and not owned else None)
        check_words(block, g, m, motion, self.state)
        s = self.state
        if block.comments:
            self.comment(block.comments[-1])
        if GGroup.FEED_MODE in g:
            self._feed_mode(g[GGroup.FEED_MODE])
        if "f" in block.words and s.feed_mode != G.G93:  # in inverse time each move sets its own rate
            s.feed = block.words["f"]
            self.emit("SET_FEED_RATE", s.feed)
        if "s" in block.words:
            s.speed = block.words["s"]
            self.emit("SET_SPINDLE_SPEED", s.speed)
        if "t" in block.words:
            self._select_tool(block.words["t"])
        if m.get(MGroup.TOOL_CHANGE) == M.M6:
            self.emit("START_CHANGE")
            self.emit("STOP_SPINDLE_TURNING", 0)
            s.spindle = "stop"
            self.emit("CHANGE_TOOL", s.selected_tool)
            if s.selected_tool != 0:  # T0 M6 leaves the last tool's data in rs274's spindle slot
                s.tool_in_spindle = s.tool_data = s.selected_tool
                s.slot_tools = None  # the slot holds the table's entry, G10 L1 edits included
            s.pocket = s.tools.index(s.selected_tool)
        elif m.get(MGroup.TOOL_CHANGE) == M.M61:
            self._set_tool_number(block)
        if MGroup.SPINDLE in m:
            self._spindle(m[MGroup.SPINDLE])
        if MGroup.COOLANT in m:
            self._coolant(m[MGroup.COOLANT])
        if MGroup.USER_DEFINED in m:
            self._force_control(m[MGroup.USER_DEFINED], block)
        if g.get(GGroup.NON_MODAL) == G.G4:
            self.motion.dwell(block)
        if GGroup.SET_PLANE in g:
            s.plane = g[GGroup.SET_PLANE]
            self.emit("SELECT_PLANE", g[GGroup.SET_PLANE])
        if GGroup.LENGTH_UNITS in g:
            s.change_units(g[GGroup.LENGTH_UNITS])
            self.emit("USE_LENGTH_UNITS", g[GGroup.LENGTH_UNITS])
        if g.get(GGroup.CUTTER_COMP) == G.G40:
            self.emit("COMMENT", "interpreter: cutter radius compensation off")
        if GGroup.TOOL_LENGTH_OFFSET in g:
            self._tool_length(g[GGroup.TOOL_LENGTH_OFFSET], block)
        if GGroup.COORD_SYSTEM in g:
            self._work_system(SYSTEM_CODES[g[GGroup.COORD_SYSTEM]])
        if GGroup.CONTROL_MODE in g:
            self._path_control(g[GGroup.CONTROL_MODE], block)
        if GGroup.DISTANCE_MODE in g and g[GGroup.DISTANCE_MODE] != s.distance:
            s.distance = g[GGroup.DISTANCE_MODE]
            self.emit("COMMENT", "interpreter: distance mode changed to " +
                      ("absolute" if g[GGroup.DISTANCE_MODE] == G.G90 else "incremental"))
        if GGroup.IJK_DISTANCE_MODE in g and g[GGroup.IJK_DISTANCE_MODE] != s.ijk_distance:
            s.ijk_distance = g[GGroup.IJK_DISTANCE_MODE]
            self.emit("COMMENT", "interpreter: IJK distance mode changed to " +
                      ("absolute" if g[GGroup.IJK_DISTANCE_MODE] == G.G90_1 else "incremental"))
        # G8 (group 15), radius mode, is what a mill always is: nothing to do (G7 is refused)
        if GGroup.RETRACT_MODE in g:
            s.retract = g[GGroup.RETRACT_MODE]
            self.emit("COMMENT", "interpreter: retract mode set to " +
                      ("old_z" if g[GGroup.RETRACT_MODE] == G.G98 else "r_plane"))
        if g.get(GGroup.NON_MODAL) in NON_MODAL_STEPS:
            self._non_modal(g[GGroup.NON_MODAL], block)
        if g.get(GGroup.MOTION) == G.G80:
            s.motion = G.G80
            self.emit("COMMENT", "interpreter: motion mode set to none")
        if motion is not None and motion != G.G80:
            self.motion.move(motion, block, g.get(GGroup.NON_MODAL) == G.G53)
            s.motion = motion  # after the move, as LinuxCNC: a canned cycle reads the mode before it
        if m.get(MGroup.TOOL_CHANGE) == M.M6:
            s.resynchronise()
        return self._stop(m.get(MGroup.STOPPING))

    def _plain_move(self, block: Block) -> bool:
        """A block of axis words and F only (most of a CAM program): what :meth:`_execute` does
        with it, without the checks that cannot refuse it (no codes, no other words)."""
        s = self.state
        words = block.words
        moving = len(words) > ("f" in words)
        if moving and s.motion == G.G80:
            raise BlockError("Cannot use axis values without a g code that uses them")
        if "f" in words and s.feed_mode != G.G93:  # in inverse time each move sets its own rate
            s.feed = words["f"]
            self.emit("SET_FEED_RATE", s.feed)
        if moving:
            self.motion.move(s.motion, block, False)
        return False

    # -- the steps ---------------------------------------------------------------------------
    def comment(self, text: str) -> None:
        """The step of a block's comment (its last): ``text`` as written, leading spaces dropped."""
        kind, body = read_comment(text, self.params)
        if kind == "comment":
            self.emit("COMMENT", body)
        elif kind == "print":
            self.printed.append(body)
        elif kind == "logclose":
            self.emit("LOGCLOSE")
        elif kind != "silent":
            self.emit(CALLS[kind], body)

    def _feed_mode(self, code: int) -> None:
        s = self.state
        if code == G.G93:
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
        if code == M.M3:
            s.spindle = "cw"
            self.emit("START_SPINDLE_CLOCKWISE", 0)
        elif code == M.M4:
            s.spindle = "ccw"
            self.emit("START_SPINDLE_COUNTERCLOCKWISE", 0)
        else:
            s.spindle = "stop"
            self.emit("STOP_SPINDLE_TURNING", 0)

    def _coolant(self, code: int) -> None:
        s = self.state
        if code == M.M7:
            s.mist = True
            self.emit("MIST_ON")
        elif code == M.M8:
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
        """G43 (H0 or no H: the spindle's tool), G43.1 (the axes not given keep their offset)
        and G49; the tool table's lengths are in machine units."""
        s = self.state
        offsets = [0.0] * 9
        if code == G.G43:
            number = self._tool_number(block.words["h"]) if "h" in block.words else 0
            for axis, value in enumerate(s.tools.offsets(number) if number else s.spindle_offsets()):
                offsets[axis] = s.user_to_program(axis, value)
        elif code == G.G43_1:
            offsets = list(s.tool_offset)
            for axis, letter in enumerate(AXIS_LETTERS):
                offsets[axis] = block.words.get(letter, offsets[axis])
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
        if code == G.G61:
            s.control = ("CANON_EXACT_PATH",)
        elif code == G.G61_1:
            s.control = ("CANON_EXACT_STOP",)
        else:
            tolerance = max(block.words.get("p", 0.0), 0.0)
            s.control = ("CANON_CONTINUOUS", tolerance)
        self.emit("SET_MOTION_CONTROL_MODE", *s.control)
        if code == G.G64:
            s.naivecam = block.words.get("q", s.control[1])
            self.emit("SET_NAIVECAM_TOLERANCE", s.naivecam)

    def _non_modal(self, code: int, block: Block) -> None:
        s = self.state
        words = block.words
        given = {k: words[letter] for k, letter in enumerate(AXIS_LETTERS) if letter in words}
        if code == G.G10:
            self._g10(block, given)
        elif code in (G.G28, G.G30):
            self.motion.home(code, block, list(given))
        elif code in (G.G28_1, G.G30_1):
            s.save_home(HOME_PARAMETERS[code - 1])  # G28.1 -> G28's, G30.1 -> G30's
        elif code == G.G92:
            s.set_g92(given)
            self.emit("SET_G92_OFFSET", *s.g92)
        elif code in (G.G92_1, G.G92_2):
            s.clear_g92(save=code == G.G92_1)
            self.emit("SET_G92_OFFSET", *s.g92)
        elif code == G.G92_3:
            s.restore_g92()
            self.emit("SET_G92_OFFSET", *s.g92)

    def _g10(self, block: Block, given: dict[int, float]) -> None:
        """G10 L2 / L20 (P checked with the block): LinuxCNC truncates P (``P1.5`` is G54); the
        tool table's L0 / L1 / L10 / L11: :mod:`~cnc_twin.gcode.tool_edits`."""
        s = self.state
        words = block.words
        if round(words["l"]) in TOOL_EDITS:
            edit_tool_table(self, block)
            return
        if words.get("r", 0.0) != 0.0:
            raise BlockError(f"G10 L2 R (rotated work coordinates) is {UNSUPPORTED_MARK}")
        system = int(words["p"] + 0.0001) or s.system
        offsets = s.write_system(system, given, relative=round(words["l"]) == 20)
        if system == s.system:
            s.set_active_origin(offsets)
            self.emit("SET_G5X_OFFSET", system, *s.g5x)
            self.emit("SET_XY_ROTATION", 0.0)
        else:
            self.emit("COMMENT", "interpreter: setting coordinate system origin")

    def _stop(self, code: int | None) -> bool:
        if code == M.M0:
            self.emit("PROGRAM_STOP")
        elif code == M.M1:
            self.emit("OPTIONAL_PROGRAM_STOP")
        elif code == M.M60:
            self.emit("PALLET_SHUTTLE")
            self.emit("PROGRAM_STOP")
        elif code in (M.M2, M.M30, M.M99):
            if code == M.M99 and self.flow.frames:  # LinuxCNC's own words (an M99 first on a line: reading.py)
                raise BlockError("Bug:  Reached convert_stop() from M99 as subprogram return")
            self._program_end(code)
            return True
        return False

    def _program_end(self, code: int) -> None:
        s = self.state
        # G54 again, its offsets read anew from #5221.. (even when it is the active system)
        s.system = 1
        self.params.numbered[ACTIVE_SYSTEM] = 1.0
        s.set_active_origin(s.system_offsets(1))
        self.emit("SET_G5X_OFFSET", 1, *s.g5x)
        self.emit("SET_XY_ROTATION", 0.0)
        if s.plane != G.G17:
            s.plane = G.G17
            self.emit("SELECT_PLANE", int(G.G17))
        s.distance = G.G90
        s.feed_mode, s.feed = G.G94, 0.0
        self.emit("SET_FEED_MODE", 0)
        self.emit("SET_FEED_RATE", 0.0)
        self.emit("STOP_SPINDLE_TURNING", 0)
        s.spindle = "stop"
        self.emit("SET_SPINDLE_MODE", 0.0)
        s.motion = G.G1
        if s.mist:
            s.mist = False
            self.emit("MIST_OFF")
        if s.flood:
            s.flood = False
            self.emit("FLOOD_OFF")
        if code == M.M30:
            self.emit("PALLET_SHUTTLE")
        self.emit("PROGRAM_END")
        if self.source.percent_missing_after(self._line - 1):
            self.emit("COMMENT", "interpreter: percent sign missing from end of file")


def read_program(source: Source, tools: ToolTable, *, start: Sequence[float] | None = None,
                 parameters: Mapping[int, float] | None = None, probe: Probe | None = None,
                 subroutine_path: Sequence[Path] = (), max_calls: int = MAX_CALLS) -> Reading:
    """Run ``source`` with ``tools``; :class:`~cnc_twin.gcode.outcome.ProgramError` if it is refused.

    ``parameters``: numbered parameters as LinuxCNC's parameter file (``.var``) holds them at the
    start, in machine units (the work offsets #5221.., the active system #5220, G92's #5210..);
    ``start``: where the machine stands, x y z a b c in machine coordinates and units (LinuxCNC's
    interpreter starts from the machine's position; rs274 alone, and None here, from 0);
    ``probe``: the machine's answer to a G38.n probing move (:data:`~cnc_twin.gcode.probing.Probe`);
    None: rs274's standalone answer (:func:`~cnc_twin.gcode.probing.standalone_probe`). A G10 L1 /
    L10 / L11 edits this reading's copy of ``tools``, never ``tools``. ``subroutine_path``: folders
    a called subroutine's file is looked for in after the program's own (:mod:`~cnc_twin.gcode.subfiles`).
    ``max_calls``: the calls a program may make in its loops before it is refused as one that does
    not end (at the line of its innermost open loop); its own lines, however many, end with its file."""
    interpreter = Interpreter(source, tools, start=start, parameters=parameters, probe=probe,
                              subroutine_path=subroutine_path, max_calls=max_calls)
    # The calls hold no reference cycles; the cyclic collector's passes over their growing list
    # cost a fifth of a long program's reading (measured), so it waits until the program is read.
    paused = gc.isenabled()
    gc.disable()
    try:
        return interpreter.run()
    finally:
        if paused:
            gc.enable()
