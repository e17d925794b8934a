"""Loops designed on the measured mechanics (cnc_twin/studies/drive_tuning.py): margins against
python-control's, the loops composed on a response against the full linearised machine's, and
`cnc-twin tune` on the compliant machine landing where real ball-screw position loops are.

References: python-control's ``stability_margins`` (an outside implementation of the margins);
the linearised machine (:func:`~cnc_twin.studies.linearize.analyse`: the card's PID on MuJoCo's
transition matrices with every drive's loops closed), a derivation independent of the
composition from a frequency response; the achievable range of the issue's machine-dynamics
reference (position loops of 30-70 1/s on ball-screw axes of this size).
"""

from __future__ import annotations

import re
import warnings

import control
import numpy as np
import pytest

from cnc_twin import load_scenario
from cnc_twin.scenario.resources import scenarios_dir
from cnc_twin.studies import drive_tuning
from cnc_twin.studies.commissioning import model_mechanics, measure_mechanics
from cnc_twin.studies.linearize import analyse

COMPLIANT = scenarios_dir() / "jog_axes.yaml"


@pytest.fixture(scope="module")
def compliant():
    return load_scenario(COMPLIANT)


def test_the_margins_are_python_controls_on_a_loop_that_crosses_once():
    dt = 0.00025
    # a mass and damper behind a one-sample delay
    loop = control.sample_system(control.tf([2000.0], [1.0, 60.0, 0.0]), dt) * control.tf([1.0], [1.0, 0.0], dt)
    f = np.linspace(0.01, 1999.0, 400000)
    response = np.asarray(loop(np.exp(2j * np.pi * f * dt))).ravel()
    ours = drive_tuning.loop_margins(response, f)
    with warnings.catch_warnings():  # its note on which of its methods it used
        warnings.simplefilter("ignore")
        gm, pm, _, _, wgc, _ = control.stability_margins(loop)
    assert ours.phase_margin_deg == pytest.approx(pm, abs=0.05)
    assert ours.gain_margin_db == pytest.approx(20 * np.log10(gm), abs=0.05)
    assert ours.crossover_hz == pytest.approx(wgc / (2 * np.pi), abs=0.01)


def test_a_loop_above_0_db_at_the_bands_end_has_no_crossover_in_it():
    f = np.linspace(1.0, 100.0, 100)
    assert drive_tuning.loop_margins(10.0 / (1j * f / 200.0 + 1.0), f).crossover_hz == np.inf


@pytest.mark.parametrize("axis", ["X", "A"])
def test_the_position_loop_composed_on_a_response_is_the_linearised_machines(compliant, axis):
    """The card's PID on the drive's closed velocity loop on the mechanics' response (what the
    tuner does with the measured one), here the linearised mechanics' response, gives the margins
    the full linearised machine gives: within 1 deg (the two frequency grids), 0.1 dB and the
    grid's 0.25 Hz. X's position loop crosses -180 deg at its motor-side antiresonance, where the
    gain changes by 3 dB in 0.75 Hz: the grid is 200 times finer over 20-50 Hz there, and 0.01 Hz
    between the two methods' crossings is still 0.04 dB."""
    cfg, dt = compliant.axis(axis), compliant.timing.physics_timestep
    f = np.union1d(np.linspace(0.25, 2000.0, 8000), np.linspace(20.0, 50.0, 24001))
    mechanics = model_mechanics(compliant, axis, f)
    velocity = drive_tuning.current_velocity_loop(mechanics, cfg.drive, dt)
    for kp in (50.0, 150.0):
        composed = drive_tuning.loop_margins(drive_tuning.position_open_loop(
            mechanics, velocity, cfg, compliant.timing.servo_period, dt, kp=kp, ki=0.0, kd=0.0), f, f >= 1.0)
        machine = analyse(compliant, axis, kp=kp, ki=0.0)[0]
        assert composed.phase_margin_deg == pytest.approx(machine.phase_margin_deg, abs=1.0)
        # 0.3 dB: the drives' dead time moves A's phase crossing up, where the grid is coarser
        assert composed.gain_margin_db == pytest.approx(machine.gain_margin_db, abs=0.3)
        assert composed.crossover_hz == pytest.approx(machine.crossover_hz, abs=0.3)


def test_the_velocity_loop_designed_on_the_measured_response_keeps_its_margins_on_the_model(compliant):
    """Designed on the twin's measured response, the proposed velocity loop meets the margins
    there, and on the linearised mechanics within 2 deg and 0.5 dB of what was measured."""
    cfg, dt = compliant.axis("Y"), compliant.timing.physics_timestep
    measured = measure_mechanics(compliant, "Y")
    loop = drive_tuning.propose_velocity_loop(measured, cfg.drive, dt, phase_margin=40.0, gain_margin=6.0)
    assert loop.margins.phase_margin_deg >= 40.0 and loop.margins.gain_margin_db >= 6.0
    assert loop.margins.crossover_hz <= drive_tuning.CURRENT_LOOP_SHARE * cfg.drive.current_bandwidth
    model = model_mechanics(compliant, "Y", measured.frequency)
    on_model = drive_tuning.loop_margins(drive_tuning.velocity_open_loop(model, loop.kp, loop.tn, loop.notches, dt,
                                                                             loop.speed_filter, loop.torque_filter),
                                         model.frequency, drive_tuning.valid_band(measured, dt))
    assert on_model.phase_margin_deg == pytest.approx(loop.margins.phase_margin_deg, abs=2.0)
    assert on_model.gain_margin_db == pytest.approx(loop.margins.gain_margin_db, abs=0.5)


