"""The validated scenario in SI units: frozen dataclasses, no I/O and no heavy imports.

Built by :mod:`cnc_twin.scenario.load` (which owns the YAML schema and the unit conversion) and
passed as plain data to every part of the twin, including the planner process.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cnc_twin.core.axes import AXES
from cnc_twin.core.axis_config import AxisConfig, Compensation, DriveConfig, Notch  # noqa: F401  (part of this module's interface)
from cnc_twin.core.gcode_config import GcodeProgram


@dataclass(frozen=True)
class Timing:
    """Periods [s] and the integer ratios between them."""

    interpolation_period: float
    servo_period: float
    physics_timestep: float
    ticks_per_period: int
    """servo ticks per interpolation period"""
    substeps_per_tick: int
    """physics steps per servo tick"""
    mode: str


@dataclass(frozen=True)
class ForceSensorConfig:
    range_min: float
    """[N] at ADC code 0"""
    range_max: float
    """[N] at full scale"""
    bits: int


@dataclass(frozen=True)
class Move:
    """One point-to-point move in SI: its targets, its feed cap and the dwell after it."""

    targets: tuple[float | None, ...]
    """per axis absolute target [m | rad] or None (keep), shape (6,)"""
    feed: float | None
    """cap on the X/Y/Z path speed [m/s]"""
    dwell: float
    """[s]"""


@dataclass(frozen=True)
class PointToPoint:
    """The point-to-point program in SI: its moves in order, then the settle time."""

    moves: tuple[Move, ...]
    settle: float
    """[s]"""


@dataclass(frozen=True)
class PathLimits:
    """Limits for one tool path. Speeds [m/s], accelerations [m/s^2], jerks [m/s^3]; axes X, Y, Z."""

    feed: float
    chord_tolerance: float
    """[m]"""
    path_acceleration: float
    path_jerk: float
    normal_acceleration: float
    normal_jerk: float
    axis_velocity: tuple[float, float, float]
    axis_acceleration: tuple[float, float, float]
    axis_jerk: tuple[float, float, float]

    @property
    def tangential_acceleration(self) -> float:
        """Tangential budget: half of the tightest axis acceleration (the normal part gets the rest)."""
        return min(self.path_acceleration, 0.5 * min(self.axis_acceleration))

    @property
    def tangential_jerk(self) -> float:
        return min(self.path_jerk, min(self.axis_jerk) / 3.0)


@dataclass(frozen=True)
class AxisCurve:
    """The tool axis along a curve: a NURBS of direction vectors (world frame, tip -> spindle),
    sharing the tool-tip curve's parameter."""

    degree: int
    knots: tuple[float, ...]
    weights: tuple[float, ...]
    control_points: tuple[tuple[float, float, float], ...]


@dataclass(frozen=True)
class NurbsProgram:
    """A tool-tip NURBS curve with the tool axis held, converted to axis space (X/Y/Z, m).

    The curve's control points are the tip path's control points shifted by the constant head
    offset (NURBS are affine invariant), so the card interpolates X/Y/Z directly.
    """

    degree: int
    knots: tuple[float, ...]
    weights: tuple[float, ...]
    control_points: tuple[tuple[float, float, float], ...]
    """axis space X/Y/Z [m]"""
    hold: tuple[float, float, float]
    """A, B, C held during the curve [rad]"""
    limits: PathLimits
    approach_feed: float | None
    """X/Y/Z speed cap of the move from home to the curve's start [m/s]; None = rapid"""
    settle: float
    """[s]"""
    tip_shift: tuple[float, float, float]
    """tip = axes + tip_shift for the held A/B [m] (world frame)"""
    tool_offset: tuple[float, float, float]
    """tip - pivot at A = B = 0 [m], for the actual tip from actual A/B"""
    pivot_home: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """A/B pivot at X = Y = Z = 0 [m] (world frame)"""
    axis_curve: AxisCurve | None = None
    """the tool axis along the path; None = held at ``hold``. When set, ``control_points`` are
    tool-tip positions in the world frame and the card solves the kinematics every period"""
    rotary_limits: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    """(velocity, acceleration, jerk) of A and B [rad/s, rad/s^2, rad/s^3] when the axis varies"""


