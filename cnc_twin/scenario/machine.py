"""The machine's part of a scenario: axes (limits, encoders, servo gains, pulse output), the load
cell, the three rates, the planner and whiteboard settings; their schema in machinist units and
their conversion to SI (:mod:`cnc_twin.core.config`).

A machine parameter file (``machine.parameters``, default ``polisher.yaml``: the compliant
machine's; ``polisher_rigid.yaml`` the rigid variant's) gives every axis's limits, encoder and
servo gains; a scenario's own ``axes:`` / ``force_sensor:`` keys override any of them, key by key.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Literal

from pydantic import Field, model_validator

from cnc_twin.core import units
from cnc_twin.core.axes import AXES, is_rotary
from cnc_twin.core.config import AxisConfig, DriveConfig, Notch, Timing
from cnc_twin.core.errors import ScenarioError
from cnc_twin.machine.plant import ModelInfo
from cnc_twin.scenario.compensation import CompensationSpec, convert_compensation
from cnc_twin.scenario.schema_base import DAY, KeyedValueError, Strict


class EncoderSpec(Strict):
    """The axis's position feedback: a quadrature encoder on the motor shaft (semi-closed loop),
    or a linear scale on the table / an encoder on a rotary axis's output (full-closed loop)."""

    lines_per_rev: int = Field(gt=0, le=2**24, description="encoder lines per motor revolution; the QEP counts 4 edges per line")
    gear_ratio: float = Field(1.0, gt=0, description="motor revolutions per screw (linear) or axis (rotary) revolution")
    pitch: float | None = Field(None, gt=0, description="ball-screw lead [mm per screw revolution]; linear axes only")
    index_offset: float = Field(0.0, description="where one of the index pulses (one per motor revolution) is [mm | deg]")
    mount: Literal["motor", "table"] = Field("motor", description="motor: the encoder on the motor (semi-closed "
                                             "loop); table: a linear scale on the table, or an encoder on a rotary "
                                             "axis's output (full-closed loop); the same on a rigid machine")
    resolution: float | None = Field(None, gt=0, le=1.0, description="a table-mounted encoder's resolution "
                                     "[mm | deg per count]; default: the motor encoder's (lines, pitch, gear)")

    @model_validator(mode="after")
    def _resolution_only_on_the_table(self) -> "EncoderSpec":
        if self.resolution is not None and self.mount != "table":
            raise KeyedValueError(("resolution",), "a resolution is given for a table-mounted encoder (mount: table) only")
        return self


PerAxis = dict[Literal["X", "Y", "Z", "A", "B", "C"], float]
"""a number per axis named (a servo's deflection and coupling on the other axes)"""


