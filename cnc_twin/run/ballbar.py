"""The circular test (ISO 230-4) measured on a run, as a ballbar measures it: the tool tip's
distance from a pivot fixed at the circles' centre, over each pass around it.

A pass is a stretch of the program's path (the trace's ``path_u >= 0``, between rapids) whose tip
stays within ``ON_CIRCLE`` of the nominal radius and goes around the centre; its lead-in and
lead-out (``overshoot`` each) are left out, the rest (the data arc, 360 deg as the test is
written) measured. The tip is where it really is (the trace's ``tip_x``.. : MuJoCo's pad face
centre, which the structure's and screws' compliance moves too), as the bar between tool and
table sees it; angles run from the plane's first axis towards its second (XY: from +X to +Y).

Figures, for each direction (``ccw``, ``cw``), in um and as ISO 230-4 names them:

- ``radial_deviation``: ``max`` and ``min`` of the radius less the nominal one, about the
  nominal centre (ISO's F).
- ``circular_deviation``: the radial band the path fills about its own least-squares centre
  (ISO's G, least-squares circle), with that circle's ``radius_error`` (its radius less the
  nominal one) and ``centre_offset`` (its centre less the nominal one, along the plane's axes).
- ``reversal_spikes``: at 0, 90, 180 and 270 deg (where one axis reverses), the largest step of
  the radial deviation within ``SPIKE_HALF_WIDTH`` of the point above the median of the band
  ``SPIKE_HALF_WIDTH``..``BASELINE_HALF_WIDTH`` either side (signed: outward positive).

With both directions, ``hysteresis`` (ISO's H): the largest radial difference between them at
the same angle, on a 1 deg grid.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cnc_twin.core.config import BallbarTest, Scenario
from cnc_twin.trace.trace import Trace

PLANE_AXES = {"XY": (0, 1), "XZ": (0, 2), "YZ": (1, 2)}
"""plane -> the world axes (x 0, y 1, z 2) angles run from and towards"""
ON_CIRCLE = 0.05
"""a sample is on the test circle when its radius is within this share of the nominal radius"""
SPIKE_HALF_WIDTH = np.radians(5.0)
BASELINE_HALF_WIDTH = np.radians(15.0)
QUADRANTS = (0, 90, 180, 270)
"""[deg] the axis reversal points"""


@dataclass(frozen=True)
class BallbarPass:
    """One pass's data arc: ``angle`` [rad, 0..2 pi, in the order run], ``deviation`` [m]
    (radius less the nominal, about the nominal centre), ``points`` (n, 2) [m] relative to the
    nominal centre in the plane, ``direction`` ``ccw`` or ``cw``, ``feed`` [m/s] mean tip speed."""

    direction: str
    angle: np.ndarray
    deviation: np.ndarray
    points: np.ndarray
    feed: float


def ballbar_passes(trace: Trace, test: BallbarTest, period: float) -> list[BallbarPass]:
    """The passes around ``test``'s centre in ``trace`` (``period``: the interpolation period [s])."""
    across, up = PLANE_AXES[test.plane]
    tips = trace.tool[:, :3]
    u = trace.periods["path_u"][: len(tips)]
    relative = tips[:, [across, up]] - np.asarray(test.centre)[[across, up]]
    radius = np.hypot(relative[:, 0], relative[:, 1])
    near = (u >= 0) & (np.abs(radius - test.radius) <= ON_CIRCLE * test.radius)
    passes = []
    edges = np.flatnonzero(np.diff(np.concatenate([[0], near.astype(np.int8), [0]])))
    for first, stop in zip(edges[::2], edges[1::2]):
        theta = np.unwrap(np.arctan2(relative[first:stop, 1], relative[first:stop, 0]))
        sweep = theta[-1] - theta[0]
        if abs(sweep) < 2 * test.overshoot + np.radians(180):  # not around the centre: not a pass
            continue
        sign = 1.0 if sweep > 0 else -1.0
        run = sign * (theta - theta[0])
        keep = (run >= test.overshoot) & (run <= abs(sweep) - test.overshoot)
        if keep.sum() < 8:
            continue
        idx = first + np.flatnonzero(keep)
        steps = np.linalg.norm(np.diff(tips[idx], axis=0), axis=1)
        passes.append(BallbarPass("ccw" if sign > 0 else "cw", np.mod(theta[keep], 2 * np.pi),
                                  radius[idx] - test.radius, relative[idx],
                                  float(steps.sum() / max(period * (len(idx) - 1), period))))
    return passes


