"""Straight probing, G38.2 .. G38.5, as LinuxCNC's interpreter reads it: the block's checks
(its convert_probe), the calls ``TURN_PROBE_ON`` / ``STRAIGHT_PROBE`` / ``TURN_PROBE_OFF``,
then the probe's result read back (its set_probe_data): #5061 .. #5066 the point where the
probe tripped (x y z a b c, program coordinates and units), #5067 .. #5069 the U V W the machine
does not have (0), #5070 1 when it tripped and 0 when not; and the interpreter's current point
becomes where the machine stopped.

G38.2 moves until the probe trips, G38.4 until it clears; G38.3 and G38.5 are the same moves
that accept not tripping (LinuxCNC's probe type: its bit 0 "no error", its bit 1 "until clear").

Where the probe trips is the machine's to say, so it is asked (:data:`Probe`): an
:class:`~cnc_twin.gcode.interpreter.Interpreter` takes a ``probe`` callable given the move
(:class:`ProbeMove`) and answering a :class:`ProbeResult`. The default,
:func:`standalone_probe`, answers as LinuxCNC's standalone ``rs274`` does (its canon in
saicanon.cc), so a program's calls and what it reads after a probe match rs274's; the twin runs
the probe on its simulated machine and answers with the real trip point. The
``STRAIGHT_PROBE`` call carries the move and its answer (``payload``: ``(ProbeMove,
ProbeResult)``), so what turns the calls into machine steps knows where the machine stopped.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from cnc_twin.gcode.blocks import Block, BlockError
from cnc_twin.gcode.modal import G

if TYPE_CHECKING:  # the motion runner that calls this step; only its type is needed here
    from cnc_twin.gcode.motion import MotionRunner

PROBE_CODES = {G.G38_2: 2, G.G38_3: 3, G.G38_4: 4, G.G38_5: 5}
"""G38.2 .. G38.5 (tenths) -> probe kind 2 .. 5"""
PROBE_PARAMETER = 5061
"""#5061 .. #5069: the trip point (x y z a b c u v w); #5070: tripped (1) or not (0)"""
TRIPPED_PARAMETER = 5070
BACK_OFF = {G.G20: 0.01, G.G21: 0.254}
"""how far rs274's standalone canon backs the probe off its target toward the start, in the
program's units (inch / mm)"""


@dataclass(frozen=True)
class ProbeMove:
    """One probing move as the ``STRAIGHT_PROBE`` call carries it.

    ``kind``: 2 .. 5 for G38.2 .. G38.5 (see the module docstring); ``start``: the point the
    move starts from, the canon's (the last motion's end, tool length offset changes since then
    not included), and ``target``: the programmed end; both x y z a b c in program coordinates
    (the active work and G92 offsets and the tool length offset applied, as every canon call),
    lengths in ``units`` (200: inch, 210: mm, the program's G20 / G21), angles in degrees;
    ``line``: the program line (1-based).
    """

    kind: int
    start: tuple[float, ...]
    target: tuple[float, ...]
    units: int
    line: int


@dataclass(frozen=True)
class ProbeResult:
    """What the machine says after a probing move, in the frame and units of its
    :class:`ProbeMove`: ``tripped``, whether the probe changed state (#5070); ``trip``, the
    point where it did (x y z a b c, #5061 ..; where the move ended when it did not); ``stop``,
    where the machine stopped, the interpreter's next current point (past the trip point by the
    machine's stopping distance, or backed off)."""

    tripped: bool
    trip: tuple[float, ...]
    stop: tuple[float, ...]


Probe = Callable[[ProbeMove], ProbeResult]
"""a probing move -> its result (see :class:`ProbeMove` and :class:`ProbeResult`)"""


def standalone_probe(move: ProbeMove) -> ProbeResult:
    """LinuxCNC's standalone rs274: the probe "trips" at the target, which #5061 .. report,
    yet reports not tripping (#5070 0); the machine ends backed off from the target toward the
    start by 0.254 mm (0.01 inch) along x y z (not at all for a move of no x y z length), at the
    target's a b c."""
    d = [move.start[k] - move.target[k] for k in range(3)]
    distance = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    stop = list(move.target)
    if distance != 0:
        back = BACK_OFF[move.units]
        for k in range(3):
            stop[k] = move.target[k] + back * (d[k] / distance)
    return ProbeResult(False, tuple(move.target), tuple(stop))


def straight_probe(runner: MotionRunner, code: int, block: Block) -> None:
    """The motion step of a G38.2 .. G38.5 block (``code`` in tenths): LinuxCNC's checks in its
    order, its calls, then the result read back as it reads it before the next line.

    :type block: ~cnc_twin.gcode.blocks.Block
    """
    interpreter, s = runner.interpreter, runner.state
    kind = PROBE_CODES[code]
    # cutter radius compensation and feed per revolution are refused before any block runs
    if s.feed == 0.0:
        raise BlockError("Cannot probe with zero feed rate")
    target = runner.ends(block)
    if kind in (2, 4) and target == s.position:  # a move that must trip must go somewhere
        raise BlockError("Start point too close to probe point")
    # the canon measures the move from its own point, which tool length offset changes since
    # the last motion have not moved
    start = tuple(p - shift for p, shift in zip(s.position, s.tool_shift))
    move = ProbeMove(kind, start, tuple(target), s.units, block.line)
    result = interpreter.probe(move)  # asked first: the call carries the answer to what runs it
    interpreter.emit("TURN_PROBE_ON")
    interpreter.emit("STRAIGHT_PROBE", *target, payload=(move, result))
    interpreter.emit("TURN_PROBE_OFF")
    numbered = s.params.numbered
    for k in range(9):
        numbered[PROBE_PARAMETER + k] = float(result.trip[k]) if k < 6 else 0.0
    numbered[TRIPPED_PARAMETER] = 1.0 if result.tripped else 0.0
    s.position = [float(v) for v in result.stop]
    s.tool_shift = [0.0] * 6  # the point is the canon's again
