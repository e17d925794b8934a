"""What each kind of program brings to a run: its plant, its process models, its metrics.

The twin's wiring asks :func:`kind_of` once and calls the kind's hooks; it never branches on the
program's type itself. A new kind of program (say, G-code) plugs in here on the run side with one
:class:`ProgramKind` subclass and one line in :data:`KINDS`, next to its schema
(:func:`cnc_twin.scenario.load.convert_program`'s table) and its plan
(:func:`cnc_twin.planner.job.plan_for`).

Hooks, each with a default that serves a point-to-point program:

- :meth:`ProgramKind.build_plant`: the MuJoCo plant (and, for a surface, the workpiece's collision
  tiles and the removal map), returned as :class:`PlantParts`;
- ``referenced``: whether the axes count as referenced at power-on (the motion chip homes them);
- ``reversal_compensation``: whether the card's reversal compensation runs (the older cards' kinds
  had none);
- :meth:`ProgramKind.stop_time`: the time to stop from the programmed feed, which the planner's
  look-ahead must always cover on a path program;
- :meth:`ProgramKind.warm_up`: compile what the run will call, while the planner starts;
- :meth:`ProgramKind.metrics`: the kind's own figures, added to ``metrics.json``;
- :meth:`ProgramKind.describe`: one line on what the program does (``cnc-twin validate``);
- :meth:`ProgramKind.run_files`: files the run directory keeps beside ``scenario.yaml`` (a G-code
  program).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from cnc_twin.core.config import (
    AxisConfig, ContourProgram, GcodeProgram, MotionChipProgram, NurbsProgram, PointToPoint, Scenario, SurfaceProgram,
)
from cnc_twin.core.packed_text import PackedText
from cnc_twin.machine.model_file import load_model_with_obstacles
from cnc_twin.machine.plant import Plant

if TYPE_CHECKING:  # the twin hands itself to the hooks; typing only, no import at run time
    from cnc_twin.dsp.task import DspTask
    from cnc_twin.run.twin import Twin
    from cnc_twin.trace.trace import Trace


class PlantParts(NamedTuple):
    """What :meth:`ProgramKind.build_plant` builds: the plant, and for a workpiece its removal map
    (:class:`~cnc_twin.polishing.polish.RemovalTracker`) and collision tiles (None otherwise)."""

    plant: Plant
    removal: Any = None
    tiling: Any = None


class ProgramKind:
    """The run-side set-up of one kind of program (the defaults serve point-to-point moves)."""

    referenced = True
    """the axes count as referenced at power-on (soft limits apply from the start)"""
    reversal_compensation = True
    """the card's reversal compensation runs as the axes configure it (the older cards' kinds: off)"""

    def build_plant(self, twin: Twin, obstacles: list) -> PlantParts:
        """The plant for ``twin.scenario`` with the injected collision ``obstacles`` (centre, half
        sizes [m]) added, and what comes with it."""
        sc = twin.scenario
        model = load_model_with_obstacles(sc.model_file, obstacles, sc.block_shift)  # the part as set up
        return PlantParts(Plant(model, timestep=sc.timing.physics_timestep, drives=sc.drives,
                                encoder_mounts=sc.encoder_mounts))

    def stop_time(self, program) -> float | None:
        """Time to stop from the programmed feed, jerk-limited [s]; None for programs without a
        path feed (the look-ahead is then what the scenario says)."""
        return None

    def as_run(self, scenario, dsp: DspTask):
        """The scenario with its program as the machine ran it (a program whose course depends on
        what the machine found, read again with that), for the metrics and the recording."""
        return scenario

    def warm_up(self, twin: Twin) -> None:
        """Compile (or load) what the run will call; runs while the planner starts."""

    def for_planner(self, program):
        """What the planner's process is given of ``program``: all of it, unless the kind holds
        what only the run's own side measures with."""
        return program

    def metrics(self, twin: Twin, trace: Trace, dsp: DspTask, wall_time: float) -> dict[str, Any]:
        """The kind's own entries for ``metrics.json``."""
        return {}

    def describe(self, program) -> str:
        """One line on what the program does."""
        return f"{len(program.moves)} moves"

    def notices(self, scenario: Scenario) -> list[str]:
        """What the run will do otherwise than the program asks (a cap, a clamp), one line each,
        starting with the key path: said before the run and kept in ``metrics.json``."""
        return []

    def run_files(self, program) -> dict[str, PackedText]:
        """Files the run directory keeps beside ``scenario.yaml`` so it runs again as it is
        (name -> its text, packed): the program a scenario names."""
        return {}


