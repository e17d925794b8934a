"""The motion chip on the card: index, linear, jog and home-return commands, one cycle per period.

The chip (a 4-axis pulse chip of the kind the older cards carry) runs its profiles in pulses
(:mod:`cnc_twin.legacy.motion_chip`); here its cycle is the interpolation period, and the pulses
of each cycle add to the axes' commands, which the servo task sends on (analog or pulses).

Commands (:class:`~cnc_twin.whiteboard.records.ChipCommand`)::

    index   one axis by a fixed number of pulses (ends exactly on target)
    linear  X/Y/Z together along a straight line (Bresenham slaves of the longest axis)
    jog     one axis at a speed for a time, then the fastest stop of the profile
    home    the axis's home return, in the + direction (home switches sit at the + end):
              clear   switch already on: jog - at search speed until it is off, stop
              search  jog + at search speed until the switch is on, stop
              backoff jog - at creep speed until the switch is off ...
              index   ... and on, until the encoder's index pulse: latch its count, stop
              return  index move back to the latched count: the axis stands on its home
            The latched count is the home: it depends only on the index mark that follows the
            switch's release, not on where the search started or where the switch tripped.

Travel limits: a limit switch on the side the axis is moving towards stops it (index, linear:
at once, the rest of the move dropped; jog, home: the profile's stop) and raises an event.

Events per axis, as bits (also in the status block and the trace, see :mod:`cnc_twin.dsp.task`)::

    MOTION_DONE 1   the command finished           HOME_FOUND 2   index latched (value: the count)
    LIMIT_POS   4   + limit switch stopped the axis  LIMIT_NEG 8   - limit switch stopped it
"""

from __future__ import annotations

import math

from cnc_twin.legacy.motion_chip import IndexMove, Jog, linear_move
from cnc_twin.core.axes import SWITCH_HOME, SWITCH_LIMIT_NEG, SWITCH_LIMIT_POS
from cnc_twin.whiteboard.records import (
    CHIP_CONSTANT, CHIP_HOME, CHIP_INDEX, CHIP_JOG, CHIP_LINEAR, CHIP_TRAPEZOID, ChipCommand,
)

EVENT_MOTION_DONE, EVENT_HOME_FOUND, EVENT_LIMIT_POS, EVENT_LIMIT_NEG = 1, 2, 4, 8
EVENT_NAMES = {EVENT_MOTION_DONE: "motion_done", EVENT_HOME_FOUND: "home_found", EVENT_LIMIT_POS: "limit_pos",
               EVENT_LIMIT_NEG: "limit_neg"}


class IndexMarks:
    """Where one axis's encoder index pulses are, in counts from power-on.

    Marks lie at ``offset + m * period`` [m | rad]; the QEP latches the count of the mark's edge.
    """

    def __init__(self, counts_per_unit: float, period: float, offset: float, power_on: float):
        self.cpu, self.period, self.offset = counts_per_unit, period, offset
        self.zero = math.floor(power_on * counts_per_unit)

    def mark_of(self, count: int) -> int:
        """Number of the last mark at or below the position of ``count``."""
        return math.floor(((count + self.zero + 0.5) / self.cpu - self.offset) / self.period)

    def count_of(self, mark: int) -> int:
        """The count latched at mark ``mark``."""
        return math.floor((self.offset + mark * self.period) * self.cpu) - self.zero


def _limits(profile: int, accel: float, jerk: float) -> tuple[float | None, float | None]:
    if profile == CHIP_CONSTANT:
        return None, None
    if profile == CHIP_TRAPEZOID:
        return accel, None
    return accel, jerk


