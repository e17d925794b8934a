"""Canned cycles (G73, G74, G81 .. G89) read as LinuxCNC 2.9's ``rs274`` reads them: each cycle in
each plane, G98 / G99, G90 / G91 with L repeats, modal repeats, the level a series started at,
the path mode a cycle sets and gives back, LinuxCNC's refusals of bad cycle blocks, and random
cycle programs, each compared call for call with the oracle (``gcode_conformance.compare``);
then what the twin makes of a drilling program's calls (:mod:`cnc_twin.gcode.toolpath`)."""

from __future__ import annotations

import random

import pytest

import oracle
from cnc_twin.gcode.checks import UNSUPPORTED_MARK
from cnc_twin.gcode.interpreter import ProgramError, read_program
from cnc_twin.gcode.source import Source
from cnc_twin.gcode.toolpath import FeedPath, Pause, SpindleChange, Traverse, operations
from gcode_conformance import TOOLS, compare

PLANES = {"G17": ("X", "Y", "Z"), "G18": ("Z", "X", "Y"), "G19": ("Y", "Z", "X")}
"""plane -> its first, second and normal axis letters"""
CYCLE_WORDS = {"G73": "Q1.3", "G74": "P0.5", "G81": "", "G82": "P0.25", "G83": "Q1.1", "G84": "P0.5",
               "G85": "", "G86": "P0.5", "G87": "I0.5 J-0.25 K-1.5", "G88": "P1", "G89": "P0.75"}
"""each cycle -> the words it needs the first time"""
SPINDLE = {"G74": "M4"}
"""the spindle a cycle needs (M3 otherwise)"""


def _verdicts(programs: list[str], folder) -> list[tuple[str, str, str]]:
    """Each program's (program, verdict kind, detail) through both readers."""
    out = []
    for k, text in enumerate(programs):
        verdict = compare(text, folder / str(k))
        out.append((text, verdict.kind, verdict.detail))
    return out


def _all_matched(programs: list[str], folder) -> list[tuple[str, str, str]]:
    verdicts = _verdicts(programs, folder)
    wrong = [v for v in verdicts if v[1] != "matched"]
    assert not wrong, "\n".join(f"{text!r}\n  {kind}: {detail}" for text, kind, detail in wrong[:6])
    return verdicts


def _cycle_program(code: str, plane: str) -> str:
    """One cycle at work in ``plane``: G98 and G99, a modal repeat, G91 with L3 (R from the
    series' starting level), back to G90, an L repeat in place, G80."""
    a, b, n = PLANES[plane]
    need = CYCLE_WORDS[code]
    repeats = ("", "") if code == "G74" else ("L3", "L2")  # LinuxCNC takes no L with G74
    return (f"G21 G17 F150 S800 {SPINDLE.get(code, 'M3')}\n"
            f"G0 {a}1 {b}2 {n}12\n"
            f"{plane} G98 {code} {a}3 {b}4 {n}-2.5 R3 {need}\n"
            f"{a}5\n"
            f"G99 {b}6.5\n"
            f"G91 {code} {a}2 {b}-1 {n}-4 R-8 {repeats[0]} {need}\n"
            f"G90 G98 {a}0 {b}0 {n}-1 R2 {repeats[1]}\n"
            f"G80\n"
            f"G0 {n}12\n"
            "M2\n")


@pytest.mark.parametrize("plane", sorted(PLANES))
@pytest.mark.parametrize("code", sorted(CYCLE_WORDS))
def test_each_cycle_in_each_plane_is_what_rs274_does(code, plane, tmp_path):
    oracle.require()
    verdict = compare(_cycle_program(code, plane), tmp_path)
    if code in ("G74", "G84") and plane != "G17":
        # LinuxCNC 2.9 taps at swapped axes outside G17: refused, in one line, before any difference
        assert verdict.kind == "refused" and UNSUPPORTED_MARK in verdict.detail and "\n" not in verdict.detail
    else:
        assert (verdict.kind, verdict.detail) == ("matched", "")


