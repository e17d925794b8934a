"""The card's reversal (quadrant error) compensation block (cnc_twin.dsp.reversal) against its
definition: a pulse of the set amplitude with the new direction's sign at a reversal of the
commanded velocity, decaying by exp(-dt / T) a tick, through its rise time's low-pass; none at the
first move from rest, at a stop (jerk-limited or not) or on a standing axis's rounding noise; the
lead starts it that long before the velocity's zero, predicted to second order; half of it at a stop and at
the start after it when asked; its height adapted to the acceleration at the reversal when asked."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnc_twin.dsp.reversal import REVERSAL, pulse_height, reversal_pulse, setup_reversal

DT = 2.5e-4  # s, the servo period
SPV = 0.05  # m/s per V


def _block(amplitude=0.004, time=0.02, lead=0.0, rise=0.0, arm_speed=0.0, **more):
    """A block set up with ``more`` of setup_reversal's keywords (standstill, adaptation)."""
    r = np.zeros(1, REVERSAL)
    setup_reversal(r[0], amplitude=amplitude, time=time, lead=lead, rise=rise, arm_speed=arm_speed,
                   counts_per_unit=1e6, speed_per_volt=SPV, dt=DT, **more)
    return r


def _run(r, velocities, accelerations=None, jerks=None, path_on=True):
    """The block's outputs over the ticks; ``path_on``: another axis moves (a contour goes on)."""
    accelerations = np.zeros(len(velocities)) if accelerations is None else accelerations
    jerks = np.zeros(len(velocities)) if jerks is None else jerks
    return np.array([reversal_pulse(r[0], v, a, j, path_on) for v, a, j in zip(velocities, accelerations, jerks)])


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


def test_the_rise_time_low_passes_the_pulse():
    out = _run(_block(rise=0.005), [100.0] + [-100.0] * 400)
    decay, rise = math.exp(-DT / 0.02), 1 - math.exp(-DT / 0.005)
    pulse, shaped = 0.0, []
    for k in range(401):  # the definition, tick by tick
        pulse = -0.004 / SPV if k == 1 else pulse * decay
        shaped.append((shaped[-1] if shaped else 0.0) + rise * (pulse - (shaped[-1] if shaped else 0.0)))
    assert out == pytest.approx(np.array(shaped), rel=1e-12, abs=1e-15)
    assert abs(out).max() < 0.004 / SPV  # a rise takes off the step's height


def test_a_stop_jerk_limited_or_with_the_circle_s_tangent_is_no_reversal_but_a_circle_s_reversal_is():
    lead, jerk = 0.02, 5e6  # s, counts/s^3
    t_left = np.arange(0.2, 0.0, -DT)  # the time left to the stop
    v = jerk * t_left ** 2 / 2  # an S-curve's last phase: v, a, j of (T - t)^2
    assert np.all(_run(_block(lead=lead), v, -jerk * t_left, np.full(len(v), jerk)) == 0.0)
    c = 1e7  # counts/s^4: v ~ (T - t)^3, the circle's end (feed and tangent both going to zero)
    assert np.all(_run(_block(lead=lead), c * t_left ** 3, -3 * c * t_left ** 2, 6 * c * t_left) == 0.0)
    omega, speed = 2.0, 50000.0  # rad/s, counts/s: a circle's axis, reversing at t = 0
    t = np.arange(-0.2, 0.2, DT)
    out = _run(_block(lead=lead), speed * np.cos(omega * t + np.pi / 2) * -1, speed * omega * np.sin(omega * t + np.pi / 2),
               speed * omega ** 2 * np.cos(omega * t + np.pi / 2))
    first = int(np.flatnonzero(out)[0])
    assert t[first] == pytest.approx(-lead, abs=2 * DT)


def test_a_standing_axis_s_rounding_noise_is_no_reversal():
    rng = np.random.default_rng(0)
    r = _block()
    _run(r, [100.0] * 4)  # it moved up, then stands with noise of a floating-point command
    noise = rng.normal(0.0, 1e-8, 4000)
    assert np.all(_run(r, noise, rng.normal(0.0, 1e-5, 4000), rng.normal(0.0, 1e-2, 4000)) == 0.0)
    assert r[0]["count"] == 0


def test_a_start_the_other_way_after_a_standstill_longer_than_twice_the_decay_time_is_no_reversal():
    r = _block(time=0.02)  # patience: 2 x 20 ms = 160 ticks
    assert r[0]["patience"] == 160
    out = _run(r, [30.0] * 10 + [0.0] * 161 + [-30.0] * 10)
    assert np.all(out == 0.0) and r[0]["count"] == 0
    out = _run(r, [0.0] * 160 + [30.0])  # within it: a reversal
    assert out[-1] > 0.0 and r[0]["count"] == 1


