"""G2 / G3 arcs as LinuxCNC makes them: planes and axis order, the turn count's sign, I J K (G91.1
and G90.1) and R centres, full circles, helices, P, and every refusal with its wording and
numbers. A table of cases and 300 seeded random arcs go through `rs274` and through
:func:`arc_move`: the ARC_FEED it prints, or its first error, must be ours character for character.
The plain tests pin the rules without the oracle."""

from __future__ import annotations

import math
import random
import re
from dataclasses import dataclass

import pytest

import oracle
from cnc_twin.gcode.arcs import (CENTER_ARC_RADIUS_TOLERANCE_INCH, CENTER_ARC_RADIUS_TOLERANCE_MM, PLANE_AXES,
                                 RADIUS_TOLERANCE_INCH, RADIUS_TOLERANCE_MM, ArcMove, arc_feed_text, arc_move,
                                 check_arc_words, glibc_hypot, turns_of)
from cnc_twin.gcode.blocks import BlockError

ZERO_FEED = "Cannot make arc with zero feed rate"


@dataclass(frozen=True)
class Case:
    """One arc block: ``text`` its words (``X1 Y1 I0.5 J0.5``), from ``start`` (x, y, z), with
    the modes given; ``feed``: False for no F at all (LinuxCNC's feed check then fails)."""

    plane: int
    clockwise: bool
    text: str
    start: tuple[float, float, float] = (0.0, 0.0, 0.0)
    metric: bool = True
    ijk_absolute: bool = False
    feed: bool = True


def _words(text: str) -> dict[str, float]:
    return {letter.lower(): float(value) for letter, value in re.findall(r"([A-Za-z])([-+]?[0-9.]+)", text)}


def _end(case: Case) -> tuple[float, float, float]:
    words = _words(case.text)
    return tuple(words.get(axis, case.start[k]) for k, axis in enumerate("xyz"))


def _ours(case: Case) -> tuple[str, str]:
    """``("arc", ARC_FEED text)`` or ``("error", message)``."""
    try:
        move = arc_move(case.plane, case.clockwise, case.start, _end(case), _words(case.text), case.ijk_absolute,
                        case.metric, feed_error=None if case.feed else ZERO_FEED)
    except BlockError as exc:
        return "error", str(exc)
    return "arc", arc_feed_text(move)


def _num(value: float) -> str:
    """A coordinate as program text (no exponent; our side reads back the same double)."""
    return f"{value:.6f}".rstrip("0").rstrip(".")


def _program_lines(case: Case) -> str:
    plane = {170: "G17", 180: "G18", 190: "G19", 171: "G17.1", 181: "G18.1", 191: "G19.1"}[case.plane]
    modes = f"{'G21' if case.metric else 'G20'} G90 {'G90.1' if case.ijk_absolute else 'G91.1'} {plane}"
    modes += " F100" if case.feed else ""
    x, y, z = (_num(v) for v in case.start)
    return f"{modes}\nG0 X{x} Y{y} Z{z}\nG{2 if case.clockwise else 3} {case.text}\n"


def _theirs(cases: list[Case], folder) -> list[tuple[str, str]]:
    """What rs274 makes of each case: the arcs we accept run together in one program, each refusal
    (which ends a program) in its own; a batch that goes otherwise is rerun case by case."""
    ours = [_ours(case) for case in cases]
    results: list[tuple[str, str] | None] = [None] * len(cases)
    runs = 0

    def run(indices: list[int]) -> tuple[list[str], list[str]]:
        nonlocal runs
        runs += 1
        calls, other = oracle.run("".join(_program_lines(cases[k]) for k in indices) + "M2\n", folder / str(runs))
        return [args for name, args in calls if name == "ARC_FEED"], other

    def alone(k: int) -> None:
        arcs, other = run([k])
        results[k] = ("error", other[0]) if other else ("arc", arcs[0] if arcs else "(no ARC_FEED)")

    batch = [k for k, result in enumerate(ours) if result[0] == "arc"]
    for chunk in (batch[i:i + 150] for i in range(0, len(batch), 150)):
        arcs, other = run(chunk)
        if len(arcs) == len(chunk) and not other:
            for k, text in zip(chunk, arcs):
                results[k] = ("arc", text)
        else:
            for k in chunk:
                alone(k)
    for k, result in enumerate(ours):
        if result[0] == "error":
            alone(k)
    return results


