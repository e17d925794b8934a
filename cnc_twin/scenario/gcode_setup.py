"""A G-code program set up on the machine as a machinist sets it up: where it starts (the
machine's home, as LinuxCNC's interpreter starts from the machine's position), its work offsets
(a touch-off, held in LinuxCNC's parameters #5221..), in the air (``program.in_air``), and where
it goes against where the machine reaches when it does not fit
(:func:`~cnc_twin.scenario.gcode_setup.with_placement`)."""

from __future__ import annotations

import numpy as np

from cnc_twin.core import units
from cnc_twin.core.errors import ScenarioError
from cnc_twin.scenario.schema_base import Strict

WORK_SYSTEMS = ("G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3")
"""the work systems in LinuxCNC's order (system 1 .. 9: parameters #5221 + 20 (n - 1) ..)"""


class WorkOffsetSpec(Strict):
    """A work system's origin in the workpiece frame, as a touch-off sets it [mm; deg for A B C]."""

    X: float = 0.0
    Y: float = 0.0
    Z: float = 0.0
    A: float = 0.0
    B: float = 0.0
    C: float = 0.0


def start_point(head, home: tuple[float, ...] | None, air: float) -> tuple[float, ...]:
    """Where the machine stands at ``home`` (six axes [m | rad]; None: the head's home pose) as a
    program sees it: the tool tip in the workpiece frame [mm] less the run's raise ``air`` [mm]
    in Z, and A B C [deg]."""
    q = np.zeros(6) if home is None else np.asarray(home, dtype=float)
    tip = head.tip_from_axes(q[:3], q[3], q[4]) - np.asarray(head.workpiece_origin)
    return (*(float(v) / units.MM for v in tip[:2]), float(tip[2]) / units.MM - air,
            *(float(v) / units.DEG for v in q[3:]))


def work_offset_parameters(offsets: dict[str, WorkOffsetSpec], per_mm: float) -> dict[int, float]:
    """The work systems' origins as LinuxCNC's parameter file holds them: #5221 + 20 (n - 1) + k,
    lengths in machine units (``per_mm`` of them in a mm), angles in deg."""
    out = {}
    for name, offset in offsets.items():
        base = 5221 + 20 * WORK_SYSTEMS.index(name)
        for k, value in enumerate((offset.X, offset.Y, offset.Z, offset.A, offset.B, offset.C)):
            out[base + k] = value * per_mm if k < 3 else value
    return out


def in_units(point: tuple[float, ...], per_mm: float) -> tuple[float, ...]:
    """A machine point [mm, deg] with its lengths in machine units."""
    return (*(v * per_mm for v in point[:3]), *point[3:])


def with_placement(exc: ScenarioError, box_of, axes, head) -> ScenarioError:
    """A program that leaves an axis's soft limits, and whose tip goes beyond what the machine
    reaches with the head upright, is refused with both boxes (workpiece frame), so the user sees
    the work offset that places it; any other refusal as it is. ``box_of()``: the program's box
    (:func:`~cnc_twin.gcode.extents.extents`), asked for only for such a refusal."""
    from cnc_twin.gcode.extents import describe

    if not any(cfg.allowed is not None and cfg.allowed_name in exc.message for cfg in axes[:3]):
        return exc
    box = box_of()
    if box is None:
        return exc
    shift = (np.asarray(head.pivot_home) + np.asarray(head.tool_offset) - np.asarray(head.workpiece_origin)) / units.MM
    reach = (np.array([cfg.allowed[0] for cfg in axes[:3]]) / units.MM + shift,
             np.array([cfg.allowed[1] for cfg in axes[:3]]) / units.MM + shift)
    if np.all(box[0] >= reach[0]) and np.all(box[1] <= reach[1]):
        return exc  # it fits upright: its tilt (A / B) takes it out, which no offset mends
    return ScenarioError(exc.file, exc.key_path, f"{exc.message}; the program goes to {describe(box)}, the machine "
                         f"reaches {describe(reach)} (workpiece frame, head upright): program.work_offsets places it")


def air_clearance(lowest: float | None, top: float | None) -> float | None:
    """[m] the program's ``lowest`` point [mm] (as it runs, raised) above the workpiece's top
    ``top`` [mm, workpiece frame]; None without a top or a move."""
    return None if lowest is None or top is None else float(lowest - top) * units.MM