class PointKind(ProgramKind):
    """Point-to-point moves: a feed above what the axes allow along a move is said."""

    def notices(self, scenario: Scenario) -> list[str]:
        from cnc_twin.core.units import MM_PER_MIN
        from cnc_twin.planner.ptp import axis_scales, move_ends

        said = []
        for k, (move, (start, end)) in enumerate(zip(scenario.program.moves, move_ends(scenario.program, scenario.home))):
            v_s, _, xyz, slowest = axis_scales(start, end, scenario.axes)
            if move.feed is None or xyz == 0.0 or move.feed <= v_s * xyz * (1.0 + 1e-9):
                continue
            said.append(f"program.moves[{k}].feed: {move.feed / MM_PER_MIN:g} mm/min is more than the axes allow along "
                        f"this move; it runs at {v_s * xyz / MM_PER_MIN:.0f} mm/min "
                        f"({_at_max_velocity(scenario.axes[slowest])})")
        return said


def spindle_notes(scenario: Scenario) -> list[str]:
    """An NC program's S more than the spindle turns, once per S value: its first line, how many
    more, and the speed it turns at."""
    from cnc_twin.core.gcode_config import GcodeSpindle
    from cnc_twin.core.units import RPM

    by_speed: dict[float, list[int]] = {}
    for step in scenario.program.steps:
        if isinstance(step, GcodeSpindle) and step.asked is not None:
            lines = by_speed.setdefault(abs(step.asked), [])
            if step.line not in lines:  # an S and its M3 / M4 on one line change the spindle twice
                lines.append(step.line)
    c = scenario.axes[5]
    said = []
    for asked, lines in by_speed.items():
        more = len(lines) - 1
        where = f"line {lines[0]}" + (f" (and {more} more line{'s' if more > 1 else ''} with this S)" if more else "")
        said.append(f"{where}: S{abs(asked) / RPM:g} rpm is more than the spindle turns; it turns at "
                    f"{c.max_velocity / RPM:.0f} rpm ({_at_max_velocity(c)}), as LinuxCNC's motion holds a spindle "
                    "to its [SPINDLE_0]MAX_FORWARD_VELOCITY")
    return said


def _feed_note(key: str, feed: float, along: str, cap: float, axis: int, axes: tuple[AxisConfig, ...]) -> str:
    """"program.feed: F mm/min is more than the axes allow along ...; it runs at ... at most (...)"."""
    from cnc_twin.core.units import MM_PER_MIN

    return (f"{key}: {feed / MM_PER_MIN:g} mm/min is more than the axes allow along {along}; it runs at "
            f"{cap / MM_PER_MIN:.0f} mm/min at most ({_at_max_velocity(axes[axis])})")


def _at_max_velocity(axis: AxisConfig) -> str:
    """"X at its max_velocity 24000 mm/min": the axis that holds a feed notice's speed."""
    return f"{axis.name} at its max_velocity {axis.max_velocity * axis.display_factor * 60:g} {axis.display_unit}/min"


def _path_stop_time(limits) -> float:
    """Time to stop from the feed of a path with these :class:`PathLimits`, jerk-limited [s]."""
    a, j = limits.tangential_acceleration, limits.tangential_jerk
    return limits.feed / a + a / j


def _warm_curve_stepper(twin: Twin) -> None:
    """Compile (or load) the curve stepper when the card runs the compiled one."""
    if twin.interpolator.compiled:
        from cnc_twin.dsp import curve_stepper

        curve_stepper.warm_up()


class _PathKind(ProgramKind):
    """A program with a programmed path feed: the look-ahead must cover a stop from it."""

    def stop_time(self, program) -> float:
        return _path_stop_time(program.limits)


