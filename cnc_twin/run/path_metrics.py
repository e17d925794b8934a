"""Contour metrics of a NURBS run, computed after it from the trace (nothing here runs per tick).

Per interpolation period ``k`` on the curve the trace holds the parameter ``u_k`` and the arc
length commanded ``ds_k``; positions come from the commanded and encoder counts.

- feed fluctuation: ``|s_k - ds_k| / ds_k`` with ``s_k`` the arc length between ``u_{k-1}`` and
  ``u_k`` by Gauss-Legendre quadrature (split at knots), not the chord; periods that ended
  clamped at the curve's end, or commanded under 1 nm, are left out;
- chord error: largest distance of the curve between ``u_{k-1}`` and ``u_k`` from the chord
  between the commanded points, by dense sampling;
- axis velocity / acceleration / jerk: finite differences of the commanded X/Y/Z per period,
  against each axis's limits (peak, limit, ratio); any ratio above :data:`LIMIT_TOLERANCE` is
  listed in ``limit_violations`` with the axis and the time;
- contour error: distance of the tool tip from the ideal curve, per period: nearest of dense
  curve samples, refined on the segment to its neighbours. ``contour_error_um``: the tool tip
  where it really was (the trace's ``tip``: MuJoCo's kinematics of every joint, so the screws'
  and gears' windup and the structure's modes are in it), the error the part gets;
  ``encoder_contour_error_um``: the tip where the encoders put it (through the kinematics), the
  error the card sees. On a rigid machine the two differ by the encoders' quantisation; on the
  compliant one with encoders on the motors, by the drive train's windup.

Everything is measured on the tool tip in the world frame: commanded and actual tips come from
the axes through the forward kinematics, so a varying tool axis is measured the same way as a
held one. Axis peaks cover X/Y/Z, and A/B when the tool axis varies.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cnc_twin.core import units
from cnc_twin.core.config import Scenario
from cnc_twin.geometry.kinematics import HeadGeometry
from cnc_twin.geometry.nurbs import NurbsCurve
from cnc_twin.geometry.polyline import point_to_polyline
from cnc_twin.geometry.tip_path import tip_curve
from cnc_twin.trace.trace import PeriodSamples

_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)

LIMIT_TOLERANCE = 1.01
"""a commanded axis peak above this multiple of its limit is reported as a violation"""


def _arc_lengths(curve: NurbsCurve, u0: np.ndarray, u1: np.ndarray) -> np.ndarray:
    mid, half = 0.5 * (u0 + u1), 0.5 * (u1 - u0)
    nodes = mid[:, None] + half[:, None] * _GL_X[None, :]
    speed = np.linalg.norm(curve.derivatives(nodes.ravel(), 1)[1], axis=1).reshape(nodes.shape)
    out = half * (speed @ _GL_W)
    knots = np.unique(curve.knots)  # sorted: the knots strictly inside (a, b) are those between two searches
    straddle = np.flatnonzero(np.searchsorted(knots, u1, side="left") > np.searchsorted(knots, u0, side="right"))
    if straddle.size:  # a kink in |C'| at a knot: split there
        out[straddle] = curve.arc_lengths(u0[straddle], u1[straddle])
    return out


def path_metrics(ends: PeriodSamples, scenario: Scenario, *, interpolator_ns: np.ndarray | None = None,
                 plan_us: int = 0, plan_blocks: int = 0, force_axis: tuple | None = None) -> dict[str, Any]:
    """The contour metrics of a curve run (see the module docstring); lengths in um.

    ``force_axis``: the tool axis (world frame, unit) of a run with the force loop on. The loop's
    offset along it (the trace's ``force_depth``) is taken off the commanded and actual X/Y/Z
    first, so the chord error, the contour error (tracking) and the axis peaks are the path's;
    the offset's own peaks (``force_offset``: its speed, acceleration and jerk along the axis) are
    reported beside them, without limits (the force loop's correction, not the planned path).
    ``ends``: the run's signals at its periods' ends (:class:`~cnc_twin.trace.trace.PeriodSamples`:
    the whole run's, ``PeriodSamples.whole(trace)``, or a window of it from its period ``first``,
    which the violations' times count from)."""
    prog = scenario.program
    curve = tip_curve(prog)
    T = scenario.timing.interpolation_period
    u = ends.signal("path_u")
    ds = ends.signal("path_ds")
    on = u >= 0.0
    cpu = ends.counts_per_unit
    home = np.asarray(scenario.home)
    command_axes = ends.command / cpu + home
    actual_axes = ends.actual / cpu + home
    true_tip = ends.tool[:, :3].copy()  # sampled with the period's last tick, as the rows above
    depth = None
    if force_axis is not None:  # the force loop pushed X/Y/Z depth along -axis: put it back
        depth = ends.signal("force_depth")
        shift = depth[:, None] * np.asarray(force_axis)
        command_axes[:, :3] += shift
        actual_axes[:, :3] += shift
        true_tip += shift
    head = HeadGeometry(pivot_home=prog.pivot_home, tool_offset=prog.tool_offset, workpiece_origin=(0.0, 0.0, 0.0))
    command, actual = head.forward(command_axes[:, :5])[0], head.forward(actual_axes[:, :5])[0]  # the tips
    out: dict[str, Any] = {"periods_on_curve": int(on.sum()), "length_mm": curve.arc_length() * 1e3}
    if on.sum() < 3:
        return out
    k = np.flatnonzero(on[1:] & on[:-1]) + 1  # periods whose start and end are both on the curve
    u_end = curve.domain[1]
    steps = k[(ds[k] > 1e-9) & (u[k] < u_end)]
    s_true = _arc_lengths(curve, u[steps - 1], u[steps])
    fluct = np.abs(s_true - ds[steps]) / ds[steps]
    out["feed_fluctuation"] = {"max": float(fluct.max()), "rms": float(np.sqrt(np.mean(fluct**2))),
                               "periods": int(len(steps))}
    frac = np.linspace(0.0, 1.0, 9)[1:-1]
    uu = u[k - 1][:, None] + (u[k] - u[k - 1])[:, None] * frac[None, :]
    pts = curve.point(uu.ravel()).reshape(len(k), len(frac), 3)
    a, b = command[k - 1], command[k]
    d = b - a
    t = np.clip(np.einsum("kij,kj->ki", pts - a[:, None, :], d) / np.maximum(np.sum(d * d, axis=1), 1e-300)[:, None], 0, 1)
    chord = np.linalg.norm(pts - (a[:, None, :] + t[..., None] * d[:, None, :]), axis=2).max(axis=1)
    out["chord_error_um"] = {"max": float(chord.max() * 1e6), "tolerance": prog.limits.chord_tolerance * 1e6}
    seg = np.flatnonzero(on)
    lim = prog.limits
    names = "XYZ" if prog.axis_curve is None else "XYZAB"
    limits = [(lim.axis_velocity[i], lim.axis_acceleration[i], lim.axis_jerk[i]) for i in range(3)]
    if prog.axis_curve is not None:
        limits += [tuple(group[i] for group in prog.rotary_limits) for i in range(2)]
    pos = command_axes[seg[0] - 1:seg[-1] + 2, :len(names)]
    v = np.diff(pos, axis=0) / T
    acc = np.diff(v, axis=0) / T
    jerk = np.diff(acc, axis=0) / T
    # the period a difference belongs to: v[k] spans periods first+k .. first+k+1 (and so on)
    first = seg[0] - 1 + ends.first  # in the run (``ends`` may be a window of it)
    out["axis_peaks"] = {}
    violations = []
    for i, name in enumerate(names):
        # in the parameter file's units (mm/min, mm/s^2, mm/s^3; deg for A, B), limits beside them
        per_unit, unit_names = peak_units(name in "ABC")
        peaks = {}
        for quantity, series, limit, lag in (("velocity", v, limits[i][0], 1), ("acceleration", acc, limits[i][1], 1),
                                             ("jerk", jerk, limits[i][2], 2)):
            k = int(np.argmax(np.abs(series[:, i])))
            peak = float(abs(series[k, i]))
            ratio = peak / limit if limit > 0 else 0.0
            shown, shown_limit = peak / per_unit[quantity], limit / per_unit[quantity]
            peaks.update({quantity: shown, f"{quantity}_limit": shown_limit, f"{quantity}_ratio": ratio})
            if ratio > LIMIT_TOLERANCE:
                violations.append({"axis": name, "quantity": quantity, "peak": shown, "limit": shown_limit,
                                   "unit": unit_names[quantity], "ratio": ratio, "time_s": (first + k + lag) * T})
        peaks["units"] = unit_names
        out["axis_peaks"][name] = peaks
    out["limit_violations"] = violations
    if depth is not None:
        dv = np.diff(depth[seg[0] - 1:seg[-1] + 2]) / T
        da = np.diff(dv) / T
        per_unit, unit_names = peak_units(False)  # in the axes' units: mm/min, mm/s^2, mm/s^3
        out["force_offset"] = {"velocity": float(np.abs(dv).max()) / per_unit["velocity"],
                               "acceleration": float(np.abs(da).max()) / per_unit["acceleration"],
                               "jerk": float(np.abs(np.diff(da) / T).max()) / per_unit["jerk"], "units": unit_names,
                               "depth_range_mm": [float(depth[seg].min() * 1e3), float(depth[seg].max() * 1e3)]}
    poly = curve.point(np.linspace(*curve.domain, 20001))
    for key, tips in (("contour_error_um", true_tip), ("encoder_contour_error_um", actual)):
        contour = point_to_polyline(tips[on], poly)
        out[key] = {"max": float(contour.max() * 1e6), "rms": float(np.sqrt(np.mean(contour**2)) * 1e6)}
    if interpolator_ns is not None and len(interpolator_ns):
        out["interpolator_us_per_period"] = {"median": float(np.median(interpolator_ns) / 1e3),
                                             "p99": float(np.percentile(interpolator_ns, 99) / 1e3)}
    if plan_blocks:
        block_time = float(on.sum()) * T / max(1, plan_blocks)
        out["planning"] = {"total_ms": plan_us / 1e3, "blocks": plan_blocks,
                           "per_block_ms": plan_us / 1e3 / plan_blocks,
                           "block_execution_ms": block_time * 1e3,
                           "ratio_execution_over_planning": block_time * 1e6 / max(1.0, plan_us / plan_blocks)}
    return out


def peak_units(rotary: bool) -> tuple[dict[str, float], dict[str, str]]:
    """Per quantity (velocity, acceleration, jerk) the SI value of one unit of the parameter
    file's (mm/min, mm/s^2, mm/s^3; deg/min, deg/s^2, deg/s^3 on a rotary axis) and its name."""
    length, name = (units.DEG, "deg") if rotary else (units.MM, "mm")
    return ({"velocity": units.velocity_factor(rotary), "acceleration": length, "jerk": length},
            {"velocity": f"{name}/min", "acceleration": f"{name}/s^2", "jerk": f"{name}/s^3"})
