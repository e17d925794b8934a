"""Path metrics of a G-code run: each feed path measured from the trace as a curve run is
(:func:`cnc_twin.run.path_metrics.path_metrics`), then the figures over the whole program.

The trace's periods on a curve (``path_u >= 0``) fall into runs, one per card curve, in program
order (:func:`~cnc_twin.run.program_check.curve_runs`). Each run is measured against its own
curve; the whole against the program as written: :mod:`cnc_twin.run.program_check`. On a path run with the force loop on (M100), the
chord and contour errors are measured after taking the loop's offset along the tool axis off
(the trace's ``force_depth``); the axis peaks keep it.

With a workpiece, :func:`gcode_polish_metrics` adds the force tracking and the removal map.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from cnc_twin.core.config import GcodeProgram, Scenario
from cnc_twin.geometry.kinematics import tool_axis
from cnc_twin.run.program_check import curve_runs, pressed_paths
from cnc_twin.trace.trace import Trace


class _PathTrace:
    """The trace seen by one path: a window from two periods before it to its last period (so
    what follows, a rapid move's start, is not counted in the path's axis peaks; the period before
    it is, as a curve run's), ``path_u`` -1 before the path, ``period_offset`` the window's first
    period in the run. A window, not the run up to the path: a program of thousands of paths is
    measured in time proportional to its length, not to the square of it."""

    def __init__(self, trace: Trace, first: int, stop: int):
        """``first``, ``stop``: the path's first and one-past-last period."""
        tpp = trace.ticks_per_period
        begin = max(0, first - 2)
        self.period_offset = begin
        signals = trace.period_signals

        def window(name: str) -> np.ndarray:
            return np.repeat(signals.per_period(name)[begin:stop].astype(np.float64), tpp)

        u = window("path_u")
        u[:(first - begin) * tpp] = -1.0
        self.period_signals = {"path_u": u, "path_ds": window("path_ds"), "force_depth": window("force_depth")}
        self.command, self.actual = trace.command[begin * tpp:stop * tpp], trace.actual[begin * tpp:stop * tpp]
        self.tool = trace.tool[begin:stop]
        self.counts_per_unit = trace.counts_per_unit
        self._tpp = tpp

    def at_period_ends(self, name: str) -> np.ndarray:
        """As :meth:`Trace.at_period_ends <cnc_twin.trace.trace.Trace.at_period_ends>`, in the window."""
        return self.period_signals[name][self._tpp - 1::self._tpp]


def gcode_metrics(trace: Trace, scenario: Scenario) -> dict[str, Any]:
    """Chord error, feed fluctuation, contour error [um] and axis peaks over the program's feed
    paths, and each path's own (``paths``: the program line it starts at, length, errors)."""
    from cnc_twin.run.path_metrics import path_metrics

    prog: GcodeProgram = scenario.program
    u = trace.period_signals.per_period("path_u").astype(np.float64)
    per_path = []
    pressed = pressed_paths(prog)
    for path, (first, stop) in zip(prog.paths, curve_runs(u)):
        axis = tool_axis(*path.curve.hold[:2]) if id(path) in pressed else None
        window = _PathTrace(trace, first, stop)
        m = path_metrics(window, dataclasses.replace(scenario, program=path.curve), force_axis=axis,
                         period_offset=window.period_offset)
        per_path.append((path, m))
    out: dict[str, Any] = {"file": str(prog.file), "feed_paths": len(prog.paths), "paths_run": len(per_path)}
    measured = [(p, m) for p, m in per_path if "chord_error_um" in m]
    out["length_mm"] = float(sum(m["length_mm"] for _, m in per_path))
    if not measured:
        return out
    out["chord_error_um"] = {"max": max(m["chord_error_um"]["max"] for _, m in measured),
                             "tolerance": measured[0][1]["chord_error_um"]["tolerance"]}
    out["feed_fluctuation"] = {"max": max(m["feed_fluctuation"]["max"] for _, m in measured)}
    for key in ("contour_error_um", "encoder_contour_error_um"):
        out[key] = {"max": max(m[key]["max"] for _, m in measured),
                    "rms": float(np.sqrt(np.mean([m[key]["rms"] ** 2 for _, m in measured])))}
    peaks: dict[str, dict[str, float]] = {}
    for _, m in measured:
        for axis, values in m["axis_peaks"].items():
            best = peaks.setdefault(axis, dict(values))
            for q in ("velocity", "acceleration", "jerk"):
                if values[q] > best[q]:
                    best[q], best[f"{q}_ratio"] = values[q], values[f"{q}_ratio"]
    out["axis_peaks"] = peaks
    out["limit_violations"] = [dict(v, line=p.line) for p, m in measured for v in m["limit_violations"]]
    pressed = [m["force_offset"] for _, m in measured if "force_offset" in m]
    if pressed:  # the force loop's own motion along the tool axis on the paths it pressed
        out["force_offset"] = {q: max(f[q] for f in pressed) for q in ("velocity", "acceleration", "jerk")}
        out["force_offset"]["units"] = pressed[0]["units"]
    out["paths"] = [{"line": p.line, "length_mm": m["length_mm"],
                     "chord_error_um": m.get("chord_error_um", {}).get("max"),
                     "contour_error_um": m.get("contour_error_um", {}).get("max"),
                     "feed_fluctuation": m.get("feed_fluctuation", {}).get("max")} for p, m in per_path]
    return out


def gcode_polish_metrics(trace: Trace, prog: GcodeProgram, removal, wall_time: float) -> dict[str, Any]:
    """Force tracking (against the setpoint in effect each period) and the removal map of a
    program with a workpiece; the Preston volume by hand when every M100 ran at one spindle
    speed."""
    from cnc_twin.polishing.polish import force_metrics, preston_by_hand, removal_metrics

    pressed = prog.force_setpoints()
    setpoints = [setpoint for setpoint, _ in pressed]
    speeds = {abs(speed) for _, speed in pressed}
    w = prog.workpiece
    out: dict[str, Any] = {"force": force_metrics(trace, setpoints[0]) if setpoints else None,
                           "setpoints_n": setpoints,
                           "removal": removal_metrics(removal, wall_time)}
    if len(speeds) == 1:
        out["removal"]["preston_by_hand_mm3"] = preston_by_hand(trace, w.preston, speeds.pop()) * 1e9
    return out
