"""The point-to-point program (``type: point_to_point``): moves to absolute targets, each on a
synchronised trapezoid; its schema in machinist units and its conversion to SI."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field

from cnc_twin.core import units
from cnc_twin.core.config import AxisConfig, Move, PointToPoint
from cnc_twin.core.errors import ScenarioError
from cnc_twin.machine.plant import ModelInfo
from cnc_twin.scenario.schema_base import DAY, FEED_MIN, Strict


class MoveSpec(Strict):
    """One point-to-point move: absolute targets; axes not named keep their position."""

    X: float | None = Field(None, description="[mm]")
    Y: float | None = Field(None, description="[mm]")
    Z: float | None = Field(None, description="[mm]")
    A: float | None = Field(None, description="[deg]")
    B: float | None = Field(None, description="[deg]")
    C: float | None = Field(None, description="[deg]")
    feed: float | None = Field(None, ge=FEED_MIN, description="cap on the tool's X/Y/Z path speed [mm/min]; default: rapid")
    dwell: float = Field(0.0, ge=0, le=DAY, description="pause after arriving [s]")


class PointToPointProgram(Strict):
    """Moves executed in turn, each on a synchronised trapezoid profile (all axes arrive together)."""

    type: Literal["point_to_point"]
    moves: list[MoveSpec] = Field(min_length=1)
    settle: float = Field(0.3, ge=0, le=DAY, description="time simulated after the last move [s]")


def convert(spec: PointToPointProgram, axes: tuple[AxisConfig, ...], info: ModelInfo, label: Path) -> PointToPoint:
    """The program in SI: each move's targets [m | rad] (None: the axis stays), feed [m/s] and
    dwell (a ScenarioError on ``program.moves[i].AXIS`` for a target outside the axis's allowed
    range)."""
    moves = []
    for m_index, move in enumerate(spec.moves):
        targets: list[float | None] = []
        for cfg in axes:
            value = getattr(move, cfg.name)
            if value is None:
                targets.append(None)
                continue
            si = value * units.position_factor(cfg.rotary)
            if cfg.allowed is not None and not (cfg.allowed[0] <= si <= cfg.allowed[1]):
                lo, hi = (v * cfg.display_factor for v in cfg.allowed)
                raise ScenarioError(
                    label,
                    f"program.moves[{m_index}].{cfg.name}",
                    f"target {value:g} {cfg.display_unit} is outside the {cfg.name} {cfg.allowed_name} "
                    f"{lo:g}..{hi:g} {cfg.display_unit}",
                )
            targets.append(si)
        feed = move.feed * units.MM_PER_MIN if move.feed is not None else None
        moves.append(Move(targets=tuple(targets), feed=feed, dwell=move.dwell))
    return PointToPoint(moves=tuple(moves), settle=spec.settle)
