"""Scenario schema and conversion of the ``motion_chip`` program (machinist units -> counts).

The commands are what a program for a motion-chip card sends, one after another::

    - home:   {axis: X, speed: 1200, creep: 60}        # home return (X, Y, Z: the axes with switches)
    - index:  {axis: X, distance: -37.5, speed: 6000}  # fixed-length move, relative [mm | deg]
    - jog:    {axis: Y, speed: -3000, time: 0.5}       # continuous move for a time, then stop
    - linear: {X: 10, Y: -20, speed: 3000}             # X/Y/Z together along a line, relative
    - dwell:  0.3                                      # [s]

Speeds in mm/min (deg/min); accelerations and jerks are each axis's limits (linear: the
smallest over the axes that move), in counts as the chip takes them. ``profile`` picks the
chip's ramps for every command: ``constant`` (none), ``trapezoid`` or ``s_curve``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, model_validator

from cnc_twin.core import units
from cnc_twin.core.axes import AXES
from cnc_twin.core.config import AxisConfig, ChipStep, MotionChipProgram
from cnc_twin.core.errors import ScenarioError
from cnc_twin.scenario.schema_base import DAY, KeyedValueError, Strict

AxisName = Literal["X", "Y", "Z", "A", "B", "C"]


class HomeSpec(Strict):
    axis: Literal["X", "Y", "Z"]
    speed: float = Field(1200.0, gt=0, description="search speed towards the home switch [mm/min]")
    creep: float = Field(60.0, gt=0, description="speed off the switch and on to the index pulse [mm/min]")


class IndexSpec(Strict):
    axis: AxisName
    distance: float = Field(description="signed move length [mm | deg]")
    speed: float = Field(gt=0, description="[mm/min | deg/min]")


class JogSpec(Strict):
    axis: AxisName
    speed: float = Field(description="signed speed [mm/min | deg/min]")
    time: float = Field(gt=0, description="how long before the stop [s]")


class LinearSpec(Strict):
    X: float = Field(0.0, description="[mm] relative")
    Y: float = Field(0.0, description="[mm] relative")
    Z: float = Field(0.0, description="[mm] relative")
    speed: float = Field(gt=0, description="path speed [mm/min]")


class ChipCommandSpec(Strict):
    """Exactly one of the keys."""

    home: HomeSpec | None = None
    index: IndexSpec | None = None
    jog: JogSpec | None = None
    linear: LinearSpec | None = None
    dwell: float | None = Field(None, ge=0, le=DAY, description="[s]")

    @model_validator(mode="after")
    def _one(self) -> "ChipCommandSpec":
        given = [k for k in ("home", "index", "jog", "linear", "dwell") if getattr(self, k) is not None]
        if len(given) != 1:
            raise KeyedValueError((), f"give exactly one of home, index, jog, linear, dwell (got {given or 'none'})")
        return self


class MotionChipProgramSpec(Strict):
    type: Literal["motion_chip"]
    profile: Literal["constant", "trapezoid", "s_curve"] = "s_curve"
    commands: list[ChipCommandSpec] = Field(min_length=1)
    settle: float = Field(0.3, ge=0, le=DAY, description="time simulated after the last command [s]")


def _speed(cfg: AxisConfig, value: float, label: Path, key: str) -> float:
    """A speed in mm/min (deg/min) -> counts/s, checked against the axis's limit."""
    si = abs(value) * units.velocity_factor(cfg.rotary)
    if si > cfg.max_velocity * (1 + 1e-9):
        top = cfg.max_velocity * cfg.display_factor * 60.0
        raise ScenarioError(label, key, f"{abs(value):g} {cfg.display_unit}/min is above {cfg.name}'s "
                            f"max_velocity {top:g} {cfg.display_unit}/min")
    return si * cfg.counts_per_unit * (1 if value >= 0 else -1)


def convert(spec: MotionChipProgramSpec, axes: tuple[AxisConfig, ...], has_home_switch, label: Path) -> MotionChipProgram:
    """Check and convert; ``has_home_switch(axis_index)`` tells whether the model has that switch."""
    steps = []
    for i, c in enumerate(spec.commands):
        key = f"program.commands[{i}]"
        if c.dwell is not None:
            steps.append(ChipStep(op="dwell", time=c.dwell))
            continue
        if c.linear is not None:
            moving = [j for j, name in enumerate(AXES[:3]) if getattr(c.linear, name) != 0.0]
            if not moving:
                raise ScenarioError(label, f"{key}.linear", "the line moves no axis")
            deltas = tuple(round(getattr(c.linear, name) * units.MM * axes[j].counts_per_unit)
                           for j, name in enumerate(AXES[:3]))
            speed = min(abs(_speed(axes[j], c.linear.speed, label, f"{key}.linear.speed")) for j in moving)
            steps.append(ChipStep(op="linear", axis=moving[0], deltas=deltas, speed=speed,
                                  accel=min(axes[j].max_acceleration * axes[j].counts_per_unit for j in moving),
                                  jerk=min(axes[j].max_jerk * axes[j].counts_per_unit for j in moving)))
            continue
        op, body = next((k, getattr(c, k)) for k in ("home", "index", "jog") if getattr(c, k) is not None)
        j = AXES.index(body.axis)
        cfg = axes[j]
        cpu = cfg.counts_per_unit
        common = dict(axis=j, accel=cfg.max_acceleration * cpu, jerk=cfg.max_jerk * cpu)
        if op == "home":
            if not has_home_switch(j):
                raise ScenarioError(label, f"{key}.home.axis", f"the machine model has no home switch on {body.axis}")
            if body.creep > body.speed:
                raise ScenarioError(label, f"{key}.home.creep", "the creep speed must not exceed the search speed")
            span = (cfg.travel[1] - cfg.travel[0]) * cpu if cfg.travel is not None else 0.0
            steps.append(ChipStep(op="home", speed=_speed(cfg, body.speed, label, f"{key}.home.speed"),
                                  creep=_speed(cfg, body.creep, label, f"{key}.home.creep"), span=span, **common))
        elif op == "index":
            distance = round(body.distance * units.position_factor(cfg.rotary) * cpu)
            if distance == 0:
                raise ScenarioError(label, f"{key}.index.distance", "shorter than one pulse")
            steps.append(ChipStep(op="index", distance=distance,
                                  speed=_speed(cfg, body.speed, label, f"{key}.index.speed"), **common))
        else:
            if body.speed == 0:
                raise ScenarioError(label, f"{key}.jog.speed", "a jog needs a speed")
            steps.append(ChipStep(op="jog", speed=_speed(cfg, body.speed, label, f"{key}.jog.speed"), time=body.time,
                                  **common))
    return MotionChipProgram(profile=spec.profile, commands=tuple(steps), settle=spec.settle)
