"""The planner's side of a contour program: one pass per method, records handed out in chunks.

Records, for each pass ``i`` (1-based) in the program's method order::

    Move          to the contour's start (from home, or from where the last pass ended)
    Dwell         the program's dwell
    Mark i        the trace shows the pass from here ...
    per element:  nurbs:  CurveGeometry + its CurveBlocks (feed planned window by window)
                  step:   StepContour (the card's point-by-point or DDA, clocked by an S-curve)
    Mark 0        ... to here

then Move Z up to its home position, Move every axis home, Dwell (settle), EndOfProgram.

Every element starts and ends at rest (exact stop), whatever the method, so the passes differ
only in how the card interpolates.
"""

from __future__ import annotations

import math

from cnc_twin.core.config import AxisConfig, ContourProgram, LatticeElement
from cnc_twin.motion.scurve import SCurve
from cnc_twin.geometry.contour import element_length
from cnc_twin.planner.ptp import dwell_chunk, move_chunk
from cnc_twin.whiteboard.records import (
    STEP_ARC, STEP_DDA, STEP_LINE, STEP_POINT_BY_POINT, CurveBlock, EndOfProgram, Mark, StepContour,
)

STEP_METHODS = {"point_by_point": STEP_POINT_BY_POINT, "dda": STEP_DDA}


def step_record(prog: ContourProgram, method: str, i: int) -> StepContour:
    """Element ``i`` as a StepContour for ``method``, clocked by a rest-to-rest S-curve at its feed."""
    el: LatticeElement = prog.lattice[i]
    lim = prog.limits
    profile = SCurve.plan(element_length(prog.elements[i]), 0.0, 0.0, v_max=prog.element_feeds[i],
                          a_max=lim.tangential_acceleration, j_max=lim.tangential_jerk)
    return StepContour(method=STEP_METHODS[method], kind=STEP_LINE if el.kind == "line" else STEP_ARC,
                       start=el.start, end=el.end, center=el.center, clockwise=el.clockwise, profile=profile,
                       dda_bits=prog.dda_bits)


class ContourPlan:
    """A contour program set up once, its records handed out in chunks (see the module docstring)."""

    def __init__(self, prog: ContourProgram, axes: tuple[AxisConfig, ...], home: tuple[float, ...], period: float):
        self.prog, self.axes, self.home, self.period = prog, axes, tuple(home), period
        self.lengths = [element_length(e) for e in prog.elements]
        self.end = (prog.elements[-1].end[0], prog.elements[-1].end[1], *prog.start[2:])

    @property
    def estimated_periods(self) -> int:
        p, T = self.prog, self.period
        contour = sum(L / v for L, v in zip(self.lengths, p.element_feeds))
        reach = max(abs(a - b) for a, b in zip(p.start[:3], self.home[:3]))
        per_pass = 1.2 * contour + p.dwell + 2.0 * reach / min(a.max_velocity for a in self.axes[:3]) + 0.5
        return math.ceil((len(p.methods) * per_pass + p.settle) / T)

    def chunks(self):
        """Successive ``(records, periods)`` chunks, planned as they are asked for."""
        from cnc_twin.planner.feed import plan_feed_windows, plan_key
        from cnc_twin.planner.curve_program import curve_setup

        prog, T = self.prog, self.period
        here = self.home
        for number, method in enumerate(prog.methods, start=1):
            records, periods = move_chunk(here, prog.start, self.axes, feed=prog.approach_feed, period=T)
            dwell = dwell_chunk(prog.dwell, T)
            yield records + dwell[0] + [Mark(number)], periods + dwell[1] + [0]
            for i, curve_prog in enumerate(prog.curves):
                if method == "nurbs":
                    curve, _, _, _, geometry = curve_setup(curve_prog)
                    yield [geometry], [0]
                    # the element's plan depends on its curve program and the period alone: kept
                    # for a later run in the same planner process (a sweep's next gains)
                    for blocks in plan_feed_windows(curve, curve_prog.limits, period=T, window=0.05,
                                                    key=plan_key(curve_prog, T, 0.05)):
                        yield [CurveBlock(b) for b in blocks], [math.ceil(b.duration / T) for b in blocks]
                else:
                    rec = step_record(prog, method, i)
                    yield [rec], [math.ceil(rec.profile.duration / T)]
            yield [Mark(0)], [0]
            here = self.end
        up = (here[0], here[1], self.home[2], *here[3:])
        tail, tail_periods = move_chunk(here, up, self.axes, period=T)
        home, home_periods = move_chunk(up, self.home, self.axes, period=T)
        settle = dwell_chunk(prog.settle, T)
        yield tail + home + settle[0] + [EndOfProgram()], tail_periods + home_periods + settle[1] + [0]
