"""The card's fault supervisor (cnc_twin.dsp.supervisor.supervise) against its definition in the
module's table: a following error |command - actual| over the axis's limit trips FOLLOWING_ERROR
on that axis, whichever way the axis lags; at the limit itself nothing trips; a limit of 0 is off."""

from __future__ import annotations

import numpy as np
import pytest

from cnc_twin.dsp.supervisor import LIMITS, SUPERVISOR, supervise
from cnc_twin.whiteboard.status import FaultCode

N = 3
LIMIT = 3000.0  # counts (3 mm at 1 um per count)


def _check(command, actual, limits=(LIMIT, LIMIT, LIMIT)):
    settings = np.zeros(1, SUPERVISOR)[0]
    records = np.zeros(N, LIMITS)
    records["ferr_limit"] = limits
    records["soft_lo"], records["soft_hi"] = -np.inf, np.inf
    code, axis = supervise(settings, records, np.asarray(command, dtype=np.float64),
                           np.asarray(actual, dtype=np.float64), np.zeros(N, np.int64), np.zeros(0, np.int64), 0.0)
    return int(code), int(axis)


@pytest.mark.parametrize("sign", [1.0, -1.0])
@pytest.mark.parametrize("axis", range(N))
def test_a_following_error_over_the_limit_trips_on_its_axis_either_way(axis, sign):
    command = np.full(N, 1000.0)
    at, over = command.copy(), command.copy()
    at[axis] -= sign * LIMIT
    over[axis] -= sign * (LIMIT + 1.0)
    assert _check(command, at) == (0, -1)  # at the limit: nothing
    assert _check(command, over) == (FaultCode.FOLLOWING_ERROR, axis)


def test_a_limit_of_zero_is_off():
    assert _check([0.0, 0.0, 0.0], [1e6, -1e6, 5e5], limits=(0.0, 0.0, 0.0)) == (0, -1)