class ServoSpec(Strict):
    """Position loop gains in machine terms; the DSP converts them to volts per count."""

    kp: float = Field(ge=0, le=1e5, description="position loop gain [1/s]: commanded speed per unit of following error")
    ki: float = Field(0.0, ge=0, le=1e8, description="integral gain [1/s^2]")
    kd: float = Field(0.0, ge=0, le=1e3, description="derivative gain [-]: speed per unit error rate")
    kvff: float = Field(1.0, ge=0, le=100.0, description="velocity feed-forward [-]; 1 feeds the full commanded speed")
    kaff: float = Field(0.0, ge=0, le=100.0, description="acceleration feed-forward [s]: speed per unit commanded acceleration")
    aff_washout: float = Field(0.0, ge=0, le=10000.0, description="the acceleration feed-forward's high-pass "
                               "time constant [ms]: the drive's speed-loop integral time (its integral takes "
                               "over a lasting acceleration); 0 = no high-pass")
    ff_equivalent_time: float = Field(0.0, ge=0, le=100.0, description="the drive speed loop's equivalent "
                                      "time constant [ms]: the position loop compares the actual position with the "
                                      "command through a first-order lag of this time, so that the feed-forward "
                                      "and the position loop do not fight (symmetrised feed-forward); 0 = off")
    deflection: PerAxis = Field(
        default_factory=dict, description="the tool tip's deflection along this axis (tip less encoder) per unit "
        "commanded acceleration of each axis named, as a scale on the table or the circular test measures it "
        "[um per m/s^2, i.e. ms^2; for a rotary axis read deg for mm: mdeg, 1000 deg/s^2]: the card "
        "corrects the command by the opposite, so that the tip lands on the path (an acceleration-dependent "
        "position correction: a screw's windup, a bridge's bending, as Heidenhain's cross-talk compensation "
        "does); {} = none")
    coupling: PerAxis = Field(
        default_factory=dict, description="the axis's inertia coupling to the axes named: the force (torque) "
        "another axis's acceleration puts on this axis's drive over this axis's own inertia, the mass matrix's "
        "off-diagonal over its diagonal [mm per mm, deg per mm, mm per deg or deg per deg: this axis's "
        "acceleration per the other's]; the acceleration feed-forward adds it, kaff x (a + sum coupling_j a_j), "
        "so that a tilting head holds still while the table under it accelerates; {} = none")
    friction_ff: float = Field(0.0, ge=0, le=10.0, description="friction feed-forward [V]: added with the sign of the "
                               "commanded speed to cancel the axis's Coulomb friction; 0 = off")
    friction_ff_band: float = Field(1.0, gt=0, description="commanded speed over which the friction feed-forward "
                                    "ramps from 0 to full [mm/s | deg/s]")
    reversal_amplitude: float = Field(0.0, ge=0, le=6000.0, description="reversal (quadrant error) compensation: "
                                      "the speed pulse added to the drive command when the commanded velocity "
                                      "changes sign [mm/min | deg/min]; 0 = off")
    reversal_time: float = Field(0.0, ge=0, le=1000.0, description="reversal compensation: the pulse's decay time "
                                 "constant [ms]; 0 = off")
    reversal_lead: float = Field(0.0, ge=0, le=100.0, description="reversal compensation: how long before the "
                                 "commanded velocity's zero, predicted from the commanded acceleration, the pulse "
                                 "starts [ms]")
    reversal_rise: float = Field(0.0, ge=0, le=100.0, description="reversal compensation: the pulse's rise time "
                                 "constant [ms] (a first-order low-pass on it, so that it excites the axis's modes "
                                 "less); 0 = a step")
    reversal_min_speed: float = Field(0.0, ge=0, le=1e6, description="reversal compensation: the commanded "
                                      "speed a move must reach for its reversal to count (a force loop's small "
                                      "turns get no pulse) [mm/min | deg/min]; 0 = any")
    reversal_standstill: float = Field(0.0, ge=0, le=1.0, description="reversal compensation at stops and "
                                       "starts: the share of the pulse given against the motion as the axis "
                                       "comes to a stop and with it as it starts again (0.5: the drive's "
                                       "integrator at rest holds no friction); 0 = none")
    reversal_start_speed: float = Field(0.0, ge=0, le=1e6, description="reversal compensation: the commanded "
                                        "speed a start's pulse waits for [mm/min | deg/min]")
    reversal_stop_speed: float = Field(0.0, ge=0, le=1e6, description="reversal compensation: the commanded "
                                       "speed under which a decelerating axis gets a stop's pulse "
                                       "[mm/min | deg/min]")
    reversal_adapt_amplitude: float = Field(0.0, ge=0, le=6000.0, description="reversal compensation's "
                                            "adaptation characteristic: the pulse at a reversal with the commanded "
                                            "acceleration reversal_adapt_to, linear from reversal_amplitude at "
                                            "reversal_adapt_from, held beyond [mm/min | deg/min]; 0 = none")
    reversal_adapt_from: float = Field(0.0, ge=0, le=1e6, description="reversal compensation's adaptation: the "
                                       "acceleration up to which the pulse is reversal_amplitude "
                                       "[mm/s^2 | deg/s^2]")
    reversal_adapt_to: float = Field(0.0, ge=0, le=1e6, description="reversal compensation's adaptation: the "
                                     "acceleration from which the pulse is reversal_adapt_amplitude "
                                     "[mm/s^2 | deg/s^2]")
    output_limit: float = Field(10.0, gt=0, le=10.0, description="clamp on the loop output [V]")
    integrator_limit: float = Field(3.0, ge=0, le=10.0, description="clamp on the integrator's contribution [V]")

    @model_validator(mode="after")
    def _adaptation_between_two_accelerations(self) -> "ServoSpec":
        if self.reversal_adapt_amplitude > 0 and not self.reversal_adapt_from < self.reversal_adapt_to:
            raise KeyedValueError(("reversal_adapt_to",), "an adaptation (reversal_adapt_amplitude > 0) needs "
                                  "reversal_adapt_to above reversal_adapt_from")
        return self