class CurveKind(_PathKind):
    """A NURBS curve: the compiled stepper, and the path metrics from the trace."""

    def warm_up(self, twin: Twin) -> None:
        _warm_curve_stepper(twin)

    def metrics(self, twin: Twin, trace: Trace, dsp: DspTask, wall_time: float) -> dict[str, Any]:
        from cnc_twin.run.path_metrics import path_metrics
        from cnc_twin.trace.trace import PeriodSamples

        return {"path": path_metrics(PeriodSamples.whole(trace), twin.scenario, interpolator_ns=np.asarray(dsp.interpolator_ns),
                                     plan_us=twin.plan_us, plan_blocks=twin.plan_blocks)}

    def describe(self, program: NurbsProgram) -> str:
        return f"NURBS curve, degree {program.degree}, {len(program.control_points)} control points"

    def notices(self, scenario: Scenario) -> list[str]:
        """A feed more than the axes allow anywhere along the curve."""
        from cnc_twin.planner.feed import curve_feed_cap

        capped = curve_feed_cap(scenario.program, scenario.axes)
        return [] if capped is None else [_feed_note("program.feed", scenario.program.limits.feed, "the curve",
                                                     *capped, scenario.axes)]


class ContourKind(_PathKind):
    """Lines and arcs, run pass by pass with each interpolation method: per-pass contour metrics."""

    reversal_compensation = False  # the older cards' point-by-point and DDA steps: their cards had none

    def metrics(self, twin: Twin, trace: Trace, dsp: DspTask, wall_time: float) -> dict[str, Any]:
        from cnc_twin.run.contour_metrics import contour_metrics

        return {"contour": contour_metrics(trace, twin.scenario)}

    def notices(self, scenario: Scenario) -> list[str]:
        """A feed more than the axes allow along an element (every pass runs it at the cap)."""
        from cnc_twin.planner.feed import curve_feed_cap

        for k, curve in enumerate(scenario.program.curves):
            capped = curve_feed_cap(curve, scenario.axes)
            if capped is not None:
                return [_feed_note("program.feed", curve.limits.feed, f"the contour (from element {k})", *capped,
                                   scenario.axes)]
        return []

    def describe(self, program: ContourProgram) -> str:
        return (f"contour of {len(program.elements)} element(s), {len(program.methods)} pass(es): "
                f"{', '.join(program.methods)}")


def _workpiece_plant(twin: Twin, obstacles: list, surface_def, preston, friction, tile_size: float) -> PlantParts:
    """The scene with ``surface_def`` (:class:`~cnc_twin.core.config.SurfaceDef`) as its workpiece,
    its collision tiles and the removal map on it; the workpiece as the process built it for an
    earlier run, if it did (:mod:`cnc_twin.run.workpiece_cache`)."""
    from cnc_twin.polishing.polish import RemovalTracker
    from cnc_twin.run.workpiece_cache import workpiece

    sc = twin.scenario
    surface, model, tiling, grid = workpiece(sc.model_file, surface_def, tile_size, obstacles, preston.grid_spacing)
    plant = Plant(model, timestep=sc.timing.physics_timestep, drives=sc.drives, encoder_mounts=sc.encoder_mounts)
    removal = RemovalTracker(preston, friction, surface, plant.model, plant.data, sc.timing.interpolation_period,
                             compiled=twin.compiled, grid=grid)
    return PlantParts(plant, removal, tiling)


class SurfaceKind(_PathKind):
    """Polishing a NURBS surface: the workpiece in the plant, the removal map, the force metrics."""

    def warm_up(self, twin: Twin) -> None:
        _warm_curve_stepper(twin)
        twin.interpolator.force.warm_up()

    def build_plant(self, twin: Twin, obstacles: list) -> PlantParts:
        prog = twin.scenario.program
        return _workpiece_plant(twin, obstacles, prog.surface, prog.preston, prog.friction, prog.surface_tile_size)

    def metrics(self, twin: Twin, trace: Trace, dsp: DspTask, wall_time: float) -> dict[str, Any]:
        from cnc_twin.geometry.surface import control_net_is_planar
        from cnc_twin.polishing.polish import force_metrics, polished_band, preston_by_hand, removal_metrics

        prog, removal = twin.scenario.program, twin.removal
        band = polished_band(prog, removal.uv, removal.scales)
        figures = removal_metrics(removal, wall_time, band)
        if control_net_is_planar(prog.surface.control_net):
            # the closed form holds on a flat face only (uniform pressure under the pad): on a
            # curved one it would be a second, wrong figure beside the map's
            figures["preston_by_hand_mm3"] = preston_by_hand(trace, prog.preston, prog.spindle_speed) * 1e9
        return {"polish": {
            "force": force_metrics(trace, prog.force.setpoint),
            "removal": figures,
            "collision_tiles": list(twin.tiling.tiles),
            "tile_hull_gap_mm": twin.tiling.hull_gap * 1e3,
            "path_length_mm": prog.path_length * 1e3,
            "sections": len(prog.sections),
        }}

    def describe(self, program: SurfaceProgram) -> str:
        s = program.surface
        return (f"{program.pattern} on a {len(s.control_net)} x {len(s.control_net[0])} NURBS surface, "
                f"{program.path_length * 1e3:.0f} mm of path in {len(program.sections)} section(s), "
                f"{program.force.setpoint:g} N")