@dataclass(frozen=True)
class LatticeElement:
    """One contour element on the pulse lattice [counts from the encoders' power-on position]."""

    kind: str
    """``line`` or ``arc``"""
    start: tuple[int, int]
    end: tuple[int, int]
    center: tuple[int, int]
    """arcs only ((0, 0) for lines)"""
    clockwise: bool


@dataclass(frozen=True)
class ContourProgram:
    """Lines and arcs in the X/Y plane at a fixed Z with the tool axis held, run once per method.

    Each pass moves to the start, dwells, runs every element with exact stops between them
    (each element starts and ends at rest), and is bracketed by Mark records ``pass number`` and
    0 so the trace shows which pass ran when.
    """

    methods: tuple[str, ...]
    """``nurbs``, ``point_by_point`` or ``dda``: one pass each, in this order"""
    elements: tuple
    """the contour in axis space (X, Y [m]): :class:`cnc_twin.geometry.contour.Line` / ``Arc``"""
    start: tuple[float, ...]
    """all six axes at the contour's start [m | rad]"""
    limits: PathLimits
    curves: tuple[NurbsProgram, ...]
    """each element as an exact NURBS in axis space, for the ``nurbs`` method"""
    lattice: tuple[LatticeElement, ...]
    """each element on the pulse lattice, for the step methods"""
    element_feeds: tuple[float, ...]
    """step methods: each element's feed [m/s], the programmed feed capped by the axes' speed
    and, on arcs, by the normal acceleration limit"""
    dda_bits: int
    """DDA register length; 0 = the smallest that holds each element"""
    approach_feed: float | None
    dwell: float
    """[s] at the start before each pass"""
    settle: float
    """[s] after the last pass"""


@dataclass(frozen=True)
class ChipStep:
    """One motion-chip command in counts (see :class:`cnc_twin.whiteboard.records.ChipCommand`),
    or a dwell (``op == "dwell"``)."""

    op: str
    """``index``, ``linear``, ``jog``, ``home`` or ``dwell``"""
    axis: int = 0
    deltas: tuple[int, int, int] = (0, 0, 0)
    """linear: [counts] X, Y, Z"""
    distance: int = 0
    """index: [counts] on ``axis``"""
    speed: float = 0.0
    """[counts/s]; signed for jog"""
    creep: float = 0.0
    """home return's creep speed [counts/s]"""
    accel: float = 0.0
    """[counts/s^2]"""
    jerk: float = 0.0
    """[counts/s^3]"""
    time: float = 0.0
    """jog duration or dwell [s]"""
    span: float = 0.0
    """home return: the axis's travel [counts], for the time estimate"""


@dataclass(frozen=True)
class MotionChipProgram:
    """Commands for the card's motion chip, in order; every profile of one kind."""

    profile: str
    """``constant``, ``trapezoid`` or ``s_curve``"""
    commands: tuple[ChipStep, ...]
    settle: float


@dataclass(frozen=True)
class UvCurve:
    """A 2-D NURBS in a surface's (u, v) parameter space: one section of a surface tool path."""

    degree: int
    knots: tuple[float, ...]
    weights: tuple[float, ...]
    control_points: tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class SurfaceDef:
    """A NURBS surface in the world frame [m]: the workpiece's polished face."""

    degree_u: int
    degree_v: int
    knots_u: tuple[float, ...]
    knots_v: tuple[float, ...]
    weights: tuple[tuple[float, ...], ...]
    """shape (nu, nv)"""
    control_net: tuple[tuple[tuple[float, float, float], ...], ...]
    """shape (nu, nv, 3) [m], world frame"""


@dataclass(frozen=True)
class ForceControl:
    """Grinding-force control along the tool axis (the card's force loop); SI units."""

    setpoint: float
    """[N]"""
    profile: tuple[tuple[float, float], ...]
    """setpoint along the path: (path length from its start [m], force [N]) pairs, linear between;
    empty = ``setpoint`` everywhere"""
    ramp_time: float
    """force ramp after first contact and before retracting [s]"""
    seek_speed: float
    """approach speed along the tool axis until contact [m/s]"""
    standoff: float
    """gap above the surface where the seek starts and the retract ends [m]"""
    contact_threshold: float
    """measured force that counts as contact [N]"""
    kp: float
    """proportional gain [m/N]: tool-axis offset per newton of error"""
    ki: float
    """integral gain [m/(N s)]"""
    max_depth: float
    """clamp on the offset into the surface (anti-windup) [m]"""
    retract_speed: float
    """[m/s]"""
    adapt_threshold: float
    """force error, as a fraction of the setpoint, above which the feed is reduced"""
    adapt_feed: float
    """feed fraction while the force error is above the threshold"""
    adapt_hold: float
    """how long the error must stay below half the threshold before the feed is restored [s]"""


