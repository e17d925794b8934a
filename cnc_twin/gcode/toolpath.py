"""Canonical calls -> the operations a machine runs, in workpiece coordinates (mm, deg, s).

The calls carry program coordinates in the program's units; as LinuxCNC's canon does
(``rotate_and_offset_pos``), a point on the machine is the program's point plus the G92 offset,
the G5x work offset and the tool length offset, each converted from the units it was given in.
The twin's machine coordinates are the tool tip's in the workpiece frame (the bundled machine's
head kinematics carries the pad): so work offsets put the program's zero onto the workpiece.

The operations, in program order (:mod:`cnc_twin.gcode.path_ops`): traverses, feed paths (A B C
held; corners between lines blended within the G64 ``P`` tolerance, others, and all in G61 /
G61.1, stop; under G64 P runs of gently turning lines fitted as one curve,
:mod:`cnc_twin.gcode.line_fit`), tool-axis paths (G1 runs turning the head, fitted under G64 P),
pauses, spindle and force changes, probing moves. The feed paths are shaped in
:mod:`cnc_twin.gcode.feed_paths` (joins, fits, corner blends).

:func:`iter_operations` makes them as the calls come, so a program of any length is held a feed
path at a time: a run of G1 lines is gathered as one array (a
:class:`~cnc_twin.gcode.path_ops.LineChain`), and a chain of more than ``PATH_ELEMENTS``
elements is cut there, with an exact stop.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field

import numpy as np

from cnc_twin.gcode.canon import Call
from cnc_twin.gcode.feed_paths import OpenChain
from cnc_twin.gcode.modal import G
from cnc_twin.gcode.paths_ahead import PathsAhead
from cnc_twin.gcode.path_ops import (
    Element, FeedPath, ForceChange, LineChain, Operation, Pause, Probe, SpindleChange, ToolAxisPath, ToolpathError,
    Traverse, line_element, programmed_geometry,
)
from cnc_twin.geometry.bezier import bezier_pieces, homogeneous, knot_spans

__all__ = ["operations", "iter_operations", "arc_element", "curve_element", "Element", "FeedPath", "ForceChange",
           "Operation", "Pause", "Probe", "SpindleChange", "ToolAxisPath", "ToolpathError", "Traverse", "line_element", "programmed_geometry"]
"""the operations are re-exported: what the program becomes is looked for here"""

INCH = 25.4
"""[mm]"""
DEFAULT_AXIS_TOLERANCE = 0.05
"""[deg] how far a fitted tool axis may turn from the programmed one (A / B words)"""
DEFAULT_BLEND = 0.01
"""[mm] blend tolerance of G64 without P (LinuxCNC: "as fast as possible", no limit)"""
PATH_ELEMENTS = 20_000
"""programmed elements of one feed path at most: a longer chain of blended lines (a CAM raster of
hours under G64 is one) is cut into paths of this many, each ending in an exact stop on its last
programmed vertex, so a program is prepared a bounded piece at a time. A cut costs a stop a few
tens of milliseconds long; the card already stops every few hundred of a fitted path's spans
(``CARD_CONTROL_POINTS``)"""


def _arc_piece_points(center, e1, e2, radius, a0, sweep, n, z0, dz, normal):
    """Rational quadratic pieces of a circle (helix: the normal coordinate linear in each piece's
    control points) from angle ``a0`` through ``sweep`` [rad] in ``n`` equal pieces."""
    half = 0.5 * sweep / n
    w = math.cos(abs(half))
    pieces = []
    for i in range(n):
        t0, tm, t1 = a0 + 2 * i * half, a0 + (2 * i + 1) * half, a0 + (2 * i + 2) * half
        z_a, z_b = z0 + dz * i / n, z0 + dz * (i + 1) / n
        p0 = center + radius * (math.cos(t0) * e1 + math.sin(t0) * e2) + z_a * normal
        pm = center + radius / w * (math.cos(tm) * e1 + math.sin(tm) * e2) + 0.5 * (z_a + z_b) * normal
        p1 = center + radius * (math.cos(t1) * e1 + math.sin(t1) * e2) + z_b * normal
        pieces.append(homogeneous([p0, pm, p1], [1.0, w, 1.0]))
    return pieces


def _helix_error(half: float) -> float:
    """Largest error of a rational quadratic helix piece of half-angle ``half`` [rad] in its
    normal coordinate, as a fraction of the piece's rise (the rational parameter is not the angle)."""
    w = math.cos(half)
    t = np.linspace(0.0, 1.0, 65)
    d = (1 - t) ** 2 + 2 * w * t * (1 - t) + t ** 2
    rise = (w * t * (1 - t) + t ** 2) / d  # z of control points 0, 1/2, 1
    x = ((1 - t) ** 2 * math.cos(-half) + 2 * w * t * (1 - t) / w + t ** 2 * math.cos(half)) / d
    y = ((1 - t) ** 2 * math.sin(-half) + t ** 2 * math.sin(half)) / d
    angle = (np.arctan2(y, x) + half) / (2 * half)
    return float(np.max(np.abs(rise - angle)))


