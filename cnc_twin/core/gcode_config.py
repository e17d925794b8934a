"""The G-code program kind's validated program in SI (built by :mod:`cnc_twin.scenario.gcode`):
the machine steps an NC program becomes. Re-exported by :mod:`cnc_twin.core.config`."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from cnc_twin.core.packed_text import PackedText
from cnc_twin.core.spill import StoredArray

if TYPE_CHECKING:  # config imports this module: its types only for annotations
    from cnc_twin.core.config import ForceControl, NurbsProgram, Preston, SurfaceDef


@dataclass(frozen=True)
class GcodeMove:
    """A coordinated move of the six axes to ``end`` (G0, or a G1 that turns A / B / C)."""

    end: tuple[float, ...]
    """[m | rad], axis space, shape ``(6,)``"""
    feed: float | None
    """X/Y/Z speed cap [m/s] (or A/B/C [rad/s] when ``rotary_only``); None = rapid"""
    rotary_only: bool
    line: int
    """program line (1-based)"""


@dataclass(frozen=True, eq=False)
class GcodeReference:
    """A feed path as programmed (before blends and fits), what its run is measured against; one
    object shared by the card curves a path is cut into. Its arrays are needed only when the run
    is measured: a long path's wait in the spill file (:class:`~cnc_twin.core.spill.StoredArray`),
    read back by :attr:`polyline`, :attr:`vertices` and :attr:`axes`. Made with :meth:`of`."""

    stored_polyline: StoredArray
    stored_vertices: StoredArray
    tolerance: float | None
    """the path's G64 P [m]; None without one"""
    fits: int
    """runs of lines fitted as one curve"""
    fit_spans: int
    fit_deviation: float
    """the fits' largest distance from their programmed points and segments, as the fitter
    measured it [m] (a claim: the run is checked against ``polyline`` from the trace)"""
    stored_axes: StoredArray | None = None
    axis_tolerance: float | None = None
    """[rad] how far the fitted tool axis may turn from the programmed one"""

    @classmethod
    def of(cls, polyline: np.ndarray, vertices: np.ndarray, *, axes: np.ndarray | None = None,
           **figures) -> "GcodeReference":
        """From its arrays (``vertices is polyline`` for a path of lines: stored once) and its
        figures (``tolerance``, ``fits``, ``fit_spans``, ``fit_deviation``, ``axis_tolerance``)."""
        stored = StoredArray(polyline)
        return cls(stored_polyline=stored, stored_vertices=stored if vertices is polyline else StoredArray(vertices),
                   stored_axes=None if axes is None else StoredArray(axes), **figures)

    @property
    def polyline(self) -> np.ndarray:
        """(k, 3) [m] world frame, tool tip: lines by their ends, arcs and curves finely sampled"""
        return self.stored_polyline.array()

    @property
    def vertices(self) -> np.ndarray:
        """(m, 3) [m] the programmed elements' ends"""
        return self.stored_vertices.array()

    def read(self) -> tuple[np.ndarray, np.ndarray]:
        """``(polyline, vertices)`` read once each (a path of lines: the one array twice)."""
        vertices = self.vertices
        return (vertices if self.stored_polyline is self.stored_vertices else self.polyline), vertices

    @property
    def axes(self) -> np.ndarray | None:
        """(m, 3) the programmed tool axis at each vertex (a path turning the head), unit; None
        for a path that holds the head"""
        return None if self.stored_axes is None else self.stored_axes.array()


@dataclass(frozen=True)
class GcodePath:
    """Consecutive feed moves as one curve the card interpolates directly, rest to rest."""

    curve: NurbsProgram
    lines: tuple[tuple[float, int], ...]
    """``(u, line)``: from parameter ``u`` on, the curve runs the block of program line ``line``"""
    line: int
    reference: GcodeReference | None = field(default=None, compare=False)
    """the feed path as programmed"""


@dataclass(frozen=True)
class GcodePause:
    seconds: float
    line: int


@dataclass(frozen=True)
class GcodeSpindle:
    speed: float
    """[rad/s], signed (M4 negative); 0 = stopped"""
    line: int
    asked: float | None = None
    """[rad/s] the program's S when more than the spindle turns (``speed`` is then its limit), else None"""


@dataclass(frozen=True)
class GcodeForce:
    """M100 P / M101: the grinding-force loop on at the start of the next feed path, or off at
    the end of the last one."""

    control: ForceControl | None
    """the loop's parameters with the program's setpoint; None = off (M101)"""
    line: int


@dataclass(frozen=True)
class GcodeProbe:
    """G38.2 .. G38.5: a straight move down (G38.2 / .3) or up (G38.4 / .5) the tool axis that the
    card stops when the pad's load cell reads ``trip_force`` (or, up, falls below it); the program
    after it is read again with where the machine found the work (:attr:`GcodeProgram.after_probe`)."""

    end: tuple[float, ...]
    """the programmed end [m | rad], axis space, shape ``(6,)``"""
    feed: float
    """tool-axis speed [m/s]"""
    kind: int
    """2 .. 5 for G38.2 .. G38.5 (2 and 4 must trip: the card faults when they do not)"""
    trip_force: float
    """[N] the load-cell force that trips the probe"""
    line: int
    """program line (1-based)"""
    offset: tuple[float, ...] = ()
    """the program's offsets at the probe (G92 + G5x + tool length), x y z [mm] a b c [deg]: a
    machine point less these, divided by ``scale`` (x y z), is the program's"""
    scale: float = 1.0
    """[mm per program unit] (25.4 under G20)"""