def _compare(cases: list[Case], folder) -> None:
    theirs = _theirs(cases, folder)
    wrong = [(case, _ours(case), their) for case, their in zip(cases, theirs) if _ours(case) != their]
    assert not wrong, "\n".join(f"{_program_lines(c)!r}\n  ours:   {o}\n  rs274:  {t}" for c, o, t in wrong[:8])


XY, XZ, YZ = 170, 180, 190
CASES = [
    # planes, axis order and the sign of the turn count
    Case(XY, True, "X1 Y1 I0.5 J0.5"), Case(XY, False, "X1 Y1 I0.5 J0.5"),
    Case(XZ, True, "X1 Z1 I0.5 K0.5", (0, 2, 0)), Case(XZ, False, "X1 Z1 I0.5 K0.5", (0, 2, 0)),
    Case(YZ, True, "Y1 Z1 J0.5 K0.5", (3, 0, 0)), Case(YZ, False, "Y1 Z1 J0.5 K0.5", (3, 0, 0)),
    Case(XZ, True, "X1 Z3 I1", (1, 2, 3)), Case(YZ, False, "Y2 Z3 K1", (1, 2, 3)),
    # full circles (no end words), a missing offset is 0, helices, turns
    Case(XY, False, "I1"), Case(XY, True, "J-2"), Case(XZ, False, "K1"), Case(YZ, True, "J1"),
    Case(XY, True, "J-1 P3 Z-2"), Case(XZ, False, "K1 Y7 P2"), Case(YZ, True, "Y1 Z1 J0.5 K0.5 X-4 P5"),
    Case(XY, False, "X1 I1 P1.0009"), Case(XY, True, "X1 I0.5 P2147483647"),
    # absolute centres
    Case(XY, True, "X1 Y4 I1 J3", (1, 2, 3), ijk_absolute=True),
    Case(XZ, False, "X3 Z3 I2 K3", (1, 2, 3), ijk_absolute=True),
    Case(YZ, True, "Y2 Z5 J2 K4", (1, 2, 3), ijk_absolute=True),
    # R: short and long way, half circles, P, each plane; signed zeros from the extended-precision pi/2
    Case(XY, True, "X2 R1"), Case(XY, True, "X2 R-1"), Case(XY, False, "X1 Y1 R1"), Case(XY, False, "X1 Y1 R-1"),
    Case(XY, True, "X1 Y1 R-1 P2 Z5"), Case(XZ, False, "X1 Z1 R1"), Case(YZ, True, "Y1 Z1 R-1"),
    Case(XY, True, "X0 Y1 R1", (0, -1, 0)), Case(XY, False, "X0 Y1 R1", (0, -1, 0)),
    Case(XY, False, "X1 Y0 R-1", (-1, 0, 0)), Case(XY, False, "X1 Y1 R-1.4142135623730951", (-1, -1, 0)),
    Case(XY, False, "X1 R-0.5"), Case(XZ, True, "Z-1 R1.5", (0, 0, 1)),
    # R: a half chord longer than R within the tolerance is a half circle; R0 within it is NaN
    Case(XY, False, "X2.00254 R1"), Case(XY, False, "X2.0001 R1", metric=False), Case(XY, False, "X0.001 R0"),
    Case(XY, True, "X-0.0001 R-0", metric=False),
    # ... and within 1e-12 of R (TINY) too, not just past it
    Case(XY, False, "X2000 R1000.0000000001"), Case(XY, False, "X2000 R1000.00000001"),
    # glibc's hypot, one ulp from a correctly rounded one, decides these two
    Case(XY, False, "X8.2376 Y5.5529 R4.965941294328036"), Case(XY, False, "X3.9398 Y4.1731 R2.86825904019109"),
    # zero radius: under 0.00127 mm / 0.00005 in
    Case(XY, False, "X0 I0.00127 J0"), Case(XY, False, "X0 I0.0012699 J0"),
    Case(XY, False, "X0 I0.00005 J0", metric=False), Case(XY, False, "X0 I0.0000499 J0", metric=False),
    Case(XY, False, "X1 I0 J0"), Case(XZ, True, "X1 Z1 I1 K1", (0, 0, 0)),
    # radii that differ: 2*sqrt(2)*0.01 mm (0.001 in) allowed, 100 times that within 0.1 %
    Case(XY, False, "X2.0282 I1 J0"), Case(XY, False, "X2.0283 I1 J0"),
    Case(XY, False, "X2.0028 I1 J0", metric=False), Case(XY, False, "X2.0029 I1 J0", metric=False),
    Case(XY, False, "X2001.0009 I1000 J0"), Case(XY, False, "X2001.0011 I1000 J0"),
    Case(XY, False, "X2000.2828 I1000 J0", metric=False), Case(XY, False, "X2000.2829 I1000 J0", metric=False),
    Case(XY, False, "X4001.0009 I1000 J0", (2000, 0, 0)), Case(YZ, True, "Y3 Z1 J1", (5, 0, 0)),
    # P
    Case(XY, True, "X1 I1 P0"), Case(XY, True, "X1 I1 P-1"), Case(XY, True, "X1 I1 P1.5"),
    Case(XY, True, "X1 I1 P1.0011"), Case(XY, True, "X1 I1 P0.4"), Case(XY, True, "X1 I1 P-0.0001"),
    Case(XY, True, "X1 I1 P2147483648"), Case(XY, True, "X1 P0"), Case(171, True, "X1 R1 I1 P0"),
    # the format and the words of the plane, in LinuxCNC's order
    Case(171, False, "X1 R1"), Case(181, False, "X1 R1 I1"), Case(XY, False, "X1"), Case(XY, False, "X1 R1 I1"),
    Case(XZ, False, "X1 Y1 R1 J0"), Case(XY, False, "X1 Y1 R1 K0"),
    Case(XY, False, "X1 I1 K1"), Case(XZ, False, "X1 I1 J1"), Case(YZ, False, "Y1 I1 J1"),
    Case(XY, False, "X1 I1", ijk_absolute=True), Case(XY, False, "X1 J1", ijk_absolute=True),
    Case(XZ, False, "X1 K1", ijk_absolute=True), Case(XZ, False, "X1 I1", ijk_absolute=True),
    Case(YZ, False, "Y1 K1", ijk_absolute=True), Case(YZ, False, "Y1 J1", ijk_absolute=True),
    Case(XY, False, "R1"), Case(XY, False, "Z1 R1"), Case(XZ, False, "Y1 R1"), Case(YZ, False, "X1 R1"),
    Case(XY, False, "X0 Y0 R1"), Case(XY, False, "X0 Z5 R1"), Case(XY, False, "X3 R1"),
    Case(XY, False, "X1 R0.4", metric=False), Case(XY, False, "X1 R0", metric=False),
    # the feed check comes after the format checks, before the plane's words
    Case(XY, False, "X1", feed=False), Case(XY, False, "X1 R1 I1", feed=False), Case(XY, False, "R1", feed=False),
    Case(YZ, False, "X1 I1", feed=False), Case(XY, False, "X1 J1 K1", ijk_absolute=True, feed=False),
]