def arc_element(start: np.ndarray, arc, offset: np.ndarray, scale: float, tolerance: float, line: int) -> Element:
    """An ARC_FEED's arc (:class:`~cnc_twin.gcode.arcs.ArcMove`, program units) in workpiece mm,
    from ``start`` (mm); a helix within ``tolerance`` [mm] in its normal coordinate."""
    from cnc_twin.gcode.arcs import PLANE_AXES

    first, second, normal = {2: PLANE_AXES[G.G17], 1: PLANE_AXES[G.G18], 0: PLANE_AXES[G.G19]}[arc.normal]
    e1, e2, en = np.eye(3)[first], np.eye(3)[second], np.eye(3)[normal]
    center = np.asarray(arc.center, dtype=float) * scale + offset
    center = center - center[normal] * en  # in the plane through the origin; the normal part goes in z
    end = start.copy()
    end[first] = arc.first_end * scale + offset[first]
    end[second] = arc.second_end * scale + offset[second]
    end[normal] = arc.axis_end * scale + offset[normal]
    r_start = math.hypot(start[first] - center[first], start[second] - center[second])
    a0 = math.atan2(start[second] - center[second], start[first] - center[first])
    a1 = math.atan2(end[second] - center[second], end[first] - center[first])
    turns = abs(arc.rotation)
    if arc.rotation > 0:
        sweep = (a1 - a0) % (2 * math.pi)
    else:
        sweep = (a0 - a1) % (2 * math.pi)
    if sweep <= 1e-12:
        sweep = 2 * math.pi
    sweep += 2 * math.pi * (turns - 1)
    signed = sweep if arc.rotation > 0 else -sweep
    rise = end[normal] - start[normal]
    n = max(1, math.ceil(sweep / (math.pi / 2) - 1e-9))
    while rise != 0.0 and abs(rise) / n * _helix_error(0.5 * sweep / n) > 0.25 * tolerance and n < 4096:
        n *= 2
    pieces = _arc_piece_points(center, e1, e2, r_start, a0, signed, n, start[normal], rise, en)
    # the programmed end exactly, so elements join bit for bit (the radius may differ within
    # LinuxCNC's tolerance; that difference goes into the last piece)
    pieces[0][0] = np.append(start, 1.0)
    pieces[-1][-1] = np.append(end, 1.0)
    return Element(pieces, line, "arc")


def curve_element(block, start: np.ndarray, offset: np.ndarray, scale: float, line: int) -> Element:
    """A NURBS_FEED's curve (:class:`~cnc_twin.gcode.nurbs.NurbsBlock`) in workpiece mm, its first
    control point ``start`` (mm): the curve starts where the tool is, bit for bit."""
    points = np.asarray(block.control_points, dtype=float) * scale + offset
    points[0] = start
    return Element(bezier_pieces(points, block.weights, block.knots, block.degree), line, "curve",
                   knot_spans(block.knots, block.degree),
                   (block.degree, [float(k) for k in block.knots], [float(w) for w in block.weights], points))


# -- calls -> operations ------------------------------------------------------------------------

@dataclass
class _Canon:
    """What LinuxCNC's canon keeps between calls: units, offsets (mm / deg), feed, modes."""

    scale: float = 1.0
    g5x: np.ndarray = field(default_factory=lambda: np.zeros(6))
    g92: np.ndarray = field(default_factory=lambda: np.zeros(6))
    tool: np.ndarray = field(default_factory=lambda: np.zeros(6))
    feed: float = 0.0
    """[mm/min] (or deg/min)"""
    control: tuple = ("CANON_CONTINUOUS", 0.0)
    spindle_speed: float = 0.0
    spindle_direction: int = 0
    air: np.ndarray = field(default_factory=lambda: np.zeros(6))
    """x y z a b c [mm / deg]: the run's raise in Z (a run in the air), outside the program's sight
    as LinuxCNC's external offsets are"""

    def to_mm(self, values) -> np.ndarray:
        """Program values x y z a b c -> mm / deg, unoffset."""
        v = np.asarray(values[:6], dtype=float).copy()
        v[:3] *= self.scale
        return v

    def machine(self, values) -> np.ndarray:
        """Program point x y z a b c -> the machine's (workpiece frame) point, mm / deg."""
        return self.to_mm(values) + self.offset

    def point(self, values) -> list[float]:
        """:meth:`machine` in Python floats, the same numbers (each ``value * scale + offset``
        for x y z, ``value + offset`` for a b c, as numpy's element-wise operations make them)
        at a tenth of its cost: a CAM program's every line asks."""
        o, s = self.offset_list, self.scale
        return [values[0] * s + o[0], values[1] * s + o[1], values[2] * s + o[2],
                values[3] + o[3], values[4] + o[4], values[5] + o[5]]

    @property
    def offset(self) -> np.ndarray:
        """G92 + G5x + tool length offset (+ the run's raise in Z), x y z a b c [mm / deg]."""
        return self.g92 + self.g5x + self.tool + self.air

    @property
    def offset_list(self) -> list[float]:
        """:attr:`offset` as Python floats, kept until an offset is set again (:meth:`offsets_set`)."""
        kept = self.__dict__.get("_offset_list")
        if kept is None:
            kept = self.__dict__["_offset_list"] = self.offset.tolist()
        return kept

    def offsets_set(self) -> None:
        """An offset was set: :attr:`offset_list` is made anew when next asked for."""
        self.__dict__.pop("_offset_list", None)


