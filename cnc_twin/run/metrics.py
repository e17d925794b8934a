"""A run's summary figures from its trace: following errors, saturation, force, timing."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cnc_twin.core.axes import AXES
from cnc_twin.core.config import Scenario
from cnc_twin.trace.trace import Trace


def compute_metrics(trace: Trace, scenario: Scenario, *, wall_time: float, dac_saturations: list[int],
                    warnings: dict[str, int], final_error_ticks: int = 1) -> dict[str, Any]:
    """Summary figures of a run; following errors in counts and in mm / deg."""
    sim_time = float(len(trace)) * scenario.timing.servo_period
    ferr: dict[str, Any] = {}
    final: dict[str, Any] = {}
    n_axes = len(scenario.axes)
    # piece by piece (a long run's whole error matrix would be twice its trace): maxima, and the
    # sums of squares in the order np.mean sums them within a piece
    peak, squares = np.zeros(n_axes), [[] for _ in range(n_axes)]
    force_peak, tail = -np.inf, None
    for piece in trace.chunks():
        e = piece.following_error
        if len(e):
            peak = np.maximum(peak, np.max(np.abs(e), axis=0))
            for i in range(n_axes):
                squares[i].append(float(np.sum(e[:, i] * e[:, i])))
            force_peak = max(force_peak, float(np.max(piece.pad_force)))
            # the last ticks' errors, reaching into the piece before when this one is shorter
            tail = e[-final_error_ticks:] if tail is None or len(e) >= final_error_ticks else \
                np.vstack([tail, e])[-final_error_ticks:]
    last = tail if tail is not None else np.zeros((0, n_axes))
    for i, cfg in enumerate(scenario.axes):
        to_user = cfg.display_factor / cfg.counts_per_unit
        max_c = float(peak[i]) if len(trace) else 0.0
        rms_c = math.sqrt(math.fsum(squares[i]) / len(trace)) if len(trace) else 0.0
        ferr[cfg.name] = {"max_counts": max_c, "rms_counts": rms_c, "max": max_c * to_user,
                          "rms": rms_c * to_user, "unit": cfg.display_unit}
        end = float(last[:, i].mean()) if len(trace) else 0.0
        final[cfg.name] = {"counts": end, "value": end * to_user, "unit": cfg.display_unit}
    return {
        "scenario": scenario.name,
        "machine": dict(scenario.machine),
        "status": "complete",
        "sim_time_s": sim_time,
        "wall_time_s": wall_time,
        "real_time_factor": sim_time / wall_time if wall_time > 0 else math.inf,
        "servo_ticks": len(trace),
        "physics_steps": len(trace) * scenario.timing.substeps_per_tick,
        "following_error": ferr,
        "final_following_error": final,
        "dac_saturation_ticks": dict(zip(AXES, dac_saturations)),
        "pad_force_max_n": force_peak if len(trace) else 0.0,
        "mujoco_warnings": warnings,
    }
