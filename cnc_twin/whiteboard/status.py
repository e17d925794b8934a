"""The DSP status block: what the card reports to the PC once per interpolation period.

Written by the DSP into the status area while it owns the bus, then published by the DSP -> PC
mailbox. One aligned numpy record (``STATUS_DTYPE``); per-axis arrays in ``X Y Z A B C`` order.

=====================  ==========  ===============================================================
field                  type        meaning
=====================  ==========  ===============================================================
period                 u32         interpolation period counter of this status
state                  u16         controller state (:class:`DspState`)
fault                  u16         fault code (:class:`FaultCode`), 0 = none
fifo_fill              u32         words waiting in the command FIFO after this exchange
expected_seq           u32         sequence number the DSP accepts next
last_seq_executed      u32         last record whose execution finished (0 = none yet)
records_accepted       u32         records accepted so far
records_rejected       u32         records rejected (CRC, framing, sequence) so far
missed_exchanges       u32         periods the DSP found the PC had not answered in time
underrun_periods       u32         periods spent starved of commands before the program's end
queued_periods         u32         motion time still queued on the card, incl. the running move [periods]
sim_time               f64         simulated time at the start of this period [s]
feed_override          f64         effective feed override (0 while held) [-]
pad_force              f64         load-cell force, tared [N]
command                f64 x6      commanded position [counts]
actual                 i32 x6      encoder position [counts]
dac                    i16 x6      DAC code
following_error        f64 x6      command - actual [counts]
events                 u16 x6      motion-chip event bits raised since the last status
                                   (1 motion done, 2 home found, 4 + limit, 8 - limit)
index_latch            i32 x6      count latched at the index pulse by the last home return
probes                 u32         probing moves finished so far (G38.n); the next three fields
                                   are the last one's
probe_tripped          u16         1 when the load cell crossed the trip force, 0 when the move
                                   ended first
probe_latch            i32 x6      encoder position latched when it crossed [counts] (where the
                                   move ended when it did not)
probe_stop             f64 x6      commanded position where the card stopped the axes [counts]:
                                   the next move starts there
=====================  ==========  ===============================================================
"""

from __future__ import annotations

import struct

import numpy as np

STATUS_DTYPE = np.dtype(
    [
        ("period", "<u4"),
        ("state", "<u2"),
        ("fault", "<u2"),
        ("fifo_fill", "<u4"),
        ("expected_seq", "<u4"),
        ("last_seq_executed", "<u4"),
        ("records_accepted", "<u4"),
        ("records_rejected", "<u4"),
        ("missed_exchanges", "<u4"),
        ("underrun_periods", "<u4"),
        ("queued_periods", "<u4"),
        ("sim_time", "<f8"),
        ("feed_override", "<f8"),
        ("pad_force", "<f8"),
        ("command", "<f8", (6,)),
        ("actual", "<i4", (6,)),
        ("dac", "<i2", (6,)),
        ("following_error", "<f8", (6,)),
        ("events", "<u2", (6,)),
        ("index_latch", "<i4", (6,)),
        ("probes", "<u4"),
        ("probe_tripped", "<u2"),
        ("probe_latch", "<i4", (6,)),
        ("probe_stop", "<f8", (6,)),
    ],
    align=True,
)


class DspState:
    """Controller states reported in the status block."""

    IDLE = 0        # powered, no program yet
    RUNNING = 1
    FEED_HOLD = 2   # starved of commands (FIFO underrun) or told to hold; resumes by itself
    STOPPING = 3    # controlled stop after a fault
    FAULT = 4       # stopped after a fault
    FINISHED = 5    # end of program executed

    NAMES = {0: "IDLE", 1: "RUNNING", 2: "FEED_HOLD", 3: "STOPPING", 4: "FAULT", 5: "FINISHED"}


class FaultCode:
    """Fault codes reported in the status block and ``metrics.json``."""

    NONE = 0
    PLANNER_LOST = 1       #: planner process died or its heartbeat stopped
    PLANNER_START = 2      #: planner never attached
    RUN_TIMEOUT = 3        #: program did not finish within the scenario's time limit
    FOLLOWING_ERROR = 4    #: an axis's following error beyond its limit
    SOFT_LIMIT = 5         #: a command beyond an axis's soft limit
    HARD_LIMIT = 6         #: a limit switch on
    DAC_SATURATION = 7     #: a DAC channel clamped for longer than allowed
    FORCE_LIMIT = 8        #: pad force above the maximum
    WATCHDOG = 9           #: the card's task stopped running (servo interrupts missed)
    PROBE = 10             #: a probing move that must trip did not, or the probe was tripped at its start

    NAMES = {0: "NONE", 1: "PLANNER_LOST", 2: "PLANNER_START", 3: "RUN_TIMEOUT", 4: "FOLLOWING_ERROR",
             5: "SOFT_LIMIT", 6: "HARD_LIMIT", 7: "DAC_SATURATION", 8: "FORCE_LIMIT", 9: "WATCHDOG",
             10: "PROBE"}


def _struct_format(dtype: np.dtype) -> str:
    """A ``struct`` format with the same byte layout as the aligned numpy ``dtype``."""
    codes = {("<u4",): "I", ("<u2",): "H", ("<i4",): "i", ("<i2",): "h", ("<f8",): "d"}
    fmt, offset = "<", 0
    for name in dtype.names:
        field, field_offset = dtype.fields[name][:2]
        if field_offset > offset:
            fmt += f"{field_offset - offset}x"
        base = field.base.str
        count = field.shape[0] if field.shape else 1
        fmt += (str(count) if count > 1 else "") + codes[(base,)]
        offset = field_offset + field.itemsize
    if dtype.itemsize > offset:
        fmt += f"{dtype.itemsize - offset}x"
    return fmt


STATUS_STRUCT = struct.Struct(_struct_format(STATUS_DTYPE))
"""packs a status in one call, field order as in ``STATUS_DTYPE`` (per-axis fields flattened)"""
