"""A block's codes and words checked before it runs, as LinuxCNC checks a block it has read
(its enhance_block, check_g_codes and check_other_codes, in that order), with its wording; and
what the twin's machine does not have, refused in one line naming it (cutter radius
compensation, threading, lathe modes...).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from cnc_twin.gcode.arcs import turns_of
from cnc_twin.gcode.blocks import Block, BlockError
from cnc_twin.gcode.modal import CANNED_CYCLES, G, GGroup, M, MGroup

if TYPE_CHECKING:  # the interpreter's state, read here for its modes only
    from cnc_twin.gcode.state import State

UNSUPPORTED_MARK = "not supported by cnc-twin"
"""every refusal of a feature the machine does not have says this"""
UNSUPPORTED_G = {
    50: "G5 (cubic spline)", 51: "G5.1 (quadratic spline)", 70: "G7 (lathe diameter mode)",
    330: "G33 (spindle-synchronised motion)", 331: "G33.1 (rigid tapping)", 410: "G41 (cutter radius compensation)",
    411: "G41.1 (cutter radius compensation)", 420: "G42 (cutter radius compensation)",
    421: "G42.1 (cutter radius compensation)", 432: "G43.2 (additional tool length offset)",
    760: "G76 (threading cycle)", 950: "G95 (feed per revolution)", 960: "G96 (constant surface speed)",
    **{c: f"G{c / 10:g} (lathe cycle)" for c in (700, 710, 711, 712, 720, 721, 722)},
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
FORCE_ON, FORCE_OFF = M.M100, M.M101
"""the machine's own M codes: M100 P<newtons> switches the grinding-force loop on with that
setpoint, M101 switches it off (LinuxCNC's user M-code range)"""
AXIS_LETTERS = "xyzabc"
MOVE_WORDS = AXIS_LETTERS + "@^"
"""words that make a block move (``@`` / ``^`` polar radius and angle)"""
PROBES = (G.G38_2, G.G38_3, G.G38_4, G.G38_5)
"""straight probing (:mod:`~cnc_twin.gcode.probing`)"""
AXIS_CODES = (G.G10, G.G28, G.G30, G.G92)
"""group 0 codes whose axis words are their own (G10, G28, G30, G92)"""


def refuse_unsupported(block: Block, g: dict[int, int], m: dict[int, int]) -> None:
    """What the twin's machine does not have, refused in one line naming it."""
    for code in g.values():
        if code in UNSUPPORTED_G:
            raise BlockError(f"{UNSUPPORTED_G[code]} is {UNSUPPORTED_MARK}'s machine")
    for code in m.values():
        if code in UNSUPPORTED_M:
            raise BlockError(f"{UNSUPPORTED_M[code]} is {UNSUPPORTED_MARK}'s machine")
        if M.M100 <= code <= M.M199 and code not in (FORCE_ON, FORCE_OFF):
            raise BlockError(f"Unknown m code used: M{code}")
    for letter in "uvw":
        if letter in block.words:
            raise BlockError(f"Bad character '{letter}' used")
    if "e" in block.words:
        raise BlockError(f"E word (lathe threading) is {UNSUPPORTED_MARK}'s machine")


def check_words(block: Block, g: dict[int, int], m: dict[int, int], motion: int | None, state: State) -> None:
    """LinuxCNC's checks of a block read whole, in its order: the axis words (its
    enhance_block), the group 0 codes (check_g_codes), then the other words
    (check_other_codes). ``motion`` is the motion the block will make, or None.

    :type block: ~cnc_twin.gcode.blocks.Block
    """
    _check_axis_words(block, g, state)
    _check_g_codes(block, g, motion, state)
    _check_other_words(block, g, m, motion)


def _check_axis_words(block: Block, g: dict[int, int], state: State) -> None:
    words = block.words
    g0 = g.get(GGroup.NON_MODAL)
    if "@" in words or "^" in words:
        if state.plane != G.G17:  # the plane before the block's own plane code
            raise BlockError("Cannot use polar coordinate except in G17 plane")
        for letter in "xy":
            if letter in words:
                raise BlockError(f"Cannot specify both polar coordinate and {letter.upper()} word")
    if g0 == G.G92 and GGroup.MOTION not in g and not any(letter in words for letter in AXIS_LETTERS):
        raise BlockError("All axes missing with g52 or g92")
    moving = any(a in words for a in MOVE_WORDS)
    if g.get(GGroup.MOTION) == G.G80 and moving and g0 not in AXIS_CODES:
        raise BlockError("Cannot use axis values with g80")
    if g.get(GGroup.MOTION) in CANNED_CYCLES and not moving:  # a G1 alone is allowed, a cycle is not
        raise BlockError("All axes missing with motion code")
    if g.get(GGroup.MOTION) in PROBES and not moving:
        raise BlockError("All axes missing with motion code")
    owned = g0 in AXIS_CODES or g.get(GGroup.TOOL_LENGTH_OFFSET) == G.G43_1 or GGroup.MOTION in g
    if not owned and state.motion == G.G80 and moving:
        raise BlockError("Cannot use axis values without a g code that uses them")


def _check_g_codes(block: Block, g: dict[int, int], motion: int | None, state: State) -> None:
    words = block.words
    g0 = g.get(GGroup.NON_MODAL)
    if g0 == G.G4 and words.get("p", -1.0) == -1.0:  # LinuxCNC's "no P" is P -1
        raise BlockError("Dwell time missing with g4")
    if g0 == G.G10:
        _check_g10(words.get("p", -1.0), round(words.get("l", -1)))
    if g0 == G.G53 and motion not in (G.G0, G.G1):
        raise BlockError("Must use g0 or g1 with g53")
    if g0 == G.G53 and (g.get(GGroup.DISTANCE_MODE) == G.G91
                        or (GGroup.DISTANCE_MODE not in g and state.distance == G.G91)):
        raise BlockError("Cannot use g53 incremental")


def _check_g10(p: float, l_word: int) -> None:
    """G10's L and P as LinuxCNC checks them (P -1 when absent): P rounded half away from zero
    must be 0..9 for L2 / L20, and P may not exceed its rounding by more than 0.0001 (so P1.7
    passes the check, and runs as P1)."""
    if l_word not in (0, 1, 2, 10, 11, 20):
        raise BlockError("Line with G10 does not have L0, L1, L10, L11, L2, or L20")
    p_int = int(p + 0.5) if p >= 0 else int(p - 0.5)
    if (p + 0.0001) - p_int > 0.0002:
        raise BlockError("P value not an integer with G10")
    if l_word in (2, 20) and not 0 <= p_int <= 9:
        raise BlockError(f"P value out of range (0-9) with G10 L{l_word}")
    if l_word in (1, 10, 11) and p_int < 1:  # P is the tool number
        raise BlockError(f"P value out of range with G10 L{l_word}")


def _check_other_words(block: Block, g: dict[int, int], m: dict[int, int], motion: int | None) -> None:
    words = block.words
    arc = motion in (G.G2, G.G3)
    g0 = g.get(GGroup.NON_MODAL)
    user_m = MGroup.USER_DEFINED in m
    cycle = motion in CANNED_CYCLES
    for letter in "abc":
        if letter in words and cycle:
            raise BlockError(f"Cannot put {'an' if letter == 'a' else 'a'} {letter} in canned cycle")
    if "d" in words:
        raise BlockError("D word with no G41, G41.1, G42, G42.1, G71, G71.1, G71.2 or G96 to use it")
    if "$" in words:
        _check_spindle_number(words["$"], "s" in words or m.get(MGroup.SPINDLE) in (M.M3, M.M4, M.M5)
                              or GGroup.SPINDLE_MODE in g)
    if "h" in words and g.get(GGroup.TOOL_LENGTH_OFFSET) != G.G43:
        raise BlockError("H word with no G43 or G76 to use it")
    if ("i" in words or "j" in words) and not (arc or motion == G.G87 or g0 == G.G10):
        letter = "I" if "i" in words else "J"
        raise BlockError(f"{letter} word with no G2, G3, G5, G5.1, G10, G33.1, G76, or G87 to use it")
    if "k" in words and not (arc or motion in (G.G6_2, G.G87)):
        raise BlockError("K word with no G2, G3, G33, G33.1, G76, or G87 to use it")
    if "l" in words and not (g0 == G.G10 or motion in (G.G5_2, G.G6_2) or (cycle and motion != G.G74)):
        raise BlockError("L word with no G10, cutter compensation, canned cycle, digital/analog input, M98 "
                         "or NURBS code")
    if "p" in words and not (arc or g0 in (G.G4, G.G10) or g.get(GGroup.CONTROL_MODE) == G.G64 or user_m
                              or motion in (G.G5_2, G.G6_2, G.G74, G.G82, G.G84, G.G86, G.G88, G.G89)):
        raise BlockError("P word with no G2 G3 G4 G10 G64 G5 G5.2 G76 G82 G86 G88 G89 or M50 M51 M52 M53 "
                         "M62 M63 M64 M65 M66 M98 or user M code to use it")
    if "p" in words and arc:
        turns_of(words["p"])  # refused here, before the block's F and S take effect
    # Q -1 is LinuxCNC's "no Q"
    if words.get("q", -1.0) != -1.0 and not (g.get(GGroup.CONTROL_MODE) == G.G64 or g0 == G.G10 or user_m
                                             or m.get(MGroup.TOOL_CHANGE) == M.M61
                                             or motion in (G.G6_2, G.G73, G.G83)):
        raise BlockError("Q word with no G5, G10, G64, G73, G76, G83, M19, M66, M67, M68 or user M code "
                         "that uses it")
    if "r" in words and not (arc or g0 == G.G10 or motion == G.G6_2 or cycle):
        raise BlockError("R word with no g code that uses it")


def _check_spindle_number(value: float, used: bool) -> None:
    """The ``$`` word (LinuxCNC 2.9's spindle number, truncated): spindle 0, or -1 for all
    spindles, is the machine's only one."""
    if not used:
        raise BlockError("$ (spindle selection) word with no M3, M4, M5, M19, M51, G33, G33.1, G76, G95, G96 "
                         "or G97 to use it")
    if int(value) not in (0, -1):
        raise BlockError(f"spindle ${int(value)} is {UNSUPPORTED_MARK}'s machine (it has spindle 0 only)")