class PulseSpec(Strict):
    """Pulse-train output (``command_output: pulse``): the generator's limit and the amplifier
    in position mode."""

    max_rate: float = Field(500.0, gt=0, le=10000.0, description="highest step rate of the card and the drive input [kHz]")
    position_gain: float = Field(80.0, gt=0, description="the amplifier's position-loop gain [1/s]")
    velocity_ff: float = Field(1.0, ge=0, le=1.0, description="the amplifier's velocity feed-forward [-]")
    ff_filter: float = Field(1.0, ge=0, description="feed-forward filter time constant [ms]")


class NotchSpec(Strict):
    """A notch filter on the drive's torque command (drive commissioning's "current setpoint filter")."""

    frequency: float = Field(gt=1.0, le=2000.0, description="centre frequency [Hz]")
    width: float = Field(gt=0.0, le=2000.0, description="-3 dB bandwidth [Hz]")
    depth: float = Field(gt=0.0, le=60.0, description="attenuation at the centre [dB]")


class DriveSpec(Strict):
    """The servo amplifier's own loops, in motor terms as a drive's parameter list gives them, for
    a machine whose MJCF drive is current-mode (models/polisher.xml)."""

    speed_at_10v: float = Field(gt=0.0, le=20000.0, description="motor speed commanded by +10 V [rpm]")
    kp_speed: float = Field(gt=0.0, le=1e3, description="velocity-loop proportional gain [N m s/rad at the motor]")
    tn_speed: float = Field(0.0, ge=0.0, le=1000.0, description="velocity-loop integral time [ms]; 0 = P only")
    current_bandwidth: float = Field(1000.0, gt=10.0, le=20000.0, description="current-loop bandwidth [Hz]")
    torque_limit: float = Field(gt=0.0, le=1e4, description="peak torque [N m at the motor]")
    notch_filters: list[NotchSpec] = Field([], max_length=2, description="on the torque command, at most two")
    speed_filter: float = Field(0.0, ge=0.0, le=20000.0,
                                description="the actual speed's first-order low-pass [Hz] (the velocity "
                                            "feedback's bandwidth, e.g. 600); 0: the motor's exact speed")
    torque_filter: float = Field(0.0, ge=0.0, le=100.0,
                                 description="the torque command's first-order low-pass time constant [ms], "
                                             "before the notch filters (a drive's torque reference filter, "
                                             "e.g. 1.0); 0: none")
    feedback_resolution: int = Field(0, ge=0, le=2**32,
                                     description="the drive's motor feedback [counts per motor revolution]: "
                                                 "its speed is their difference over a step; 0: not quantised")


class AxisSpec(Strict):
    """One axis: limits (mm or deg based), encoder, servo gains."""

    max_velocity: float = Field(gt=0, description="[mm/min] linear, [deg/min] rotary")
    max_acceleration: float = Field(gt=0, description="[mm/s^2] linear, [deg/s^2] rotary")
    max_jerk: float = Field(gt=0, description="[mm/s^3] linear, [deg/s^3] rotary")
    encoder: EncoderSpec
    servo: ServoSpec
    pulse: PulseSpec = PulseSpec()
    drive: DriveSpec | None = Field(None, description="the amplifier's own loops (a current-mode MJCF drive); "
                                    "none: the MJCF's velocity-mode drive")
    compensation: CompensationSpec | None = Field(None, description="the card's backlash and pitch-error "
                                                                    "compensation (LinuxCNC's BACKLASH, COMP_FILE)")
    following_error_limit: float = Field(0.0, ge=0, description="the supervisor's following-error limit [mm | deg]; 0 = off")
    soft_limits: list[float] | None = Field(None, min_length=2, max_length=2,
                                            description="[low, high] the supervisor keeps the axis within [mm | deg]; "
                                                        "default: the hard travel of the MJCF")

    @model_validator(mode="after")
    def _ordered_limits(self) -> "AxisSpec":
        if self.soft_limits is not None and not self.soft_limits[0] < self.soft_limits[1]:
            raise KeyedValueError(("soft_limits",), f"expected [low, high] with low < high, got {self.soft_limits}")
        return self