def test_a_pulse_fired_ahead_of_a_trapezoid_s_stop_ends_at_the_stop_and_the_direction_stays():
    lead, decel = 0.02, 2e5  # s, counts/s^2: a trapezoid's constant deceleration to rest
    v = np.maximum(decel * np.arange(0.1, 0.0, -DT), 0.0)
    velocities = np.concatenate([v, np.zeros(100)])  # 100 ticks at rest: within the patience (160)
    accelerations = np.concatenate([np.full(len(v), -decel), np.zeros(100)])
    r = _block(lead=lead, rise=0.01)
    out = _run(r, velocities, accelerations)
    fired = int(np.flatnonzero(out)[0])
    assert velocities[fired] == pytest.approx(decel * lead, rel=0.02)  # predicted like a reversal ...
    assert r[0]["count"] == 0 and r[0]["direction"] == 1.0 and r[0]["pending"] == 0.0  # ... and withdrawn
    stop = len(v)
    assert abs(out[stop + 1]) < abs(out[stop - 1])  # at the stop it falls away, with the rise's time constant
    assert abs(out[-1]) < 0.1 * abs(out[stop - 1])  # 25 ms on: e^-2.5 of it
    back = _run(r, [-30.0] * 3)  # the next move the other way, soon after: a reversal from the old direction
    assert back[-1] < 0.0 and r[0]["count"] == 1


def test_a_reversal_counts_only_after_a_move_of_the_arming_speed():
    r = _block(arm_speed=0.005)  # 5 mm/s: 5000 counts/s at 1e6 counts/m
    dither = np.tile(np.concatenate([np.full(40, 900.0), np.full(40, -900.0)]), 20)  # a force loop's turns
    assert np.all(_run(r, dither) == 0.0) and r[0]["count"] == 0
    out = _run(r, [6000.0] * 10 + [-900.0])  # a move at speed, then its turn: a reversal
    assert out[-1] < 0.0 and r[0]["count"] == 1
    _run(r, [900.0] * 10 + [-900.0] * 10)  # slow turns after it: none
    assert r[0]["count"] == 1


def test_with_no_other_axis_moving_a_prediction_does_not_fire_but_the_turn_itself_does():
    lead, decel = 0.02, 2e5
    v = np.maximum(decel * np.arange(0.1, 0.0, -DT), 0.0)  # a single axis's trapezoid stop
    r = _block(lead=lead)
    assert np.all(_run(r, np.concatenate([v, np.zeros(20)]), np.concatenate([np.full(len(v), -decel), np.zeros(20)]),
                       path_on=False) == 0.0)
    out = _run(r, [-500.0, -1000.0], [-decel, -decel], path_on=False)  # then back: the turn itself
    assert out[0] < 0.0 and r[0]["count"] == 1


def _ramp(v0, v1, ticks):
    """Velocities [counts/s] from v0 to v1 over ``ticks`` and their accelerations [counts/s^2]."""
    v = np.linspace(v0, v1, ticks)
    return v, np.full(ticks, (v1 - v0) / ((ticks - 1) * DT))


STILL = dict(standstill=0.5, start_speed=0.3e-3, stop_speed=1e-3)  # m/s: 300 and 1000 counts/s


def test_a_stop_gets_the_share_against_the_motion_and_the_start_after_it_the_share_with_it():
    r = _block(**STILL)
    cruise = _run(r, np.full(20, 5000.0))
    v, a = _ramp(5000.0, 0.0, 200)  # decelerating to rest: 25 counts/s a tick
    stop = _run(r, v, a)
    assert np.all(cruise == 0.0)
    first = np.flatnonzero(stop != 0.0)[0]
    assert v[first] < 1000.0 <= v[first - 1]  # under the stop speed
    assert stop[first] == pytest.approx(-0.5 * 0.004 / SPV)  # half the pulse, against the motion
    rest = _run(r, np.zeros(1200))
    assert abs(rest[-1]) < 1e-6  # decayed at rest (15 time constants)
    v, a = _ramp(0.0, -2000.0, 100)  # a start the other way, after a rest longer than the patience
    start = _run(r, v, a)
    first = np.flatnonzero(np.abs(start) > 1e-6)[0]
    assert v[first] < -300.0 <= v[first - 1]  # past the start speed
    assert start[first] == pytest.approx(-0.5 * 0.004 / SPV)  # half the pulse, with the motion
    assert r[0]["count"] == 0  # neither is a reversal


