"""The planner's side of a motion-chip program: one ChipCommand record per command.

The chip plans its own profiles, so the PC sends the commands as they are (dwells as Dwell
records), then a Dwell for the settle time and EndOfProgram. The card runs them one after the
other; how long a home return takes is known only when it ends, so the look-ahead counts none of
them as queued motion.
"""

from __future__ import annotations

import math

from cnc_twin.core.config import ChipStep, MotionChipProgram
from cnc_twin.planner.ptp import dwell_chunk, dwell_periods
from cnc_twin.whiteboard.records import (
    CHIP_CONSTANT, CHIP_HOME, CHIP_INDEX, CHIP_JOG, CHIP_LINEAR, CHIP_S_CURVE, CHIP_TRAPEZOID, ChipCommand, Dwell,
    EndOfProgram, Record,
)

_OPS = {"index": CHIP_INDEX, "linear": CHIP_LINEAR, "jog": CHIP_JOG, "home": CHIP_HOME}
_PROFILES = {"constant": CHIP_CONSTANT, "trapezoid": CHIP_TRAPEZOID, "s_curve": CHIP_S_CURVE}


def chip_record(step: ChipStep, profile: str) -> ChipCommand:
    """The ChipCommand record of a program's command ``step``, with the program's ``profile``."""
    return ChipCommand(op=_OPS[step.op], axis=step.axis, profile=_PROFILES[profile], deltas=step.deltas,
                       distance=step.distance, speed=step.speed, creep=step.creep, accel=step.accel,
                       jerk=step.jerk, time=step.time)


def _estimate(step: ChipStep) -> float:
    """A generous guess of a command's duration [s] (progress bar and default time limit)."""
    ramp = abs(step.speed) / step.accel + step.accel / step.jerk if step.accel > 0 else 0.0
    if step.op == "dwell":
        return step.time
    if step.op == "jog":
        return step.time + 2.0 * ramp
    if step.op == "home":  # search across the whole travel, then a revolution or two at creep
        return step.span / abs(step.speed) + 2e4 / abs(step.creep) + 4.0 * ramp
    length = abs(step.distance) if step.op == "index" else math.hypot(*step.deltas)
    return length / abs(step.speed) + 2.0 * ramp


class ChipPlan:
    """A motion-chip program's records in one chunk: its commands, then the settle dwell and
    EndOfProgram (see the module docstring)."""

    def __init__(self, prog: MotionChipProgram, period: float):
        self.prog, self.period = prog, period

    @property
    def estimated_periods(self) -> int:
        return math.ceil((sum(_estimate(s) for s in self.prog.commands) + self.prog.settle) / self.period)

    def chunks(self):
        records: list[Record] = []
        periods: list[int] = []
        for step in self.prog.commands:
            if step.op == "dwell":
                n = dwell_periods(step.time, self.period)
                records.append(Dwell(periods=n))
                periods.append(n)
            else:
                records.append(chip_record(step, self.prog.profile))
                periods.append(0)
        settle = dwell_chunk(self.prog.settle, self.period)
        yield records + settle[0] + [EndOfProgram()], periods + settle[1] + [0]
