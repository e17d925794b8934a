"""G and M codes of a block sorted into LinuxCNC's modal groups, refused as it refuses them.

A code is kept in tenths (``G5.2`` is 52, ``G61.1`` is 611). A block may hold at most one code
of each group (``G80`` may share group 1 with another motion code, which then applies) and at
most four M codes. The messages are LinuxCNC's, checked against its interpreter
(``tests/test_gcode_modal.py``).

The groups and the codes the reader tests by number are named: :class:`GGroup` and
:class:`MGroup` (rs274ngc's ``GM_...`` modal groups and its M groups), :class:`G` (G codes in
tenths: ``G.G80`` is 800, ``G.G61_1`` is 611) and :class:`M`. All four are ``IntEnum``
classes: a member equals, and hashes as, its plain number, so :func:`modal_codes`'s dicts (keyed
by group members, holding plain ints) are looked up with either.
"""

from __future__ import annotations

import enum

from cnc_twin.gcode.blocks import Block, BlockError


class GGroup(enum.IntEnum):
    """LinuxCNC's G modal groups (rs274ngc's ``GM_...``; 9 and 11 are unused)."""

    NON_MODAL = 0  # GM_MODAL_0: G4, G10, G28, G30, G52, G53, G92...
    MOTION = 1  # G0, G1, G2, G3, G5.2, G33, G38.n, G73, G80..G89...
    SET_PLANE = 2  # G17 .. G19.1
    DISTANCE_MODE = 3  # G90 / G91
    IJK_DISTANCE_MODE = 4  # G90.1 / G91.1 (arc centres)
    FEED_MODE = 5  # G93 / G94 / G95
    LENGTH_UNITS = 6  # G20 / G21
    CUTTER_COMP = 7  # G40 / G41 / G42 (.1)
    TOOL_LENGTH_OFFSET = 8  # G43 / G43.1 / G43.2 / G49
    RETRACT_MODE = 10  # G98 / G99 (canned-cycle return)
    COORD_SYSTEM = 12  # G54 .. G59.3
    CONTROL_MODE = 13  # G61 / G61.1 / G64 (path control)
    SPINDLE_MODE = 14  # G96 / G97
    LATHE_DIAMETER_MODE = 15  # G7 / G8


class MGroup(enum.IntEnum):
    """LinuxCNC's M modal groups (the indices of rs274ngc's ``m_modes``)."""

    STOPPING = 4  # M0, M1, M2, M30, M60
    IO = 5  # M62 .. M68 (digital / analog I/O)
    TOOL_CHANGE = 6  # M6, M61
    SPINDLE = 7  # M3, M4, M5, M19, M70 .. M73
    COOLANT = 8  # M7, M8, M9
    OVERRIDES = 9  # M48 .. M53
    USER_DEFINED = 10  # M100 .. M199


class G(enum.IntEnum):
    """The G codes (in tenths) the reader tests by number."""

    G0 = 0
    G1 = 10
    G2 = 20
    G3 = 30
    G4 = 40
    G5_2 = 52
    G5_3 = 53
    G6_2 = 62
    G10 = 100
    G17 = 170
    G17_1 = 171
    G18 = 180
    G18_1 = 181
    G19 = 190
    G19_1 = 191
    G20 = 200
    G21 = 210
    G28 = 280
    G28_1 = 281
    G30 = 300
    G30_1 = 301
    G38_2 = 382
    G38_3 = 383
    G38_4 = 384
    G38_5 = 385
    G40 = 400
    G43 = 430
    G43_1 = 431
    G49 = 490
    G52 = 520
    G53 = 530
    G54 = 540
    G55 = 550
    G56 = 560
    G57 = 570
    G58 = 580
    G59 = 590
    G59_1 = 591
    G59_2 = 592
    G59_3 = 593
    G61 = 610
    G61_1 = 611
    G64 = 640
    G73 = 730
    G74 = 740
    G80 = 800
    G81 = 810
    G82 = 820
    G83 = 830
    G84 = 840
    G85 = 850
    G86 = 860
    G87 = 870
    G88 = 880
    G89 = 890
    G90 = 900
    G90_1 = 901
    G91 = 910
    G91_1 = 911
    G92 = 920
    G92_1 = 921
    G92_2 = 922
    G92_3 = 923
    G93 = 930
    G94 = 940
    G98 = 980
    G99 = 990


class M(enum.IntEnum):
    """The M codes the reader tests by number."""

    M0 = 0
    M1 = 1
    M2 = 2
    M3 = 3
    M4 = 4
    M5 = 5
    M6 = 6
    M7 = 7
    M8 = 8
    M9 = 9
    M30 = 30
    M60 = 60
    M99 = 99
    M61 = 61
    M100 = 100
    M101 = 101
    M199 = 199


