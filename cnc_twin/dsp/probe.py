"""The card's probing move (G38.2 .. G38.5, a :class:`~cnc_twin.whiteboard.records.Probe`
record): a move that watches the load cell.

It runs as a move (its trapezoid, the feed override and holds acting on it) while, once per
interpolation period, the tared load-cell force from the ADC is compared with the record's trip
force: rising to it (kinds 2, 3: the pad pressed onto the work) or falling below it (kinds 4, 5:
the pad lifted off). At the first period it has crossed, the card latches the encoder counts of
that ADC sample (the servo tick the force came from) and stops the move along its path within
every axis's acceleration limit, as a feed hold does; the move is done once at rest, or at its
end when the force never crossed. Then :class:`ProbeState` logs the result the status block
reports (``probes``, ``probe_tripped``, ``probe_latch``, ``probe_stop``), and the next move
starts where the axes stopped. A probe already past its trip force at the start (kinds 2, 3: the
pad pressed; 4, 5: not) and a kind 2 or 4 that ends without crossing are faults
(:attr:`~cnc_twin.whiteboard.status.FaultCode.PROBE`), as LinuxCNC's motion controller errs on them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from cnc_twin.motion.segments import MoveSegment

MUST_TRIP = (2, 4)
"""G38.2, G38.4: the move must trip (the others accept not tripping)"""
PRESSING = (2, 3)
"""G38.2, G38.3: trip when the force rises to the trip force (G38.4, G38.5: falls below it)"""
NO_PROBE = (False, [0] * 6, [0.0] * 6)
"""what the status block reports before any probe has finished"""


@dataclass(frozen=True)
class ProbeSegment(MoveSegment):
    """A probing move on the card: a move (start, end [m | rad], trapezoid, periods) with the
    trip force [N] and the kind (2 .. 5)."""

    trip_force: float = 0.0
    kind: int = 2


@dataclass
class ProbeState:
    """The card's probing state: the running probe's, and every finished one's result."""

    active: bool = False
    """a probe is running: the period task hands the interpolator the encoder counts (``actual``)"""
    hit: bool = False
    """the running probe has crossed its trip force (the move is stopping)"""
    latch: list[int] = field(default_factory=lambda: [0] * 6)
    """the running probe's encoder counts when the force crossed"""
    fault: str | None = None
    """a probe fault the period task raises (then clears)"""
    log: list[tuple[bool, list[int], list[float]]] = field(default_factory=list)
    """``(tripped, latch, stop)`` of every probe finished, in order: whether the force crossed,
    the encoder counts then (where the move ended when it did not), the commanded counts where
    the axes stopped; the status block reports how many and the last (:meth:`last`)"""

    def last(self) -> tuple[bool, list[int], list[float]]:
        """The last finished probe's ``(tripped, latch, stop)``; zeros before any."""
        return self.log[-1] if self.log else NO_PROBE

    def start(self, seg: ProbeSegment, force: float) -> None:
        """A probing move starts with the load cell at ``force`` [N] (a fault when already past)."""
        self.active, self.hit = True, False
        if crossed(seg, force):
            way = "pressed to" if seg.kind in PRESSING else "below"
            self.fault = (f"G38.{seg.kind} starts with the load cell already {way} its trip force "
                          f"({force:.3g} N, trip {seg.trip_force:g} N)")

    def watch(self, seg: ProbeSegment, force: float, actual) -> bool:
        """One period's look at the load cell: latch the encoder counts ``actual`` at the first
        crossing; whether the move is to stop."""
        if not self.hit and crossed(seg, force):
            self.hit = True
            self.latch = [int(c) for c in actual]
        return self.hit

    def finish(self, seg: ProbeSegment, counts, actual) -> None:
        """The move is done, the axes commanded at ``counts``: the result, and a fault for a
        G38.2 / G38.4 that did not cross."""
        self.active = False
        if not self.hit:
            self.latch = [int(c) for c in actual]
            if seg.kind in MUST_TRIP:
                self.fault = (f"G38.{seg.kind} ended without the load cell "
                              f"{'reaching' if seg.kind in PRESSING else 'falling below'} {seg.trip_force:g} N")
        self.log.append((self.hit, self.latch, list(counts)))


def crossed(seg: ProbeSegment, force: float) -> bool:
    """The load-cell ``force`` [N] is past ``seg``'s trip force in its direction."""
    return force >= seg.trip_force if seg.kind in PRESSING else force < seg.trip_force
