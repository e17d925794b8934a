"""The interpreter's state between blocks: modes, the current point, coordinate systems, offsets,
tool and spindle, kept as LinuxCNC keeps them.

Lengths are in the program's current units (G20 inch / G21 mm) and are converted when the
units change; A B C are degrees. The current point is in program coordinates: the machine
position is the point plus the active work offset (G54..G59.3), the G92 offset and the tool
length offset. Work offsets live in LinuxCNC's parameters (``#5221`` onwards, 20 per system;
``#5220`` the active system; ``#5211`` the G92 offsets; ``#5161`` / ``#5181`` the G28 / G30
positions), kept as LinuxCNC keeps them in the machine's units (the tool table's: inches for
rs274) whatever the program's, and converted on every read and write by the codes that use them;
a program that sets one directly sets it in machine units, as in LinuxCNC. The tool length
offset keeps its number across G20 / G21, as LinuxCNC's does.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from cnc_twin.gcode.comments import DEBUG_SWITCH
from cnc_twin.gcode.expressions import Parameters
from cnc_twin.gcode.modal import G

MM_PER_INCH = 25.4
AXES = "xyzabc"
"""the machine's axes, in the order of every position call"""
LINEAR = 3
"""the first LINEAR axes are lengths (converted with the units), the others angles"""
SYSTEM_PARAMETER = 5201
"""#(5201 + 20 n) + k: work offset k (0 x .. 5 c) of system n (1 G54 .. 9 G59.3); #5210 + 20 n is its R"""
ACTIVE_SYSTEM = 5220
"""parameter holding the active work system's number"""
G92_PARAMETER = 5211
"""#5211 .. #5216: the saved G92 offsets"""
G92_ENABLED = 5210
HOME_PARAMETERS = {G.G28: 5161, G.G30: 5181}
"""G28 / G30 -> first of their saved positions (machine coordinates)"""
EXTERNAL_LENGTH_UNITS = {G.G20: 0.03937007874016, G.G21: 1.0}
"""the machine's units (the tool table's: 200 inch, 210 mm) -> LinuxCNC's external length units
(machine units per mm)"""
SYSTEM_CODES = {G.G54: 1, G.G55: 2, G.G56: 3, G.G57: 4, G.G58: 5, G.G59: 6, G.G59_1: 7, G.G59_2: 8, G.G59_3: 9}
"""G54 .. G59.3 (tenths) -> work system number"""


@dataclass
class ToolTable:
    """Tools by number, in the table's order: ``lengths`` tool -> its length offsets along x y z
    (in ``units``: 200 inch, 210 mm: LinuxCNC's machine units), ``diameters`` tool -> diameter,
    ``angles`` tool -> its A B C offsets (degrees; none: 0), ``shapes`` tool -> its lathe data
    (front angle, back angle, orientation; none: 0, 0, 0), kept to be printed as rs274 prints
    a tool table entry. A program's G10 L1 / L10 / L11 edits a copy (:meth:`with_tool`)."""

    lengths: dict[int, tuple[float, float, float]] = field(default_factory=dict)
    diameters: dict[int, float] = field(default_factory=dict)
    units: int = G.G21
    angles: dict[int, tuple[float, float, float]] = field(default_factory=dict)
    shapes: dict[int, tuple[float, float, int]] = field(default_factory=dict)

    def index(self, number: int) -> int:
        """LinuxCNC's index of tool ``number``: its place in the table from 1 (0: tool 0, the
        spindle's own slot); the tool must be in the table."""
        return 0 if number == 0 else list(self.lengths).index(number) + 1

    def offsets(self, number: int) -> tuple[float, ...]:
        """Tool ``number``'s x y z (machine units) and a b c (degrees) offsets; zeros for a tool
        not in the table."""
        return self.lengths.get(number, (0.0, 0.0, 0.0)) + self.angles.get(number, (0.0, 0.0, 0.0))

    def with_tool(self, number: int, offsets, diameter: float, shape: tuple[float, float, int]) -> "ToolTable":
        """A copy with tool ``number``'s entry (in the table already, keeping its place) replaced."""
        table = ToolTable(dict(self.lengths), dict(self.diameters), self.units, dict(self.angles), dict(self.shapes))
        table.lengths[number] = tuple(offsets[:3])
        table.angles[number] = tuple(offsets[3:6])
        table.diameters[number] = diameter
        table.shapes[number] = shape
        return table

    @classmethod
    def parse(cls, text: str, units: int = G.G21) -> "ToolTable":
        """A LinuxCNC tool table's text (``T1 P1 Z0.511 D0.125`` lines; ``;`` starts a remark)."""
        table = cls(units=units)
        for raw in text.splitlines():
            words = raw.split(";")[0].split()
            if not words:
                continue
            values = {w[0].lower(): w[1:] for w in words}
            number = int(values["t"])
            table.lengths[number] = tuple(float(values.get(axis, 0.0)) for axis in "xyz")
            table.diameters[number] = float(values.get("d", 0.0))
            if any(axis in values for axis in "abc"):
                table.angles[number] = tuple(float(values.get(axis, 0.0)) for axis in "abc")
            if any(letter in values for letter in "ijq"):
                table.shapes[number] = (float(values.get("i", 0.0)), float(values.get("j", 0.0)),
                                        int(float(values.get("q", 0))))
        return table