def test_the_table_is_what_linuxcnc_does(tmp_path):
    oracle.require()
    _compare(CASES, tmp_path)


def _random_case(rng: random.Random) -> Case:
    """An arc of random plane, direction, units and format, often near a tolerance's edge, now
    and then with a word that LinuxCNC refuses."""
    plane = rng.choice((XY, XZ, YZ))
    first, second, normal = PLANE_AXES[plane]
    metric = rng.random() < 0.6
    unit = 1.0 if metric else 0.05
    start = [round(rng.uniform(-20, 20) * unit, 4) for _ in range(3)]
    if rng.random() < 0.1:
        start[first] = start[second] = 0.0
    letters = "xyz"
    offsets = {XY: "ij", XZ: "ik", YZ: "jk"}[plane]
    words: dict[str, float] = {}
    end = list(start)
    if rng.random() < 0.55:  # centre format
        radius = rng.choice((0.001, 0.01, 0.1, 1.0, 10.0, 100.0)) * rng.uniform(0.5, 2.0) * unit
        a0, a1 = rng.uniform(-math.pi, math.pi), rng.uniform(-math.pi, math.pi)
        center = [start[first] - radius * math.cos(a0), start[second] - radius * math.sin(a0)]
        tolerance = CENTER_ARC_RADIUS_TOLERANCE_MM if metric else CENTER_ARC_RADIUS_TOLERANCE_INCH
        spiral = rng.choice((0.0, 0.0, 0.0, tolerance, tolerance * 100, radius * 0.001, radius))
        radius2 = radius + spiral * rng.uniform(0.6, 1.4) * rng.choice((1, -1))
        if rng.random() < 0.15:
            a1, radius2 = a0, radius
        end[first] = round(center[0] + radius2 * math.cos(a1), 6)
        end[second] = round(center[1] + radius2 * math.sin(a1), 6)
        absolute = rng.random() < 0.3
        centre_words = center if absolute else [center[0] - start[first], center[1] - start[second]]
        ijk = {letter: round(v, 6) for letter, v in zip(offsets if plane != XZ else "ki", centre_words)}
        if not absolute and rng.random() < 0.1:
            drop = rng.choice(sorted(ijk))
            ijk.pop(drop)
        if rng.random() < 0.03:
            ijk["ijk".replace(offsets[0], "").replace(offsets[1], "")] = 1.0
        if rng.random() < 0.05:
            ijk.pop(rng.choice(sorted(ijk)))
            if not ijk:
                ijk[offsets[0]] = 0.5
    else:  # radius format
        absolute = rng.random() < 0.2
        length = rng.choice((0.002, 0.1, 1.0, 10.0, 50.0)) * rng.uniform(0.2, 2.0) * unit
        angle = rng.choice((0.0, math.pi / 2, math.pi, -math.pi / 2, rng.uniform(-math.pi, math.pi)))
        if rng.random() < 0.2:  # symmetric about the origin: the centre's sign hangs on the last bit
            start[first], start[second] = -length / 2 * math.cos(angle), -length / 2 * math.sin(angle)
            start[first], start[second] = round(start[first], 6), round(start[second], 6)
        end[first] = round(start[first] + length * math.cos(angle), 6)
        end[second] = round(start[second] + length * math.sin(angle), 6)
        half = math.dist((start[first], start[second]), (end[first], end[second])) / 2
        tolerance = RADIUS_TOLERANCE_MM if metric else RADIUS_TOLERANCE_INCH
        radius = rng.choice((half, half, half * rng.uniform(1.0, 4.0), half - tolerance * rng.uniform(0.6, 1.4),
                             half * (1 + 1e-13), 0.0))
        ijk = {"r": round(radius, 6) * rng.choice((1, -1))}
        if rng.random() < 0.03:
            end[first], end[second] = start[first], start[second]
        if rng.random() < 0.03:
            ijk["i"] = 1.0
    for axis in (first, second):
        if end[axis] != start[axis] or rng.random() < 0.5:
            words[letters[axis]] = end[axis]
    if rng.random() < 0.2:
        end[normal] = words[letters[normal]] = round(start[normal] + rng.uniform(-5, 5) * unit, 4)
    if rng.random() < 0.03 and "r" in ijk:
        words.clear()
    words.update(ijk)
    if rng.random() < 0.15:
        words["p"] = rng.choice((2, 3, 7, 0, 1.5, 1.0004))
    text = " ".join(f"{letter.upper()}{_num(value)}" for letter, value in words.items())
    return Case(plane, rng.random() < 0.5, text, (start[0], start[1], start[2]), metric, absolute)