G_GROUPS: dict[int, int] = {}
"""G code in tenths -> its modal group (:class:`GGroup`; NON_MODAL: the non-modal codes)"""
for _group, _codes in {
    GGroup.NON_MODAL: (40, 100, 280, 281, 300, 301, 520, 530, 920, 921, 922, 923),
    GGroup.MOTION: (0, 10, 20, 30, 50, 51, 52, 53, 330, 331, 382, 383, 384, 385, 730, 740, 760, 800, 810, 820, 830,
                    840, 850, 860, 870, 880, 890, 700, 710, 711, 712, 720, 721, 722),
    GGroup.SET_PLANE: (170, 171, 180, 181, 190, 191),
    GGroup.DISTANCE_MODE: (900, 910),
    GGroup.IJK_DISTANCE_MODE: (901, 911),
    GGroup.FEED_MODE: (930, 940, 950),
    GGroup.LENGTH_UNITS: (200, 210),
    GGroup.CUTTER_COMP: (400, 410, 411, 420, 421),
    GGroup.TOOL_LENGTH_OFFSET: (430, 431, 432, 490),
    GGroup.RETRACT_MODE: (980, 990),
    GGroup.COORD_SYSTEM: (540, 550, 560, 570, 580, 590, 591, 592, 593),
    GGroup.CONTROL_MODE: (610, 611, 640),
    GGroup.SPINDLE_MODE: (960, 970),
    GGroup.LATHE_DIAMETER_MODE: (70, 80),
}.items():
    for _code in _codes:
        G_GROUPS[_code] = _group

EXTENSIONS = {G.G6_2: GGroup.MOTION}
"""codes the twin reads that LinuxCNC 2.9 does not know -> group: G6.2, the Fanuc-style NURBS
block (explicit knots and weights) of the published benchmark curves"""
G_GROUPS.update(EXTENSIONS)

M_GROUPS: dict[int, int] = {}
"""M code -> its modal group (:class:`MGroup`)"""
for _group, _codes in {
    MGroup.STOPPING: (0, 1, 2, 30, 60, 99),  # M99 outside a subroutine ends the program as M2 does
    MGroup.IO: (62, 63, 64, 65, 66, 67, 68),
    MGroup.TOOL_CHANGE: (6, 61),
    MGroup.SPINDLE: (3, 4, 5, 19, 70, 71, 72, 73),
    MGroup.COOLANT: (7, 8, 9),
    MGroup.OVERRIDES: (48, 49, 50, 51, 52, 53),
    MGroup.USER_DEFINED: tuple(range(100, 200)),
}.items():
    for _code in _codes:
        M_GROUPS[_code] = _group
MAX_M_CODES = 4
"""most M codes one block may hold"""
CANCEL_CYCLE = G.G80
"""G80, which may share group 1 with another motion code"""
CANNED_CYCLES = frozenset((G.G73, G.G74, G.G81, G.G82, G.G83, G.G84, G.G85, G.G86, G.G87, G.G88, G.G89))
"""the canned cycles (:mod:`~cnc_twin.gcode.cycles`): modal motion codes that stay in force,
repeating at each new position, until G80 or another motion code"""
AXIS_USERS = frozenset((G.G10, G.G28, G.G30, G.G52, G.G92))
"""non-modal codes whose axis words are their own (G10, G28, G30, G52, G92): not with a motion code"""


def g_code(value: float) -> int:
    """A G word's value in tenths, or LinuxCNC's refusal (in its order: a value between
    tenths or over G99.9, then a negative one)."""
    tenths = round(value * 10.0)
    if abs(value * 10.0 - tenths) > 1e-3 or tenths > 999:
        raise BlockError("G-code out of range")
    if tenths < 0:
        raise BlockError("Negative g code used")
    if tenths not in G_GROUPS:
        raise BlockError("Unknown g code used")
    return tenths


def m_code(value: float) -> int:
    """An M word's value, or LinuxCNC's refusal (in its order: not a whole number, then
    negative, over 199, unknown)."""
    code = round(value)
    if abs(value - code) >= 1e-4:
        raise BlockError("Non integer value for integer")
    if code < 0:
        raise BlockError("Negative m code used")
    if code > M.M199:
        raise BlockError(f"M-code greater than 199: M{code}")
    if code not in M_GROUPS:
        raise BlockError(f"Unknown m code used: M{code}")
    return code


def read_codes(block: Block) -> tuple[dict[int, int], dict[int, int]]:
    """``(g, m)``: group -> code of the block's G codes (tenths) and M codes, each checked in
    the order written, as LinuxCNC checks them while it reads the line (``M40 G999`` is refused
    for M40). A block read only up to a refusal (``block`` of
    :class:`~cnc_twin.gcode.blocks.BlockError`) holds the codes read before it, which LinuxCNC has
    checked by then."""
    order = block.codes
    if len(order) != len(block.g) + len(block.m):  # a block made otherwise than read
        order = "g" * len(block.g) + "m" * len(block.m)
    g: dict[int, int] = {}
    m: dict[int, int] = {}
    values = {"g": iter(block.g), "m": iter(block.m)}
    for letter in order:
        value = next(values[letter])
        if letter == "m":
            code = m_code(value)
            group = M_GROUPS[code]
            if group in m:
                raise BlockError("Two m codes used from same modal group")
            m[group] = code
            continue
        code = g_code(value)
        group = G_GROUPS[code]
        if group in g:
            if group == GGroup.MOTION and CANCEL_CYCLE in (code, g[group]):
                g[group] = code if g[group] == CANCEL_CYCLE else g[group]
                continue
            raise BlockError("Two g codes used from same modal group")
        g[group] = code
    return g, m


def modal_codes(block: Block) -> tuple[dict[int, int], dict[int, int]]:
    """``(g, m)``: group -> code of the block's G codes (tenths) and M codes: the checks made
    while reading (:func:`read_codes`), then those of the block read whole."""
    g, m = read_codes(block)
    if g.get(GGroup.NON_MODAL) in AXIS_USERS and g.get(GGroup.MOTION, CANCEL_CYCLE) != CANCEL_CYCLE:
        raise BlockError("Cannot use two g codes that both use axis values")
    if len(block.m) > MAX_M_CODES:
        raise BlockError("Too many m codes on line")
    return g, m
