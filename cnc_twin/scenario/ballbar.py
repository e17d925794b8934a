"""Scenario schema of the ``ballbar:`` section, and its conversion to SI.

::

    ballbar:                  # a circular test (ISO 230-4) measured on the run
      plane: XY               # XY, XZ or YZ: the plane the program's circles run in
      centre: [0, 0, 20]      # [mm] the pivot, workpiece frame (the program's coordinates)
      radius: 50              # [mm] the bar's length: the circles' nominal radius
      overshoot: 90           # [deg] lead-in and lead-out arc at each end of a pass, not measured

The program runs the circles (a G-code program of G2 / G3 arcs, as a ballbar's own software
writes one); the twin measures the tool tip's distance from the pivot on every feed path that
goes around it (:mod:`cnc_twin.run.ballbar`).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from cnc_twin.core import units
from cnc_twin.core.config import BallbarTest
from cnc_twin.geometry.kinematics import HeadGeometry
from cnc_twin.scenario.schema_base import Strict


class BallbarSpec(Strict):
    """The ``ballbar:`` section."""

    plane: Literal["XY", "XZ", "YZ"] = Field(description="the plane of the circles")
    centre: list[float] = Field(min_length=3, max_length=3, description="[mm] the pivot X Y Z, workpiece frame")
    radius: float = Field(gt=1.0, le=1000.0, description="[mm] nominal radius (the bar's length)")
    overshoot: float = Field(90.0, ge=0.0, le=180.0,
                             description="[deg] lead-in and lead-out arc at each end of a pass, not measured")


def convert_ballbar(spec: BallbarSpec | None, model) -> BallbarTest | None:
    """The test in SI, its centre in the world frame (the workpiece origin added)."""
    if spec is None:
        return None
    origin = np.asarray(HeadGeometry.from_model(model).workpiece_origin)
    centre = np.asarray(spec.centre, dtype=np.float64) * units.MM + origin
    return BallbarTest(spec.plane, tuple(float(c) for c in centre), spec.radius * units.MM,
                       float(np.radians(spec.overshoot)), tuple(float(c) * units.MM for c in spec.centre))
