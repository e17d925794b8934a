"""An axis's positioning errors measured on the twin as a laser calibration measures a machine's
(ISO 230-2's bidirectional run), and the pitch-error table that corrects them, written in
LinuxCNC's ``COMP_FILE`` format for the card (``axes.<axis>.compensation.comp_file``).

The run: from below the first target, the axis stops at each target going up, goes past the
last, and stops at each going down, dwelling at each stop; at each dwell's end the tool's true
position (the trace's tool pose through the head's inverse kinematics) is read against the
target. The errors are reached - target [m | rad], per target and direction.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cnc_twin.core import units
from cnc_twin.core.axes import AXES
from cnc_twin.geometry.kinematics import HeadGeometry
from cnc_twin.run.twin import run_scenario
from cnc_twin.scenario.load import load_scenario


@dataclass(frozen=True)
class Positioning:
    """Targets [mm | deg] and the positions reached there going up and going down [mm | deg]."""

    targets: np.ndarray
    forward: np.ndarray
    reverse: np.ndarray

    @property
    def forward_error(self) -> np.ndarray:
        """reached - target going up [mm | deg]"""
        return self.forward - self.targets

    @property
    def reverse_error(self) -> np.ndarray:
        """reached - target going down [mm | deg]"""
        return self.reverse - self.targets


def measure_positioning(scenario_file: Path, axis: str, targets, *, dwell: float = 0.3, overshoot: float = 20.0,
                        overrides: dict[str, Any] | None = None) -> Positioning:
    """The bidirectional run of ``axis`` over ``targets`` [mm | deg, machine coordinates,
    increasing] on ``scenario_file``'s machine (its program replaced), each stop held ``dwell``
    [s], turning ``overshoot`` [mm | deg] beyond the ends. ``overrides``: more scenario overrides.
    ValueError when the run does not complete."""
    i = AXES.index(axis)
    targets = np.asarray(targets, dtype=np.float64)
    if targets.size < 2 or not np.all(np.diff(targets) > 0):
        raise ValueError("targets: at least two, increasing")
    stops = [targets[0] - overshoot, *targets, targets[-1] + overshoot, *targets[::-1]]
    program = {"type": "point_to_point", "settle": 0.05, "moves": [{axis: float(x), "dwell": dwell} for x in stops]}
    scenario = load_scenario(scenario_file, overrides={**(overrides or {}), "program": program})
    result = run_scenario(scenario)
    if result.status != "complete":
        raise ValueError(f"the calibration run did not complete: {result.status}")
    trace = result.trace
    tpp = trace.ticks_per_period
    head = HeadGeometry.from_model(result.model)
    tip, pivot = trace.tool[:, :3], trace.tool[:, 3:]
    factor = units.position_factor(scenario.axes[i].rotary)
    reached = head.axes_from_pose(tip, pivot - tip)[:, i] / factor if i < 5 else None
    if reached is None:
        raise ValueError("the tool pose gives X..B; C has no position to calibrate")
    command = trace.command[tpp - 1::tpp, i] / trace.counts_per_unit[i] / factor + scenario.home[i] / factor
    n = min(len(reached), len(command))
    moving = np.diff(command[:n]) != 0.0
    # each stop's last period: the command stood still and moves next (the run's end for the last)
    ends = [k for k in range(1, n - 1) if not moving[k - 1] and moving[k]] + [n - 1]
    if len(ends) != len(stops):
        raise ValueError(f"found {len(ends)} stops in the run, expected {len(stops)}")
    at = reached[ends]
    m = len(targets)
    return Positioning(targets, at[1:m + 1], at[m + 2:][::-1])


def write_comp_file(positioning: Positioning, path: Path) -> Path:
    """The table that corrects ``positioning``, LinuxCNC's ``COMP_FILE_TYPE = 0`` format: per
    target, the nominal position and the positions reached going up and going down [mm | deg]."""
    lines = ["# nominal, reached going up, reached going down (LinuxCNC COMP_FILE_TYPE 0)"]
    lines += [f"{t:.6f} {f:.6f} {r:.6f}" for t, f, r in zip(positioning.targets, positioning.forward,
                                                            positioning.reverse)]
    path.write_text("\n".join(lines) + "\n")
    return path