def operations(calls: Iterable[Call], *, default_blend: float = DEFAULT_BLEND,
               axis_tolerance: float = DEFAULT_AXIS_TOLERANCE, start=None, air: float = 0.0) -> list[Operation]:
    """The operations of a program's calls (:func:`iter_operations`), all of them."""
    return list(iter_operations(calls, default_blend=default_blend, axis_tolerance=axis_tolerance, start=start,
                                air=air))


def iter_operations(calls: Iterable[Call], *, default_blend: float = DEFAULT_BLEND,
                    axis_tolerance: float = DEFAULT_AXIS_TOLERANCE, start=None, air: float = 0.0,
                    path_elements: int = PATH_ELEMENTS, helper: bool = False) -> Iterator[Operation]:
    """The operations of a program's canonical calls in order
    (:func:`~cnc_twin.gcode.interpreter.read_program`, or
    :meth:`~cnc_twin.gcode.interpreter.Interpreter.stream` as they are made), each yielded as
    soon as the calls after it end it: a program of any length is held a feed path at a time.
    ``axis_tolerance`` [deg]: how far a fitted tool axis may turn from the programmed one;
    ``start``: where the machine stands when the program starts (x y z a b c, machine point in mm /
    deg, as the program was read from: see ``read_program``'s ``start``), or None when not known;
    ``air`` [mm]: every point raised this far along Z (the program proved in the air);
    ``path_elements``: a feed path (or a run of G1 lines turning the head) of more programmed
    elements is cut there, an exact stop on the programmed vertex (``PATH_ELEMENTS``);
    ``helper``: the feed paths fitted and blended in a helper process while the calls are read on
    (:mod:`~cnc_twin.gcode.paths_ahead`: the same operations, bit for bit; a long program's load).

    Raises :class:`ToolpathError` for what reads but cannot run: an arc, a curve or a probing move
    as the first motion when ``start`` is not known (the tool's place is not known before a G0 / G1).
    """
    ahead = PathsAhead(helper)
    try:
        yield from _operations(calls, ahead, default_blend, axis_tolerance, start, air, path_elements)
    except Exception:
        if not ahead.failed:  # the reader's (or a move's) error: what was made before it first
            yield from ahead.drain()
        raise
    finally:
        ahead.close()