def test_random_arcs_are_what_linuxcnc_does(tmp_path):
    oracle.require()
    rng = random.Random(2749)
    cases = [_random_case(rng) for _ in range(300)]
    outcomes = [_ours(case)[0] for case in cases]
    assert 120 < outcomes.count("arc") < 280  # both kinds well represented
    _compare(cases, tmp_path)


# without the oracle -----------------------------------------------------------------------------

def _arc(plane, clockwise, start, end, words, absolute=False, metric=True) -> ArcMove:
    return arc_move(plane, clockwise, start, end, words, absolute, metric)


def _refusal(plane, clockwise, start, end, words, absolute=False, metric=True) -> str:
    with pytest.raises(BlockError) as info:
        _arc(plane, clockwise, start, end, words, absolute, metric)
    return str(info.value)


def test_a_quarter_circle_and_its_printed_form():
    move = _arc(XY, True, (0, 0, 0), (1, 1, 0), {"x": 1, "y": 1, "i": 0.5, "j": 0.5})
    assert (move.first_center, move.second_center, move.rotation, move.normal) == (0.5, 0.5, -1, 2)
    assert move.center == (0.5, 0.5, 0)
    assert arc_feed_text(move) == "1.0000, 1.0000, 0.5000, 0.5000, -1, 0.0000, 0.0000, 0.0000, 0.0000"
    assert arc_feed_text(move, 1, -2.5, 3).endswith("0.0000, 1.0000, -2.5000, 3.0000")


