"""NURBS blocks collected into one curve: LinuxCNC's G5.2 ... G5.3 and the Fanuc-style G6.2.

**G5.2 / G5.3** (LinuxCNC 2.9, checked against ``rs274`` and its Python ``gcode`` module by
``tests/test_gcode_nurbs.py``). ``G5.2`` starts a curve whose first control point is the current
point; its weight is the first block's ``P`` when that block has neither X nor Y and ``P > 0``,
else 1. Every block with X and Y (the G5.2 block itself and each following block while G5.2 is
the motion mode) adds the control point ``(X, Y)`` with weight ``P``. ``L`` sets the order ``k``
(default 3; ``L`` <= 3 leaves it as it is, ``L`` > 3 sets it, on any block of the curve).
``G5.3`` ends the curve: ``n + 1`` control points (at least ``k``) get LinuxCNC's clamped uniform
integer knots (``knot_vector_creator``)::

    k zeros, 1, 2, ..., n - k + 1, then k copies of n - k + 2        (n + k + 1 knots)

LinuxCNC 2.9 ignores the plane: in G18 / G19 the blocks still need X and Y and the curve lies
in XY. Other axis words (Z, A, ...) are read and ignored; the curve stays at the start's Z and the
current point moves only at G5.3, to the last control point. So under G91 every control point is
relative to the point before G5.2 (the interpreter must not move its current point while
collecting), and G5.3's own axis words are ignored. A motion code other than G5.2 while
collecting drops the curve without a word (a later G5.3 is then refused), and so does the end of
the program; blocks without motion (F, S, M3, G4, comments) leave it alone.

One divergence: a first block with X and Y and no positive ``P`` is refused here (LinuxCNC takes
the missing P as weight -1, or P0 / P-2 as written, and samples a curve through a non-positive
weight, which a machine cannot follow).

**G6.2** (Fanuc-style NURBS, as in the Lo Valvo & Drago programs LinuxCNC ships; LinuxCNC 2.9
answers ``Unknown g code used``, so there is no oracle)::

    G6.2 P<order> X Y Z R<weight> K<knot> [Q<method>] [F]     first control point
         X Y Z R<weight> K<knot>                              one block per further control point
    G6.2 K<knot>                                              order times: the closing knots

Control points are the blocks' own points in 3-D (the interpreter's resolved end points; the
first must be the current point, where the curve starts), ``R`` defaults to 1, every control
point block carries one knot, and the ``order`` knot-only blocks complete the knot vector to
``n + order`` values. The knots must be non-decreasing and clamped (exactly the first and the
last ``order`` equal), no interior knot repeated ``order`` times, and ``order`` (2 or more) at
most the number of control points; ``Q`` (LinuxCNC's choice of interpolation method) does not
change the geometry and is only read. G6.2 is not in :mod:`~cnc_twin.gcode.modal`'s groups
(LinuxCNC 2.9 has no such code): the interpreter adds it to group 1.

Units: whatever the program's are. Messages are LinuxCNC's where it has one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cnc_twin.gcode.blocks import BlockError
from cnc_twin.geometry.nurbs import NurbsCurve

DEFAULT_ORDER = 3
"""G5.2's order without an L word above 3"""
AXES = "xyzabcuvw"
"""axis letters: a block with one of them (or a G5.2 / G6.2 code) is a NURBS block"""
CLOSE_TOLERANCE = 1e-6
"""G6.2's first control point may differ from the current point by this much (program units)"""

NO_G52 = "Cannot use G5.3 without G5.2 first"
BOTH_XY = "You must specify both X and Y coordinates for Control Points"
P_ONLY_FIRST = "Can specify P without X and Y only for the first control point"
POSITIVE_P = "Must specify positive weight P for every Control Point"
ZERO_FEED = "Cannot make a NURBS with 0 feedrate"


