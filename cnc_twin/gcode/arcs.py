"""Arcs (G2 / G3): the centre, turn count and refusals exactly as LinuxCNC 2.9 computes them
(``convert_arc`` / ``arc_data_ijk`` / ``arc_data_r``), checked call for call against its
interpreter (``tests/test_gcode_arcs.py``).

Planes and signs. An arc lies in the active plane, named by its *first* and *second* axis (the
order of ``ARC_FEED``'s arguments) and the *normal* axis a helix climbs along:

- G17: first X, second Y, normal Z, centre words I J;
- G18: first **Z**, second **X**, normal Y, centre words K I (``ARC_FEED`` prints z before x);
- G19: first Y, second Z, normal X, centre words J K.

The turn count is ``-P`` for G2 and ``+P`` for G3 in every plane (P defaults to 1): "clockwise"
is seen looking down the normal with the first axis to the right and the second up, which for G18
is the view from +Y. A turn count of one goes from start to end the given way round, less than a
whole circle (a whole circle when start = end); each further turn adds a whole circle.

Coordinates are program coordinates, as ``rs274`` prints them (the canonical layer applies G92 /
G5x offsets, so neither side sees them), a G90.1 centre included. In lathe diameter mode (G7) the
caller halves X; I stays a radius (LinuxCNC does not halve it).

Centre format (I J K). In G91.1 (the default) the offsets add to the start point and a missing
one of the plane's two letters is 0; in G90.1 they are the centre itself, in program coordinates,
and both letters must be given. The radius to the start (r1) and to the end (r2) must both be at
least ``RADIUS_TOLERANCE`` (0.00005 in, 0.00127 mm) and may differ by at most
``CENTER_ARC_RADIUS_TOLERANCE`` (2·√2·0.001 in, 2·√2·0.01 mm), or by up to 100 times that if the
difference is within 0.1 % of the larger radius (``rel_err <= 0.001``). An end equal to the start
is a full circle.

Radius format (R). The centre lies on the perpendicular bisector of start and end; ``R > 0`` takes
the short way (at most half a circle), ``R < 0`` the long way. Start = end (in the plane's two
axes, exactly) is refused, as is a half chord longer than ``|R|`` by more than
``RADIUS_TOLERANCE``; within it the arc is a half circle. ``R0`` (or ``R-0``) reaching that far
gives a centre of NaN, printed ``-nan``, as LinuxCNC does.

P (turns). Checked first, before anything else about the arc: it must be within 0.001 of a whole
number (C's ``(int)(p + 0.5)``, so 2147483648 and beyond are "not an integer") and at least 1.

Floating point is LinuxCNC's, so the printed centre and the tolerance checks agree to the last
bit: ``hypot`` is glibc 2.35+'s (not Python's, which rounds differently in about 0.1 % of cases)
and the R-format angle ``atan2(...) ± π/2`` is done in x87 extended precision, as the C code's
``M_PI_2l`` makes it.

Errors, in LinuxCNC's order (each is a :class:`~cnc_twin.gcode.blocks.BlockError` with its
wording): P; plane G17.1/G18.1/G19.1; neither R nor I J K; both; the feed check (done by the
caller, passed in as ``feed_error``); an offset letter of another plane / a missing letter in
G90.1 / no end-point word in the plane with R; the geometry (start = end with R, radius too
small, zero radius, radii differ). Not covered here: cutter compensation (G41/G42 arcs) and polar
end points (``@`` ``^``).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # exact arithmetic only for R arcs' angles: imported there (1.5 ms a start-up)
    from fractions import Fraction

from cnc_twin.gcode.blocks import BlockError
from cnc_twin.gcode.modal import G

PLANE_AXES: dict[int, tuple[int, int, int]] = {G.G17: (0, 1, 2), G.G18: (2, 0, 1), G.G19: (1, 2, 0)}
"""plane (G code in tenths) -> indices into (x, y, z) of its first, second and normal axis"""
CENTER_LETTERS: dict[int, tuple[str, str]] = {G.G17: ("i", "j"), G.G18: ("k", "i"), G.G19: ("j", "k")}
"""plane -> the offset words of its first and second axis"""
UV_PLANES = frozenset((G.G17_1, G.G18_1, G.G19_1))
"""G17.1 G18.1 G19.1: LinuxCNC makes no arcs there"""

MM_PER_INCH = 25.4
RADIUS_TOLERANCE_INCH = 0.00005
"""a centre-format radius below this is zero; an R arc may fall short of its end by this (inch)"""
RADIUS_TOLERANCE_MM = RADIUS_TOLERANCE_INCH * MM_PER_INCH
CENTER_ARC_RADIUS_TOLERANCE_INCH = 2 * 0.001 * math.sqrt(2)
"""how much the end radius may differ from the start radius (inch; LinuxCNC's default, an INI
setting on a real machine): rounding both ends and the centre to 0.001 in stays within it"""
CENTER_ARC_RADIUS_TOLERANCE_MM = 2 * 0.01 * math.sqrt(2)
SPIRAL_RELATIVE_TOLERANCE = 0.001
"""a radius difference within this fraction of the larger radius may reach 100 times the above"""
SPIRAL_ABSOLUTE_LIMIT = 100.0
"""no radius difference beyond this many times the absolute tolerance, whatever the radius"""
TINY = 1e-12
"""an R arc whose half chord is within this fraction of R is a half circle"""
P_INTEGER_TOLERANCE = 0.001
"""P must be this close to a whole number"""

_PLANE_NAMES = {G.G17: "xy", G.G18: "xz", G.G19: "yz"}
_AXIS_NAMES = "XYZ"
# the offset letter that does not belong to the plane, and the order LinuxCNC looks for the two
# that do when the centre is absolute (I before K in G18, whatever the axes' order)
_STRAY_LETTER = {G.G17: "k", G.G18: "j", G.G19: "i"}
_ABSOLUTE_ORDER = {G.G17: ("i", "j"), G.G18: ("i", "k"), G.G19: ("j", "k")}
_END_LETTERS = {G.G17: ("x", "y"), G.G18: ("x", "z"), G.G19: ("y", "z")}


@dataclass(frozen=True, init=False)
class ArcMove:
    """One arc as LinuxCNC's ``ARC_FEED`` gives it, in program units and coordinates.

    ``first_end`` / ``second_end``: the end point on the plane's first and second axis;
    ``first_center`` / ``second_center``: the centre on them; ``rotation``: the signed turn count
    (``-P`` for G2, ``+P`` for G3); ``axis_end``: the end on the normal axis (a helix when it
    differs from the start's); ``center``: the centre as (x, y, z), its normal-axis coordinate the
    start's; ``normal``: index (0, 1, 2) of the normal axis.
    """

    first_end: float
    second_end: float
    first_center: float
    second_center: float
    rotation: int
    axis_end: float
    center: tuple[float, float, float]
    normal: int

    def __init__(self, first_end: float, second_end: float, first_center: float, second_center: float, rotation: int,
                 axis_end: float, center: tuple[float, float, float], normal: int):
        # one a G2 / G3 line: filled in directly, as Call is (the frozen way costs twice as much)
        fields = self.__dict__
        fields["first_end"], fields["second_end"] = first_end, second_end
        fields["first_center"], fields["second_center"] = first_center, second_center
        fields["rotation"], fields["axis_end"], fields["center"], fields["normal"] = rotation, axis_end, center, normal


def arc_move(plane: int, clockwise: bool, start: tuple[float, float, float], end: tuple[float, float, float],
             words: dict[str, float], ijk_absolute: bool, metric: bool, *,
             feed_error: str | None = None) -> ArcMove:
    """The arc a G2 (``clockwise``) or G3 block makes, or LinuxCNC's refusal.

    ``plane``: 170 / 180 / 190 (G17 / G18 / G19 in tenths; 171 / 181 / 191 are refused as LinuxCNC
    refuses them); ``start``, ``end``: program coordinates (x, y, z) of the current point and the
    programmed end (G90 / G91 already resolved); ``words``: the block's letters -> values (``i j
    k r p`` are read here, ``x y z`` only for whether they were given); ``ijk_absolute``: G90.1;
    ``metric``: G21 (the tolerances are in program units). ``feed_error``: the message of the
    caller's feed check (zero feed rate, no F in inverse time...), if it failed: LinuxCNC makes
    that check after the R / I J K format checks and before the rest, so it is raised there.
    """
    turns = check_arc_words(plane, words, ijk_absolute, feed_error=feed_error)
    start, end = (float(start[0]), float(start[1]), float(start[2])), (float(end[0]), float(end[1]), float(end[2]))
    first, second, normal = PLANE_AXES[plane]
    radius_tolerance = RADIUS_TOLERANCE_MM if metric else RADIUS_TOLERANCE_INCH
    args = (plane, clockwise, start[first], start[second], end[first], end[second])
    if "r" in words:
        c1, c2 = _center_from_radius(*args, words["r"], radius_tolerance)
    else:
        letter1, letter2 = CENTER_LETTERS[plane]
        spiral = CENTER_ARC_RADIUS_TOLERANCE_MM if metric else CENTER_ARC_RADIUS_TOLERANCE_INCH
        c1, c2 = _center_from_offsets(*args, ijk_absolute, words.get(letter1, 0.0), words.get(letter2, 0.0),
                                      radius_tolerance, spiral)
    center = list(start)
    center[first], center[second] = c1, c2
    # first_end, second_end, first_center, second_center, rotation, axis_end, center, normal
    return ArcMove(end[first], end[second], c1, c2, -turns if clockwise else turns, end[normal],
                   (center[0], center[1], center[2]), normal)


def xy_offset_arc(clockwise: bool, start, end, i: float, j: float, metric: bool) -> ArcMove:
    """The arc of a G17 G2 / G3 block given by I and / or J alone, centre relative (G91.1), with a
    feed (the checks :func:`check_arc_words` makes cannot fail then): :func:`arc_move`'s result
    for it, the common CAM arc's short way. ``start``, ``end``: x y z (program coordinates)."""
    c1, c2 = _center_from_offsets(
        G.G17, clockwise, start[0], start[1], end[0], end[1], False, i, j,
        RADIUS_TOLERANCE_MM if metric else RADIUS_TOLERANCE_INCH,
        CENTER_ARC_RADIUS_TOLERANCE_MM if metric else CENTER_ARC_RADIUS_TOLERANCE_INCH)
    return ArcMove(end[0], end[1], c1, c2, -1 if clockwise else 1, end[2], (c1, c2, start[2]), 2)