@dataclass(frozen=True)
class ProbeAnswer:
    """What the card reported after a probing move, in axis space [m | rad] (shape ``(6,)``)."""

    tripped: bool
    trip: tuple[float, ...]
    """the encoder positions the card latched when the load cell crossed the trip force (where
    the move ended when it did not trip)"""
    stop: tuple[float, ...]
    """where the card stopped the axes (commanded): the next move starts here"""

    @classmethod
    def from_counts(cls, tripped: bool, latch, stop, axes, power_on) -> "ProbeAnswer":
        """The answer from the card's counts (its status block's ``probe_latch``, ``probe_stop``),
        converted as the card's interpolator converts them: ``count / counts_per_unit + power_on``
        per axis (``axes``: the :class:`~cnc_twin.core.axis_config.AxisConfig` of each)."""
        def position(counts) -> tuple[float, ...]:
            return tuple(float(c) / a.counts_per_unit + float(z) for c, a, z in zip(counts, axes, power_on))

        return cls(bool(tripped), position(latch), position(stop))


@dataclass(frozen=True)
class GcodeWorkpiece:
    """The workpiece a G-code program polishes: its surface in the scene, the removal map on it."""

    surface: SurfaceDef
    """world frame [m]"""
    preston: Preston
    friction: float | None
    """pad-workpiece sliding friction; None = the model's"""
    tile_size: float
    """edge of the convex collision tiles [m]"""


@dataclass(frozen=True)
class GcodeProgram:
    """An NC program read whole (:mod:`cnc_twin.gcode`), as machine steps in SI."""

    file: Path
    packed_text: PackedText
    """the program as read, packed (the run directory keeps it; :attr:`text` unpacks it)"""
    steps: tuple[GcodeMove | GcodePath | GcodePause | GcodeSpindle | GcodeForce | GcodeProbe, ...]
    lines: int
    """lines in the file"""
    settle: float
    """[s] simulated after the program end"""
    workpiece: GcodeWorkpiece | None = None
    """the surface pressed on and polished; None = the scene as it is, no removal map"""
    tool_table: tuple[str, str] | None = None
    """``(name as the scenario gives it, text)`` of its LinuxCNC tool table (the run directory
    keeps it beside the program); None without one"""
    air: float = 0.0
    """[m] how far above where it is written the program runs (``program.in_air``: a dry run)"""
    air_clearance: float | None = None
    """[m] in the air: how far the program's lowest point stays above the scene's workpiece top
    (negative: it still reaches into the work); None when not in the air or no block to measure"""
    after_probe: object = field(default=None, compare=False)
    """for a program that probes: a picklable callable ``answers -> steps``, given the card's
    :class:`ProbeAnswer` to each probe so far (in order, with its :class:`GcodeProbe`), the steps
    after the last of them, the program read again with those answers (LinuxCNC's interpreter
    reads on past a probe only once the machine has answered); None otherwise"""
    subroutine_files: tuple[tuple[str, str], ...] = ()
    """``(name, text)`` of the subroutine files the program called that the run directory keeps:
    the name relative to the scenario's folder (beside the program, or in a folder of
    ``program.subroutine_path`` under it); files elsewhere are found there again"""

    def as_run(self, answers: list[ProbeAnswer]) -> "GcodeProgram":
        """The program as the machine ran it: its steps up to each probe, then those read again
        with the card's ``answers`` (one per probe run, in order; :attr:`after_probe`)."""
        if not answers or self.after_probe is None:
            return self
        steps, ran, given = list(self.steps), [], []
        for answer in answers:
            k = next((i for i, s in enumerate(steps) if isinstance(s, GcodeProbe)), None)
            if k is None:
                break
            ran += steps[:k + 1]
            given.append((steps[k], answer))
            steps = list(self.after_probe(given))
        return dataclasses.replace(self, steps=tuple(ran + steps))

    @property
    def paths(self) -> tuple[GcodePath, ...]:
        return tuple(s for s in self.steps if isinstance(s, GcodePath))

    def pressed_paths(self) -> tuple[GcodePath, ...]:
        """The feed paths the program runs with the force loop on (M100 ... M101)."""
        on, out = False, []
        for step in self.steps:
            if isinstance(step, GcodeForce):
                on = step.control is not None
            elif on and isinstance(step, GcodePath):
                out.append(step)
        return tuple(out)

    def force_setpoints(self) -> tuple[tuple[float, float], ...]:
        """``(setpoint [N], spindle speed [rad/s])`` of each M100 that turns the force loop on, the
        speed being the last M3/M4/M5's before it (0 before any)."""
        speed, out = 0.0, []
        for step in self.steps:
            if isinstance(step, GcodeSpindle):
                speed = step.speed
            elif isinstance(step, GcodeForce) and step.control is not None:
                out.append((step.control.setpoint, speed))
        return tuple(out)

    def steps_only(self) -> "GcodeProgram":
        """The program without its text and its paths' programmed points (what the planner's
        process is given: a long program's text and references stay in the twin's)."""
        steps = tuple(dataclasses.replace(s, reference=None) if isinstance(s, GcodePath) else s for s in self.steps)
        return dataclasses.replace(self, packed_text=PackedText.of(""), steps=steps)

    @property
    def text(self) -> str:
        """The program as read."""
        return self.packed_text.text()

    def feed_rates(self) -> dict[int, float]:
        """``{line: F [m/s]}`` of the program's feed moves (G1) of the linear axes: those with a
        feed that move more than the rotary axes."""
        return {s.line: s.feed for s in self.steps
                if isinstance(s, GcodeMove) and s.feed is not None and not s.rotary_only}
