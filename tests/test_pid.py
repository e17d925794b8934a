"""Position loop: gain conversion to volts per count, feed-forward, anti-windup, clamp."""

from __future__ import annotations

import math

import pytest

from cnc_twin.dsp.pid import new_pid, pid_update

SPV = 0.05      # m/s per V
CPU = 1e6       # counts per m
DT = 0.00025


class loop:
    """A position loop's record with ``update`` calling :func:`pid_update` on it."""

    def __init__(self, **gains):
        self.record = new_pid(speed_per_volt=SPV, counts_per_unit=CPU, dt=DT, **gains)

    def update(self, command, feedback, velocity, acceleration) -> float:
        return pid_update(self.record, command, feedback, velocity, acceleration)

    @property
    def integrator(self) -> float:
        return float(self.record["integrator"])


def test_kp_is_speed_per_unit_error():
    """kp = 40/s and 1 mm of error ask for 40 mm/s, i.e. 0.8 V at 0.05 m/s/V."""
    assert loop(kp=40.0).update(1000.0, 0.0, 0.0, 0.0) == pytest.approx(0.04 / SPV)


def test_velocity_feed_forward_gives_commanded_speed():
    """kvff = 1 turns a commanded 0.2 m/s into exactly the voltage for 0.2 m/s."""
    u = loop(kp=0.0, kvff=1.0).update(0.0, 0.0, 0.2 * CPU, 0.0)
    assert u * SPV == pytest.approx(0.2)


def test_acceleration_feed_forward():
    u = loop(kp=0.0, kaff=0.002).update(0.0, 0.0, 0.0, 2.0 * CPU)
    assert u * SPV == pytest.approx(0.004)


def test_the_acceleration_feed_forward_through_its_high_pass_fades_with_the_washout_time():
    """A lasting acceleration: kaff a exp(-t / washout), the drive's integral taking it over (the
    inverse of a PI speed loop); the high-pass's discrete step is exp(-dt / washout) per tick."""
    kaff, washout, a = 0.004, 0.02, 2.0 * CPU
    pid = loop(kp=0.0, kaff=kaff, aff_washout=washout)
    for k in range(1, 401):  # 0.1 s = 5 washout times
        u = pid.update(0.0, 0.0, 0.0, a)
        assert u * SPV == pytest.approx(kaff * 2.0 * math.exp(-k * DT / washout), rel=1e-9)


def test_the_command_the_loop_compares_with_lags_by_the_equivalent_time():
    """A 1000-count step of the command: the loop sees the first-order lag 1000 (1 - exp(-t / T))
    of it from the tick after the first (which takes the command as it is)."""
    kp, lag = 40.0, 0.002
    pid = loop(kp=kp, ff_equivalent_time=lag)
    assert pid.update(0.0, 0.0, 0.0, 0.0) == 0.0  # the first tick: the reference is the command
    for k in range(1, 41):
        u = pid.update(1000.0, 0.0, 0.0, 0.0)
        seen = 1000.0 * (1.0 - math.exp(-k * DT / lag))
        assert u * SPV * CPU == pytest.approx(kp * seen, rel=1e-9)


def test_without_the_lag_the_loop_compares_with_the_command_itself():
    pid = loop(kp=40.0)
    pid.update(0.0, 0.0, 0.0, 0.0)
    assert pid.update(1000.0, 0.0, 0.0, 0.0) * SPV * CPU == pytest.approx(40.0 * 1000.0)


def test_integrator_accumulates_error_over_time():
    pid = loop(kp=0.0, ki=400.0, integrator_limit=10.0)
    for _ in range(400):  # 0.1 s of 10 counts error
        u = pid.update(10.0, 0.0, 0.0, 0.0)
    assert u * SPV * 1e6 == pytest.approx(400.0 * 10 * 0.1 / 1e6 * 1e6, rel=1e-9)  # ki * e * t [counts/s]


def test_output_clamped():
    pid = loop(kp=40.0, output_limit=10.0)
    assert pid.update(1e9, 0.0, 0.0, 0.0) == 10.0
    assert pid.update(-1e9, 0.0, 0.0, 0.0) == -10.0


def test_anti_windup_integrator_does_not_grow_while_saturated():
    pid = loop(kp=40.0, ki=400.0, output_limit=10.0, integrator_limit=5.0)
    for _ in range(4000):  # 1 s of huge error with the output pinned at the limit
        assert pid.update(1e6, 0.0, 0.0, 0.0) == 10.0
    assert pid.integrator == pytest.approx(0.0)
    # As soon as the error reverses the loop responds without unwinding a stored integral.
    assert pid.update(-100.0, 0.0, 0.0, 0.0) < 0.0


def test_integrator_clamped_to_its_limit():
    pid = loop(kp=0.0, ki=1e4, integrator_limit=2.0)
    for _ in range(10000):
        pid.update(100.0, 0.0, 0.0, 0.0)
    assert pid.integrator == pytest.approx(2.0)


def test_derivative_acts_on_error_rate():
    pid = loop(kp=0.0, kd=1.0)
    pid.update(0.0, 0.0, 0.0, 0.0)
    u = pid.update(10.0, 0.0, 0.0, 0.0)  # error rate 10 counts per tick = 40000 counts/s
    assert u * SPV == pytest.approx(10 / DT / CPU)