def check_arc_words(plane: int, words: dict[str, float], ijk_absolute: bool, *,
                    feed_error: str | None = None) -> int:
    """The checks of an arc block that need no geometry, in LinuxCNC's order; the turn count P
    (1 if absent). :func:`arc_move` makes them first; a caller that finds the end point with
    checks of its own (LinuxCNC's ``find_ends`` comes after these) may call this before."""
    turns = turns_of(words.get("p"))
    if plane in UV_PLANES:
        raise BlockError("Cannot do an arc in planes G17.1, G18.1, or G19.1")
    if plane not in PLANE_AXES:
        raise ValueError(f"no arc plane {plane} (170, 180 or 190)")
    ijk = "i" in words or "j" in words or "k" in words
    if "r" not in words and not ijk:
        raise BlockError("R i j k words all missing for arc")
    if "r" in words and ijk:
        raise BlockError("Mixed radius ijk format for arc")
    if feed_error is not None:
        raise BlockError(feed_error)
    name = _PLANE_NAMES[plane]
    if ijk:
        stray = _STRAY_LETTER[plane]
        if stray in words:
            raise BlockError(f"{stray.upper()} word given for arc in {name} plane")
        if ijk_absolute:
            for letter in _ABSOLUTE_ORDER[plane]:
                if letter not in words:
                    raise BlockError(f"{letter.upper()} word missing in absolute center arc")
    elif not any(letter in words for letter in _END_LETTERS[plane]):
        # an R arc needs an end point away from the start: a full circle is not possible
        a, b = _END_LETTERS[plane]
        raise BlockError(f"{a.upper()} and {b} words missing for arc in {name} plane")
    return turns


