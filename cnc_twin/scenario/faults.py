"""Scenario schema of the ``faults:`` list and the ``supervisor:`` section, and their conversion to SI.

Faults are injected at a simulated time ``at`` [s] and are deterministic: the same scenario and
seed inject the same faults at the same periods (encoder noise draws from the scenario's seed).

PC side (the planner process): ``planner_stall``, ``planner_delay``, ``planner_kill``,
``record_bitflip``. Card and machine side (:mod:`cnc_twin.run.faults`): ``encoder_loss``,
``encoder_noise``, ``dac_stuck``, ``dac_dead``, ``torque_drop``, ``force_spike``,
``force_offset``, ``collision``, ``dsp_hang``.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal, Union

from pydantic import Field, model_validator

from cnc_twin.core import units
from cnc_twin.core.axes import AXES
from cnc_twin.core.config import FaultInjection, SupervisorConfig
from cnc_twin.scenario.schema_base import DAY, KeyedValueError, Strict as _Strict

AxisName = Literal["X", "Y", "Z", "A", "B", "C"]


class PlannerStallFault(_Strict):
    """The planner stops answering (and beating) for a while."""

    type: Literal["planner_stall"]
    at: float = Field(ge=0, le=DAY, description="simulated time of the first status it does not answer in time [s]")
    duration: float = Field(gt=0, le=600000.0, description="wall-clock stall [ms], at most 10 minutes")


class PlannerDelayFault(_Strict):
    """Every answer of the planner is late by ``delay`` for a simulated time window (repeated
    every ``every`` seconds if given)."""

    type: Literal["planner_delay"]
    at: float = Field(ge=0, le=DAY, description="[s] simulated")
    duration: float = Field(gt=0, le=DAY, description="window [s] simulated")
    delay: float = Field(gt=0, le=600000.0, description="wall-clock delay per answer [ms], at most 10 minutes")
    every: float = Field(0.0, ge=0, le=DAY, description="repeat the window every this many seconds [s] simulated; 0 = once")


class PlannerKillFault(_Strict):
    """The planner process dies (SIGKILL) when it sees a status at or after ``at``."""

    type: Literal["planner_kill"]
    at: float = Field(ge=0, le=DAY, description="[s] simulated")


class RecordBitflipFault(_Strict):
    """One bit of the next record written at or after ``at`` is flipped after its CRC was computed."""

    type: Literal["record_bitflip"]
    at: float = Field(ge=0, le=DAY, description="[s] simulated")
    bit: int = Field(0, ge=0, description="bit index within the record (wraps to its length)")


class EncoderLossFault(_Strict):
    """The axis's QEP misses ``counts`` edges at ``at`` (noise on the A/B lines): the card's
    position is off by that many counts from then on."""

    type: Literal["encoder_loss"]
    at: float = Field(ge=0, le=DAY, description="[s] simulated")
    axis: AxisName
    counts: int = Field(description="counts lost (negative: gained)")


class EncoderNoiseFault(_Strict):
    """Every encoder reading of the axis is off by a random whole number of counts within
    +-amplitude for a window (seeded by the scenario's seed)."""

    type: Literal["encoder_noise"]
    at: float = Field(ge=0, le=DAY, description="[s] simulated")
    axis: AxisName
    amplitude: int = Field(gt=0, description="[counts]")
    duration: float = Field(0.0, ge=0, description="window [s] simulated; 0 = for good")


class DacStuckFault(_Strict):
    """The axis's DAC channel keeps the code it has at ``at`` whatever the card writes."""

    type: Literal["dac_stuck"]
    at: float = Field(ge=0, le=DAY, description="[s] simulated")
    axis: AxisName


class DacDeadFault(_Strict):
    """The axis's DAC channel outputs 0 V from ``at`` on."""

    type: Literal["dac_dead"]
    at: float = Field(ge=0, le=DAY, description="[s] simulated")
    axis: AxisName


class TorqueDropFault(_Strict):
    """The axis's drive can deliver only ``fraction`` of its peak force or torque from ``at`` on
    (a failing amplifier or a motor phase lost)."""

    type: Literal["torque_drop"]
    at: float = Field(ge=0, le=DAY, description="[s] simulated")
    axis: AxisName
    fraction: float = Field(ge=0, lt=1, description="peak force kept [-]")


class ForceSpikeFault(_Strict):
    """The load cell reads ``force`` newtons more than it feels, for ``duration``."""

    type: Literal["force_spike"]
    at: float = Field(ge=0, le=DAY, description="[s] simulated")
    force: float = Field(description="[N] added to the reading")
    duration: float = Field(gt=0, description="[ms] simulated; at least one interpolation period acts")


class ForceOffsetFault(_Strict):
    """The load cell's reading is offset by ``force`` newtons from ``at`` on (a drifting bridge)."""

    type: Literal["force_offset"]
    at: float = Field(ge=0, le=DAY, description="[s] simulated")
    force: float = Field(description="[N] added to the reading")


class CollisionFault(_Strict):
    """An obstacle (a box, e.g. a clamp left on the table) that the head or pad collides with;
    it is in place from ``at`` on (before that it is far away)."""

    type: Literal["collision"]
    at: float = Field(0.0, ge=0, le=DAY, description="[s] simulated")
    position: list[float] = Field(min_length=3, max_length=3, description="box centre, world frame [mm]")
    size: list[float] = Field(min_length=3, max_length=3, description="box half sizes [mm], each > 0")

    @model_validator(mode="after")
    def _positive_size(self) -> "CollisionFault":
        if min(self.size) <= 0:
            raise KeyedValueError(("size",), f"expected three half sizes > 0 [mm], got {self.size}")
        return self


class DspHangFault(_Strict):
    """The card's task hangs: no servo interrupt runs for ``duration`` (the DACs hold their
    last codes). The watchdog disables the drives if the hang outlasts its timeout."""

    type: Literal["dsp_hang"]
    at: float = Field(ge=0, le=DAY, description="[s] simulated")
    duration: float = Field(gt=0, description="[ms] simulated")


FaultSpec = Annotated[
    Union[PlannerStallFault, PlannerDelayFault, PlannerKillFault, RecordBitflipFault, EncoderLossFault,
          EncoderNoiseFault, DacStuckFault, DacDeadFault, TorqueDropFault, ForceSpikeFault, ForceOffsetFault,
          CollisionFault, DspHangFault],
    Field(discriminator="type"),
]
FAULT_TAGS = {"planner_stall", "planner_delay", "planner_kill", "record_bitflip", "encoder_loss", "encoder_noise",
              "dac_stuck", "dac_dead", "torque_drop", "force_spike", "force_offset", "collision", "dsp_hang"}
"""the discriminator tags (pydantic puts them in error locations; messages leave them out)"""


class SupervisorSpec(_Strict):
    """The card's fault supervisor. Per-axis following-error and soft limits are under
    ``axes.<axis>``; 0 turns a check off."""

    following_error_stop: Literal["disable", "controlled"] = Field(
        "disable", description="disable: drives off at once, the axes coast to rest; "
                               "controlled: decelerate along the path, drives stay on")
    dac_saturation_time: float = Field(100.0, ge=0, description="a DAC channel clamped this long is a fault [ms]")
    max_force: float = Field(100.0, ge=0, description="pad force that makes the tool retract [N]")
    retract: float = Field(5.0, ge=0, description="retract distance along the tool axis [mm]")
    retract_speed: float = Field(3000.0, gt=0, description="retract speed [mm/min]")
    watchdog: float = Field(5.0, ge=0, description="servo interrupts missed this long disable the drives [ms]")


def convert_supervisor(spec: SupervisorSpec) -> SupervisorConfig:
    """The ``supervisor:`` section in SI (times in s, the retract in m and m/s)."""
    return SupervisorConfig(
        following_error_stop=spec.following_error_stop,
        dac_saturation_time=spec.dac_saturation_time * units.MS,
        max_force=spec.max_force,
        retract=spec.retract * units.MM,
        retract_speed=spec.retract_speed * units.MM_PER_MIN,
        watchdog=spec.watchdog * units.MS,
    )


def convert_fault(f: Any) -> FaultInjection:
    """One fault spec in SI."""
    axis = AXES.index(f.axis) if hasattr(f, "axis") else -1
    if isinstance(f, PlannerStallFault):
        return FaultInjection(kind=f.type, at=f.at, duration=f.duration * units.MS)
    if isinstance(f, PlannerDelayFault):
        return FaultInjection(kind=f.type, at=f.at, duration=f.duration, delay=f.delay * units.MS, every=f.every)
    if isinstance(f, RecordBitflipFault):
        return FaultInjection(kind=f.type, at=f.at, bit=f.bit)
    if isinstance(f, EncoderLossFault):
        return FaultInjection(kind=f.type, at=f.at, axis=axis, value=float(f.counts))
    if isinstance(f, EncoderNoiseFault):
        return FaultInjection(kind=f.type, at=f.at, axis=axis, value=float(f.amplitude), duration=f.duration)
    if isinstance(f, TorqueDropFault):
        return FaultInjection(kind=f.type, at=f.at, axis=axis, value=f.fraction)
    if isinstance(f, ForceSpikeFault):
        return FaultInjection(kind=f.type, at=f.at, value=f.force, duration=f.duration * units.MS)
    if isinstance(f, ForceOffsetFault):
        return FaultInjection(kind=f.type, at=f.at, value=f.force)
    if isinstance(f, CollisionFault):
        return FaultInjection(kind=f.type, at=f.at, position=tuple(v * units.MM for v in f.position),
                              size=tuple(v * units.MM for v in f.size))
    if isinstance(f, DspHangFault):
        return FaultInjection(kind=f.type, at=f.at, duration=f.duration * units.MS)
    return FaultInjection(kind=f.type, at=f.at, axis=axis)  # planner_kill, dac_stuck, dac_dead