@dataclass(frozen=True)
class Preston:
    """Material removal by Preston's law on a Winkler pad."""

    k: float
    """Preston coefficient [m^2/N]"""
    pad_radius: float
    """[m]"""
    pad_modulus: float
    """Winkler foundation modulus of the pad [N/m^3]"""
    grid_spacing: float
    """pitch of the removal map's points on the surface [m]"""
    every: int
    """removal update interval [interpolation periods]"""


@dataclass(frozen=True)
class SurfaceProgram:
    """Polishing a NURBS surface along a raster or spiral path in its (u, v) space, at a controlled
    force. The path is a list of (u, v) NURBS curves (sections, each run from rest to rest); the
    card interpolates them on the surface with the tool axis along the surface normal."""

    surface: SurfaceDef
    sections: tuple[UvCurve, ...]
    """the path in the surface's parameter space"""
    pattern: str
    """raster | spiral"""
    direction: str
    """raster passes along "u" or "v"""
    lead: float
    """tool axis leaning forward along the feed direction [rad]"""
    tilt: float
    """tool axis leaning sideways (about the feed direction) [rad]"""
    spindle_speed: float
    """[rad/s]"""
    limits: PathLimits
    force: ForceControl
    preston: Preston
    approach_feed: float | None
    settle: float
    pivot_home: tuple[float, float, float]
    tool_offset: tuple[float, float, float]
    rotary_limits: tuple[tuple[float, float], tuple[float, float], tuple[float, float]]
    """(velocity, acceleration, jerk) of A and B"""
    spindle_acceleration: float
    """C acceleration used to start and stop the spindle [rad/s^2]"""
    path_length: float
    """total length of the sections [m]"""
    surface_tile_size: float = 0.02
    """edge of the convex collision tiles [m]"""
    friction: float | None = None
    """pad-workpiece sliding friction; None = the model's"""


@dataclass(frozen=True)
class PlannerConfig:
    """The PC planner process."""

    lookahead: float
    """motion time kept queued on the card ahead of execution [s]; 0 = no limit"""
    heartbeat_timeout: float
    """wall-clock time without a planner heartbeat before the DSP declares it lost [s]"""
    start_timeout: float
    """wall-clock time allowed for the planner process to start and attach [s]"""
    replay: Any = None
    """None, or the :class:`~cnc_twin.whiteboard.capture.PcStream` the planner writes again instead
    of planning the program (``planner.replay``)"""


@dataclass(frozen=True)
class WhiteboardConfig:
    words: int
    """RAM size [16-bit words]"""
    chunk_words: int
    """most FIFO words the planner writes per exchange"""
    fifo_interrupt: bool = True
    """the card's FIFO-threshold interrupt: while the planner's next record does not fit, the card
    exchanges only once it does (False: an exchange every period, however full the FIFO)"""


PLANNER_FAULTS = frozenset({"planner_stall", "planner_delay", "planner_kill", "record_bitflip"})
"""fault kinds injected on the PC side (the planner process); the rest act on the card or machine"""


@dataclass(frozen=True)
class FaultInjection:
    """One injected fault. ``at`` is simulated time [s]; other fields as the kind needs
    (see :mod:`cnc_twin.scenario.faults` for what each kind means)."""

    kind: str
    """planner_stall | planner_delay | planner_kill | record_bitflip | encoder_loss | encoder_noise |
    dac_stuck | dac_dead | torque_drop | force_spike | force_offset | collision | dsp_hang"""
    at: float
    duration: float = 0.0
    """planner_stall, dsp_hang: wall-clock / simulated stall [s]; planner_delay, encoder_noise,
    force_spike: simulated window [s] (0 = for good)"""
    delay: float = 0.0
    """planner_delay: wall-clock delay of each answer [s]"""
    every: float = 0.0
    """planner_delay: repeat the window every this much simulated time [s]; 0 = once"""
    bit: int = 0
    """record_bitflip: bit index in the record (wraps to its length)"""
    axis: int = -1
    """encoder_*, dac_*, torque_drop: the axis (index in X Y Z A B C)"""
    value: float = 0.0
    """encoder_loss: counts lost; encoder_noise: amplitude [counts]; torque_drop: fraction of the
    peak force kept [-]; force_spike, force_offset: added force [N]"""
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """collision: obstacle centre in the world frame [m]"""
    size: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """collision: obstacle half sizes [m]"""


