"""The card's leadscrew compensations, per axis: a pitch-error table and backlash, as LinuxCNC's
motion controller applies its ``[JOINT_n]`` ``COMP_FILE`` / ``COMP_FILE_TYPE`` and ``BACKLASH``.

Each servo tick the position loop is told the fine command plus a correction [counts]::

    direction   +1 while the period's command moves up, -1 while it moves down, held while it
                stands: |velocity| <= REST_SPEED (cnc_twin.dsp.reversal's: a standing axis's
                rounding noise is no motion); 0 before the first move
    target      the table's trim at the command, its forward column going up, its reverse
                column going down (their mean before the first move), linearly interpolated
                between the table's nominal positions and held beyond its ends;
                plus backlash / 2 x direction
    correction  moves towards the target by at most ``step`` counts a tick, so a reversal's
                jump does not kick the drive

A trim is nominal - actual: how much more the axis must be told to be where the nominal
position says (the file's second and third columns are those trims with ``COMP_FILE_TYPE = 1``,
the positions reached going forward / in reverse with ``COMP_FILE_TYPE = 0``; the scenario's
reader converts). The trace keeps the fine command itself, so its following error shows the
correction the card added.

:data:`COMP` is one axis's record, its table an array beside it; :func:`comp_correction` is the block (plain, compiled with numba
from this source for every path that runs the servo).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from cnc_twin.core.axis_config import COMP_MAX_POINTS as MAX_POINTS
from cnc_twin.dsp.reversal import REST_SPEED

COMP = np.dtype([("points", np.int64), ("backlash", np.float64), ("step", np.float64),
                 ("direction", np.float64), ("correction", np.float64)])
"""One axis's compensation; its table is an array of its own (:data:`TABLE_ROWS` x
:data:`~cnc_twin.core.axis_config.COMP_MAX_POINTS`, see :func:`setup_comp`), kept out of the
record so the compiled servo's records stay small (a 6 KB record per axis doubled numba's
compile time):

==========  ======  ===========================================================
field       unit    meaning
==========  ======  ===========================================================
points      -       table rows in use (0: no table)
backlash    counts  the backlash (0: none)
step        counts  the most the correction changes in a tick
direction   -       +1 / -1 / 0 (see the module docstring), state
correction  counts  the correction applied last tick, state
==========  ======  ===========================================================
"""
TABLE_ROWS = 3
"""a table's rows: nominal positions [counts] (increasing), forward trims, reverse trims [counts]"""


def setup_comp(c, table, *, nominal=(), forward=(), reverse=(), backlash: float = 0.0, step: float = np.inf) -> None:
    """Fill ``c`` (a :data:`COMP` record) and ``table`` (shape ``(TABLE_ROWS, MAX_POINTS)``) in
    counts and clear the state. ValueError for a table longer than
    :data:`~cnc_twin.core.axis_config.COMP_MAX_POINTS`, of unequal columns, or whose nominal
    positions do not increase."""
    nominal, forward, reverse = (np.asarray(v, dtype=np.float64) for v in (nominal, forward, reverse))
    if not len(nominal) == len(forward) == len(reverse):
        raise ValueError("the table's columns differ in length")
    if len(nominal) > MAX_POINTS:
        raise ValueError(f"at most {MAX_POINTS} rows, got {len(nominal)}")
    if len(nominal) > 1 and not np.all(np.diff(nominal) > 0):
        raise ValueError("the nominal positions must increase")
    c["points"] = len(nominal)
    table[:] = 0.0
    for row, values in enumerate((nominal, forward, reverse)):
        table[row, :len(values)] = values
    c["backlash"], c["step"] = backlash, step
    reset_comp(c)


def reset_comp(c) -> None:
    """The state at power-on: no direction known, no correction applied."""
    c["direction"] = 0.0
    c["correction"] = 0.0


@njit(cache=True)
def table_trim(nominal, column, n, position):
    """The trim at ``position`` [counts] from ``column`` against ``nominal`` (their first ``n``
    entries): linear between rows, held beyond the ends."""
    if position <= nominal[0]:
        return column[0]
    if position >= nominal[n - 1]:
        return column[n - 1]
    lo, hi = 0, n - 1
    while hi - lo > 1:  # bisection: the row below position
        mid = (lo + hi) // 2
        if nominal[mid] <= position:
            lo = mid
        else:
            hi = mid
    t = (position - nominal[lo]) / (nominal[hi] - nominal[lo])
    return column[lo] + t * (column[hi] - column[lo])


@njit(cache=True)
def comp_correction(c, table, command, velocity):
    """The correction [counts] to add to ``command`` [counts] this tick, ``velocity`` the period's
    commanded velocity [counts/s] (its sign is the direction); advances ``c`` (a :data:`COMP`);
    ``table``: its rows (:data:`TABLE_ROWS`, see :func:`setup_comp`)."""
    n = c.points
    if n == 0 and c.backlash == 0.0:
        return 0.0
    if velocity > REST_SPEED:
        c.direction = 1.0
    elif velocity < -REST_SPEED:
        c.direction = -1.0
    target = 0.5 * c.backlash * c.direction
    if n > 0:
        if c.direction > 0.0:
            target += table_trim(table[0], table[1], n, command)
        elif c.direction < 0.0:
            target += table_trim(table[0], table[2], n, command)
        else:
            target += 0.5 * (table_trim(table[0], table[1], n, command) + table_trim(table[0], table[2], n, command))
    change = target - c.correction
    if change > c.step:
        change = c.step
    elif change < -c.step:
        change = -c.step
    c.correction += change
    return c.correction