def turns_of(p: float | None) -> int:
    """The turn count a G2 / G3 block's P word gives (1 without one), or LinuxCNC's refusal."""
    if p is None:
        return 1
    turns = _round_to_int(p)
    if abs(float(turns) - p) > P_INTEGER_TOLERANCE:
        raise BlockError("P value not an integer with M19 G2 or G3")
    if turns < 1:
        raise BlockError("P value should be 1 or greater with G2 or G3")
    return turns


def arc_feed_text(move: ArcMove, a: float = 0.0, b: float = 0.0, c: float = 0.0) -> str:
    """The arguments of ``ARC_FEED`` as ``rs274`` prints them: four decimals, the turn count as
    an integer, then the normal-axis end and the rotary axes a, b, c (``-0.0000`` and ``-nan`` as
    C prints them)."""
    values = (move.first_end, move.second_end, move.first_center, move.second_center, move.axis_end, a, b, c)
    total = sum(values)
    if total == total:  # no NaN among them (inf - inf is NaN too: then value by value)
        return _ARC_TEXT % (*values[:4], move.rotation, *values[4:])
    texts = [_fixed(v) for v in values]
    return ", ".join(texts[:4] + [str(move.rotation)] + texts[4:])


_ARC_TEXT = "%.4f, %.4f, %.4f, %.4f, %d, %.4f, %.4f, %.4f, %.4f"
"""ARC_FEED's arguments when none is NaN (``%.4f`` as ``_fixed`` prints a number)"""