def test_g18_puts_z_first_and_the_sign_is_the_code_s_in_every_plane():
    move = _arc(XZ, True, (1, 2, 3), (1, 2, 3), {"i": 1})  # a full circle about (x2, z3)
    assert (move.first_end, move.second_end, move.first_center, move.second_center) == (3, 1, 3, 2)
    assert (move.axis_end, move.normal, move.center) == (2, 1, (2, 2, 3))
    for plane in (XY, XZ, YZ):
        a, b = {XY: "ij", XZ: "ki", YZ: "jk"}[plane]
        assert _arc(plane, True, (0, 0, 0), (0, 0, 0), {a: 1, "p": 3}).rotation == -3
        assert _arc(plane, False, (0, 0, 0), (0, 0, 0), {b: 1}).rotation == 1
    helix = _arc(YZ, False, (5, 0, 0), (-4, 1, 1), {"y": 1, "z": 1, "x": -4, "j": 0.5, "k": 0.5})
    assert (helix.axis_end, helix.center, helix.normal) == (-4, (5, 0.5, 0.5), 0)


def test_the_long_way_and_a_half_circle():
    short = _arc(XY, False, (0, 0, 0), (1, 1, 0), {"x": 1, "y": 1, "r": 1})
    long = _arc(XY, False, (0, 0, 0), (1, 1, 0), {"x": 1, "y": 1, "r": -1})
    assert (round(short.first_center, 12), round(short.second_center, 12)) == (0, 1)
    assert (round(long.first_center, 12), round(long.second_center, 12)) == (1, 0)
    # a half chord up to 0.00127 mm over R still makes a half circle (1.00127 - 1 rounds above it)
    half = _arc(XY, False, (0, 0, 0), (2.0025, 0, 0), {"x": 2.0025, "r": 1})
    assert half.first_center == pytest.approx(1.00125) and abs(half.second_center) < 1e-12
    assert _refusal(XY, False, (0, 0, 0), (2.00254, 0, 0), {"x": 2.00254, "r": 1}) == \
        "Arc radius too small to reach end point"


def test_signed_zeros_and_nan_are_printed_as_c_prints_them():
    # pi/2 in extended precision leaves -4e-33 where a double pi/2 leaves 0: rs274 prints -0.0000
    move = _arc(XY, True, (0, -1, 0), (0, 1, 0), {"x": 0, "y": 1, "r": 1})
    assert arc_feed_text(move).startswith("0.0000, 1.0000, 0.0000, -0.0000, -1")
    nan = _arc(XY, False, (0, 0, 0), (0.001, 0, 0), {"x": 0.001, "r": 0})
    assert arc_feed_text(nan) == "0.0010, 0.0000, -nan, -nan, 1, 0.0000, 0.0000, 0.0000, 0.0000"


def test_tolerances_in_mm_and_inch():
    assert RADIUS_TOLERANCE_MM == 0.00005 * 25.4
    assert CENTER_ARC_RADIUS_TOLERANCE_MM == pytest.approx(0.0282842712474619)
    assert _refusal(XY, False, (0, 0, 0), (0, 0, 0), {"i": 0.0012699}).startswith("Zero-radius arc:")
    _arc(XY, False, (0, 0, 0), (0, 0, 0), {"i": 0.00127})
    _arc(XY, False, (0, 0, 0), (0, 0, 0), {"i": 0.00005}, metric=False)
    assert _refusal(XY, False, (0, 0, 0), (2.0029, 0, 0), {"i": 1}, metric=False).startswith("Radius to end")
    _arc(XY, False, (0, 0, 0), (2.0028, 0, 0), {"i": 1}, metric=False)
    _arc(XY, False, (0, 0, 0), (2001.0009, 0, 0), {"i": 1000})  # 1.0009 mm off, but under 0.1 %
    _arc(XY, False, (0, 0, 0), (2000.2828, 0, 0), {"i": 1000}, metric=False)  # under 100 times 0.0028 in
    assert _refusal(XY, False, (0, 0, 0), (2000.2829, 0, 0), {"i": 1000}, metric=False).startswith("Radius")
    assert _refusal(XY, False, (0, 0, 0), (2.0002, 0, 0), {"x": 2.0002, "r": 1}, metric=False) == \
        "Arc radius too small to reach end point"
    _arc(XY, False, (0, 0, 0), (2.00009, 0, 0), {"x": 2.00009, "r": 1}, metric=False)


