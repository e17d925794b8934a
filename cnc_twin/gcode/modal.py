"""G and M codes of a block sorted into LinuxCNC's modal groups, refused as it refuses them.

A code is kept in tenths (``G5.2`` is 52, ``G61.1`` is 611). A block may hold at most one code
of each group (``G80`` may share group 1 with another motion code, which then applies) and at
most four M codes. The messages are LinuxCNC's, checked against its interpreter
(``tests/test_gcode_modal.py``).
"""

from __future__ import annotations

from cnc_twin.gcode.blocks import Block, BlockError

G_GROUPS: dict[int, int] = {}
"""G code in tenths -> its modal group (0: the non-modal codes)"""
for _group, _codes in {
    0: (40, 100, 280, 281, 300, 301, 520, 530, 920, 921, 922, 923),
    1: (0, 10, 20, 30, 50, 51, 52, 53, 330, 331, 382, 383, 384, 385, 730, 740, 760, 800, 810, 820, 830, 840, 850,
        860, 870, 880, 890, 700, 710, 711, 712, 720, 721, 722),
    2: (170, 171, 180, 181, 190, 191),
    3: (900, 910),
    4: (901, 911),
    5: (930, 940, 950),
    6: (200, 210),
    7: (400, 410, 411, 420, 421),
    8: (430, 431, 432, 490),
    10: (980, 990),
    12: (540, 550, 560, 570, 580, 590, 591, 592, 593),
    13: (610, 611, 640),
    14: (960, 970),
    15: (70, 80),
}.items():
    for _code in _codes:
        G_GROUPS[_code] = _group

EXTENSIONS = {62: 1}
"""codes the twin reads that LinuxCNC 2.9 does not know -> group: G6.2, the Fanuc-style NURBS
block (explicit knots and weights) of the published benchmark curves"""
G_GROUPS.update(EXTENSIONS)

M_GROUPS: dict[int, int] = {}
"""M code -> its modal group"""
for _group, _codes in {
    4: (0, 1, 2, 30, 60),
    5: (62, 63, 64, 65, 66, 67, 68),
    6: (6, 61),
    7: (3, 4, 5, 19, 70, 71, 72, 73),
    8: (7, 8, 9),
    9: (48, 49, 50, 51, 52, 53),
    10: tuple(range(100, 200)),
}.items():
    for _code in _codes:
        M_GROUPS[_code] = _group
MAX_M_CODES = 4
"""most M codes one block may hold"""
CANCEL_CYCLE = 800
"""G80, which may share group 1 with another motion code"""
AXIS_USERS = frozenset((100, 280, 300, 520, 920))
"""non-modal codes whose axis words are their own (G10, G28, G30, G52, G92): not with a motion code"""


def g_code(value: float) -> int:
    """A G word's value in tenths, or LinuxCNC's refusal."""
    if value < 0:
        raise BlockError("Negative g code used")
    tenths = round(value * 10.0)
    if abs(value * 10.0 - tenths) > 1e-3 or tenths > 999:
        raise BlockError("G-code out of range")
    if tenths not in G_GROUPS:
        raise BlockError("Unknown g code used")
    return tenths


def m_code(value: float) -> int:
    """An M word's value, or LinuxCNC's refusal."""
    if value < 0:
        raise BlockError("Negative m code used")
    code = round(value)
    if abs(value - code) >= 1e-4:
        raise BlockError("Non integer value for integer")
    if code > 199:
        raise BlockError(f"M-code greater than 199: M{code}")
    if code not in M_GROUPS:
        raise BlockError("Unknown m code used")
    return code


def modal_codes(block: Block) -> tuple[dict[int, int], dict[int, int]]:
    """``(g, m)``: group -> code of the block's G codes (tenths) and M codes."""
    if len(block.m) > MAX_M_CODES:
        raise BlockError("Too many m codes on line")
    g: dict[int, int] = {}
    for value in block.g:
        code = g_code(value)
        group = G_GROUPS[code]
        if group in g:
            if group == 1 and CANCEL_CYCLE in (code, g[group]):
                g[group] = code if g[group] == CANCEL_CYCLE else g[group]
                continue
            raise BlockError("Two g codes used from same modal group")
        g[group] = code
    if g.get(0) in AXIS_USERS and g.get(1, CANCEL_CYCLE) != CANCEL_CYCLE:
        raise BlockError("Cannot use two g codes that both use axis values")
    m: dict[int, int] = {}
    for value in block.m:
        code = m_code(value)
        group = M_GROUPS[code]
        if group in m:
            raise BlockError("Two m codes used from same modal group")
        m[group] = code
    return g, m
