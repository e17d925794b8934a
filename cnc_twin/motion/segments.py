"""Program segments: what the planner sends the card, one record per motion or pause.

Positions are absolute machine positions per axis [m | rad], shape ``(6,)``, axis order
``X Y Z A B C``. Every segment lasts a whole number of interpolation periods.
"""

from __future__ import annotations

from dataclasses import dataclass

from cnc_twin.motion.trapezoid import Trapezoid


@dataclass(frozen=True)
class MoveSegment:
    """A synchronised point-to-point move on a normalised trapezoid profile."""

    start: tuple[float, ...]
    end: tuple[float, ...]
    profile: Trapezoid
    periods: int


@dataclass(frozen=True)
class DwellSegment:
    """Hold ``position`` for ``periods`` interpolation periods."""

    position: tuple[float, ...]
    periods: int


Segment = MoveSegment | DwellSegment