SERIES = [
    # the old Z of G98 is the level the series started at, kept by later cycles of any kind
    "G21 F100\nG0 Z10\nG98 G81 X1 Z-1 R2\nX2\nG0 Z20\nG81 X3 Z-1 R2\nG82 X4 Z-2 R1 P1\nG83 X5 Z-3 R3 Q1\nM2\n",
    # a cycle started below R rises to R first (and returns there in G98)
    "G21 F100\nG0 Z0\nG98 G81 X1 Z-1 R2\nG99 X2\nG98 G91 X1 R1 Z-1 L2\nM2\n",
    # G80 or a move ends the series; G28, a dwell, a plane change do not
    "G21 F100\nG0 Z10\nG98 G81 X1 Z-1 R2\nG4 P1\nG28 Z15\nX2\nG80\nG0 Z30\nG81 X3 Z-1 R2\nG1 X4\nG81 X5 Z-1 R2\nM2\n",
    "G21 F100\nG0 Z10 Y5\nG98 G81 X1 Z-1 R2\nG18 G81 X2 Y1 R4\nZ3\nG19 G81 Y1 X-1 R3\nM2\n",
    # modal repeats keep R, the bottom, P, Q and I J K; a new cycle code needs them again
    "G21 F100 M3\nG0 Z10\nG82 X1 Z-1 R2 P2\nY1\nG86 X2 Z-1 R2 P0.5\nG89 X3 Z-2 R1 P1\nX4 R3 P-1\nM2\n",
    "G21 F100 M3\nG0 Z10\nG87 X1 Z-4 R2 I1 J1 K-2\nY3\nX2 I-1\nG91 X1 Z-3 R-8 K1\nM2\n",
    "G21 F100\nG0 Z10\nG83 X1 Z-1.9 R1 Q0.4\nY1\nG73 X2 Z-1 R2 Q0.7\nX3 Q0.45\nY4 Z-3.3\nM2\n",
    # G74 / G84 fall back to the P of any earlier cycle; G88 stops the program, G86 stops the spindle
    "G21 F100 M3\nG0 Z10\nG82 X1 Z-1 R2 P1.5\nG84 X2 Z-1 R2\nM4\nG74 X3 Z-1 R2\nG88 X4 Z-1 R2 P0.2\nM2\n",
    # inch: the peck clearance is 0.010 inch (0.254 mm in G21)
    "G20 F10\nG0 Z1\nG83 X0.1 Z-0.3 R0.1 Q0.07\nG73 X0.2 Z-0.3 R0.1 Q0.07\nG21\nG83 X5 Z-3 R1 Q0.5\nM2\n",
    # R and the bottom at and around the current level, L in place, G91 R from the start level
    "G21 F100\nG0 Z2\nG81 X1 Z2 R2\nG81 X1 Z-1 R2 L3\nG91 X0 Z0 R0 L2\nG90 G98 Z1 R5\nM2\n",
    # the path mode: G64 P Q given back with its naive-CAM tolerance, G61.1 given back, G61 untouched
    "G21 F100\nG64 P0.02 Q0.01\nG0 Z10\nG81 X1 Z-1 R2\nG61.1\nX2\nG61\nX3\nG64\nX4\nM2\n",
    "G21 F100\nG64 P0.05\nG0 Z10\nG20\nG81 X1 Z-0.1 R0.2\nM2\n",
    # polar words in G17: absolute, and turned / lengthened per repeat in G91
    "G21 F100\nG0 X1 Z10\nG81 Z-3 R2 @2 ^45\n^90\nG91 ^20 R0 Z-1 L3\n@1 L2\nM2\n",
    # a tool length offset and work offsets move the cycle's points with them
    "G21 F100 T1 M6\nG43\nG10 L2 P2 X10 Y-5 Z-20\nG55\nG0 Z10\nG81 X1 Z-1 R2\nG92 X0 Y0\nX1 Y1\nM2\n",
    # a cycle block's F, S and spindle act before the cycle; A B C stay where they are
    "G21\nG0 Z10 A30 B-5\nG86 X1 Z-1 R2 P1 F80 S1000 M4\nX2 F60\nM2\n",
]


def test_cycle_series_are_what_rs274_does(tmp_path):
    oracle.require()
    _all_matched(SERIES, tmp_path)