class AxesSpec(Strict):
    """The six axes by name: X, Y, Z linear [mm], A, B, C rotary [deg]."""

    X: AxisSpec
    Y: AxisSpec
    Z: AxisSpec
    A: AxisSpec
    B: AxisSpec
    C: AxisSpec

    @model_validator(mode="after")
    def _pitch_only_on_linear_axes(self) -> "AxesSpec":
        for axis in AXES:
            enc = getattr(self, axis).encoder
            if is_rotary(axis) and enc.pitch is not None:
                raise KeyedValueError((axis, "encoder", "pitch"), "rotary axes have no screw pitch; remove the key")
            if not is_rotary(axis) and enc.pitch is None:
                raise KeyedValueError((axis, "encoder", "pitch"), "linear axes need the screw pitch [mm/rev]")
        return self


class ForceSensorSpec(Strict):
    """Load cell between head and pad, read by the DSP's ADC."""

    range: list[float] = Field(min_length=2, max_length=2, description="[N] force at ADC code 0 and at full scale")
    bits: int = Field(12, ge=8, le=16, description="ADC resolution [bits]")

    @model_validator(mode="after")
    def _ordered(self) -> "ForceSensorSpec":
        if not self.range[0] < self.range[1]:
            raise KeyedValueError(("range",), f"expected [low, high] with low < high, got {self.range}")
        return self


class MachineParameters(Strict):
    """A machine parameter file (e.g. ``models/polisher.yaml``)."""

    axes: AxesSpec
    force_sensor: ForceSensorSpec
    tool_table: str | None = Field(None, description="the machine's LinuxCNC tool table (mm), next to this file: "
                                                     "NC programs use it unless their scenario names one")


class TimingSpec(Strict):
    """The three rates; each period must be an integer multiple of the next."""

    interpolation_period: float = Field(1.0, ge=0.05, le=100.0, description="PC <-> DSP exchange and interpolation period [ms]")
    servo_period: float = Field(0.25, ge=0.01, le=100.0, description="DSP servo interrupt period [ms]")
    physics_timestep: float = Field(0.25, ge=0.001, le=10.0, description="MuJoCo timestep [ms]")
    mode: Literal["lockstep", "realtime"] = Field(
        "lockstep",
        description="lockstep: the DSP waits for every exchange (deterministic); "
        "realtime: the DSP is paced to the wall clock and never waits (late answers are missed exchanges)",
    )


class MachineRef(Strict):
    """The machine the scenario runs on: its MJCF model and its parameter file, each looked for
    next to the scenario, then among the bundled models."""

    model: str = Field("scene.xml", description="MJCF file, relative to the scenario or bundled in models/")
    parameters: str = Field("polisher.yaml", description="machine parameter file, same lookup as model")
    block_shift: list[float] = Field(
        [0.0, 0.0, 0.0], min_length=3, max_length=3, description="[mm] x y z: the workpiece block sits this far from where the scene draws it, "
        "the work frame (the programs' zero) staying: a part set up off its place or thicker than drawn, which a "
        "program finds by probing (G38.2)")


HEARTBEAT_DEFAULT_MS = {"realtime": 1000.0, "lockstep": 10000.0}