def _operations(calls: Iterable[Call], ahead: PathsAhead, default_blend: float, axis_tolerance: float, start,
                air: float, path_elements: int) -> Iterator[Operation]:
    """:func:`iter_operations`' reading: the feed paths it closes prepared in ``ahead``."""
    canon = _Canon(air=np.array([0.0, 0.0, air, 0.0, 0.0, 0.0]))
    # machine point, mm / deg (raised with the program); None until the first move when not known
    # (in Python floats: every line compares it, numpy's arrays only where they are worked with)
    here: list[float] | None = None if start is None else (np.asarray(start, dtype=float) + canon.offset).tolist()
    path: list[tuple[Element | OpenChain, tuple]] = []  # the open feed path's elements, with their modes
    held = 0  # programmed elements in it (a chain's lines each)
    tilting: list[tuple[np.ndarray, np.ndarray, int, tuple]] = []  # G1s turning the head: start, end, line, modes

    def close() -> None:
        nonlocal held
        if path:
            ahead.prepare("feed_paths", list(path), default_blend)
            path.clear()
            held = 0
        if tilting:
            ahead.prepare("tool_axis_paths", list(tilting), math.radians(axis_tolerance))
            tilting.clear()

    for call in calls:
        if ahead.fresh:
            yield from ahead.ready()
        if held >= path_elements or len(tilting) >= path_elements:
            close()
        name, v = call.name, call.values
        if name == "STRAIGHT_FEED" or name == "STRAIGHT_TRAVERSE":  # first: most calls are
            # which axes move, compared as Python floats (np.any on a 3-vector costs more than a line's rest)
            e, h = canon.point(v), here
            rotary = h is not None and e[3:] != h[3:]
            if name == "STRAIGHT_FEED" and h is not None and not rotary:
                if tilting:
                    close()
                if e[:3] != h[:3]:
                    modes = _modes(canon, h)
                    last = path[-1] if path else None
                    if last is not None and last[1] == modes and last[0].__class__ is OpenChain:
                        last[0].add(e, call.line)
                    else:
                        path.append((OpenChain(h, e, call.line), modes))
                    held += 1
            elif (name == "STRAIGHT_FEED" and h is not None and canon.control[0] == "CANON_CONTINUOUS"
                  and canon.control[1] > 0.0 and e[5] == h[5] and e[:3] != h[:3]):
                # a G1 turning A / B as the tip moves, under G64 P: gathered for a 5-axis fit
                if path:
                    close()
                tilting.append((np.array(here), np.array(e), call.line, (canon.feed, canon.control)))
            else:
                close()
                rotary_only = h is not None and e[:3] == h[:3]
                feed = None
                if name == "STRAIGHT_FEED":
                    feed = canon.feed / canon.scale if rotary_only else canon.feed
                ahead.add(Traverse(tuple(float(x) for x in e), feed, call.line, rotary_only))
            here = e
        elif name == "USE_LENGTH_UNITS":
            canon.scale = INCH if v[0] == G.G20 else 1.0
        elif name == "SET_G5X_OFFSET":
            canon.g5x = canon.to_mm(v[1:7])
            canon.offsets_set()
        elif name == "SET_G92_OFFSET":
            canon.g92 = canon.to_mm(v[:6])
            canon.offsets_set()
        elif name == "USE_TOOL_LENGTH_OFFSET":
            canon.tool = canon.to_mm(v[:6])
            canon.offsets_set()
        elif name == "SET_FEED_RATE":
            canon.feed = v[0] * canon.scale
        elif name == "SET_MOTION_CONTROL_MODE":
            canon.control = (v[0], v[1] * canon.scale if len(v) > 1 else 0.0)
        elif name in ("ARC_FEED", "NURBS_FEED"):
            if here is None:
                raise ToolpathError(call.line, "an arc or a curve as the program's first motion: the tool's place "
                                    "is not known yet (start with a G0 or G1 to the start point)")
            offset = canon.offset[:3]
            if name == "ARC_FEED":
                tol = canon.control[1] or default_blend
                element = arc_element(np.array(here[:3]), call.payload, offset, canon.scale, tol, call.line)
            else:
                # the line of the block that started the curve (the call comes at its last block)
                element = curve_element(call.payload, np.array(here[:3]), offset, canon.scale, call.payload.line)
            path.append((element, _modes(canon, here)))
            held += 1
            here = element.end.tolist() + here[3:]
        elif name == "STRAIGHT_PROBE":
            if here is None:
                raise ToolpathError(call.line, "a probing move as the program's first motion: the tool's place "
                                    "is not known yet (start with a G0 or G1 to where the probe starts)")
            close()
            move, result = call.payload
            end, stop = canon.machine(v), canon.machine(result.stop)
            ahead.add(Probe(tuple(float(x) for x in here), tuple(float(x) for x in end),
                             tuple(float(x) for x in stop), canon.feed, move.kind, call.line,
                             tuple(float(x) for x in canon.offset), canon.scale))
            here = stop.tolist()
        elif name == "DWELL":
            close()
            ahead.add(Pause(float(v[0]), call.line))
        elif name in ("PROGRAM_STOP", "OPTIONAL_PROGRAM_STOP"):
            close()
            ahead.add(Pause(0.0, call.line))
        elif name == "SET_SPINDLE_SPEED":
            canon.spindle_speed = float(v[0])
            if canon.spindle_direction:
                close()
                ahead.add(SpindleChange(canon.spindle_direction * canon.spindle_speed, call.line))
        elif name in ("START_SPINDLE_CLOCKWISE", "START_SPINDLE_COUNTERCLOCKWISE", "STOP_SPINDLE_TURNING"):
            close()
            canon.spindle_direction = {"START_SPINDLE_CLOCKWISE": 1, "START_SPINDLE_COUNTERCLOCKWISE": -1}.get(name, 0)
            ahead.add(SpindleChange(canon.spindle_direction * canon.spindle_speed, call.line))
        elif name == "FORCE_CONTROL_ON":
            close()
            ahead.add(ForceChange(float(v[0]), call.line))
        elif name == "FORCE_CONTROL_OFF":
            close()
            ahead.add(ForceChange(None, call.line))
        elif name == "PROGRAM_END":
            break
    close()
    yield from ahead.drain()


def _modes(canon: _Canon, here: list[float]) -> tuple:
    """What a feed element carries that may end a path: feed, held A B C, control mode."""
    return (canon.feed, tuple(here[3:]), canon.control)
