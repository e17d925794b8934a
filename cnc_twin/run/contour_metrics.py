"""Per-pass contour metrics of a ``contour`` run, from the trace (after the run).

A pass is the ticks whose ``mark`` is its number (the planner brackets each pass with Mark
records). For each pass, on X/Y in axis space (the tool axis is vertical, so that is the tool
tip shifted by a constant)::

    contour error       distance of the tool's true position (the trace's tool pose, through the
                        head's inverse kinematics, per period) from the ideal lines and arcs
                        (exact: :func:`cnc_twin.geometry.contour.contour_distance`) [um]
    encoder contour     the same for the encoders' position (what the card sees), per tick
    error
    command deviation   the same for the card's command: the interpolator's own error (chord
                        error for NURBS, lattice error for the step methods) [um]
    steps               X + Y step pulses the command made (whole counts; step methods)
    duration, mean feed the pass's time and length / time
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cnc_twin.core.config import ContourProgram, Scenario
from cnc_twin.geometry.contour import contour_distance, elements_length
from cnc_twin.geometry.kinematics import HeadGeometry
from cnc_twin.trace.trace import Trace


def contour_metrics(trace: Trace, scenario: Scenario) -> dict[str, Any]:
    """``{"length_mm", "passes": [{method, duration_s, ...}, ...]}`` for a contour program's run."""
    prog: ContourProgram = scenario.program
    cpu = np.array([a.counts_per_unit for a in scenario.axes[:2]])
    zero = np.array(scenario.home[:2])
    mark = trace.period_signals["mark"]
    period_mark = trace.periods["mark"][:len(trace.tool)]
    head = HeadGeometry(pivot_home=prog.curves[0].pivot_home, tool_offset=prog.curves[0].tool_offset,
                        workpiece_origin=(0.0, 0.0, 0.0))
    tip, pivot = trace.tool[:, :3], trace.tool[:, 3:]
    true_xy = head.axes_from_pose(tip, pivot - tip)[:, :2]
    length = elements_length(prog.elements)
    passes = []
    for number, method in enumerate(prog.methods, start=1):
        ticks = np.flatnonzero(mark == number)
        row: dict[str, Any] = {"method": method, "ran": bool(ticks.size)}
        if ticks.size:
            actual = trace.actual[ticks, :2] / cpu + zero
            command = trace.command[ticks, :2] / cpu + zero
            error = contour_distance(true_xy[period_mark == number], prog.elements) * 1e6
            seen = contour_distance(actual, prog.elements) * 1e6
            deviation = contour_distance(command, prog.elements) * 1e6
            duration = ticks.size * scenario.timing.servo_period
            row.update({
                "duration_s": duration,
                "mean_feed_mm_min": length / duration * 6e4,
                "contour_error_um": {"max": float(error.max()), "rms": float(np.sqrt(np.mean(error ** 2)))},
                "encoder_contour_error_um": {"max": float(seen.max()), "rms": float(np.sqrt(np.mean(seen ** 2)))},
                "command_deviation_um": {"max": float(deviation.max())},
            })
            if method != "nurbs":
                row["steps"] = int(np.abs(np.diff(trace.command[ticks, :2], axis=0)).sum())
        passes.append(row)
    return {"length_mm": length * 1e3, "passes": passes}


def format_passes(contour: dict[str, Any]) -> str:
    """The passes side by side, one row each (for the terminal)."""
    lines = [f"contour: {contour['length_mm']:.1f} mm per pass",
             f"{'method':<16}{'time s':>8}{'feed mm/min':>13}{'contour err max':>17}{'rms':>9}"
             f"{'command dev max':>17}{'steps':>9}"]
    for p in contour["passes"]:
        if not p["ran"]:
            lines.append(f"{p['method']:<16}{'(did not run)':>8}")
            continue
        err, dev = p["contour_error_um"], p["command_deviation_um"]
        steps = f"{p['steps']:>9d}" if "steps" in p else f"{'-':>9}"
        lines.append(f"{p['method']:<16}{p['duration_s']:>8.3f}{p['mean_feed_mm_min']:>13.0f}"
                     f"{err['max']:>14.2f} um{err['rms']:>6.2f} um{dev['max']:>14.3f} um{steps}")
    return "\n".join(lines)
