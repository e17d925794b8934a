"""Path metrics of a G-code run: each feed path measured from the trace as a curve run is
(:func:`cnc_twin.run.path_metrics.path_metrics`), then the figures over the whole program.

The trace's periods on a curve (``path_u >= 0``) fall into runs, one per card curve, in program
order (:mod:`~cnc_twin.run.curve_windows`). Each run is measured against its own curve as it ends,
from its window of the trace; the whole against the program as written:
:mod:`cnc_twin.run.program_check`. On a path run with the force loop on (M100), the
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
from cnc_twin.run.curve_windows import curve_windows
from cnc_twin.run.program_check import ProgramCheck
from cnc_twin.trace.trace import PIECE_PERIODS, Trace


def gcode_run_metrics(trace: Trace, scenario: Scenario, *, periods: int = PIECE_PERIODS) -> tuple[dict[str, Any], dict[str, Any]]:
    """The run's path figures (:func:`path_figures`) and its check against the program
    (:class:`~cnc_twin.run.program_check.ProgramCheck`), from one pass over the trace a piece at a
    time: each feed path is measured as its curve run ends
    (:func:`~cnc_twin.run.curve_windows.curve_windows`, ``periods`` a piece)."""
    from cnc_twin.run.path_metrics import path_metrics

    prog: GcodeProgram = scenario.program
    check = ProgramCheck(scenario)
    paths = iter(prog.paths)
    per_path = []
    for samples, runs in curve_windows(trace, periods):
        check.add_periods(samples)
        for run in runs:
            path = next(paths, None)
            if path is None:  # more runs than paths: none is a path of the program
                continue
            axis = tool_axis(*path.curve.hold[:2]) if id(path) in check.pressed else None
            per_path.append((path, path_metrics(run.window, dataclasses.replace(scenario, program=path.curve),
                                                force_axis=axis)))
            check.add_path(path, run.window.slice(run.first, run.stop))
    return path_figures(prog, per_path), check.result()


def path_figures(prog: GcodeProgram, per_path: list) -> dict[str, Any]:
    """Chord error, feed fluctuation, contour error [um] and axis peaks over the program's feed
    paths, and each path's own (``paths``: the program line it starts at, length, errors), from
    ``per_path``: ``(path, its path_metrics)`` for each path run."""
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
