"""The servo task's recorder frame: which values it holds, in which order.

Its own module, with no numba: the trace's layout and the recording process need the names
without compiling or loading the card's kernels (importing :mod:`cnc_twin.dsp.servo` costs
0.3 - 0.4 s, numba's start).
"""

from __future__ import annotations

FRAME_FIELDS = ("command", "actual", "dac")
"""per-axis groups in :attr:`~cnc_twin.dsp.servo.ServoTask.frame`, each 6 wide, followed by one
force value"""
PERIOD_FIELDS = ("state", "fault", "fifo_fill", "feed_override", "missed_exchanges", "records_rejected",
                 "last_seq_executed", "path_u", "path_ds", "force_state", "force_setpoint", "force_depth",
                 "feed_factor", "mark", "events")
"""per-period values after the force in :attr:`~cnc_twin.dsp.servo.ServoTask.frame`, written once
per period"""