REFUSALS = [
    ("G81 X1 Y2 Z3 R2", "R less than z in cycle in xy plane"),
    ("G18 G81 X1 Z2 Y4 R3", "R less than y in cycle in xz plane"),
    ("G19 G81 Y1 Z2 X4 R3", "R less than x in cycle in yz plane"),
    ("G81 X1 Y2 Z-3", "R clearance plane unspecified in cycle"),
    ("G81 X1 Y2 R3", "Z value unspecified in xy plane canned cycle"),
    ("G18 G81 X1 Z2 R3", "Y value unspecified in xz plane canned cycle"),
    ("G19 G81 Y1 Z2 R3", "X value unspecified in yz plane canned cycle"),
    ("G81 R2", "All axes missing with motion code"),
    ("G83 X1 Y2 Z-3 R2", "Q word missing with g83"),
    ("G73 X1 Y2 Z-3 R2 Q-1", "Q word missing with g73"),
    ("G83 X1 Y2 Z-3 R2 Q0", "Negative or zero q value used"),
    ("G73 X1 Y2 Z-3 R2 Q-2", "Negative or zero q value used"),
    ("G81 X1 Y2 Z-3 R2 L0", "Cannot do zero repeats of cycle"),
    ("G81 X1 Y2 Z-3 R2 L-2", "Negative l word used"),
    ("G81 X1 Y2 Z-3 R2 L1.5", "Non integer value for integer"),
    ("G81 X1 Y2 Z-3 R2 L2 L3", "Multiple l words on one line"),
    ("G81 X1 Y2 Z-3 R2 A3", "Cannot put an a in canned cycle"),
    ("G81 X1 Y2 Z-3 R2 B3", "Cannot put a b in canned cycle"),
    ("G81 X1 Y2 Z-3 R2 C3 D1", "Cannot put a c in canned cycle"),
    ("G82 X1 Y2 Z-3 R2", "Dwell time p word missing with g82"),
    ("G86 X1 Y2 Z-3 R2 M3", "Dwell time p word missing with g86"),
    ("G88 X1 Y2 Z-3 R2 P-1", "Dwell time p word missing with g88"),
    ("G89 X1 Y2 Z-3 R2", "Dwell time p word missing with g89"),
    ("G87 X1 Y2 Z-3 R2 J1 K1", "I word missing with g87"),
    ("G87 X1 Y2 Z-3 R2 I1 K1", "J word missing with g87"),
    ("G87 X1 Y2 Z-3 R2 I1 J1", "K word missing with g87"),
    ("G86 X1 Y2 Z-3 R2 P1", "Spindle not turning in g86"),
    ("G87 X1 Y2 Z-3 R2 I1 J1 K1", "Spindle not turning in g87"),
    ("G88 X1 Y2 Z-3 R2 P1", "Spindle not turning in g88"),
    ("G84 X1 Y2 Z-3 R2 P1", "Spindle not turning in G84"),
    ("G74 X1 Y2 Z-3 R2 P1", "Spindle not turning in G74"),
    ("G84 X1 Y2 Z-3 R2 M4", "Spindle turning counterclockwise in G84"),
    ("G74 X1 Y2 Z-3 R2 M3", "Spindle turning clockwise in G74"),
    ("G74 X1 Y2 Z-3 R2 L2 M4", "L word with no G10, cutter compensation, canned cycle, digital/analog input, M98 "
                               "or NURBS code"),
    ("G81 X1 Y2 Z-3 R2 P1", "P word with no G2 G3 G4 G10 G64 G5 G5.2 G76 G82 G86 G88 G89 or M50 M51 M52 M53 M62 "
                            "M63 M64 M65 M66 M98 or user M code to use it"),
    ("G81 X1 Y2 Z-3 R2 Q1", "Q word with no G5, G10, G64, G73, G76, G83, M19, M66, M67, M68 or user M code that "
                            "uses it"),
    ("G82 X1 Y2 Z-3 R2 P1 I1", "I word with no G2, G3, G5, G5.1, G10, G33.1, G76, or G87 to use it"),
    ("G81 X1 Y2 Z-3 R2 K1", "K word with no G2, G3, G33, G33.1, G76, or G87 to use it"),
    ("G81 X1 Z-3 R2 @2", "Cannot specify both polar coordinate and X word"),
    ("G17.1 G81 X1 R2", "Cannot put an X in a canned cycle in the UV plane"),
    ("G18.1 G81 Y1 Z2 R2", "Cannot put a Y in a canned cycle in the UW plane"),
    ("G17.1 G81 @1 R2", "G17.1 canned cycle is not possible on a machine without W axis"),
    ("G81 X1 Z-1 R2 G53", "Must use g0 or g1 with g53"),
    ("G81 X1 Z-1 R2 G28", "Cannot use two g codes that both use axis values"),
    ("G81 X1 Z-1 R2 F0", "Cannot feed with zero feed rate"),
    ("G93 G81 X1 Z-1 R2", "Cannot use inverse time feed with canned cycles"),
    ("G93 F10 G1 X1\nG81 X1 Z-1 R2", "Cannot use inverse time feed with canned cycles"),
    ("G94 F0\nG93 F10\nG81 X1 Z-1 R2", "Cannot feed with zero feed rate"),
    # on later lines of a cycle
    ("G81 X1 Z-1 R2\nA1", "Cannot put an a in canned cycle"),
    ("G81 X1 Z-1 R2\nF10 B1", "Cannot put a b in canned cycle"),
    ("G81 X1 Z-1 R2\nX2 Z3", "R less than z in cycle in xy plane"),
    ("G81 X1 Z-1 R2\nG82 X2", "R clearance plane unspecified in cycle"),
    ("G81 X1 Z-1 R2\nG82 X2 R2", "Z value unspecified in xy plane canned cycle"),
    ("G81 X1 Z-1 R2\nG19\nY2 R-3", "R less than x in cycle in yz plane"),
    ("G81 X1 Z-1 R2\nG19.1\n@1", "Cannot use polar coordinate except in G17 plane"),
    ("G83 X0 Y0 Z-1 R2 Q1\nG91 @1", "Incremental motion with polar coordinates is indeterminate when at the origin"),
]