class PlannerSpec(Strict):
    """The PC planner process."""

    lookahead: float = Field(0.0, ge=0, le=DAY * 1e3, description="motion kept queued on the card ahead of execution [ms]; 0 = no limit")
    heartbeat_timeout: float | None = Field(
        None, gt=0, le=3.6e6, description="wall-clock time without planner heartbeat before it counts as lost [ms]; "
        "default 1000 in realtime mode, 10000 in lockstep (where the card waits anyway, and a busy machine "
        "running a sweep must not pass for a hung planner)")
    start_timeout: float = Field(60.0, gt=0, le=3600.0, description="wall-clock time for the planner process to start [s]")
    replay: str | None = Field(None, description="a PC program's recorded stream (the pc_stream.bin of a `cnc-twin "
                               "serve` run), relative to the scenario: the planner writes it again, answer by answer, "
                               "instead of planning the program (which still sets up the machine and the metrics)")


class WhiteboardSpec(Strict):
    """The emulated dual-port RAM."""

    words: int = Field(8192, description="size [16-bit words]; a power of two from 2048 to 32768",
                       json_schema_extra={"enum": [2048, 4096, 8192, 16384, 32768]})  # for editors: _power_of_two's
    chunk: int = Field(4096, ge=64, description="most bytes of records the planner writes per exchange [bytes]")
    fifo_interrupt: bool = Field(True, description="the card's FIFO-threshold interrupt: while the planner's next "
                                 "record does not fit, no exchange until it does (false: an exchange every period)")

    @model_validator(mode="after")
    def _power_of_two(self) -> "WhiteboardSpec":
        if not (2048 <= self.words <= 32768 and self.words & (self.words - 1) == 0):
            raise KeyedValueError(("words",), f"expected a power of two from 2048 to 32768, got {self.words}")
        fifo_bytes = 2 * (self.words // 2 - 32)  # the PC half less its control block (whiteboard/layout.py)
        if self.chunk > fifo_bytes:
            raise KeyedValueError(("chunk",), f"at most the command FIFO's {fifo_bytes} bytes (words {self.words}), "
                                              f"got {self.chunk}")
        return self


def _whole_multiple(spec: TimingSpec, longer: str, shorter: str, label: Path) -> int:
    """How many ``shorter`` periods fit in ``longer``; an error unless a whole number >= 1."""
    numerator, denominator = getattr(spec, longer), getattr(spec, shorter)
    ratio = numerator / denominator
    nearest = round(ratio)
    if nearest >= 1 and abs(ratio - nearest) <= 1e-9 * ratio:
        return int(nearest)
    raise ScenarioError(
        label,
        f"timing.{shorter}",
        f"{longer} {numerator} ms must be an integer multiple (>= 1) of {shorter} {denominator} ms",
    )


def convert_timing(spec: TimingSpec, label: Path) -> Timing:
    """The ``timing:`` section in SI: the three periods [s], the servo ticks per interpolation
    period and the physics steps per tick (a ScenarioError when a period is no whole multiple of
    the next shorter one)."""
    ticks = _whole_multiple(spec, "interpolation_period", "servo_period", label)
    substeps = _whole_multiple(spec, "servo_period", "physics_timestep", label)
    return Timing(
        interpolation_period=spec.interpolation_period * units.MS,
        servo_period=spec.servo_period * units.MS,
        physics_timestep=spec.physics_timestep * units.MS,
        ticks_per_period=ticks,
        substeps_per_tick=substeps,
        mode=spec.mode,
    )


def _per_axis(coefficients: dict[str, float], rotary: bool, scale: float) -> tuple[float, ...]:
    """One axis's coefficients on the other axes (``servo.deflection``, ``servo.coupling``: ``scale``
    x this axis's scenario unit per the other's) in SI, one per axis in :data:`AXES` order; ()
    when empty."""
    if not coefficients:
        return ()
    own = units.position_factor(rotary)
    return tuple(scale * coefficients.get(other, 0.0) * own / units.position_factor(is_rotary(other))
                 for other in AXES)


def _counts_per_unit(axis: str, enc: EncoderSpec) -> float:
    if enc.resolution is not None:
        return 1.0 / (enc.resolution * units.position_factor(is_rotary(axis)))
    counts_per_motor_rev = 4.0 * enc.lines_per_rev
    if is_rotary(axis):
        return counts_per_motor_rev * enc.gear_ratio / (2.0 * math.pi)
    return counts_per_motor_rev * enc.gear_ratio / (enc.pitch * units.MM)


def _index_period(axis: str, enc: EncoderSpec) -> float:
    """One motor revolution at the axis [m | rad]: the distance between index pulses."""
    if is_rotary(axis):
        return 2.0 * math.pi / enc.gear_ratio
    return enc.pitch * units.MM / enc.gear_ratio


def convert_axes(spec: AxesSpec, info: ModelInfo, label: Path, folder: Path | None = None) -> tuple[AxisConfig, ...]:
    """The axes in SI; ``folder``: the scenario's, where a comp file is looked for first."""
    out = []
    for i, axis in enumerate(AXES):
        a: AxisSpec = getattr(spec, axis)
        rotary = is_rotary(axis)
        drive = _drive(axis, a, info, label)
        out.append(
            AxisConfig(
                name=axis,
                rotary=rotary,
                max_velocity=a.max_velocity * units.velocity_factor(rotary),
                max_acceleration=a.max_acceleration * units.position_factor(rotary),
                max_jerk=a.max_jerk * units.position_factor(rotary),
                counts_per_unit=_counts_per_unit(axis, a.encoder),
                kp=a.servo.kp,
                ki=a.servo.ki,
                kd=a.servo.kd,
                kvff=a.servo.kvff,
                kaff=a.servo.kaff,
                aff_washout=a.servo.aff_washout * units.MS,
                ff_equivalent_time=a.servo.ff_equivalent_time * units.MS,
                deflection=_per_axis(a.servo.deflection, rotary, 1e-6),
                coupling=_per_axis(a.servo.coupling, rotary, 1.0),
                friction_ff=a.servo.friction_ff,
                friction_ff_band=a.servo.friction_ff_band * units.position_factor(rotary),
                reversal_amplitude=a.servo.reversal_amplitude * units.velocity_factor(rotary),
                reversal_time=a.servo.reversal_time * units.MS,
                reversal_lead=a.servo.reversal_lead * units.MS,
                reversal_rise=a.servo.reversal_rise * units.MS,
                reversal_min_speed=a.servo.reversal_min_speed * units.velocity_factor(rotary),
                reversal_standstill=a.servo.reversal_standstill,
                reversal_start_speed=a.servo.reversal_start_speed * units.velocity_factor(rotary),
                reversal_stop_speed=a.servo.reversal_stop_speed * units.velocity_factor(rotary),
                reversal_adapt_amplitude=a.servo.reversal_adapt_amplitude * units.velocity_factor(rotary),
                reversal_adapt_from=a.servo.reversal_adapt_from * units.position_factor(rotary),
                reversal_adapt_to=a.servo.reversal_adapt_to * units.position_factor(rotary),
                output_limit=a.servo.output_limit,
                integrator_limit=a.servo.integrator_limit,
                travel=info.travel[i],
                speed_per_volt=drive.speed_per_volt if drive is not None else info.speed_per_volt[i],
                drive=drive,
                encoder_mount=a.encoder.mount,
                pulse_max_rate=a.pulse.max_rate * 1e3,
                drive_position_gain=a.pulse.position_gain,
                drive_velocity_ff=a.pulse.velocity_ff,
                drive_ff_filter=a.pulse.ff_filter * units.MS,
                index_period=_index_period(axis, a.encoder),
                index_offset=a.encoder.index_offset * units.position_factor(rotary),
                following_error_limit=a.following_error_limit * units.position_factor(rotary),
                soft_limits=_soft_limits(axis, a, info.travel[i], label),
                compensation=convert_compensation(a.compensation, axis, rotary, folder, label),
            )
        )
        _check_counter(out[-1], a.encoder.lines_per_rev, label)
    return tuple(out)


def _drive(axis: str, a: AxisSpec, info: ModelInfo, label: Path) -> DriveConfig | None:
    """The amplifier's loops in axis units, where the MJCF's drive is current-mode (they must be
    given then, and only then); the motor's ratio to the axis from the encoder's screw and gear,
    which must agree with the MJCF's drive gear."""
    current = info.current_mode[AXES.index(axis)]
    if (a.drive is not None) != current:
        need = "gives a current-mode drive: give the amplifier's loops here" if current else \
            "gives a velocity-mode drive (its loop is in the MJCF): remove this key"
        raise ScenarioError(label, f"axes.{axis}.drive", f"the machine's MJCF {need}")
    if a.drive is None:
        return None
    d, enc = a.drive, a.encoder
    # motor rad per axis m (screw lead and gear) or per axis rad (the gear ratio)
    ratio = enc.gear_ratio if is_rotary(axis) else 2.0 * math.pi * enc.gear_ratio / (enc.pitch * units.MM)
    model_ratio = info.motor_per_axis[AXES.index(axis)]
    if not math.isclose(ratio, model_ratio, rel_tol=1e-6):
        raise ScenarioError(label, f"axes.{axis}.encoder", f"the encoder's screw and gear give {ratio:.6g} motor rad "
                            f"per axis unit, the MJCF's drive gear {model_ratio:.6g}")
    return DriveConfig(
        speed_per_volt=d.speed_at_10v * 2.0 * math.pi / 60.0 / 10.0 / ratio,
        kp=d.kp_speed * ratio ** 2,
        tn=d.tn_speed * units.MS,
        current_bandwidth=d.current_bandwidth,
        force_limit=d.torque_limit * ratio,
        notches=tuple(Notch(n.frequency, n.width, n.depth) for n in d.notch_filters),
        motor_per_axis=ratio,
        speed_filter=d.speed_filter,
        feedback_counts=d.feedback_resolution,
        torque_filter=d.torque_filter * units.MS,
    )


COUNTER_MAX = 2**31 - 1
"""the QEP position counter's largest value (a signed 32-bit register)"""


def _check_counter(cfg: AxisConfig, lines: int, label: Path) -> None:
    """The encoder counts over the axis's travel must fit the card's 32-bit position counter (a
    continuous axis, without travel, wraps by design)."""
    if cfg.travel is None:
        return
    counts = cfg.counts_per_unit * (cfg.travel[1] - cfg.travel[0])
    if counts > COUNTER_MAX:
        raise ScenarioError(label, f"axes.{cfg.name}.encoder.lines_per_rev",
                            f"{lines} lines give {counts:.3g} counts over the {cfg.name} travel; the card's "
                            f"32-bit position counter holds {COUNTER_MAX}")


def _soft_limits(axis: str, spec: AxisSpec, travel: tuple[float, float] | None, label: Path
                 ) -> tuple[float, float] | None:
    """The soft limits in SI, checked to lie within the hard travel."""
    if spec.soft_limits is None:
        return None
    f = units.position_factor(is_rotary(axis))
    lo, hi = spec.soft_limits[0] * f, spec.soft_limits[1] * f
    if travel is not None and not (travel[0] <= lo and hi <= travel[1]):
        unit = units.position_unit(is_rotary(axis))
        raise ScenarioError(label, f"axes.{axis}.soft_limits",
                            f"{spec.soft_limits[0]:g}..{spec.soft_limits[1]:g} {unit} must lie within the "
                            f"{axis} travel {travel[0] / f:g}..{travel[1] / f:g} {unit}")
    return lo, hi


def check_pulse_rates(axes: tuple[AxisConfig, ...], label: Path) -> None:
    """Pulse output: every axis's top speed must fit its pulse rate limit (the planner plans up to it)."""
    for cfg in axes:
        needed = cfg.max_velocity * cfg.counts_per_unit
        if needed > cfg.pulse_max_rate * (1.0 + 1e-9):
            speed = cfg.max_velocity * cfg.display_factor * 60.0
            raise ScenarioError(label, f"axes.{cfg.name}.pulse.max_rate",
                                f"{cfg.name}'s max_velocity {speed:g} {cfg.display_unit}/min needs "
                                f"{needed / 1e3:g} kHz of step pulses; the limit is {cfg.pulse_max_rate / 1e3:g} kHz "
                                f"(raise it or lower max_velocity)")
