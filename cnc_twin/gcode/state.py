"""The interpreter's state between blocks: modes, the current point, coordinate systems, offsets,
tool and spindle, kept as LinuxCNC keeps them.

Lengths are in the program's current units (G20 inch / G21 mm) and are converted, offsets and
their parameters included, when the units change; A B C are degrees. The current point is in
program coordinates: the machine position is the point plus the active work offset
(G54..G59.3), the G92 offset and the tool length offset. Work offsets live in LinuxCNC's
parameters (``#5221`` onwards, 20 per system; ``#5220`` the active system; ``#5211`` the G92
offsets), so programs read and write them as LinuxCNC's do.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from cnc_twin.gcode.expressions import Parameters

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
HOME_PARAMETERS = {280: 5161, 300: 5181}
"""G28 / G30 -> first of their saved positions (machine coordinates)"""
SYSTEM_CODES = {540: 1, 550: 2, 560: 3, 570: 4, 580: 5, 590: 6, 591: 7, 592: 8, 593: 9}
"""G54 .. G59.3 (tenths) -> work system number"""


@dataclass
class ToolTable:
    """Tools by number: ``lengths`` tool -> its length offsets along x y z (in ``units``: 200
    inch, 210 mm: LinuxCNC's machine units), ``diameters`` tool -> diameter."""

    lengths: dict[int, tuple[float, float, float]] = field(default_factory=dict)
    diameters: dict[int, float] = field(default_factory=dict)
    units: int = 210

    @classmethod
    def parse(cls, text: str, units: int = 210) -> "ToolTable":
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
        return table


@dataclass
class State:
    """Everything the next block depends on (see the module docstring for units)."""

    params: Parameters
    tools: ToolTable
    position: list[float] = field(default_factory=lambda: [0.0] * 6)
    units: int = 210
    plane: int = 170
    distance: int = 900
    ijk_distance: int = 911
    feed_mode: int = 940
    feed: float = 0.0
    speed: float = 0.0
    motion: int = 800
    control: tuple = ("CANON_CONTINUOUS", 0.0)
    system: int = 1
    g5x: list[float] = field(default_factory=lambda: [0.0] * 6)
    g92: list[float] = field(default_factory=lambda: [0.0] * 6)
    tool_offset: list[float] = field(default_factory=lambda: [0.0] * 9)
    tool_in_spindle: int = 0
    tool_data: int = 0
    selected_tool: int = 0
    spindle: str = "stop"
    mist: bool = False
    flood: bool = False
    retract: int = 990
    tool_shift: list[float] = field(default_factory=lambda: [0.0] * 6)
    """how far tool length offset changes moved the current point since the last motion call:
    LinuxCNC forgets them after a tool change block (it re-reads the point from its canon)"""

    def __post_init__(self):
        self.params.numbered.setdefault(ACTIVE_SYSTEM, 1.0)

    # -- conversions -------------------------------------------------------------------------
    def length_scale(self, units: int) -> float:
        """Factor from ``units`` (200 / 210) to the program's current units."""
        if units == self.units:
            return 1.0
        return MM_PER_INCH if self.units == 210 else 1.0 / MM_PER_INCH

    def change_units(self, units: int) -> None:
        """G20 / G21: the current point, offsets and their parameters follow into the new units."""
        if units == self.units:
            return
        k = MM_PER_INCH if units == 210 else 1.0 / MM_PER_INCH
        self.units = units
        for vector in (self.position, self.g5x, self.g92):
            for axis in range(LINEAR):
                vector[axis] *= k
        for axis in (0, 1, 2, 6, 7, 8):
            self.tool_offset[axis] *= k
        numbered = self.params.numbered
        for system in range(1, 10):
            for axis in range(LINEAR):
                index = SYSTEM_PARAMETER + 20 * system + axis
                if index in numbered:
                    numbered[index] *= k
        for axis in range(LINEAR):
            if G92_PARAMETER + axis in numbered:
                numbered[G92_PARAMETER + axis] *= k

    # -- work offsets ------------------------------------------------------------------------
    def system_offsets(self, system: int) -> list[float]:
        base = SYSTEM_PARAMETER + 20 * system
        return [self.params.number(base + axis) for axis in range(6)]

    def select_system(self, system: int) -> None:
        """G54 .. G59.3: the current point is re-expressed in the new system."""
        new = self.system_offsets(system)
        for axis in range(6):
            self.position[axis] += self.g5x[axis] - new[axis]
        self.g5x, self.system = new, system
        self.params.numbered[ACTIVE_SYSTEM] = float(system)

    def reload_active_system(self) -> None:
        """After G10 changed the active system's parameters: its offsets take effect."""
        self.select_system(self.system)

    def set_g92(self, offsets: list[float], save: bool) -> None:
        """New G92 offsets; the current point moves with them. ``save`` also writes #5211.."""
        for axis in range(6):
            self.position[axis] += self.g92[axis] - offsets[axis]
        self.g92 = list(offsets)
        if save:
            for axis in range(6):
                self.params.numbered[G92_PARAMETER + axis] = offsets[axis]

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

    def to_machine(self, axis: int, value: float) -> float:
        """A program coordinate of ``axis`` as a machine coordinate (current units)."""
        return value + self.g5x[axis] + self.g92[axis] + self.tool_offset[axis]

    def from_machine(self, axis: int, value: float) -> float:
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
            "_ccomp": lambda: 400.0, "_metric": lambda: float(self.units == 210),
            "_imperial": lambda: float(self.units == 200), "_absolute": lambda: float(self.distance == 900),
            "_incremental": lambda: float(self.distance == 910),
            "_inverse_time": lambda: float(self.feed_mode == 930),
            "_units_per_minute": lambda: float(self.feed_mode == 940), "_units_per_rev": lambda: 0.0,
            "_coord_system": lambda: float(next(c for c, n in SYSTEM_CODES.items() if n == self.system)),
            "_tool_offset": lambda: float(any(self.tool_offset)),
            "_retract_r_plane": lambda: float(self.retract == 990), "_retract_old_z": lambda: float(self.retract == 980),
            "_spindle_rpm_mode": lambda: 1.0, "_spindle_css_mode": lambda: 0.0,
            "_ijk_absolute_mode": lambda: float(self.ijk_distance == 901), "_lathe_diameter_mode": lambda: 0.0,
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
            numbered[5401 + axis] = lambda k=axis: self.tool_offset[k]
        numbered[5400] = lambda: float(self.tool_in_spindle)
