"""The programmed tool-tip path of a curve program, in the world frame (for metrics and the viewer)."""

from __future__ import annotations

import numpy as np

from cnc_twin.core.config import NurbsProgram, Scenario
from cnc_twin.geometry.nurbs import NurbsCurve


def tip_curve(prog: NurbsProgram) -> NurbsCurve:
    """The programmed tool-tip curve in the world frame (a held-axis program stores its curve in
    axis space: shifted back by the head offset)."""
    points = np.asarray(prog.control_points)
    if prog.axis_curve is None:
        points = points + np.asarray(prog.tip_shift)
    return NurbsCurve(points, prog.weights, prog.knots, prog.degree)


def planned_path(scenario: Scenario, n: int = 4000) -> np.ndarray | None:
    """The programmed tool-tip curve of a curve program at ``n`` parameter values evenly spread
    over its domain, (n, 3) [m]; None for other programs."""
    prog = scenario.program
    if not isinstance(prog, NurbsProgram):
        return None
    curve = tip_curve(prog)
    return curve.point(np.linspace(*curve.domain, n))