def test_messages_carry_linuxcnc_s_numbers():
    assert _refusal(XY, False, (0, 0, 0), (1, 0, 0), {"i": 0, "j": 0}) == (
        "Zero-radius arc: start=(X0.0000,Y0.0000) center=(X0.0000,Y0.0000) end=(X1.0000,Y0.0000) "
        "r1=0.0000 r2=1.0000")
    assert _refusal(YZ, True, (0, 0, 1), (0, 1, 0), {"j": 0.5, "k": 0}) == (
        "Radius to end of arc differs from radius to start: start=(Y0.0000,Z1.0000) center=(Y0.5000,Z1.0000) "
        "end=(Y1.0000,Z0.0000) r1=0.5000 r2=1.1180 abs_err=0.618 rel_err=55.2786%")
    assert "abs_err=1 rel_err=50.0000%" in _refusal(XY, True, (3, 0, 0), (6, 0, 0), {"i": 5, "j": 0}, True)


@pytest.mark.parametrize("plane, words, absolute, message", [
    (XY, {"x": 1}, False, "R i j k words all missing for arc"),
    (XY, {"x": 1, "r": 1, "k": 0}, False, "Mixed radius ijk format for arc"),
    (171, {"x": 1}, False, "Cannot do an arc in planes G17.1, G18.1, or G19.1"),
    (XY, {"x": 1, "i": 1, "k": 1}, False, "K word given for arc in xy plane"),
    (XZ, {"x": 1, "j": 1}, False, "J word given for arc in xz plane"),
    (YZ, {"y": 1, "i": 1}, False, "I word given for arc in yz plane"),
    (XY, {"x": 1, "j": 1}, True, "I word missing in absolute center arc"),
    (XZ, {"x": 1, "i": 1}, True, "K word missing in absolute center arc"),
    (YZ, {"y": 1, "k": 1}, True, "J word missing in absolute center arc"),
    (XY, {"z": 1, "r": 1}, False, "X and y words missing for arc in xy plane"),
    (XZ, {"y": 1, "r": 1}, False, "X and z words missing for arc in xz plane"),
    (YZ, {"x": 1, "r": 1}, False, "Y and z words missing for arc in yz plane"),
    (XY, {"x": 1, "i": 1, "p": 0}, False, "P value should be 1 or greater with G2 or G3"),
    (171, {"p": 1.5}, False, "P value not an integer with M19 G2 or G3"),
])
def test_word_refusals(plane, words, absolute, message):
    with pytest.raises(BlockError) as info:
        check_arc_words(plane, words, absolute)
    assert str(info.value) == message


def test_the_feed_check_sits_between_the_format_and_the_plane_s_words():
    with pytest.raises(BlockError, match="R i j k words all missing"):
        check_arc_words(XY, {"x": 1}, False, feed_error=ZERO_FEED)
    with pytest.raises(BlockError, match=ZERO_FEED):
        check_arc_words(YZ, {"x": 1, "i": 1}, False, feed_error=ZERO_FEED)


def test_p_is_a_whole_number_within_a_thousandth():
    assert [turns_of(p) for p in (None, 1, 1.0009, 2.9995, 2147483647)] == [1, 1, 1, 3, 2147483647]
    for p, word in ((1.0011, "not an integer"), (0.5, "not an integer"), (2147483648, "not an integer"),
                    (-0.0001, "1 or greater"), (0, "1 or greater"), (-3, "1 or greater"), (math.nan, "1 or greater")):
        with pytest.raises(BlockError, match=word):
            turns_of(p)


def test_the_same_point_with_r_and_the_end_words():
    assert _refusal(XY, False, (1, 2, 3), (1, 2, 9), {"z": 9, "r": 1}) == "X and y words missing for arc in xy plane"
    assert _refusal(XY, False, (1, 2, 3), (1, 2, 9), {"x": 1, "z": 9, "r": 1}) == \
        "Current point same as end point of arc"


def test_hypot_is_glibc_s():
    # Python's math.hypot is correctly rounded; glibc's (LinuxCNC's) is not always
    rng = random.Random(5)
    pairs = [(round(rng.uniform(-100, 100), 4), round(rng.uniform(-100, 100), 4)) for _ in range(20000)]
    assert all(abs(glibc_hypot(x, y) - math.hypot(x, y)) <= 2 * math.ulp(math.hypot(x, y)) for x, y in pairs)
    assert any(glibc_hypot(x, y) != math.hypot(x, y) for x, y in pairs)
    # the half chord of the table's "X8.2376 Y5.5529 R4.965941294328036", one ulp above Python's
    assert glibc_hypot(-4.1188, -2.77645) == 4.967211294328036 != math.hypot(-4.1188, -2.77645)
    assert glibc_hypot(3.0, 0.0) == 3.0 and glibc_hypot(-0.0, 0.0) == 0.0
    assert glibc_hypot(math.inf, math.nan) == math.inf