def _row(out: str, name: str) -> list[float]:
    line = next(line for line in out.splitlines() if line.startswith(name))
    return [float(x) for x in re.findall(r"[-\d.]+|inf|nan", line[len(name):])]


def test_tune_on_the_compliant_machine_lands_x_where_real_ball_screw_loops_are(tmp_path):
    """X of the compliant machine with the loops it had before it was tuned (the rigid machine's
    kp 400 / ki 16000, a drive's cautious first velocity loop: kp_speed 0.3, no notch), the tuner's default margins (45 deg,
    6 dB): its position gain within 30-70 1/s with those margins on the measured response (at both
    ends of the travel and mid-way) and crossing over below a quarter of its velocity loop's
    crossover (the servo manuals' rule), its tool's 1 mm step on the twin with at most 2 %
    overshoot; kp 400 overshoots the tool by more than half the step. The velocity loop it uses
    keeps 45 deg / 6 dB too. (A 0.1 mm step is friction's: the drive's integral breaks the axis
    free and it overshoots whatever the position gain.) With ``--out``, the plots of what it
    decided on."""
    import yaml
    from conftest import run_cli

    raw = yaml.safe_load(COMPLIANT.read_text())
    raw["axes"] = {"X": {"servo": {"kp": 400.0, "ki": 16000.0}, "drive": {"kp_speed": 0.3, "notch_filters": []}}}
    untuned = tmp_path / "untuned.yaml"
    untuned.write_text(yaml.safe_dump(raw))
    code, out, err = run_cli("tune", untuned, "--axis", "X", "--out", tmp_path / "plots")
    assert code == 0, err
    # the plots of what it decided on: the mechanics it measured, the twin's steps, the measured loops
    for name in ("mechanics", "step", "bode"):
        plot = tmp_path / "plots" / f"X_{name}.png"
        assert plot.is_file() and plot.stat().st_size > 10_000 and str(plot) in out
    assert "velocity loop" in out and "to use: axes: {X: {servo: {kp: " in out, out
    velocity = _row(out, "proposed") if out.count("\nproposed") == 2 else _row(out, "before")
    assert velocity[2] >= 45.0 and velocity[3] >= 6.0, out  # PM, GM of the velocity loop used
    position = [line for line in out.splitlines() if line.startswith("proposed")][-1]
    kp, ki, pm, gm, fc, rise, overshoot, settle = (float(x) for x in re.findall(r"[-\d.]+|inf|nan", position[8:]))
    assert 30.0 <= kp <= 70.0 and pm >= 45.0 and gm >= 6.0, out
    assert fc <= velocity[4] / 4.0, out
    assert overshoot <= 2.0 and np.isfinite(settle), out
    before = [line for line in out.splitlines() if line.startswith("before")][-1]
    assert float(re.findall(r"[-\d.]+", before[6:])[0]) == 400.0
    assert float(re.findall(r"[-\d.]+", before[6:])[6]) > 50.0, out  # today's gains: the tool overshoots


def test_a_loop_lagging_past_minus_180_deg_at_its_crossover_has_a_negative_phase_margin():
    """An integrator behind a dead time, L = w_c e^(-j w T) / (j w): it crosses 0 dB at w_c, where
    its phase is -90 deg - w_c T. With w_c T = 120 deg the margin is -30 deg (the loop is
    unstable); wrapped, the phase there (+150 deg) reads like a 30 deg margin."""
    wc, lag = 2 * np.pi * 50.0, np.radians(120.0)
    f = np.linspace(0.5, 200.0, 4000)
    w = 2 * np.pi * f
    response = wc * np.exp(-1j * w * lag / wc) / (1j * w)
    margins = drive_tuning.loop_margins(response, f)
    assert margins.phase_margin_deg == pytest.approx(-30.0, abs=0.5)
    assert margins.first_crossover_hz == pytest.approx(50.0, abs=0.1)
    # followed along a smooth reference (the model's) the measured loop's phase is the same
    assert drive_tuning.loop_margins(response, f, reference=response * np.exp(0.2j)).phase_margin_deg == \
        pytest.approx(-30.0, abs=0.5)


def test_commissioning_measures_z_clear_of_the_workpiece_and_refuses_a_measurement_in_contact(compliant):
    """Z's stretch clear of the work ends above where the pad meets the bundled workpiece (its
    lower soft limit is far below); a measurement there is refused, not returned."""
    from cnc_twin.studies.commissioning import clear_span, commissioning_positions

    lo, hi = clear_span(compliant, "Z")
    allowed = compliant.axis("Z").allowed
    assert allowed[0] < lo - 0.05 and hi == pytest.approx(allowed[1])
    positions = commissioning_positions(compliant, "Z")
    assert len(positions) == 3 and all(lo <= p <= hi for p in positions)
    with pytest.raises(ValueError):
        measure_mechanics(compliant, "Z", at=allowed[0] + 0.06, seconds=0.5)