def test_bad_cycle_blocks_are_refused_as_rs274_refuses_them(tmp_path):
    oracle.require()
    programs = [f"G21 F100\nG0 Z10\n{block}\nM2\n" for block, _ in REFUSALS]
    verdicts = _all_matched(programs, tmp_path)
    assert [detail for _, _, detail in verdicts] == [message for _, message in REFUSALS]


def test_tapping_outside_g17_is_refused_in_one_line():
    with pytest.raises(ProgramError) as info:
        read_program(Source("G21 F100 M3 S500\nG0 Z10\nG18 G84 X1 Y-2 Z3 R1\nM2\n"), TOOLS)
    assert info.value.line == 3 and UNSUPPORTED_MARK in info.value.message and "\n" not in info.value.message


# random cycle programs --------------------------------------------------------------------------

def _num(value: float) -> str:
    return f"{value:.4f}".rstrip("0").rstrip(".")


def _random_block(rng: random.Random, state: dict) -> str:
    """One line of a random cycle program; ``state`` keeps the plane and the distance mode so
    that most lines make sense (R above the bottom), a few do not."""
    parts = []
    if rng.random() < 0.15:
        state["plane"] = rng.choice(sorted(PLANES))
        parts.append(state["plane"])
    toggled = rng.random() < 0.2
    if toggled:  # R and the bottom kept from the other mode mostly make no sense: given again
        state["g91"] = not state["g91"]
        parts.append("G91" if state["g91"] else "G90")
    if rng.random() < 0.3:
        parts.append(rng.choice(("G98", "G99")))
    if rng.random() < 0.05:
        parts.append(rng.choice(("M3", "M4", "M5")))
    if rng.random() < 0.05:
        parts.append(rng.choice(("G61", "G61.1", "G64", "G64 P0.01 Q0.005")))
    a, b, n = PLANES[state["plane"]]
    roll = rng.random()
    if roll < 0.08:
        return " ".join(parts + [f"G0 {n}{_num(rng.uniform(5, 15))}"])
    if roll < 0.12:
        return " ".join(parts + ["G80"])
    new_code = roll < 0.55 or state["code"] is None
    words = []
    if new_code:
        state["code"] = rng.choice(sorted(CYCLE_WORDS))
        words.append(state["code"])
        if state["code"] in ("G74", "G84") and rng.random() < 0.9:  # mostly the tap's own direction
            parts.append("M4" if state["code"] == "G74" else "M3")
    code = state["code"]
    for letter in (a, b):
        if rng.random() < 0.7:
            words.append(f"{letter}{_num(rng.uniform(-8, 8))}")
    if new_code or toggled or rng.random() < 0.3:
        if state["g91"]:
            words.append(f"R{_num(rng.uniform(-6, 2))}")
            words.append(f"{n}{_num(rng.uniform(-4, 0.1))}")
        else:
            r = rng.uniform(-1, 6)
            words.append(f"R{_num(r)}")
            words.append(f"{n}{_num(r - rng.uniform(-0.1, 5))}")
    if new_code or rng.random() < 0.2:
        words.extend(w for w in CYCLE_WORDS[code].split() if rng.random() < 0.95)
    if rng.random() < 0.15 and code != "G74":
        words.append(f"L{rng.choice((1, 2, 3))}")
    if rng.random() < 0.05:
        words.append(rng.choice(("F0", "F75", "A1", "L0", "Q0")))
    if len(words) == (1 if new_code else 0):  # a cycle needs an axis word
        words.append(f"{a}{_num(rng.uniform(-8, 8))}")
    return " ".join(parts + words)