def glibc_hypot(x: float, y: float) -> float:
    """``hypot`` as glibc 2.35+ computes it without FMA (Borges' corrected ``sqrt(x² + y²)``), bit
    for bit: LinuxCNC's radii come from it and Python's ``math.hypot`` rounds some differently."""
    ax, ay = abs(x), abs(y)
    if ax < ay:
        ax, ay = ay, ax
    if _TINY_VALUE <= ay and ax <= _LARGE and ay > ax * _EPS:  # the common case (NaN fails every test)
        h = math.sqrt(ax * ax + ay * ay)  # glibc's kernel (_hypot_kernel), inline: an arc takes two
        if h <= 2.0 * ay:
            delta = h - ay
            return h - (ax * (2.0 * delta - ax) + (delta - 2.0 * (ax - ay)) * delta) / (2.0 * h)
        delta = h - ax
        return h - (2.0 * delta * (ax - 2.0 * ay) + ((4.0 * delta - ay) * ay + delta * delta)) / (2.0 * h)
    if not (math.isfinite(x) and math.isfinite(y)):
        return math.inf if math.isinf(x) or math.isinf(y) else x + y
    x, y = abs(x), abs(y)
    ax, ay = (y, x) if x < y else (x, y)
    if ax > _LARGE:
        if ay <= ax * _EPS:
            return ax + ay
        return _hypot_kernel(ax * _SCALE, ay * _SCALE) / _SCALE
    if ay < _TINY_VALUE:
        if ax >= ay / _EPS:
            return ax + ay
        return _hypot_kernel(ax / _SCALE, ay / _SCALE) * _SCALE
    if ay <= ax * _EPS:
        return ax + ay
    return _hypot_kernel(ax, ay)


_SCALE, _LARGE, _TINY_VALUE, _EPS = 2.0 ** -600, 2.0 ** 511, 2.0 ** -459, 2.0 ** -54


def _hypot_kernel(ax: float, ay: float) -> float:
    """glibc's kernel for ``ax >= ay >= 0`` whose squares neither overflow nor underflow."""
    h = math.sqrt(ax * ax + ay * ay)
    if h <= 2.0 * ay:
        delta = h - ay
        t1 = ax * (2.0 * delta - ax)
        t2 = (delta - 2.0 * (ax - ay)) * delta
    else:
        delta = h - ax
        t1 = 2.0 * delta * (ax - 2.0 * ay)
        t2 = (4.0 * delta - ay) * ay + delta * delta
    return h - (t1 + t2) / (2.0 * h)


def _center_from_offsets(plane: int, clockwise: bool, start1: float, start2: float, end1: float, end2: float,
                         absolute: bool, offset1: float, offset2: float, radius_tolerance: float,
                         spiral_tolerance: float) -> tuple[float, float]:
    """``arc_data_ijk``: the centre (first, second) from I J K, its radii checked."""
    if absolute:
        c1, c2 = offset1, offset2
    else:
        c1, c2 = start1 + offset1, start2 + offset2
    r1 = glibc_hypot(c1 - start1, c2 - start2)
    r2 = glibc_hypot(c1 - end1, c2 - end2)
    if r1 < radius_tolerance or r2 < radius_tolerance:
        raise BlockError(f"Zero-radius arc: {_arc_points(plane, start1, start2, c1, c2, end1, end2, r1, r2)}")
    abs_err = abs(r1 - r2)
    rel_err = abs_err / (r2 if r1 < r2 else r1)
    if abs_err > spiral_tolerance * SPIRAL_ABSOLUTE_LIMIT or (
            rel_err > SPIRAL_RELATIVE_TOLERANCE and abs_err > spiral_tolerance):
        raise BlockError(f"Radius to end of arc differs from radius to start: "
                         f"{_arc_points(plane, start1, start2, c1, c2, end1, end2, r1, r2)} "
                         f"abs_err={_general(abs_err)} rel_err={_fixed(rel_err * 100)}%")
    return c1, c2