class MotionChipKind(ProgramKind):
    """Motion-chip commands: the axes are not referenced until the program homes them."""

    referenced = False
    reversal_compensation = False  # the motion chip's cards had none

    def metrics(self, twin: Twin, trace: Trace, dsp: DspTask, wall_time: float) -> dict[str, Any]:
        """The chip's events (motion done, home found, limits) with where each axis was [mm | deg]."""
        if not dsp.event_log:
            return {}
        from cnc_twin.core.axes import AXES
        from cnc_twin.dsp.chip import EVENT_NAMES

        sc = twin.scenario

        def shown(axis: int, count: int) -> float:  # [mm | deg]
            cfg = sc.axes[axis]
            return (count / cfg.counts_per_unit + sc.home[axis]) * cfg.display_factor

        return {"events": [
            {"time_s": t, "axis": AXES[axis], "event": EVENT_NAMES[code], "count": value,
             "position": shown(axis, value)}
            for t, axis, code, value in dsp.event_log]}

    def describe(self, program: MotionChipProgram) -> str:
        return f"{len(program.commands)} motion-chip command(s), {program.profile} profiles"


class GcodeKind(ProgramKind):
    """An NC program: its feed paths are curves (the compiled stepper), measured path by path; with
    a workpiece (M100), the plant and the removal map of a surface, and the force metrics."""

    def build_plant(self, twin: Twin, obstacles: list) -> PlantParts:
        w = twin.scenario.program.workpiece
        if w is None:
            return super().build_plant(twin, obstacles)
        return _workpiece_plant(twin, obstacles, w.surface, w.preston, w.friction, w.tile_size)

    def as_run(self, scenario, dsp: DspTask):
        """A program that probed: read again with the card's answers
        (:meth:`~cnc_twin.core.gcode_config.GcodeProgram.as_run`)."""
        log = dsp.interpolator.probe.log
        if not log or scenario.program.after_probe is None:
            return scenario
        from cnc_twin.core.gcode_config import ProbeAnswer

        answers = [ProbeAnswer.from_counts(tripped, latch, stop, scenario.axes, scenario.home)
                   for tripped, latch, stop in log]
        return dataclasses.replace(scenario, program=scenario.program.as_run(answers))

    def for_planner(self, program: GcodeProgram) -> GcodeProgram:
        """Without its text and its paths' programmed points (the run directory's and the
        metrics', in the twin's process): a long program's planner holds its steps alone."""
        return program.steps_only()

    def stop_time(self, program: GcodeProgram) -> float | None:
        times = [_path_stop_time(path.curve.limits) for path in program.paths]
        return max(times) if times else None

    def warm_up(self, twin: Twin) -> None:
        _warm_curve_stepper(twin)
        twin.interpolator.force.warm_up()  # M100 runs the force loop

    def metrics(self, twin: Twin, trace: Trace, dsp: DspTask, wall_time: float) -> dict[str, Any]:
        from cnc_twin.run.gcode_metrics import gcode_polish_metrics, gcode_run_metrics

        path, program = gcode_run_metrics(trace, twin.scenario)
        out: dict[str, Any] = {"path": path, "program": program}
        if twin.removal is not None:
            out["polish"] = gcode_polish_metrics(trace, twin.scenario.program, twin.removal, wall_time)
        return out

    def run_files(self, program: GcodeProgram) -> dict[str, PackedText]:
        files: dict[str, PackedText] = {program.file.name: program.packed_text}
        if program.tool_table is not None and Path(program.tool_table[0]).name == program.tool_table[0]:
            # named beside the scenario: kept beside it (a path elsewhere is named as it was)
            files[program.tool_table[0]] = PackedText.of(program.tool_table[1])
        # where the scenario's folder had them
        files.update((name, PackedText.of(text)) for name, text in program.subroutine_files)
        return files

    def notices(self, scenario: Scenario) -> list[str]:
        """A programmed F more than the axes allow along a feed path, once per F value: how many
        paths, the first line, and the fastest they run at (the axis that holds them)."""
        from cnc_twin.core.units import MM, MM_PER_MIN
        from cnc_twin.planner.gcode_program import feed_caps, move_starts
        from cnc_twin.planner.ptp import axis_scales

        by_feed: dict[tuple[float, str], list[tuple[int, float, int]]] = {}
        for line, feed, cap, axis in feed_caps(scenario.program, scenario.axes):
            by_feed.setdefault((feed, "path"), []).append((line, cap, axis))
        # G1 moves run one by one (exact stop, or turning the head): the feed caps the tip's X/Y/Z
        # speed, and the axes' own limits may hold the move below it
        for move, start in move_starts(scenario.program, scenario.home):
            if move.feed is None or move.rotary_only:
                continue
            v_s, _, xyz, slowest = axis_scales(start, move.end, scenario.axes)
            if xyz > 0.0 and move.feed > v_s * xyz * (1.0 + 1e-9):
                by_feed.setdefault((move.feed, "move"), []).append((move.line, v_s * xyz, slowest))
        said = spindle_notes(scenario)
        prog = scenario.program
        if prog.air:
            said.append(f"in the air: every point runs {prog.air / MM:g} mm above where the program puts it "
                        "(program.in_air)" + ("" if prog.air_clearance is None or prog.air_clearance >= 0 else
                                              f"; its lowest point still reaches {-prog.air_clearance / MM:.4g} mm "
                                              f"into the workpiece: in_air {(prog.air - prog.air_clearance) / MM:.4g} "
                                              "clears it"))
        for (feed, what), steps in sorted(by_feed.items(), key=lambda item: item[1][0][0]):
            _, cap, axis = max(steps, key=lambda p: p[1])
            more = len(steps) - 1
            where = f"line {steps[0][0]}" + (f" (and {more} more {what}{'s' if more > 1 else ''} at this F)"
                                             if more else "")
            said.append(f"{where}: F{feed / MM_PER_MIN:g} mm/min is more than the axes allow along the {what}; it "
                        f"runs at {cap / MM_PER_MIN:.0f} mm/min at most ({_at_max_velocity(scenario.axes[axis])})")
        return said

    def describe(self, program: GcodeProgram) -> str:
        moves = len(program.steps) - len(program.paths)
        return (f"{program.file.name}: {program.lines} lines, {len(program.paths)} feed path(s), "
                f"{moves} other step(s)")