def test_a_start_the_same_way_after_a_stop_loads_the_friction_again_and_without_the_share_nothing_happens():
    for standstill, expect in ((0.5, 0.5 * 0.004 / SPV), (0.0, 0.0)):
        r = _block(**{**STILL, "standstill": standstill})
        _run(r, np.full(20, 5000.0))
        _run(r, *_ramp(5000.0, 0.0, 200))
        _run(r, np.zeros(400))
        v, a = _ramp(0.0, 2000.0, 100)
        start = _run(r, v, a)
        assert start.max() == pytest.approx(expect, abs=1e-12)


def test_a_slow_axis_that_wobbles_under_the_stop_speed_gets_no_second_pulse_until_it_turns():
    r = _block(**STILL)
    _run(r, np.full(20, 5000.0))
    _run(r, *_ramp(5000.0, 800.0, 100))  # the stop's pulse at 1000 counts/s
    assert r[0]["unloaded"] == 1
    pulse = r[0]["pulse"]
    wobble = np.array([800.0, 700.0, 750.0, 600.0, 650.0] * 4)  # faster again, above the start speed
    out = _run(r, wobble, np.gradient(wobble) / DT)
    assert np.all(np.diff(np.abs(out)) <= 1e-12) and r[0]["pulse"] == pytest.approx(pulse * r[0]["decay"] ** 20)
    v, a = _ramp(600.0, -1000.0, 50)  # it turns: the start's half, the other way
    out = _run(r, v, a)
    assert out[np.flatnonzero(v < -300.0)[0]] == pytest.approx(-0.5 * 0.004 / SPV)


def test_a_stop_at_a_reversal_predicted_ahead_is_the_stop_s_share():
    r = _block(lead=0.01, **STILL)
    t = np.arange(200) * DT
    v0, acc = 4000.0, -400000.0  # a trapezoid's deceleration: the prediction crosses zero ahead
    v = np.concatenate([np.full(20, v0), np.maximum(v0 + acc * t, 0.0)])
    out = _run(r, v, np.concatenate([np.zeros(20), np.where(v[20:] > 0, acc, 0.0)]))
    stop = np.flatnonzero(v == 0.0)[0]
    fired = np.flatnonzero(out != 0.0)[0]
    assert fired <= 22 and out[fired] == pytest.approx(-0.004 / SPV)  # fired ahead as a reversal
    assert r[0]["pending"] == 0.0 and r[0]["direction"] == 1.0
    # the stop: its share, against the motion (and its first tick's decay)
    assert out[stop] == pytest.approx(-0.5 * 0.004 / SPV * math.exp(-DT / 0.02))
    assert r[0]["count"] == 0 and r[0]["unloaded"] == 2


def test_the_adaptation_goes_linearly_from_the_amplitude_to_its_own_between_two_accelerations_held_beyond():
    r = _block(amplitude=0.004, adapt_amplitude=0.006, adapt_from=0.05, adapt_to=0.2)[0]  # m/s, m/s^2, m/s^2
    height = {a: pulse_height(r, a * 1e6) * SPV for a in (0.0, 0.05, 0.125, 0.2, 0.9)}  # [m/s] at a [m/s^2]
    assert height[0.0] == pytest.approx(0.004) and height[0.05] == pytest.approx(0.004)
    assert height[0.125] == pytest.approx(0.005)  # half-way
    assert height[0.2] == pytest.approx(0.006) and height[0.9] == pytest.approx(0.006)  # held, not extrapolated
    assert pulse_height(r, -0.125e6) == pulse_height(r, 0.125e6)
    plain = _block(amplitude=0.004)[0]
    assert pulse_height(plain, 3e6) == plain["amplitude"]  # none: the amplitude at every acceleration
    v = np.linspace(1000.0, -1000.0, 9)  # a reversal at 0.125 m/s^2 (125000 counts/s^2)
    block = _block(amplitude=0.004, adapt_amplitude=0.006, adapt_from=0.05, adapt_to=0.2)
    _run(block, np.full(10, 1000.0))  # a move first: the reversal's direction
    out = _run(block, v, np.full(len(v), -125000.0))
    assert out[np.flatnonzero(out != 0.0)[0]] == pytest.approx(-0.005 / SPV)


def test_an_adaptation_without_two_accelerations_in_order_is_refused():
    with pytest.raises(ValueError):
        _block(adapt_amplitude=0.006, adapt_from=0.2, adapt_to=0.2)