@dataclass
class NurbsBlock:
    """One finished NURBS curve, as the interpreter hands it on.

    ``control_points``: shape ``(n, 3)``, program coordinates x, y, z (G5.2: the current point
    first, as LinuxCNC counts it); ``weights``: ``(n,)``, > 0; ``knots``: ``(n + degree + 1,)``,
    clamped; ``degree``: order - 1; ``line``: the line of the block that started the curve.
    """

    control_points: np.ndarray
    weights: np.ndarray
    knots: np.ndarray
    degree: int
    line: int

    def curve(self) -> NurbsCurve:
        """The curve in the program's 3-D coordinates (parameter range ``knots[0]`` to ``knots[-1]``)."""
        return NurbsCurve(self.control_points, self.weights, self.knots, self.degree)

    def canon_text(self) -> str:
        """``rs274``'s arguments of its ``NURBS_FEED`` call: the number of control points."""
        return f"{len(self.control_points)}, ..."

    @property
    def end(self) -> tuple[float, float, float]:
        """The curve's end, the last control point: the current point after it."""
        x, y, z = self.control_points[-1]
        return float(x), float(y), float(z)


def g53(collector: object, line: int) -> NurbsBlock:
    """A G5.3 block: the open G5.2 curve finished, or LinuxCNC's refusal when there is none
    (``collector`` is whatever the interpreter holds, None after any other motion)."""
    if not isinstance(collector, G52Collector):
        raise BlockError(NO_G52)
    return collector.finish(line)


def _integer(value: float) -> int:
    """An L / P order word read as LinuxCNC reads an integer (within 1e-4 of one)."""
    low = int(np.floor(value))
    if value - low > 0.9999:
        return low + 1
    if value - low > 0.0001:
        raise BlockError("Non integer value for integer")
    return low


def _check_feed(feed_rate: float | None) -> None:
    """``feed_rate``: the rate in effect after the block's own F in G94; None in G93 / G95,
    where LinuxCNC does not look at it."""
    if feed_rate is not None and feed_rate == 0.0:
        raise BlockError(ZERO_FEED)


class G52Collector:
    """LinuxCNC's G5.2 curve, block by block; :meth:`~G52Collector.finish` at G5.3.

    ``start``: the current point before the first block; ``plane``: 170 / 180 / 190 (kept, not
    used: LinuxCNC 2.9's curve is in XY whatever the plane); ``words``: the block's letters
    (lower case) -> values; ``point``: its resolved end point, of which x and y are used;
    ``feed_rate``: see ``_check_feed``. The interpreter calls :meth:`add` for each later
    block, in G5.2 mode, that holds an axis word or G5.2 itself.
    """

    def __init__(self, start: tuple[float, float, float], plane: int, words: dict[str, float],
                 point: tuple[float, float, float], line: int, feed_rate: float | None = None):
        self.start = tuple(float(v) for v in start)
        self.plane = plane
        self.line = line
        self.order = DEFAULT_ORDER
        self.points: list[tuple[float, float, float]] = [self.start]
        self.weights: list[float] = [1.0]
        self._block(words, point, feed_rate, first=True)

    def add(self, words: dict[str, float], point: tuple[float, float, float], line: int,
            feed_rate: float | None = None) -> None:
        """A following block of the curve (with or without G5.2 written)."""
        self._block(words, point, feed_rate, first=False)

    def _block(self, words: dict[str, float], point, feed_rate: float | None, first: bool) -> None:
        order = None
        if "l" in words:
            order = _integer(words["l"])
            if order < 0:
                raise BlockError("Negative l word used")
        has_x, has_y = "x" in words, "y" in words
        if has_x != has_y:
            raise BlockError(BOTH_XY)
        p = words.get("p", -1.0)  # LinuxCNC's value of an absent P
        if not has_x and p > 0 and not first:
            raise BlockError(P_ONLY_FIRST)
        if p <= 0 and not first:
            raise BlockError(POSITIVE_P)
        _check_feed(feed_rate)
        if first and not has_x and p > 0:
            self.weights[0] = float(p)
        if order is not None and order > DEFAULT_ORDER:
            self.order = order
        if has_x:
            if p <= 0:  # first block only: LinuxCNC would sample with this weight
                raise BlockError(POSITIVE_P)
            self.points.append((float(point[0]), float(point[1]), self.start[2]))
            self.weights.append(float(p))

    def finish(self, line: int) -> NurbsBlock:
        """The curve at G5.3 (``line``: the G5.3 block's), with LinuxCNC's knot vector."""
        k = self.order
        if len(self.points) < k:
            raise BlockError(f"You must specify a number of control points at least equal to the order L = {k}")
        n = len(self.points) - 1
        knots = np.concatenate([np.zeros(k), np.arange(1.0, n - k + 2), np.full(k, float(n - k + 2))])
        return NurbsBlock(np.array(self.points), np.array(self.weights), knots, k - 1, self.line)


