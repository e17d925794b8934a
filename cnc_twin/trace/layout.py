"""The trace's layout: what a run records per servo tick and per interpolation period.

Each signal is kept at its natural width and rate (:data:`TICK_BYTES` per tick,
:data:`PERIOD_DTYPE` per period); ``time``, ``period``, ``ferr`` and the per-tick view of the
per-period signals are computed when asked for (:class:`~cnc_twin.trace.trace.Trace`). Columns,
per axis ``X Y Z A B C``:

=====================  ======  ===========================================================
column                 unit    meaning
=====================  ======  ===========================================================
``time``               s       simulated time at which the tick sampled its inputs
``period``             -       interpolation period counter
``command_<axis>``     counts  fine-interpolated position command
``actual_<axis>``      counts  encoder position (32-bit extended QEP)
``ferr_<axis>``        counts  following error, command - actual
``dac_<axis>``         code    DAC code, -2048..2047 (x 10/2048 V); with ``command_output:
                               pulse``, the step pulses sent in the tick (signed)
``pad_force``          N       load cell through the ADC, tared at servo-on
``state``              -       controller state (0 IDLE, 1 RUNNING, 2 FEED_HOLD, 3 STOPPING,
                               4 FAULT, 5 FINISHED), per interpolation period
``fault``              -       fault code (0 none, else :class:`~cnc_twin.whiteboard.status.FaultCode`)
``fifo_fill``          words   command FIFO fill after the period's exchange
``feed_override``      -       effective feed scale of the running move (0 while held)
``missed_exchanges``   -       periods so far whose exchange the planner missed (real-time mode)
``records_rejected``   -       records rejected so far (CRC, framing, sequence)
``last_seq_executed``  -       sequence number of the last record executed
``path_u``             -       NURBS parameter at the period's end (-1 when not on a curve)
``path_ds``            m       arc length commanded along the curve in the period
``force_state``        -       force loop (0 OFF, 1 SEEK, 2 RAMP, 3 TRACK, 4 RAMP_DOWN, 5 RETRACT)
``force_setpoint``     N       force setpoint in effect in the period
``force_depth``        m       force loop's push along the tool axis (negative: standing off)
``feed_factor``        -       feed adaptation factor (1, or reduced while the force error is large)
``mark``               -       number of the last Mark record executed (0 before any)
``events``             -       motion-chip events raised in the period: bits ``event << 4 axis``
                               (1 motion done, 2 home found, 4 + limit, 8 - limit; :mod:`cnc_twin.dsp.chip`)
``tip_x`` ..           m       the machine's side, per period: the tool tip where it really is (pad face
``tip_z``                      centre, pad undeflected), world frame, from MuJoCo's kinematics at the
                               period's last tick (when ``actual`` sampled the encoders): every joint of
                               the machine moves it, the screws' and gears' windup and the structure's
                               modes too, which the encoders on the motors do not see
``pivot_x`` ..         m       the head's pivot (A/B axes' crossing) likewise; tip and pivot give the
``pivot_z``                    tool's true axis positions (:meth:`~cnc_twin.geometry.kinematics.HeadGeometry.axes_from_pose`)
=====================  ======  ===========================================================
"""

from __future__ import annotations

import numpy as np

from cnc_twin.dsp.frame import PERIOD_FIELDS

FLOAT_PERIOD_FIELDS = ("feed_override", "path_u", "path_ds", "force_setpoint", "force_depth", "feed_factor")
"""per-period fields kept as float64 (the others are integers)"""
INT8_PERIOD_FIELDS = ("state", "fault", "force_state")
"""per-period fields kept as int8 (the other integers as int32)"""
PERIOD_DTYPE = np.dtype([(name, np.float64 if name in FLOAT_PERIOD_FIELDS else
                          np.int8 if name in INT8_PERIOD_FIELDS else np.int32) for name in PERIOD_FIELDS])
"""one interpolation period's signals, packed, each at its natural width (75 bytes)"""
TOOL_FIELDS = ("tip_x", "tip_y", "tip_z", "pivot_x", "pivot_y", "pivot_z")
"""the tool's true pose recorded per period, float64 [m] (``tool`` of
:class:`~cnc_twin.trace.recorder.Recorder`)"""
TOOL_BYTES = len(TOOL_FIELDS) * 8
"""one period's tool pose [bytes]"""
TICK_BYTES = 6 * 8 + 6 * 4 + 6 * 2 + 8
"""one servo tick's signals: command float64 x6, actual int32 x6, DAC code int16 x6, force float64"""


def raw_bytes(ticks: int, periods: int) -> int:
    """The raw bytes of ``ticks`` servo ticks' and ``periods`` periods' recorded signals:
    :data:`TICK_BYTES` a tick, one :data:`PERIOD_DTYPE` and :data:`TOOL_BYTES` a period."""
    return ticks * TICK_BYTES + periods * (PERIOD_DTYPE.itemsize + TOOL_BYTES)

UNITS = {"time": "s", "period": "1", "command": "counts", "actual": "counts", "ferr": "counts",
         "dac": "code", "pad_force": "N", "state": "1", "fault": "1", "fifo_fill": "words",
         "feed_override": "1", "missed_exchanges": "1", "records_rejected": "1", "last_seq_executed": "1",
         "path_u": "1", "path_ds": "m", "force_state": "1", "force_setpoint": "N", "force_depth": "m",
         "feed_factor": "1", "mark": "1", "events": "1", "tip": "m", "pivot": "m"}
"""the unit of each column (by its name, or the name's prefix before ``_<axis>``)"""


def column_unit(name: str) -> str:
    """The unit of the trace column ``name`` (``UNITS``: by its name, else its prefix)."""
    return UNITS[name] if name in UNITS else UNITS[name.split("_")[0]]