class ChipRun:
    """One chip command running on the card.

    Parameters
    ----------
    record : the command.
    held : every axis's command when it starts [counts], shape ``(6,)``.
    dt : the chip's cycle, the interpolation period [s].
    marks : per axis :class:`IndexMarks` (or None), for home returns.
    """

    def __init__(self, record: ChipCommand, held: list[float], *, dt: float, marks):
        self.record = record
        self.command = list(held)
        self.dt = dt
        self.done = False
        self.events: list[tuple[int, int, int]] = []
        """``(axis, event bit, value)`` raised in the last cycle"""
        self._a, self._j = _limits(record.profile, record.accel, record.jerk)
        self._axis = record.axis
        self._marks = marks[record.axis] if marks is not None else None
        self._phase = ""
        self._jog: Jog | None = None
        self._moves = None  # per-cycle pulse rows of an index or linear move
        self._axes: tuple[int, ...] = (record.axis,)
        self._last_actual: int | None = None
        self.latched: int | None = None
        """home return: the count latched at the index pulse"""
        self._limits_hit: set[int] = set()
        op = record.op
        if op == CHIP_INDEX:
            move = IndexMove(record.distance, record.speed, self._a, self._j, dt)
            self._moves = iter([(int(p),) for p in move.pulses])
        elif op == CHIP_LINEAR:
            self._axes = tuple(i for i, d in enumerate(record.deltas) if d != 0)
            rows = linear_move([record.deltas[i] for i in self._axes], record.speed, self._a, self._j, dt)
            self._moves = iter([tuple(int(p) for p in row) for row in rows])
        elif op == CHIP_JOG:
            self._jog = Jog(record.speed, self._a, self._j, dt)
        elif op == CHIP_HOME:
            self._phase = "start"
        else:
            raise ValueError(f"unknown chip command {op}")
        self._cycle = 0

    def step(self, inputs: list[int], actual: list[int]) -> list[float]:
        """One chip cycle with the switch ``inputs`` and encoder counts ``actual``; the commands [counts]."""
        self.events = []
        self._cycle += 1
        if self.done:
            return self.command
        if self._moves is not None:
            self._step_move(inputs)
        elif self.record.op == CHIP_JOG:
            if self._cycle * self.dt > self.record.time:
                self._jog.stop()
            self._step_jog(inputs)
            if self._jog is None:
                self._finish()
        else:
            self._step_home(inputs, actual)
        return self.command

    # --- pieces ----------------------------------------------------------------------------
    def _finish(self) -> None:
        self.done = True
        for axis in self._axes:
            self.events.append((axis, EVENT_MOTION_DONE, int(round(self.command[axis]))))

    def _limit_hit(self, axis: int, direction: int, inputs: list[int]) -> bool:
        """A limit switch on the side ``axis`` moves towards is on (the event is raised once)."""
        if direction > 0 and inputs[axis] & SWITCH_LIMIT_POS:
            code = EVENT_LIMIT_POS
        elif direction < 0 and inputs[axis] & SWITCH_LIMIT_NEG:
            code = EVENT_LIMIT_NEG
        else:
            return False
        if code not in self._limits_hit:
            self._limits_hit.add(code)
            self.events.append((axis, code, int(round(self.command[axis]))))
        return True

    def _step_move(self, inputs: list[int]) -> None:
        row = next(self._moves, None)
        if row is None:
            self._finish()
            return
        if any(p and self._limit_hit(axis, p, inputs) for axis, p in zip(self._axes, row)):
            self._moves = iter(())  # the chip stops at once; the rest of the move is dropped
            self._finish()
            return
        for axis, p in zip(self._axes, row):
            self.command[axis] += p

    def _step_jog(self, inputs: list[int]) -> None:
        """One cycle of the running jog; ``self._jog`` becomes None once it is at rest."""
        jog = self._jog
        v = jog.velocity
        direction = 1 if v > 0 else -1 if v < 0 else 0
        if direction and self._limit_hit(self._axis, direction, inputs):
            jog.stop()
        pulses = next(jog, None)
        if pulses is None:
            self._jog = None
            return
        self.command[self._axis] += pulses

    def _start_jog(self, speed: float, phase: str) -> None:
        self._jog = Jog(speed, self._a, self._j, self.dt)
        self._phase = phase

    def _step_home(self, inputs: list[int], actual: list[int]) -> None:
        axis, rec = self._axis, self.record
        on = bool(inputs[axis] & SWITCH_HOME)
        phase = self._phase
        if phase == "start":
            if on:
                self._start_jog(-rec.speed, "clear")
            else:
                self._start_jog(rec.speed, "search")
        elif phase == "clear" and not on:
            self._jog.stop()
            self._phase = "clear_stop"
        elif phase == "search" and on:
            self._jog.stop()
            self._phase = "search_stop"
        elif phase == "backoff" and not on:
            self._phase = "index"
            self._last_actual = actual[axis]
        elif phase == "index":
            count = actual[axis]
            before, now = self._marks.mark_of(self._last_actual), self._marks.mark_of(count)
            if now != before:  # the index pulse came: the QEP latched the mark's count
                self.latched = self._marks.count_of(max(before, now))
                self._jog.stop()
                self._phase = "index_stop"
            self._last_actual = count
        if self._jog is not None:
            self._step_jog(inputs)
            if self._jog is not None:
                return
        # this phase's jog is at rest
        if self._phase == "clear_stop":
            self._start_jog(rec.speed, "search")
        elif self._phase == "search_stop":
            self._start_jog(-rec.creep, "backoff")
        elif self._phase == "index_stop":
            self.events.append((axis, EVENT_HOME_FOUND, self.latched))
            here = round(self.command[axis])
            self.command[axis] = float(here)
            rest = IndexMove(self.latched - here, rec.speed, self._a, self._j, self.dt).pulses \
                if self.latched != here else []
            self._moves = iter([(int(p),) for p in rest])
            self._phase = "return"
        elif self._phase in ("clear", "search", "backoff", "index"):
            self._finish()  # a limit switch stopped the jog before the home was found