class G62Collector:
    """A Fanuc-style G6.2 curve, block by block; :meth:`~G62Collector.finish` once
    :attr:`~G62Collector.complete`.

    Same arguments as :class:`G52Collector`; ``point`` is used whole (x, y, z). The interpreter
    calls :meth:`add` for each later block until :attr:`complete` (control point blocks hold an
    axis word, the closing blocks ``G6.2 K`` only a knot), then :meth:`finish`.
    """

    def __init__(self, start: tuple[float, float, float], plane: int, words: dict[str, float],
                 point: tuple[float, float, float], line: int, feed_rate: float | None = None):
        self.start = tuple(float(v) for v in start)
        self.plane = plane
        self.line = line
        if "p" not in words:
            raise BlockError("G6.2 needs the order P in its first block")
        self.order = _integer(words["p"])
        if self.order < 2:
            raise BlockError(f"G6.2 order P must be 2 or more, got P{words['p']:g}")
        if not any(axis in words for axis in AXES):
            raise BlockError("G6.2 needs its first control point (axis words) in its first block")
        if float(np.max(np.abs(np.subtract(point, self.start)))) > CLOSE_TOLERANCE:
            raise BlockError("G6.2 first control point must be the current point "
                             f"({self.start[0]:g}, {self.start[1]:g}, {self.start[2]:g})")
        self.points: list[tuple[float, float, float]] = []
        self.weights: list[float] = []
        self.knots: list[float] = []
        self.closing = 0
        self._block(words, point, feed_rate, first=True)

    @property
    def complete(self) -> bool:
        """True once ``order`` closing knot-only blocks have been read."""
        return self.closing == self.order

    def add(self, words: dict[str, float], point: tuple[float, float, float], line: int,
            feed_rate: float | None = None) -> None:
        """A following block: a control point or a closing knot."""
        if self.complete:
            raise BlockError(f"G6.2 curve already has its {self.order} closing knots")
        self._block(words, point, feed_rate, first=False)

    def _block(self, words: dict[str, float], point, feed_rate: float | None, first: bool) -> None:
        if "k" not in words:
            raise BlockError("G6.2 needs a knot K in every block")
        if not first and ("p" in words or "q" in words):
            raise BlockError("G6.2 takes P and Q only in its first block")
        _check_feed(feed_rate)
        knot = float(words["k"])
        if not any(axis in words for axis in AXES):  # a closing knot
            if "r" in words:
                raise BlockError("G6.2 closing knot block takes no weight R")
            self.closing += 1
            self.knots.append(knot)
            return
        if self.closing:
            raise BlockError("G6.2 control point after the closing knots")
        weight = float(words.get("r", 1.0))
        if not weight > 0:
            raise BlockError(f"G6.2 weight R must be positive, got R{weight:g}")
        self.points.append(tuple(float(v) for v in point))
        self.weights.append(weight)
        self.knots.append(knot)

    def finish(self, line: int) -> NurbsBlock:
        """The curve, its knots checked (``line``: the last block's)."""
        k, n = self.order, len(self.points)
        knots = np.array(self.knots)
        if n < k:
            raise BlockError(f"G6.2 order P{k} needs at least {k} control points, got {n}")
        if self.closing != k:
            # the closing blocks complete the knots: one per control point, then `order` more
            raise BlockError(f"G6.2 with {n} control points and order P{k} needs {n + k} knots K "
                             f"({k} closing G6.2 K blocks), got {len(knots)}")
        if np.any(np.diff(knots) < 0):
            raise BlockError("G6.2 knots K must not decrease")
        if np.any(knots[:k] != knots[0]) or np.any(knots[-k:] != knots[-1]) or not (
                knots[k] > knots[0] and knots[n - 1] < knots[-1]):
            # exactly `order` equal knots at each end: the curve starts and ends at the end points
            raise BlockError(f"G6.2 knots must be clamped: exactly the first {k} and the last {k} knots equal")
        _, counts = np.unique(knots[k:n], return_counts=True)
        if counts.size and counts.max() >= k:
            raise BlockError(f"G6.2 interior knot repeated {counts.max()} times: at most {k - 1} for order P{k}")
        return NurbsBlock(np.array(self.points), np.array(self.weights), knots, k - 1, self.line)