@dataclass
class State:
    """Everything the next block depends on (see the module docstring for units)."""

    params: Parameters
    tools: ToolTable
    position: list[float] = field(default_factory=lambda: [0.0] * 6)
    units: int = G.G21
    plane: int = G.G17
    distance: int = G.G90
    ijk_distance: int = G.G91_1
    feed_mode: int = G.G94
    feed: float = 0.0
    speed: float = 0.0
    motion: int = G.G80
    control: tuple = ("CANON_CONTINUOUS", 0.0)
    naivecam: float = 0.0
    """the path tolerance of the last G64 (its Q, else its P): a canned cycle gives it back to
    the canon with the path mode it restores"""
    system: int = 1
    g5x: list[float] = field(default_factory=lambda: [0.0] * 6)
    g92: list[float] = field(default_factory=lambda: [0.0] * 6)
    tool_offset: list[float] = field(default_factory=lambda: [0.0] * 9)
    tool_in_spindle: int = 0
    tool_data: int = 0
    """the tool whose table data is in rs274's spindle slot (what G43 without H, and G43 H0,
    apply): the last tool M6 loaded other than 0, since T0 M6 leaves the slot as it was"""
    pocket: int = 1
    """rs274's current pocket: the table index (:meth:`ToolTable.index`) of the tool the last M6
    loaded (0 after T0 M6); 1 before any, as rs274's standalone canon starts with slot 1 active.
    A G10 L1 / L10 / L11 of the tool at this index copies it into the spindle slot too"""
    slot_tools: ToolTable | None = None
    """the table the spindle slot's data (tool ``tool_data``) was copied from, when a G10 L1 /
    L10 / L11 has edited that tool's entry since without copying it to the slot; None: ``tools``"""
    selected_tool: int = 0
    spindle: str = "stop"
    mist: bool = False
    flood: bool = False
    retract: int = G.G99
    tool_shift: list[float] = field(default_factory=lambda: [0.0] * 6)
    """how far tool length offset changes moved the current point since the last motion call:
    LinuxCNC forgets them after a tool change block (it re-reads the point from its canon)"""

    def __post_init__(self):
        self.params.numbered.setdefault(ACTIVE_SYSTEM, 1.0)
        self.params.numbered.setdefault(DEBUG_SWITCH, 1.0)

    # -- conversions -------------------------------------------------------------------------
    @property
    def unit_factor(self) -> float:
        """mm per program unit (LinuxCNC's FROM_PROG_LEN factor)."""
        return MM_PER_INCH if self.units == G.G20 else 1.0

    @property
    def external_units(self) -> float:
        """Machine units per mm: LinuxCNC's GET_EXTERNAL_LENGTH_UNITS (rs274 writes 1/25.4 to 14
        decimals, so an inch value in a G20 program comes back 6e-14 off)."""
        return EXTERNAL_LENGTH_UNITS[self.tools.units]

    def user_to_program(self, axis: int, value: float) -> float:
        """A length in machine units (a parameter's, a tool table's) in program units, in
        LinuxCNC's order of operations (USER_TO_PROGRAM_LEN); angles are not converted."""
        if axis >= LINEAR:
            return value
        return value / self.external_units / self.unit_factor

    def program_to_user(self, axis: int, value: float) -> float:
        """A length in program units in machine units (PROGRAM_TO_USER_LEN)."""
        if axis >= LINEAR:
            return value
        return value * self.unit_factor * self.external_units

    def change_units(self, units: int) -> None:
        """G20 / G21: the current point and the active offsets follow into the new units. The
        offset parameters stay in machine units; the tool length offset keeps its number (LinuxCNC
        re-reads it from its canon, which does not convert it); the canon's own point, which
        ``tool_shift`` measures against, is converted."""
        if units == self.units:
            return
        k = MM_PER_INCH if units == G.G21 else 1.0 / MM_PER_INCH
        self.units = units
        for vector in (self.position, self.g5x, self.g92, self.tool_shift):
            for axis in range(LINEAR):
                vector[axis] *= k

    # -- the start ---------------------------------------------------------------------------
    def begin(self, start: Sequence[float] | None) -> None:
        """The state a program starts in, as LinuxCNC's interpreter takes it from its parameter
        file and its machine when it opens a program: the active system (#5220) with its offsets,
        the saved G92 offsets when #5210 is set, and the current point where the machine stands:
        ``start`` (x y z a b c in machine coordinates and machine units; everywhere 0 when None,
        where rs274 alone starts) less those offsets, in program units."""
        self.system = round(self.params.number(ACTIVE_SYSTEM))
        self.g5x = self.system_offsets(self.system)
        self.g92 = self.stored_g92() if self.params.number(G92_ENABLED) else [0.0] * 6
        machine = [self.user_to_program(axis, value) for axis, value in enumerate(start or [0.0] * 6)]
        self.position = [machine[axis] - self.g5x[axis] - self.g92[axis] for axis in range(6)]

    # -- work offsets ------------------------------------------------------------------------
    def system_offsets(self, system: int) -> list[float]:
        """System ``system``'s offsets from its parameters, in program units."""
        base = SYSTEM_PARAMETER + 20 * system
        return [self.user_to_program(axis, self.params.number(base + axis)) for axis in range(6)]

    def stored_g92(self) -> list[float]:
        """The G92 offsets saved in #5211.., in program units."""
        return [self.user_to_program(axis, self.params.number(G92_PARAMETER + axis)) for axis in range(6)]

    def point_in_system(self, system: int) -> list[float]:
        """The current point as system ``system`` would have it: LinuxCNC's
        find_current_in_system, which takes the G92 offsets from their parameters when #5210 is
        set, in its order of operations."""
        new = self.system_offsets(system)
        stored = self.stored_g92() if self.params.number(G92_ENABLED) else None
        point = []
        for axis in range(6):
            value = self.position[axis] + self.g92[axis] + self.g5x[axis] - new[axis]
            if stored is not None:
                value -= stored[axis]
            point.append(value)
        return point

    def select_system(self, system: int) -> None:
        """G54 .. G59.3: the current point is re-expressed in the new system."""
        self.position = self.point_in_system(system)
        self.g5x, self.system = self.system_offsets(system), system
        self.params.numbered[ACTIVE_SYSTEM] = float(system)

    def set_active_origin(self, offsets: list[float]) -> None:
        """New offsets of the active system (G10 for it, M2's return to G54): the point moves
        with them."""
        for axis in range(6):
            self.position[axis] = self.position[axis] + self.g5x[axis] - offsets[axis]
        self.g5x = list(offsets)

    def write_system(self, system: int, words: dict[int, float], relative: bool) -> list[float]:
        """G10 L2 (``relative`` False) / L20: the given axes of system ``system`` set, written
        to its parameters in machine units; its offsets (program units) returned."""
        base = SYSTEM_PARAMETER + 20 * system
        current = self.point_in_system(system) if relative else None
        offsets = []
        for axis in range(6):
            stored = self.user_to_program(axis, self.params.number(base + axis))
            if axis in words:
                value = words[axis]
                if relative:  # L20: the current point becomes `value` in that system
                    value = current[axis] + stored - value
                self.params.numbered[base + axis] = self.program_to_user(axis, value)
                offsets.append(value)
            else:
                offsets.append(stored)
        return offsets

    def set_g92(self, words: dict[int, float]) -> None:
        """G92: the current point takes the given values exactly; all offsets are saved."""
        self.params.numbered[G92_ENABLED] = 1.0
        for axis, value in words.items():
            self.g92[axis] = self.position[axis] + self.g92[axis] - value
            self.position[axis] = value
        for axis in range(6):
            self.params.numbered[G92_PARAMETER + axis] = self.program_to_user(axis, self.g92[axis])

    def clear_g92(self, save: bool) -> None:
        """G92.1 (``save``: the parameters are zeroed too) / G92.2."""
        self.params.numbered[G92_ENABLED] = 0.0
        for axis in range(6):
            self.position[axis] = self.position[axis] + self.g92[axis]
        self.g92 = [0.0] * 6
        if save:
            for axis in range(6):
                self.params.numbered[G92_PARAMETER + axis] = 0.0

    def restore_g92(self) -> None:
        """G92.3: the offsets saved in the parameters apply again."""
        self.params.numbered[G92_ENABLED] = 1.0
        stored = self.stored_g92()
        for axis in range(6):
            self.position[axis] = self.position[axis] + self.g92[axis] - stored[axis]
        self.g92 = stored

    # -- G28 / G30 positions -----------------------------------------------------------------
    def save_home(self, base: int) -> None:
        """G28.1 / G30.1: the machine position into #base.., in machine units."""
        for axis in range(6):
            machine = self.position[axis] + self.tool_offset[axis] + self.g5x[axis] + self.g92[axis]
            self.params.numbered[base + axis] = self.program_to_user(axis, machine)

    def home(self, base: int, axis: int) -> float:
        """The stored position #base.. of ``axis`` in program coordinates."""
        return self.from_machine(axis, self.user_to_program(axis, self.params.number(base + axis)))

    # -- tool length offsets -----------------------------------------------------------------
    def tool_lengths(self, number: int) -> tuple[float, float, float]:
        """Tool ``number``'s x y z lengths in the table (machine units); none for tool 0."""
        return self.tools.lengths.get(number, (0.0, 0.0, 0.0))

    def spindle_offsets(self) -> tuple[float, ...]:
        """The spindle slot's x y z (machine units) and a b c offsets: what G43 without H (or
        H0) applies and #5401.. read."""
        return (self.slot_tools or self.tools).offsets(self.tool_data)

    def spindle_diameter(self) -> float:
        """The spindle slot's tool diameter (machine units), #5410."""
        return (self.slot_tools or self.tools).diameters.get(self.tool_data, 0.0)

    def set_tool_offset(self, offsets: list[float]) -> None:
        """G43 / G43.1 / G49: the tool tip's program position moves with the offset."""
        for axis in range(6):
            self.position[axis] += self.tool_offset[axis] - offsets[axis]
            self.tool_shift[axis] += self.tool_offset[axis] - offsets[axis]
        self.tool_offset = list(offsets)

    def resynchronise(self) -> None:
        """After a tool change block: the point as the last motion left it, as LinuxCNC re-reads
        it from its canon (a G43 in the same block as M6 therefore moves nothing)."""
        for axis in range(6):
            self.position[axis] -= self.tool_shift[axis]
        self.tool_shift = [0.0] * 6

    def from_machine(self, axis: int, value: float) -> float:
        """A machine coordinate of ``axis`` (program units) as a program coordinate."""
        return value - self.g5x[axis] - self.g92[axis] - self.tool_offset[axis]

    # -- read-only parameters ----------------------------------------------------------------
    def install_live_parameters(self, line) -> None:
        """LinuxCNC's read-only parameters, computed from this state when a program reads them:
        ``#<_x>`` .. ``#<_c>`` and ``#5420`` .. the current point, ``#<_metric>``, ``#<_feed>``,
        ``#5400`` the tool... ``line`` gives the line being run (``#<_line>``)."""
        named = self.params.live_named
        numbered = self.params.live_numbered
        flags = {
            "_vmajor": lambda: 2.9, "_vminor": lambda: 0.0, "_line": lambda: float(line()),
            "_motion_mode": lambda: float(self.motion), "_plane": lambda: float(self.plane),
            "_ccomp": lambda: float(G.G40), "_metric": lambda: float(self.units == G.G21),
            "_imperial": lambda: float(self.units == G.G20), "_absolute": lambda: float(self.distance == G.G90),
            "_incremental": lambda: float(self.distance == G.G91),
            "_inverse_time": lambda: float(self.feed_mode == G.G93),
            "_units_per_minute": lambda: float(self.feed_mode == G.G94), "_units_per_rev": lambda: 0.0,
            "_coord_system": lambda: float(next(c for c, n in SYSTEM_CODES.items() if n == self.system)),
            "_tool_offset": lambda: float(any(self.tool_offset)),
            "_retract_r_plane": lambda: float(self.retract == G.G99),
            "_retract_old_z": lambda: float(self.retract == G.G98),
            "_spindle_rpm_mode": lambda: 1.0, "_spindle_css_mode": lambda: 0.0,
            "_ijk_absolute_mode": lambda: float(self.ijk_distance == G.G90_1), "_lathe_diameter_mode": lambda: 0.0,
            "_lathe_radius_mode": lambda: 1.0, "_spindle_on": lambda: float(self.spindle != "stop"),
            "_spindle_cw": lambda: float(self.spindle == "cw"), "_mist": lambda: float(self.mist),
            "_flood": lambda: float(self.flood), "_speed_override": lambda: 1.0, "_feed_override": lambda: 1.0,
            "_adaptive_feed": lambda: 0.0, "_feed_hold": lambda: 1.0, "_feed": lambda: self.feed,
            "_rpm": lambda: self.speed, "_current_tool": lambda: float(self.tool_in_spindle),
            "_selected_tool": lambda: float(self.selected_tool),
        }
        named.update(flags)
        for axis, letter in enumerate("xyzabcuvw"):
            position = (lambda k=axis: self.position[k]) if axis < 6 else (lambda: 0.0)
            named[f"_{letter}"] = position
            numbered[5420 + axis] = position
            # the spindle's tool as the table has it (machine units), not the offset in use
            numbered[5401 + axis] = (lambda k=axis: self.spindle_offsets()[k]) if axis < 6 else (lambda: 0.0)
        numbered[5400] = lambda: float(self.tool_in_spindle)
        numbered[5410] = self.spindle_diameter
        for index in range(5411, 5414):  # front and back angles, orientation: a mill's are 0
            numbered[index] = lambda: 0.0