def _arc_points(plane: int, start1: float, start2: float, c1: float, c2: float, end1: float, end2: float,
                r1: float, r2: float) -> str:
    """An offset arc's points and radii as LinuxCNC's refusals give them (made only for a refusal:
    a program's arcs are many)."""
    a, b = (_AXIS_NAMES[k] for k in PLANE_AXES[plane][:2])
    return (f"start=({a}{_fixed(start1)},{b}{_fixed(start2)}) center=({a}{_fixed(c1)},{b}{_fixed(c2)}) "
            f"end=({a}{_fixed(end1)},{b}{_fixed(end2)}) r1={_fixed(r1)} r2={_fixed(r2)}")


def _center_from_radius(plane: int, clockwise: bool, start1: float, start2: float, end1: float, end2: float,
                        radius: float, tolerance: float) -> tuple[float, float]:
    """``arc_data_r``: the centre (first, second) from R, step by step as the C code does it."""
    if end1 == start1 and end2 == start2:
        raise BlockError("Current point same as end point of arc")
    abs_radius = abs(radius)
    mid1 = (end1 + start1) / 2.0
    mid2 = (end2 + start2) / 2.0
    half_length = glibc_hypot(mid1 - end1, mid2 - end2)
    if half_length - abs_radius > tolerance:
        raise BlockError("Arc radius too small to reach end point")
    if abs_radius == 0.0:
        # C goes on with 0 / 0: x86's default NaN, sign bit set, through to the centre
        nan = math.copysign(math.nan, -1.0)
        return nan, nan
    if half_length / abs_radius > 1 - TINY:
        half_length = abs_radius  # a half circle, allowing for rounding
    chord_angle = math.atan2(end2 - start2, end1 - start1)
    # the centre is to the right of the chord (start -> end) for a short G2 or a long G3
    toward_right = (clockwise and radius > 0) or (not clockwise and radius < 0)
    theta = _add_half_pi(chord_angle, -1 if toward_right else 1)
    turn2 = math.asin(half_length / abs_radius)
    offset = abs_radius * math.cos(turn2)
    return mid1 + offset * math.cos(theta), mid2 + offset * math.sin(theta)


def _round_bits(x: Fraction, bits: int) -> Fraction:
    """``x`` rounded to ``bits`` significant bits, ties to even (a binary float's rounding)."""
    if x == 0:
        return x
    n, d = abs(x.numerator), x.denominator
    shift = bits - (n.bit_length() - d.bit_length())
    if (n << max(shift, 0)) // (d << max(-shift, 0)) >= 1 << bits:
        shift -= 1
    num, den = (n << shift, d) if shift >= 0 else (n, d << -shift)
    q, r = divmod(num, den)
    if 2 * r > den or (2 * r == den and q & 1):
        q += 1
    result = type(x)(q, 1 << shift) if shift >= 0 else type(x)(q << -shift)
    return result if x > 0 else -result


@functools.cache
def _half_pi_long() -> Fraction:
    """C's ``M_PI_2l``: π/2 as an x87 extended double (64-bit significand)"""
    from fractions import Fraction

    return _round_bits(Fraction("1.570796326794896619231321691639751442"), 64)


def _add_half_pi(angle: float, sign: int) -> float:
    """``angle + sign·M_PI_2l`` as C computes ``double theta = atan2(...) ± M_PI_2l``: in extended
    precision, then stored as a double (rounded twice)."""
    from fractions import Fraction

    return float(_round_bits(_round_bits(Fraction(angle) + sign * _half_pi_long(), 64), 53))


def _round_to_int(value: float) -> int:
    """LinuxCNC's ``round_to_int``: ``(int)(value ± 0.5)``, C's truncating conversion, which on
    x86-64 gives INT_MIN for anything out of range (and for NaN)."""
    shifted = value - 0.5 if value < 0.0 else value + 0.5
    if not -2147483649.0 < shifted < 2147483648.0:
        return -2147483648
    return int(shifted)


def _fixed(value: float) -> str:
    """``%.4f`` as C prints it (NaN with its sign)."""
    if math.isnan(value):
        return "-nan" if math.copysign(1.0, value) < 0 else "nan"
    return f"{value:.4f}"


def _general(value: float) -> str:
    """``%.4g`` as C prints it."""
    if math.isnan(value):
        return "-nan" if math.copysign(1.0, value) < 0 else "nan"
    return "%.4g" % value