@dataclass(frozen=True)
class SupervisorConfig:
    """The card's fault supervisor (:mod:`cnc_twin.dsp.supervisor`); 0 turns a check off."""

    following_error_stop: str = "disable"
    """what a following-error fault does: ``disable`` the drives at once or a ``controlled`` stop"""
    dac_saturation_time: float = 0.1
    """a DAC channel clamped this long without a break is a fault [s]"""
    max_force: float = 100.0
    """pad force above which the tool retracts [N]"""
    retract: float = 5e-3
    """retract distance along the tool axis [m]"""
    retract_speed: float = 0.05
    """retract speed [m/s]"""
    watchdog: float = 5e-3
    """the card's watchdog timeout: servo interrupts missed this long disable the drives [s]"""


@dataclass(frozen=True)
class BallbarTest:
    """A circular test (ISO 230-4) measured on the run: a ballbar between the tool tip and a pivot
    fixed at ``centre`` (:mod:`cnc_twin.run.ballbar`)."""

    plane: str
    """``XY``, ``XZ`` or ``YZ``: the plane of the circles"""
    centre: tuple[float, float, float]
    """the pivot, world frame [m]"""
    radius: float
    """the nominal radius (the bar's length) [m]"""
    overshoot: float
    """lead-in and lead-out arcs at each end of a pass, left out of the figures [rad]"""
    centre_in_workpiece: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """the pivot as the scenario gives it, workpiece frame [m]"""


@dataclass(frozen=True)
class Scenario:
    """A validated scenario, SI units throughout. Build with
    :func:`~cnc_twin.scenario.load.load_scenario`."""

    name: str
    description: str
    seed: int
    source_file: Path | None
    source_text: str
    """the scenario text as written (copied into the run directory)"""
    timing: Timing
    model_file: Path
    axes: tuple[AxisConfig, ...]
    """in X Y Z A B C order"""
    force_sensor: ForceSensorConfig
    program: PointToPoint | NurbsProgram | SurfaceProgram | ContourProgram | MotionChipProgram | GcodeProgram
    home: tuple[float, ...]
    """start position of every axis [m | rad]: the MJCF home keyframe"""
    planner: PlannerConfig
    whiteboard: WhiteboardConfig
    faults: tuple[FaultInjection, ...]
    max_time: float | None
    """cap on simulated time [s]; None = twice the planned program plus 5 s"""
    supervisor: SupervisorConfig = SupervisorConfig()
    block_shift: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """[m] how far the scene's workpiece block sits from where the scene draws it (the work frame
    stays): ``machine.block_shift``"""
    command_output: str = "analog"
    """``analog``: +-10 V speed commands from the card's PID (drives in velocity mode);
    ``pulse``: step/direction pulses (drives in position mode, :mod:`cnc_twin.machine.drive`)"""
    machine: dict[str, str] = field(default_factory=dict)
    """the machine's files as the scenario names them or by default (``model``: the MJCF,
    ``parameters``: the parameter file), kept in the run's metrics"""
    ballbar: BallbarTest | None = None
    """a circular test measured on the run (``ballbar:`` in the scenario), or None"""

    def axis(self, name: str) -> AxisConfig:
        return self.axes[AXES.index(name)]

    @property
    def drives(self) -> tuple[DriveConfig | None, ...]:
        """Per axis the amplifier's own loops, or None (the MJCF's velocity-mode drive)."""
        return tuple(a.drive for a in self.axes)

    @property
    def encoder_mounts(self) -> tuple[str, ...]:
        """Per axis where its encoder reads the machine: ``motor`` or ``table``."""
        return tuple(a.encoder_mount for a in self.axes)
