"""A G-code run checked against the program as written, from the trace: how far the commanded tip
strayed from the programmed path, and how much of the time the feed held the programmed F.

For each feed path, the commanded tip at every period's end on it (encoder counts through the
head's kinematics, the force loop's offset taken off on pressed paths) is measured against the
path as programmed (:class:`~cnc_twin.core.gcode_config.GcodeReference`: lines by their ends,
arcs and curves finely sampled; before corner blends and fits), both ways:

- ``deviation_um.max``: each commanded point's distance to the programmed path;
- ``deviation_um.vertices_max``: each programmed vertex's distance to the commanded path (the
  polyline through the commanded points): a corner rounded, or a point cut, by more than P shows
  here;

against the path's G64 P (``tolerance_um``); on paths that turn the head,
``axis_deviation_deg``: the commanded tool axis where the tip passes each programmed vertex
against the axis its A / B words give. ``feed``: the time on feed paths, the ideal time
(each path's programmed length at its F), and the time below 95 % of F (accelerations, corners,
curvature). ``fits``: what the fitter made and claims (spans, its own measured deviation), for
comparison with the measured one.

The check reads the run once, a piece at a time (:class:`ProgramCheck`, fed by
:func:`~cnc_twin.run.curve_windows.curve_windows`): it keeps each programmed path's vertices'
nearest distances so far, not the commanded points. A vertex is measured against each feed path's
commanded points whose box it lies within :data:`VERTEX_REACH` of; a vertex no path came that
near is measured against every :data:`COARSE_EVERY`-th commanded point (it is off by more than
the reach: the figure shows that, within that sampling).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cnc_twin.core.config import GcodeProgram, Scenario
from cnc_twin.geometry.kinematics import HeadGeometry, tool_axis
from cnc_twin.geometry.polyline import point_to_polyline
from cnc_twin.trace.trace import PeriodSamples

FULL_FEED = 0.95
"""a period runs at full feed when its speed is at least this share of the programmed F"""
VERTEX_REACH = 1e-3
"""[m] a programmed vertex is measured against a feed path's commanded points when it lies this
near their box (a vertex farther from every path is measured against the coarse points)"""
COARSE_EVERY = 16
"""every this many commanded points of a path are kept for the vertices no path came near"""


def pressed_paths(prog: GcodeProgram) -> set[int]:
    """``id`` of each feed path the program runs with the force loop on (M100 ... M101)."""
    return {id(step) for step in prog.pressed_paths()}


class _Group:
    """What is kept of one programmed path (a :class:`GcodeReference`) while its feed paths run:
    the worst distance of a commanded point from it, each vertex's nearest commanded point so far
    (distance, and the tool axis there when the path turns the head), the last commanded point
    (the next feed path's polyline begins there) and the coarse points."""

    def __init__(self, ref):
        self.ref = ref
        # read once from where a long program keeps them, held while the group's paths run
        self.polyline, self.vertices = ref.read()
        self.worst = 0.0
        self.points = 0
        self.best = np.full(len(self.vertices), np.inf)  # each vertex's distance to the commanded polyline
        self.nearest = np.full(len(self.vertices), np.inf)  # ... and to the nearest commanded point
        self.axis = np.zeros((len(self.vertices), 3)) if ref.stored_axes is not None else None
        self.last: tuple[np.ndarray, np.ndarray] | None = None
        self.coarse: list[tuple[np.ndarray, np.ndarray]] = []

    def add(self, tips: np.ndarray, tool: np.ndarray) -> None:
        """A feed path's commanded tips and tool axes (each (n, 3)), in run order."""
        self.worst = max(self.worst, float(point_to_polyline(tips, self.polyline).max()))
        if self.last is not None:  # the commanded polyline runs on from the last path's last point
            tips, tool = np.vstack([self.last[0], tips]), np.vstack([self.last[1], tool])
        self.points += len(tips) - (self.last is not None)
        self.last = (tips[-1:], tool[-1:])
        self.coarse.append((np.vstack([tips[:-1:COARSE_EVERY], tips[-1:]]), np.vstack([tool[:-1:COARSE_EVERY], tool[-1:]])))
        lo, hi = tips.min(axis=0) - VERTEX_REACH, tips.max(axis=0) + VERTEX_REACH
        near = np.flatnonzero(np.all((self.vertices >= lo) & (self.vertices <= hi), axis=1))
        if len(near):
            self._measure(near, tips, tool)

    def _measure(self, which: np.ndarray, tips: np.ndarray, tool: np.ndarray) -> None:
        """Vertices ``which`` against the commanded polyline ``tips`` (and its points, ``tool``)."""
        vertices = self.vertices[which]
        if len(tips) > 1:
            self.best[which] = np.minimum(self.best[which], point_to_polyline(vertices, tips))
        if self.axis is not None:
            from scipy.spatial import cKDTree

            distance, index = cKDTree(tips).query(vertices)
            closer = distance < self.nearest[which]
            self.nearest[which[closer]] = distance[closer]
            self.axis[which[closer]] = tool[index[closer]]

    def result(self) -> tuple[float, float, float | None]:
        """(worst point's deviation, worst vertex's, worst tool axis [deg] or None)."""
        far = np.flatnonzero(np.isinf(self.best) | (np.isinf(self.nearest) if self.axis is not None else False))
        if len(far) and self.points:
            self._measure(far, *(np.vstack(part) for part in zip(*self.coarse)))
        vertex_worst = float(self.best.max()) if self.points > 1 else 0.0
        if self.axis is None:
            return self.worst, vertex_worst, None
        cos = np.clip(np.sum(self.axis * self.ref.axes, axis=1), -1.0, 1.0)
        return self.worst, vertex_worst, float(np.degrees(np.arccos(cos)).max())


class ProgramCheck:
    """The run against its program, fed in run order: every period's samples
    (:meth:`~ProgramCheck.add_periods`, for the coordinated moves), each feed path's periods as its
    run ends (:meth:`~ProgramCheck.add_path`); :meth:`~ProgramCheck.result` at the end."""

    def __init__(self, scenario: Scenario):
        prog: GcodeProgram = scenario.program
        self.prog = prog
        self.T = scenario.timing.interpolation_period
        self.home = np.asarray(scenario.home)
        c = prog.paths[0].curve if prog.paths else None  # the head's geometry: the machine's, the same on every path
        self.head = None if c is None else HeadGeometry(pivot_home=c.pivot_home, tool_offset=c.tool_offset,
                                                        workpiece_origin=(0.0, 0.0, 0.0))
        self.pressed = pressed_paths(prog)
        self.time = self.below = self.ideal = 0.0
        self.groups: dict[int, _Group] = {}
        self.open: _Group | None = None
        self.done: list[tuple[float, float, float | None, object]] = []
        feeds = prog.feed_rates()
        self.moves = None  # the coordinated moves' lines and rates, and per move: periods, length, slow periods
        if feeds and self.head is not None:
            lines = np.fromiter(feeds.keys(), dtype=np.int64, count=len(feeds))
            rates = np.fromiter(feeds.values(), dtype=np.float64, count=len(feeds))
            order = np.argsort(lines, kind="stable")
            self.moves = (lines[order], rates[order], np.zeros(len(lines)), np.zeros(len(lines)), np.zeros(len(lines)))
        self.last_tip: np.ndarray | None = None

    def _tips(self, samples: PeriodSamples) -> tuple[np.ndarray, np.ndarray]:
        """The commanded tips and tool axes (each (n, 3)) of ``samples``' periods."""
        return self.head.forward((samples.command / samples.counts_per_unit + self.home)[:, :5])

    def add_periods(self, samples: PeriodSamples) -> None:
        """The next periods of the run: the G1 moves the card runs as coordinated moves of the
        axes (periods off a curve, marked with their line), the tip's speed from the commanded tips."""
        if self.moves is None or not len(samples):
            return
        tips, _ = self._tips(samples)
        before = tips[:1] if self.last_tip is None else self.last_tip
        speed = np.linalg.norm(np.diff(np.vstack([before, tips]), axis=0), axis=1) / self.T
        self.last_tip = tips[-1:]
        lines, rates, periods, length, slow = self.moves
        moving = (samples.signal("path_u") < 0.0) & (speed > 0.0)
        marks, speeds = samples.signal("mark")[moving], speed[moving]
        at = np.clip(np.searchsorted(lines, marks), 0, len(lines) - 1)
        ours = lines[at] == marks  # periods of a feed move's line (one lookup, not a pass per line)
        move, speeds = at[ours], speeds[ours]
        periods += np.bincount(move, minlength=len(lines))
        length += np.bincount(move, weights=speeds, minlength=len(lines)) * self.T  # [m] per move
        slow += np.bincount(move, weights=speeds < FULL_FEED * rates[move], minlength=len(lines))

    def add_path(self, path, samples: PeriodSamples) -> None:
        """A feed path's periods (its curve run, exactly)."""
        c = path.curve
        tips, tool = self._tips(samples)
        if id(path) in self.pressed:  # the loop pushed the tip depth along -axis: the path's own point
            tips = tips + samples.signal("force_depth")[:, None] * np.asarray(tool_axis(*c.hold[:2]))
        speed = samples.signal("path_ds") / self.T
        self.time += len(samples) * self.T
        self.below += float(np.count_nonzero(speed < FULL_FEED * c.limits.feed)) * self.T
        ref = path.reference
        if ref is None:
            return
        if self.open is None or self.open.ref is not ref:
            self._close()
            self.open = _Group(ref)
            self.ideal += float(np.sum(np.linalg.norm(np.diff(self.open.polyline, axis=0), axis=1))) / c.limits.feed
        self.open.add(tips, tool)

    def _close(self) -> None:
        if self.open is not None:
            self.done.append((*self.open.result(), self.open.ref))
            self.open = None

    def result(self) -> dict[str, Any]:
        """The figures (see the module docstring); lengths in um, times in s."""
        self._close()
        time, ideal, below, moves_length = self.time, self.ideal, self.below, 0.0
        if self.moves is not None and self.moves[2].sum() > 0:  # G1 moves run as coordinated moves
            _, rates, periods, length, slow = self.moves
            time += float(periods.sum()) * self.T
            ideal += float(np.sum(length / rates))
            below += float(slow.sum()) * self.T
            moves_length = float(length.sum())
        out: dict[str, Any] = {"feed": {"time_s": time, "ideal_time_s": ideal, "below_95pct_s": below,
                                        "share_at_95pct": (time - below) / time if time > 0 else None,
                                        "moves_length_mm": moves_length * 1e3}}
        if not self.done:
            return out
        refs = [ref for *_, ref in self.done]
        tolerances = [r.tolerance for r in refs if r.tolerance is not None]
        tolerance = min(tolerances) if tolerances else None
        out["deviation_um"] = {"max": max(d[0] for d in self.done) * 1e6,
                               "vertices_max": max(d[1] for d in self.done) * 1e6,
                               "tolerance_um": None if tolerance is None else tolerance * 1e6}
        axes = [(d[2], d[3].axis_tolerance) for d in self.done if d[2] is not None]
        if axes:
            out["axis_deviation_deg"] = {"max": max(a for a, _ in axes),
                                         "tolerance": float(np.degrees(min(t for _, t in axes)))}
        out["fits"] = {"runs": sum(r.fits for r in refs), "spans": sum(r.fit_spans for r in refs),
                       "fitter_deviation_um": max(r.fit_deviation for r in refs) * 1e6}
        return out