def least_squares_circle(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre (2,) and radius of the circle fitted to ``points`` (n, 2) by least squares on the
    algebraic form x^2 + y^2 + D x + E y + F = 0 (Kasa's fit; for points spread all around a
    circle it equals the geometric fit to far below a micrometre)."""
    design = np.column_stack([points, np.ones(len(points))])
    rhs = -(points ** 2).sum(axis=1)
    (d, e, f), *_ = np.linalg.lstsq(design, rhs, rcond=None)
    centre = np.array([-d / 2, -e / 2])
    return centre, float(np.sqrt(max(centre @ centre - f, 0.0)))


def reversal_spikes(angle: np.ndarray, deviation: np.ndarray) -> dict[str, float]:
    """Per quadrant point [deg as text], the spike [m] (see the module's text); NaN where the
    pass has no samples there."""
    out = {}
    for quadrant in QUADRANTS:
        off = np.angle(np.exp(1j * (angle - np.radians(quadrant))))  # wrapped to -pi..pi
        inner = np.abs(off) <= SPIKE_HALF_WIDTH
        ring = (np.abs(off) > SPIKE_HALF_WIDTH) & (np.abs(off) <= BASELINE_HALF_WIDTH)
        if not inner.any() or not ring.any():
            out[str(quadrant)] = float("nan")
            continue
        step = deviation[inner] - np.median(deviation[ring])
        out[str(quadrant)] = float(step[np.argmax(np.abs(step))])
    return out


def pass_figures(p: BallbarPass, test: BallbarTest) -> dict[str, Any]:
    """One pass's figures [um] (see the module's text)."""
    centre, radius = least_squares_circle(p.points)
    about_fit = np.hypot(*(p.points - centre).T) - radius
    um = 1e6
    return {
        "radial_deviation_um": {"max": float(p.deviation.max() * um), "min": float(p.deviation.min() * um)},
        "circular_deviation_um": float(np.ptp(about_fit) * um),
        "radius_error_um": float((radius - test.radius) * um),
        "centre_offset_um": [float(c * um) for c in centre],
        "reversal_spikes_um": {q: v * um for q, v in reversal_spikes(p.angle, p.deviation).items()},
        "data_arc_deg": float(np.degrees(_covered(p.angle))),
        "feed_mm_min": p.feed * 60e3,
    }


def hysteresis(ccw: BallbarPass, cw: BallbarPass) -> float:
    """The largest difference [m] between the two directions' radial deviations at the same
    angle, on a 1 deg grid (each interpolated periodically)."""
    grid = np.radians(np.arange(360.0))

    def at(p: BallbarPass) -> np.ndarray:
        order = np.argsort(p.angle)
        return np.interp(grid, p.angle[order], p.deviation[order], period=2 * np.pi)

    return float(np.max(np.abs(at(ccw) - at(cw))))


def ballbar_metrics(trace: Trace, scenario: Scenario) -> dict[str, Any]:
    """The ``ballbar`` section of metrics.json: the test as set, each direction's figures and the
    hysteresis (when both ran)."""
    test = scenario.ballbar
    passes = ballbar_passes(trace, test, scenario.timing.interpolation_period)
    out: dict[str, Any] = {"plane": test.plane, "radius_mm": test.radius * 1e3,
                           "centre_mm": [c * 1e3 for c in test.centre_in_workpiece],
                           "passes": len(passes)}
    for p in passes:
        out.setdefault(p.direction, pass_figures(p, test))  # the first pass of each direction
    first = {p.direction: p for p in reversed(passes)}
    if "ccw" in first and "cw" in first:
        out["hysteresis_um"] = hysteresis(first["ccw"], first["cw"]) * 1e6
    return out


def _covered(angle: np.ndarray) -> float:
    """The arc [rad] the angles cover (2 pi less the widest gap between them)."""
    if len(angle) < 2:
        return 0.0
    ordered = np.sort(angle)
    gaps = np.diff(np.concatenate([ordered, ordered[:1] + 2 * np.pi]))
    return float(2 * np.pi - gaps.max())
