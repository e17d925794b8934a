"""Probing on the twin (G38.2 .. G38.5): a probing move as a machine step, and the program after
a probe read again with where the card found the work.

The bundled machine has no touch probe: it probes with its polishing pad. The load cell between
head and pad feels the pad pressed along the tool axis, so a probing move goes straight down the
tool axis (G38.2, G38.3: until the force reaches ``program.probe.trip_force``) or up it (G38.4,
G38.5: until it falls below); the card latches the encoders when the force crosses, stops the
axes within their acceleration limits and reports both (:mod:`cnc_twin.dsp.probe`).

LinuxCNC's interpreter reads past a probe only once the machine has answered, since what follows
may use the answer (#5061 .., #5070). The twin reads the whole program at load with rs274's
standalone answers (every check, every later line, is then known to read), and at run time, after
each probe, reads it again with the card's answers so far (:class:`ProbeReplay`): the planner
runs what follows the last answered probe.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydantic import Field

from cnc_twin.core import units
from cnc_twin.core.config import AxisConfig
from cnc_twin.core.gcode_config import GcodeMove, GcodeProbe, ProbeAnswer
from cnc_twin.scenario.schema_base import Strict

KINDS = {2: "G38.2", 3: "G38.3", 4: "G38.4", 5: "G38.5"}
ALONG_AXIS = 1e-6
"""a probing move's largest sideways part, as a fraction of its length"""


class ProbeSpec(Strict):
    """How the pad probes (G38.2 .. G38.5)."""

    trip_force: float = Field(2.0, gt=0, le=100, description="[N] the load-cell force that trips the probe (the "
                              "pad is then pressed by about this over its stiffness)")


@dataclass(frozen=True)
class PartTop:
    """The top face of the scene's block where the part is set up, workpiece frame [mm], and the
    pad's radius [mm]: where a probe down the tool axis can touch."""

    x: tuple[float, float]
    y: tuple[float, float]
    z: float
    pad_radius: float


def probe_step(op, move: GcodeMove, spec: ProbeSpec, head, where, *, force_on=None, air: float = 0.0,
               part: PartTop | None = None) -> GcodeProbe:
    """The machine step of a probing ``op`` (:class:`~cnc_twin.gcode.path_ops.Probe`), its end
    already converted and checked against travel (``move``), or ``where``'s error at its line
    (with ``part``, a G38.2 straight down that cannot reach the part's top is refused: it would
    end without touching, a PROBE fault some time into the run)."""
    name = KINDS[op.kind]
    if force_on is not None:
        raise where(op.line, f"{name} while the grinding-force loop is on (M100 at line {force_on.line}): M101 first")
    if air and op.kind in (2, 4):
        raise where(op.line, f"{name} in the air (program.in_air) never touches the work and must: probe on the "
                    "work (leave in_air out), or use G38.3 / G38.5, which accept no contact")
    start, end = np.asarray(op.start, dtype=float), np.asarray(op.end, dtype=float)
    if np.any(start[3:] != end[3:]):
        raise where(op.line, f"{name} turns A / B / C: the pad probes along the tool axis only")
    d = end[:3] - start[:3]
    length = float(np.linalg.norm(d))
    a, b = (v * units.DEG for v in end[3:5])
    n = head_axis(a, b)
    along = float(np.dot(d, n))
    sideways = float(np.linalg.norm(d - along * n))
    down = op.kind in (2, 3)
    if length == 0.0 or sideways > ALONG_AXIS * length or (along < 0.0) != down:
        way = "down (toward the work)" if down else "up (away from the work)"
        raise where(op.line, f"{name} must move straight {way} the tool axis {tuple(round(x, 6) for x in n)}: the "
                    "pad's load cell feels force along that axis only")
    if op.feed <= 0.0:
        raise where(op.line, f"{name} with feed 0")
    if part is not None and op.kind == 2 and abs(n[2]) == 1.0:
        x, y, z = end[:3]
        r = part.pad_radius
        beside = not (part.x[0] - r < x < part.x[1] + r and part.y[0] - r < y < part.y[1] + r)
        if beside or z > part.z:
            raise where(op.line, f"{name} at X{x:.3f} Y{y:.3f} down to Z{z:.3f} cannot touch the part (its top X "
                        f"{part.x[0]:g}..{part.x[1]:g} Y {part.y[0]:g}..{part.y[1]:g} at Z{part.z:g} mm, the pad "
                        f"{r:g} mm in radius): it would end without contact; place the program on the part "
                        "(program.work_offsets)")
    return GcodeProbe(end=move.end, feed=op.feed * units.MM / 60.0, kind=op.kind, trip_force=spec.trip_force,
                      line=op.line, offset=op.offset, scale=op.scale)


def head_axis(a: float, b: float) -> np.ndarray:
    """The tool axis (unit, world frame, pointing from the work up to the head) at A, B [rad]."""
    from cnc_twin.geometry.kinematics import tool_axis

    return np.asarray(tool_axis(a, b), dtype=float)


def reader_answers(answers, head):
    """The reader's probe (:data:`~cnc_twin.gcode.probing.Probe`) that answers the program's probes
    in order with the card's ``answers`` (``(GcodeProbe, ProbeAnswer)`` each), then as rs274 alone
    does: the card's axis positions as the program sees them (tip in the workpiece frame, less the
    program's offsets at the probe, in its units)."""
    from cnc_twin.gcode.probing import ProbeResult, standalone_probe

    asked = [0]

    def program_point(step: GcodeProbe, axes_position) -> tuple[float, ...]:
        q = np.asarray(axes_position, dtype=float)
        tip = head.tip_from_axes(q[:3], q[3], q[4]) - np.asarray(head.workpiece_origin)
        machine = [*(float(v) / units.MM for v in tip), *(float(v) / units.DEG for v in q[3:])]
        return tuple((m - o) / (step.scale if k < 3 else 1.0) for k, (m, o) in enumerate(zip(machine, step.offset)))

    def probe(move):
        k = asked[0]
        asked[0] += 1
        if k >= len(answers):
            return standalone_probe(move)
        step, answer = answers[k]
        return ProbeResult(answer.tripped, program_point(step, answer.trip), program_point(step, answer.stop))

    return probe


@dataclass(frozen=True)
class ProbeReplay:
    """The steps of a probing program after its last answered probe (:attr:`GcodeProgram.after_probe
    <cnc_twin.core.gcode_config.GcodeProgram.after_probe>`): the program read and converted again
    as at load, its probes answered by the card. Plain data, so the planner's job carries it."""

    convert: object
    """:func:`cnc_twin.scenario.gcode.convert` (handed in: that module imports this one)"""
    spec: object
    """the scenario's :class:`~cnc_twin.scenario.gcode.GcodeProgramSpec`"""
    axes: tuple[AxisConfig, ...]
    model_file: Path
    block_shift: tuple[float, float, float]
    label: Path
    folder: Path | None
    machine_tools: Path | None
    home: tuple[float, ...] | None

    def __call__(self, answers: list[tuple[GcodeProbe, ProbeAnswer]]) -> tuple:
        from cnc_twin.machine.model_file import load_model_with_obstacles

        model = load_model_with_obstacles(self.model_file, [], self.block_shift)
        program = self.convert(self.spec, self.axes, model, self.label, self.folder, self.machine_tools, self.home,
                          model_file=self.model_file, block_shift=self.block_shift, answers=list(answers))
        probes = [k for k, step in enumerate(program.steps) if isinstance(step, GcodeProbe)]
        if len(probes) < len(answers):  # the answers changed the program's course (an O-word on #5070)
            return ()
        return program.steps[probes[len(answers) - 1] + 1:]

