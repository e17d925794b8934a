"""The drive's actual speed (cnc_twin/machine/amplifier.py: feedback_speed): its filter against the
analytic first-order lag, its quantised feedback against the counts it differences, and the
linearised machine with the filter against the nonlinear plant.

References: a first-order lag's step response ``1 - exp(-t / T)`` at the sampling instants
(``T = 1 / (2 pi f)``, f the drive's velocity-feedback bandwidth; Beckhoff's AX2000 defaults to
600 Hz); the count arithmetic of an incremental encoder; the nonlinear MuJoCo plant stepped with
the amplifiers' own code.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnc_twin import load_scenario
from cnc_twin.core.config import DriveConfig
from cnc_twin.machine import amplifier, plant
from cnc_twin.scenario.resources import scenarios_dir

DT = 0.00025


def _amp(*, speed_filter: float = 0.0, counts: int = 0, scale: float = 1.0) -> np.ndarray:
    """One amplifier's record reading qpos[0] / qvel[0] with the axis ``scale`` [axis unit / motor rad]."""
    taps = np.zeros(1, plant.ENCODER_TAP)
    taps["scale"] = scale
    drive = DriveConfig(speed_per_volt=0.05, kp=1e3, tn=0.0, current_bandwidth=1000.0, force_limit=1e4,
                        speed_filter=speed_filter, feedback_counts=counts)
    return amplifier.setup_amps([drive], taps, DT)


def _measure(amp: np.ndarray, speeds: np.ndarray) -> np.ndarray:
    """The actual speeds the drive reads while the motor turns at ``speeds`` [rad/s], one per step
    (MuJoCo's step: the position advances by dt times the step's speed), from rest at 0."""
    qpos, qvel = np.zeros(1), np.zeros(1)
    out = np.empty(len(speeds))
    amplifier.feedback_speed(amp[0], qpos, qvel)  # at rest: the feedback's first read
    for k, w in enumerate(speeds):
        qvel[0] = w
        qpos[0] += DT * w
        out[k] = amplifier.feedback_speed(amp[0], qpos, qvel)
    return out


def test_without_filter_or_quantisation_the_drive_reads_the_exact_speed():
    speeds = np.random.default_rng(1).uniform(-30, 30, 200)
    assert np.array_equal(_measure(_amp(), speeds), speeds)


@pytest.mark.parametrize("frequency", [600.0, 150.0])
def test_the_speed_filter_answers_a_speed_step_as_a_first_order_lag(frequency):
    """A speed step of 10 rad/s: at every step k the filtered speed is the lag's 1 - exp(-k dt / T)."""
    k = np.arange(1, 41)
    measured = _measure(_amp(speed_filter=frequency), np.full(k.size, 10.0))
    analytic = 10.0 * (1.0 - np.exp(-2.0 * math.pi * frequency * k * DT))
    assert measured == pytest.approx(analytic, rel=1e-9, abs=1e-9)
    assert measured[0] < 0.7 * 10.0  # really a lag: the first step reads 61 % (600 Hz) or 21 % (150 Hz)


def test_quantised_feedback_reads_whole_counts_and_averages_to_the_speed():
    """10000 counts per revolution, the motor at 2.3 counts per step: every step reads 2 or 3 counts'
    worth of speed; over the run the counts add up to the distance, so the mean speed is the
    motor's within one count over the whole time."""
    counts = 10000
    per_count = 2.0 * math.pi / counts  # [rad]
    speed = 2.3 * per_count / DT
    measured = _measure(_amp(counts=counts), np.full(400, speed))
    steps = measured * DT / per_count
    assert set(np.round(steps, 9)) == {2.0, 3.0}
    assert abs(measured.mean() - speed) <= per_count / (400 * DT)


def test_the_linear_machine_with_the_speed_filter_is_the_nonlinear_plants_response():
    """Y's drive with a 150 Hz speed filter, its loop closed: a 20 mV step, 60 ms. The linear
    model (linearize.machine_loop, the filter a state of its own) and the nonlinear plant
    (amplifier.drive_amps before every MuJoCo step; the model as it is linearised: no Coulomb
    friction, no limits) give the same motor speed within 1 % of its peak; the same loop without the
    filter differs from it by far more (so the filter is what both see)."""
    from cnc_twin.studies.linearize import linear_plant, machine_loop

    def responses(speed_filter: float) -> tuple[np.ndarray, np.ndarray]:
        scenario = load_scenario(scenarios_dir() / "jog_axes.yaml",
                                 overrides={"axes.Y.drive.speed_filter": speed_filter})
        p = linear_plant(scenario)
        M, N, speed = machine_loop(p, "Y")
        x = np.zeros(M.shape[0])
        n, volts = 240, np.zeros(6)
        volts[1] = 0.02
        linear, nonlinear = np.empty(n), np.empty(n)
        tap = p.motor_taps[1]
        p.apply_volts(volts)
        for k in range(n):
            x = M @ x + N[:, 0] * 0.02
            linear[k] = speed @ x
            p.step(1)
            nonlinear[k] = p.data.qvel[tap["dof_adr"]] * tap["scale"]
        return linear, nonlinear

    linear, nonlinear = responses(150.0)
    peak = np.abs(nonlinear).max()
    assert peak > 0.0
    assert np.abs(linear - nonlinear).max() <= 0.01 * peak
    unfiltered, _ = responses(0.0)
    assert np.abs(unfiltered - nonlinear).max() > 0.05 * peak


@pytest.mark.parametrize("time_constant", [0.001, 0.0004])
def test_the_torque_filter_answers_a_speed_error_step_as_a_first_order_lag(time_constant):
    """The drive's torque reference filter (Yaskawa's Pn401, factory setting 1.00 ms): a constant
    speed error through a P-only loop gives kp e (1 - exp(-k dt / tf)) at step k, the analytic
    first-order lag sampled exactly."""
    taps = np.zeros(1, plant.ENCODER_TAP)
    taps["scale"] = 1.0
    drive = DriveConfig(speed_per_volt=0.05, kp=1e3, tn=0.0, current_bandwidth=1000.0, force_limit=1e4,
                        torque_filter=time_constant)
    amp = amplifier.setup_amps([drive], taps, DT)[0]
    k = np.arange(1, 41)
    forces = np.array([amplifier.amp_force(amp, 1.0, 0.0) for _ in k])  # 1 V: 0.05 m/s of error
    analytic = 1e3 * 0.05 * (1.0 - np.exp(-k * DT / time_constant))
    assert forces == pytest.approx(analytic, rel=1e-9)
    assert forces[0] < 0.5 * 50.0  # really a lag: the first step gives 22 % (1 ms) or 46 % (0.4 ms)
