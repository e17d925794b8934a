"""The card's reversal (quadrant error) compensation block (cnc_twin.dsp.reversal) against its
definition: a pulse of the set amplitude with the new direction's sign at a reversal of the
commanded velocity, decaying by exp(-dt / T) a tick; none at the first move from rest or at a
stop; the lead starts it that long before the velocity's zero, predicted from the acceleration."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnc_twin.dsp.reversal import REVERSAL, reversal_pulse, setup_reversal

DT = 2.5e-4  # s, the servo period
SPV = 0.05  # m/s per V


def _block(amplitude=0.004, time=0.02, lead=0.0):
    r = np.zeros(1, REVERSAL)
    setup_reversal(r[0], amplitude=amplitude, time=time, lead=lead, speed_per_volt=SPV, dt=DT)
    return r


def _run(r, velocities, accelerations=None):
    accelerations = np.zeros(len(velocities)) if accelerations is None else accelerations
    return np.array([reversal_pulse(r[0], v, a) for v, a in zip(velocities, accelerations)])


def test_a_reversal_gives_the_pulse_in_volts_with_the_new_sign_decaying_with_the_time_constant():
    r = _block(amplitude=0.004, time=0.02)
    out = _run(r, [100.0] * 5 + [-100.0] * 200)
    assert np.all(out[:5] == 0.0)
    assert out[5] == pytest.approx(-0.004 / SPV)  # 0.08 V, negative: the new direction
    decay = math.exp(-DT / 0.02)
    assert out[6:] == pytest.approx(out[5] * decay ** np.arange(1, 200), rel=1e-12)
    assert out[5 + 80] == pytest.approx(out[5] * math.exp(-1.0), rel=1e-9)  # one time constant: 80 ticks
    assert r[0]["count"] == 1
    back = _run(r, [50.0])  # and back the other way
    assert back[0] == pytest.approx(+0.004 / SPV) and r[0]["count"] == 2


def test_the_first_move_from_rest_and_a_stop_are_no_reversal_and_a_pause_keeps_the_direction():
    r = _block()
    out = _run(r, [0.0] * 10 + [30.0] * 10 + [0.0] * 50 + [40.0] * 10)
    assert np.all(out == 0.0) and r[0]["count"] == 0  # rest, move, stop, move on the same way
    out = _run(r, [0.0] * 20 + [-10.0])  # a pause, then the other way: a reversal
    assert np.all(out[:20] == 0.0) and out[20] < 0.0 and r[0]["count"] == 1


def test_the_lead_starts_the_pulse_when_the_predicted_velocity_crosses_zero():
    # v(t) = v0 - a t: zero at t0 = v0 / a; with lead L the pulse starts at t0 - L
    v0, a, lead = 1000.0, 20000.0, 0.01  # counts/s, counts/s^2, s
    t = np.arange(400) * DT
    v = v0 - a * t
    out = _run(_block(lead=lead), v, np.full(len(t), -a))
    first = int(np.flatnonzero(out)[0])
    assert t[first] == pytest.approx(v0 / a - lead, abs=1.5 * DT)  # the first tick past the zero
    assert int(np.flatnonzero(_run(_block(), v, np.full(len(t), -a)))[0]) * DT == pytest.approx(v0 / a, abs=1.5 * DT)


@pytest.mark.parametrize("amplitude, time", [(0.0, 0.02), (0.004, 0.0)])
def test_zero_amplitude_or_time_is_off(amplitude, time):
    r = _block(amplitude=amplitude, time=time)
    assert np.all(_run(r, [10.0, -10.0, 10.0, -10.0]) == 0.0)


def test_a_negative_setting_is_refused():
    with pytest.raises(ValueError):
        _block(amplitude=-1.0)
