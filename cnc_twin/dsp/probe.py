"""The card's probing move (G38.2 .. G38.5, a :class:`~cnc_twin.whiteboard.records.Probe`
record): a move that watches the load cell.

It runs as a move (its trapezoid, the feed override and holds acting on it) while, once per
interpolation period, the tared load-cell force from the ADC is compared with the record's trip
force: rising to it (kinds 2, 3: the pad pressed onto the work) or falling below it (kinds 4, 5:
the pad lifted off). At the first period it has crossed, the card latches the encoder counts of
that ADC sample (the servo tick the force came from) and stops the move along its path within
every axis's acceleration limit, as a feed hold does; the move is done once at rest, or at its
end when the force never crossed. Then :class:`ProbeState` holds the result the status block
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


@dataclass(frozen=True)
class ProbeSegment(MoveSegment):
    """A probing move on the card: a move (start, end [m | rad], trapezoid, periods) with the
    trip force [N] and the kind (2 .. 5)."""

    trip_force: float = 0.0
    kind: int = 2


@dataclass
class ProbeState:
    """The card's probing state: the running probe's and the last finished one's result."""

    active: bool = False
    """a probe is running: the period task hands the interpolator the encoder counts (``actual``)"""
    hit: bool = False
    """the running probe has crossed its trip force (the move is stopping)"""
    count: int = 0
    """probing moves finished"""
    tripped: bool = False
    latch: list[int] = field(default_factory=lambda: [0] * 6)
    """encoder counts when the force crossed (where the move ended when it did not)"""
    stop: list[float] = field(default_factory=lambda: [0.0] * 6)
    """the commanded counts where the axes stopped"""
    fault: str | None = None
    """a probe fault the period task raises (then clears)"""
    log: list[tuple[bool, list[int], list[float]]] = field(default_factory=list)
    """``(tripped, latch, stop)`` of every probe finished, in order"""


def crossed(seg: ProbeSegment, force: float) -> bool:
    """The load-cell ``force`` [N] is past ``seg``'s trip force in its direction."""
    return force >= seg.trip_force if seg.kind in PRESSING else force < seg.trip_force


def start_probe(interp, seq: int, seg: ProbeSegment) -> None:
    """The probing move reaches the head of the queue: it starts as a move (or faults at once
    when the force is already past the trip)."""
    interp._queued_periods -= seg.periods
    interp._begin_move(seq, seg)
    state = interp.probe
    state.active, state.hit = True, False
    if crossed(seg, interp.measured_force):
        way = "pressed to" if seg.kind in PRESSING else "below"
        state.fault = (f"G38.{seg.kind} starts with the load cell already {way} its trip force "
                       f"({interp.measured_force:.3g} N, trip {seg.trip_force:g} N)")


def run_probe(interp, seq: int, seg: ProbeSegment, depth: float) -> tuple[list[float], float]:
    """One period of the probing move: latch and stop at the crossing (module docstring)."""
    interp.path_u = -1.0
    state = interp.probe
    if not state.hit and crossed(seg, interp.measured_force):
        state.hit = True
        state.latch = [int(c) for c in interp.actual]
    counts = interp._advance_move(seq, seg, stopping=state.hit)
    if interp.current is not None and state.hit and interp.override == 0.0:
        interp._complete(seq)
    if interp.current is None:  # done: at rest after the crossing, or at its end without one
        state.active = False
        state.count += 1
        state.tripped = state.hit
        if not state.hit:
            state.latch = [int(c) for c in interp.actual]
            if seg.kind in MUST_TRIP:
                state.fault = (f"G38.{seg.kind} ended without the load cell "
                               f"{'reaching' if seg.kind in PRESSING else 'falling below'} {seg.trip_force:g} N")
        state.stop = list(counts)
        state.log.append((state.tripped, state.latch, state.stop))
        interp.programmed = interp._position_of(counts)
    return counts, depth