def _random_program(rng: random.Random) -> str:
    state = {"plane": "G17", "g91": False, "code": None}
    lines = [rng.choice(("G21 F120", "G20 F12", "G21 F90 G64 P0.02")) + " M3 S600", f"G0 Z{_num(rng.uniform(2, 12))}"]
    lines += [_random_block(rng, state) for _ in range(rng.randint(3, 9))]
    return "\n".join(lines + ["M2", ""])


def test_random_cycle_programs_are_what_rs274_does(tmp_path):
    oracle.require()
    rng = random.Random(8183)
    programs = [_random_program(rng) for _ in range(200)]
    verdicts = _verdicts(programs, tmp_path)
    wrong = [v for v in verdicts if v[1] == "differs"
             or (v[1] == "refused" and "G74 in" not in v[2] and "G84 in" not in v[2])]
    assert not wrong, "\n".join(f"{text!r}\n  {kind}: {detail}" for text, kind, detail in wrong[:6])
    ends = sum(1 for _, kind, detail in verdicts if kind == "matched" and not detail)
    errors = sum(1 for _, kind, detail in verdicts if kind == "matched" and detail)
    assert ends > 50 and errors > 50  # both runs to the end and LinuxCNC's refusals well represented


# what the twin runs -------------------------------------------------------------------------------

def test_a_drilling_program_becomes_traverses_feeds_dwells_and_spindle_changes():
    text = ("G21 G17 G90 F200 S1000 M3\nG0 X0 Y0 Z50\n"
            "G98 G81 X10 Y10 Z1 R5\nX20\nG99 G82 X30 Z1 R5 P0.5\nG86 X40 Z1 R5 P0.2\nG80\nG0 Z50\nM2\n")
    ops = operations(read_program(Source(text), TOOLS).calls)
    kinds = [type(op).__name__ for op in ops]
    feeds = [op for op in ops if isinstance(op, FeedPath)]
    assert len(feeds) == 4  # one plunge a hole; the retracts are traverses
    assert [round(float(p), 6) for p in feeds[0].elements[0].end] == [10.0, 10.0, 1.0]
    assert any(isinstance(op, Pause) and op.seconds == 0.5 for op in ops)
    spindle = [op.rpm for op in ops if isinstance(op, SpindleChange)]
    assert spindle[-3:-1] == [0.0, 1000.0] and spindle[0] == 1000.0  # G86: stopped for the way out, restarted
    traverses = [op for op in ops if isinstance(op, Traverse)]
    assert traverses[-1].end[2] == 50.0 and "Pause" in kinds
