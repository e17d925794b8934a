"""Step/direction pulse output on the card and the amplifiers in position mode."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from cnc_twin.core.config import AxisConfig
from cnc_twin.machine.drive import INPUT_LIMIT, PositionModeDrive
from cnc_twin.dsp.step_output import StepGenerator
from cnc_twin.core.errors import ScenarioError
from cnc_twin.scenario.load import load_scenario
from conftest import REPO

AXIS = AxisConfig(name="X", rotary=False, max_velocity=0.4, max_acceleration=2.0, max_jerk=50.0,
                  counts_per_unit=1e6, kp=40.0, ki=0.0, kd=0.0, kvff=1.0, kaff=0.0, output_limit=10.0,
                  integrator_limit=3.0, travel=(-0.4, 0.4), speed_per_volt=0.05,
                  drive_position_gain=80.0, drive_velocity_ff=1.0, drive_ff_filter=1e-3)


@given(st.lists(st.floats(-1e6, 1e6), min_size=1, max_size=200))
def test_pulses_follow_the_command_to_the_nearest_count(commands):
    gen = StepGenerator(1e12, 0.25e-3)  # no effective limit
    total = 0
    for c in commands:
        total += gen.emit(c)
        assert total == gen.emitted == np.floor(c + 0.5)
    assert gen.limited_ticks == 0


def test_the_rate_limit_holds_pulses_back_without_losing_any():
    gen = StepGenerator(100e3, 0.25e-3)  # 25 pulses per tick
    assert gen.max_per_tick == 25
    sent = [gen.emit(1000.0) for _ in range(40)]
    assert sent == [25] * 40
    assert gen.limited_ticks == 39  # the 40th tick owed exactly 25: at the limit, not beyond it
    assert gen.emitted == 1000
    assert gen.emit(1000.0) == 0
    back = [gen.emit(-10.0) for _ in range(45)]
    assert min(back) == -25 and gen.emitted == -10 and sum(back) == -1010


def test_a_rate_limit_below_one_pulse_per_tick_is_refused():
    with pytest.raises(ValueError, match="allows no pulse"):
        StepGenerator(1000.0, 0.25e-3)


def test_the_drive_counts_pulses_and_closes_its_position_loop():
    tick = 0.25e-3
    drive = PositionModeDrive(AXIS, tick=tick, power_on=0.0)
    # 10 pulses, axis still at 0: error 10 counts -> Kp e / cpu / spv, plus the filtered rate
    volts = drive.update(10, 0.0)
    alpha = tick / (tick + 1e-3)
    expected = 80.0 * 10 / 1e6 / 0.05 + 1.0 * (10 / tick) * alpha / 1e6 / 0.05
    assert drive.command == 10
    assert volts == pytest.approx(expected, rel=1e-12)
    # at the commanded position with no new pulses, only the decaying feed-forward is left
    volts = drive.update(0, 10.5e-6)
    assert volts == pytest.approx(1.0 * (10 / tick) * alpha * (1 - alpha) / 1e6 / 0.05, rel=1e-12)


def test_the_drive_input_is_clamped_like_the_analog_input():
    drive = PositionModeDrive(AXIS, tick=0.25e-3, power_on=0.0)
    assert drive.update(100000, 0.0) == INPUT_LIMIT
    assert drive.update(-300000, 0.0) == -INPUT_LIMIT


def test_without_feed_forward_the_drive_is_a_pure_position_loop():
    axis = dataclasses.replace(AXIS, drive_velocity_ff=0.0)
    drive = PositionModeDrive(axis, tick=0.25e-3, power_on=0.0)
    assert drive.update(7, 0.0) == pytest.approx(80.0 * 7 / 1e6 / 0.05)


def test_pulse_output_refuses_axis_speeds_beyond_the_pulse_rate():
    scenarios_dir = REPO / "scenarios"
    with pytest.raises(ScenarioError, match=r"axes\.X\.pulse\.max_rate.*needs 400 kHz.*limit is 100 kHz"):
        load_scenario(scenarios_dir / "jog_axes.yaml",
                      overrides={"command_output": "pulse", "axes.X.pulse.max_rate": 100})
    # analog output does not care
    load_scenario(scenarios_dir / "jog_axes.yaml", overrides={"axes.X.pulse.max_rate": 100})
