"""Canonical machine calls: what the reader makes of a program, in the text form of LinuxCNC's
``rs274 -g`` so the two can be diffed line for line.

A :class:`Call` keeps its arguments as values (program units: mm or inch as the program's
G20 / G21 says, degrees for A B C) and formats them only when printed: four decimals for
positions, feeds, times and offsets, six for the path tolerance, as rs274 prints them. The twin
reads the same calls (:mod:`~cnc_twin.gcode.toolpath`), so what a user diffs is what runs.
"""

from __future__ import annotations

from cnc_twin.gcode.arcs import arc_feed_text
from cnc_twin.gcode.modal import G

PLANES = {G.G17: "CANON_PLANE_XY", G.G18: "CANON_PLANE_XZ", G.G19: "CANON_PLANE_YZ",
          # the UVW machine's planes: rs274 prints them as unknown (this machine has no U V W)
          G.G17_1: "CANON_PLANE_UNKNOWN", G.G18_1: "CANON_PLANE_UNKNOWN", G.G19_1: "CANON_PLANE_UNKNOWN"}
"""G17 / G18 / G19 (tenths) -> rs274's plane name"""
UNITS = {G.G20: "CANON_UNITS_INCHES", G.G21: "CANON_UNITS_MM"}
"""G20 / G21 (tenths) -> rs274's unit name"""


_F4_TEXTS = tuple(", ".join(["%.4f"] * n) for n in range(10))
"""n values with four decimals, one format for the lot (``%.4f`` prints as ``{:.4f}``)"""


def _f4(values) -> str:
    if len(values) < len(_F4_TEXTS):
        return _F4_TEXTS[len(values)] % tuple(values)
    return ", ".join(f"{v:.4f}" for v in values)


def _quoted(values) -> str:
    return f'"{values[0]}"'


def _plain(values) -> str:
    return ", ".join(str(v) for v in values)


_FORMATS = {
    "STRAIGHT_TRAVERSE": _f4,
    "STRAIGHT_FEED": _f4,
    "STRAIGHT_PROBE": _f4,
    # tool index, tool number, the nine offsets (machine units), front and back angles, orientation
    "SET_TOOL_TABLE_ENTRY": lambda v: f"{v[0]}, {v[1]}, " + " ".join(f"{x:.4f}" for x in v[2:11])
                                      + f", {v[11]:.4f}, {v[12]:.4f}, {v[13]}",
    "SET_FEED_RATE": _f4,
    "DWELL": _f4,
    "SET_XY_ROTATION": _f4,
    "SET_NAIVECAM_TOLERANCE": _f4,
    "SET_G92_OFFSET": _f4,
    "SET_G5X_OFFSET": lambda v: f"{v[0]}, " + _f4(v[1:]),
    "USE_LENGTH_UNITS": lambda v: UNITS[v[0]],
    "SELECT_PLANE": lambda v: PLANES[v[0]],
    "SET_MOTION_CONTROL_MODE": lambda v: v[0] if len(v) == 1 else f"{v[0]}, {v[1]:.6f}",
    "SET_SPINDLE_SPEED": lambda v: f"0, {v[0]:.4f}",
    "SET_SPINDLE_MODE": lambda v: f"0 {v[0]:.4f}",
    "ORIENT_SPINDLE": lambda v: f"{v[0]}, {v[1]:.4f}, {v[2]}",
    "SET_FEED_MODE": lambda v: f"0, {v[0]}",
    "USE_TOOL_LENGTH_OFFSET": lambda v: ", ".join(" ".join(f"{x:.4f}" for x in v[k:k + 3]) for k in (0, 3, 6)),
    "COMMENT": _quoted,
    "MESSAGE": _quoted,
    "LOG": _quoted,
    "LOGOPEN": _quoted,
    "LOGAPPEND": _quoted,
}
"""call name -> its arguments' text; names absent here print their values plainly"""


class Call:
    """One canonical call (a value: compared field by field, never changed once made).

    ``name``: rs274's name; ``values``: the arguments (see ``_FORMATS`` for each name's
    form); ``line``: the program line (1-based) that made it, 0 for the interpreter's own
    start-up calls; ``number``: the block's N word as written (``"0030"``), or None;
    ``payload``: what the twin needs beyond the printed text (an arc's or a curve's geometry).

    Slots, not a dataclass's dictionary: a program makes a call a line, and a call's dictionary
    was half its memory (about 300 of 610 bytes); filled in directly, as a frozen dataclass's
    ``object.__setattr__`` per field costs twice as much.
    """

    __slots__ = ("name", "values", "line", "number", "payload")

    def __init__(self, name: str, values: tuple = (), line: int = 0, number: str | None = None, payload: object = None):
        self.name = name
        self.values = values
        self.line = line
        self.number = number
        self.payload = payload

    def _key(self) -> tuple:
        return (self.name, self.values, self.line, self.number, self.payload)

    def __eq__(self, other: object) -> bool:
        if other.__class__ is not Call:
            return NotImplemented
        return self._key() == other._key()

    def __hash__(self) -> int:
        return hash(self._key())

    def __repr__(self) -> str:
        return (f"Call(name={self.name!r}, values={self.values!r}, line={self.line!r}, number={self.number!r}, "
                f"payload={self.payload!r})")

    @property
    def arguments(self) -> str:
        """The text between the parentheses, as rs274 prints it."""
        if self.name == "ARC_FEED":
            return arc_feed_text(self.payload, *self.values)
        if self.name == "NURBS_FEED":
            return self.payload.canon_text()
        return _FORMATS.get(self.name, _plain)(self.values)

    def text(self, sequence: int) -> str:
        """The whole line as ``rs274 -g`` prints it, ``sequence`` being the call's 1-based count."""
        number = "....." if self.number is None else self.number
        name = self.name
        whole = _LINE_TEXTS.get(name)
        if whole is not None and len(self.values) == 6:  # most of a program's lines: one format
            return whole % (sequence, number, *self.values)
        if name == "ARC_FEED":  # CAM's other common line: one format too when no value is NaN
            m = self.payload
            values = (m.first_end, m.second_end, m.first_center, m.second_center, m.rotation, m.axis_end,
                      *self.values)
            total = sum(values)
            if total == total:  # (NaN, or inf - inf, compares unequal)
                return _ARC_LINE % (sequence, number, *values)
        return f"{sequence:5d} N{number:<5} {name}({self.arguments})"


_LINE_TEXTS = {name: f"%5d N%-5s {name}({_F4_TEXTS[6]})" for name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED")}
"""the whole printed line of a straight move (``%-5s`` pads as ``:<5``, ``%5d`` as ``:5d``)"""
_ARC_LINE = "%5d N%-5s ARC_FEED(%.4f, %.4f, %.4f, %.4f, %d, %.4f, %.4f, %.4f, %.4f)"
"""the whole printed line of an arc (:func:`~cnc_twin.gcode.arcs.arc_feed_text`'s format)"""
