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
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cnc_twin.core.config import GcodeProgram, Scenario
from cnc_twin.geometry.kinematics import HeadGeometry, tool_axis
from cnc_twin.geometry.polyline import point_to_polyline
from cnc_twin.trace.trace import Trace

FULL_FEED = 0.95
"""a period runs at full feed when its speed is at least this share of the programmed F"""


def curve_runs(u: np.ndarray) -> list[tuple[int, int]]:
    """``[(first, stop)]`` period ranges of ``u`` (one value per period) on one curve each: a run
    ends where the tool leaves the curve or the parameter starts again from the next curve's
    beginning."""
    on = u >= 0.0
    runs, start = [], None
    for k in range(len(u)):
        if on[k] and (start is None or u[k] < u[k - 1]):
            if start is not None:
                runs.append((start, k))
            start = k
        elif not on[k] and start is not None:
            runs.append((start, k))
            start = None
    if start is not None:
        runs.append((start, len(u)))
    return runs


def pressed_paths(prog: GcodeProgram) -> set[int]:
    """``id`` of each feed path the program runs with the force loop on (M100 ... M101)."""
    return {id(step) for step in prog.pressed_paths()}


def _feed_moves(prog: GcodeProgram, tips: np.ndarray, u: np.ndarray, mark: np.ndarray, T: float):
    """``(time, ideal time, time below 95 % of F, length)`` [s, s, s, m] of the G1 moves the card runs as
    coordinated moves of the axes (their periods: off a curve, marked with their line), the tip's
    speed from the commanded tips; the arrays are per period (``tips`` (n, 3), ``u`` the path
    parameter, ``mark`` the program line); None without such moves."""
    feeds = prog.feed_rates()
    if not feeds:
        return None
    speed = np.concatenate([[0.0], np.linalg.norm(np.diff(tips, axis=0), axis=1) / T])
    lines = np.fromiter(feeds.keys(), dtype=np.int64, count=len(feeds))
    rates = np.fromiter(feeds.values(), dtype=np.float64, count=len(feeds))
    order = np.argsort(lines, kind="stable")
    moving = (u < 0.0) & (speed > 0.0)
    marks, speeds = mark[moving].astype(np.int64), speed[moving]
    at = np.clip(np.searchsorted(lines[order], marks), 0, len(lines) - 1)
    ours = lines[order][at] == marks  # periods of a feed move's line (one lookup, not a pass per line)
    move, speeds = order[at[ours]], speeds[ours]
    periods = np.bincount(move, minlength=len(lines))
    length = np.bincount(move, weights=speeds, minlength=len(lines)) * T  # [m] per move
    slow = np.bincount(move, weights=speeds < FULL_FEED * rates[move], minlength=len(lines))
    return float(periods.sum()) * T, float(np.sum(length / rates)), float(slow.sum()) * T, float(length.sum())


def against_program(trace: Trace, scenario: Scenario) -> dict[str, Any]:
    """The run against its program (see the module docstring); lengths in um, times in s."""
    prog: GcodeProgram = scenario.program
    tpp = scenario.timing.ticks_per_period
    T = scenario.timing.interpolation_period
    ends = slice(tpp - 1, None, tpp)
    u = trace.at_period_ends("path_u")
    ds = trace.at_period_ends("path_ds")
    depth = trace.at_period_ends("force_depth")
    if not prog.paths:  # no curve: nothing fed along one (and no head geometry to read)
        return {"feed": {"time_s": 0.0, "ideal_time_s": 0.0, "below_95pct_s": 0.0, "share_at_95pct": None,
                         "moves_length_mm": 0.0}}
    command = trace.command[ends] / trace.counts_per_unit + np.asarray(scenario.home)
    c = prog.paths[0].curve  # the head's geometry: the machine's, the same on every path
    head = HeadGeometry(pivot_home=c.pivot_home, tool_offset=c.tool_offset, workpiece_origin=(0.0, 0.0, 0.0))
    all_tips, all_tools = head.forward(command[:, :5])  # every period's commanded tip and tool axis
    pressed = pressed_paths(prog)
    groups: dict[int, tuple[Any, list[tuple[np.ndarray, np.ndarray]]]] = {}
    time = below = ideal = 0.0
    for path, (first, stop) in zip(prog.paths, curve_runs(u)):
        c = path.curve
        tips, tool = all_tips[first:stop], all_tools[first:stop]
        if id(path) in pressed:  # the loop pushed the tip depth along -axis: the path's own point
            tips = tips + depth[first:stop, None] * np.asarray(tool_axis(*c.hold[:2]))
        speed = ds[first:stop] / T
        time += (stop - first) * T
        below += float(np.count_nonzero(speed < FULL_FEED * c.limits.feed)) * T
        if path.reference is not None:
            ref, parts = groups.setdefault(id(path.reference), (path.reference, []))
            if not parts:
                ideal += float(np.sum(np.linalg.norm(np.diff(ref.polyline, axis=0), axis=1))) / c.limits.feed
            parts.append((tips, tool))
    moving = _feed_moves(prog, all_tips, u, trace.at_period_ends("mark"), T)
    moves_length = 0.0
    if moving is not None:  # G1 moves run as coordinated moves (exact stop, or turning the head)
        time, ideal, below, moves_length = time + moving[0], ideal + moving[1], below + moving[2], moving[3]
    out: dict[str, Any] = {"feed": {"time_s": time, "ideal_time_s": ideal, "below_95pct_s": below,
                                    "share_at_95pct": (time - below) / time if time > 0 else None,
                                    "moves_length_mm": moves_length * 1e3}}
    if not groups:
        return out
    worst = vertex_worst = 0.0
    tolerances, axis_worst, axis_tolerances = [], None, []
    for ref, parts in groups.values():
        tips = np.vstack([t for t, _ in parts])
        worst = max(worst, float(point_to_polyline(tips, ref.polyline).max()))
        if len(tips) > 1:
            vertex_worst = max(vertex_worst, float(point_to_polyline(ref.vertices, tips).max()))
        if ref.tolerance is not None:
            tolerances.append(ref.tolerance)
        if ref.axes is not None:  # the commanded tool axis where the tip passes each programmed vertex
            from scipy.spatial import cKDTree

            tool = np.vstack([a for _, a in parts])
            nearest = cKDTree(tips).query(ref.vertices)[1]
            cos = np.clip(np.sum(tool[nearest] * ref.axes, axis=1), -1.0, 1.0)
            axis_worst = max(axis_worst or 0.0, float(np.degrees(np.arccos(cos)).max()))
            axis_tolerances.append(ref.axis_tolerance)
    refs = [ref for ref, _ in groups.values()]
    tolerance = min(tolerances) if tolerances else None
    out["deviation_um"] = {"max": worst * 1e6, "vertices_max": vertex_worst * 1e6,
                           "tolerance_um": None if tolerance is None else tolerance * 1e6}
    if axis_worst is not None:
        out["axis_deviation_deg"] = {"max": axis_worst, "tolerance": float(np.degrees(min(axis_tolerances)))}
    out["fits"] = {"runs": sum(r.fits for r in refs), "spans": sum(r.fit_spans for r in refs),
                   "fitter_deviation_um": max(r.fit_deviation for r in refs) * 1e6}
    return out