KINDS: dict[type, ProgramKind] = {
    PointToPoint: PointKind(),
    NurbsProgram: CurveKind(),
    ContourProgram: ContourKind(),
    SurfaceProgram: SurfaceKind(),
    MotionChipProgram: MotionChipKind(),
    GcodeProgram: GcodeKind(),
}
"""the run side of every program kind, by the type of its validated program"""


def write_run_files(program, folder: Path) -> None:
    """The files :meth:`ProgramKind.run_files` names for ``program``, written into ``folder`` (a
    run directory) as UTF-8, each in its folder there, a piece at a time."""
    for name, text in kind_of(program).run_files(program).items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)  # a subroutine file's folder
        text.write(folder / name)


def kind_of(program) -> ProgramKind:
    """The :class:`ProgramKind` of a validated program (:mod:`cnc_twin.core.config`)."""
    try:
        return KINDS[type(program)]
    except KeyError:
        raise TypeError(f"no program kind for {type(program).__name__}") from None


def lookahead_periods(scenario: Scenario) -> int:
    """The planner's look-ahead [periods]; 0 = no limit.

    On a path program the card must always hold enough path to stop in, so a look-ahead is never
    less than twice the time to stop from the programmed feed (jerk-limited).
    """
    period = scenario.timing.interpolation_period
    periods = math.ceil(scenario.planner.lookahead / period - 1e-9)
    stop_time = kind_of(scenario.program).stop_time(scenario.program)
    if periods and stop_time is not None:
        periods = max(periods, math.ceil(2.0 * stop_time / period))
    return periods
