"""Each card block is one plain function, compiled with numba: here every compiled function runs
against its own interpreted source (``py_func``) on seeded random inputs and records, and must
give the same outputs and leave the same records, bit for bit.

The interpreted runs get the records as ``np.recarray`` views (attribute access, as numba's
records have it); the compiled runs get plain structured arrays, as the twin passes them.
"""

from __future__ import annotations

import numpy as np
import pytest

from cnc_twin.dsp import adc, dac, encoder, pid, reversal, servo

SEEDS = range(20)


def _twins(array: np.ndarray) -> tuple[np.ndarray, np.recarray]:
    """Two equal copies of a structured array: one plain (compiled), one a recarray (interpreted)."""
    return array.copy(), array.copy().view(np.recarray)


def _axes(rng: np.random.Generator, n: int = 6) -> np.ndarray:
    """Servo channels with random set-up and state, some near their limits."""
    axes = np.zeros(n, servo.AXIS)
    for i in range(n):
        channel = axes[i]
        encoder.setup_encoder(channel["qep"], 10 ** rng.uniform(3, 7), rng.uniform(-0.5, 0.5))
        pid.setup_pid(channel["pid"], kp=rng.uniform(0, 200), ki=rng.choice([0.0, rng.uniform(0, 5e4)]),
                      kd=rng.uniform(0, 2), kvff=rng.uniform(0, 1.2), kaff=rng.uniform(0, 0.01),
                      aff_washout=rng.choice([0.0, rng.uniform(1e-3, 0.1)]),
                      ff_equivalent_time=rng.choice([0.0, rng.uniform(1e-4, 5e-3)]),
                      friction_ff=rng.uniform(0, 1), friction_ff_band=rng.uniform(1e-4, 1e-2),
                      speed_per_volt=rng.uniform(0.01, 0.1), counts_per_unit=channel["qep"]["counts_per_unit"],
                      dt=2.5e-4, output_limit=10.0, integrator_limit=rng.uniform(0.1, 10))
        dac.setup_dac(channel["dac"])
        reversal.setup_reversal(channel["reversal"], amplitude=rng.choice([0.0, rng.uniform(0, 0.01)]),
                                time=rng.uniform(1e-3, 0.1), lead=rng.uniform(0, 0.02), rise=rng.uniform(0, 0.01),
                                arm_speed=rng.choice([0.0, rng.uniform(0, 0.01)]), counts_per_unit=1e6,
                                speed_per_volt=rng.uniform(0.01, 0.1), dt=2.5e-4,
                                standstill=rng.choice([0.0, rng.uniform(0, 1)]), start_speed=rng.uniform(0, 1e-3),
                                stop_speed=rng.uniform(0, 3e-3), adapt_amplitude=rng.choice([0.0, rng.uniform(0, 0.02)]),
                                adapt_from=rng.uniform(0, 0.1), adapt_to=rng.uniform(0.2, 1.0))
        channel["reversal"]["direction"] = rng.choice([-1.0, 0.0, 1.0])
        channel["reversal"]["pulse"] = rng.uniform(-0.1, 0.1)
        channel["reversal"]["unloaded"] = rng.choice([-1, 0, 1, 2])
        channel["qep"]["counter16"] = rng.integers(0, 1 << 16)
        channel["qep"]["position32"] = rng.integers(-(1 << 31), 1 << 31)
        channel["pid"]["integrator"] = rng.uniform(-1, 1)
        channel["pid"]["previous_error"] = rng.uniform(-100, 100)
        channel["dac"]["stuck"] = rng.random() < 0.2
        channel["dac"]["stuck_code"] = rng.integers(-2048, 2048)
        channel["p_prev"], channel["p_next"] = rng.uniform(-1e6, 1e6, size=2)
        channel["velocity"], channel["acceleration"] = rng.uniform(-1e6, 1e6), rng.uniform(-1e8, 1e8)
        channel["jerk"] = rng.uniform(-1e10, 1e10)
        channel["push"], channel["push_velocity"] = rng.choice([0.0, rng.uniform(-100, 100)]), rng.uniform(-1e3, 1e3)
        channel["ff_acceleration"] = channel["acceleration"]
        channel["encoder_fault"] = rng.integers(-20, 21)
        channel["pid"]["reference"] = channel["p_prev"] + rng.uniform(-100, 100)
        channel["pid"]["reference_set"] = rng.choice([0.0, 1.0])
        channel["pid"]["aff_lowpass"] = rng.uniform(-1e8, 1e8)
        channel["deflection"][:] = rng.choice([0.0, 1.0], size=n) * rng.uniform(-3e-5, 3e-5, size=n)
        channel["coupling"][:] = rng.choice([0.0, 1.0], size=n) * rng.uniform(-5, 5, size=n)
    return axes


def _same(a, b) -> None:
    """Outputs equal to the bit (floats by their bytes, so -0.0 and NaN count too)."""
    assert np.asarray(a).tobytes() == np.asarray(b).tobytes(), (a, b)


def _walk(function, records: np.ndarray, rng: np.random.Generator, draw, steps: int) -> None:
    """``steps`` calls of ``function`` (compiled) and of its ``py_func`` on a random record of
    ``records`` each, with the arguments ``draw(rng)`` gives: the same results, the same records."""
    compiled, interpreted = _twins(records)
    for _ in range(steps):
        i = rng.integers(0, len(compiled))
        args = draw(rng)
        _same(function(compiled[i], *args), function.py_func(interpreted[i], *args))
    _same(compiled, np.asarray(interpreted))


@pytest.mark.parametrize("seed", SEEDS)
def test_qep_sample(seed):
    rng = np.random.default_rng(seed)
    _walk(encoder.qep_sample, _axes(rng)["qep"], rng, lambda r: (r.uniform(-2, 2), int(r.integers(-50, 51))), 50)


@pytest.mark.parametrize("seed", SEEDS)
def test_pid_update_and_reset(seed):
    rng = np.random.default_rng(seed)
    loops = _axes(rng)["pid"]
    # errors from a count to far past saturation, either sign
    _walk(pid.pid_update, loops, rng, lambda r: (r.uniform(-1e6, 1e6), float(r.integers(-10**6, 10**6)),
                                                r.uniform(-1e6, 1e6), r.uniform(-1e9, 1e9)), 50)
    _walk(pid.pid_reset, loops, rng, lambda r: (), 3)


@pytest.mark.parametrize("seed", SEEDS)
def test_reversal_pulse(seed):
    rng = np.random.default_rng(seed)
    # velocities often 0 (a stop) and of either sign, as a reversal needs
    _walk(reversal.reversal_pulse, _axes(rng)["reversal"], rng,
          lambda r: (float(r.choice([0.0, r.uniform(-1e4, 1e4)])), r.uniform(-1e6, 1e6), r.uniform(-1e8, 1e8),
                     bool(r.random() < 0.7)), 60)


@pytest.mark.parametrize("seed", SEEDS)
def test_dac_write(seed):
    rng = np.random.default_rng(seed)
    _walk(dac.dac_write, _axes(rng)["dac"], rng,
          lambda r: (r.choice([r.uniform(-12, 12), r.uniform(-1e3, 1e3), 0.5 * 10 / 2048 * r.integers(-4200, 4200)]),),
          100)


@pytest.mark.parametrize("seed", SEEDS)
def test_adc_convert_and_the_load_cell(seed):
    rng = np.random.default_rng(seed)
    cells = np.zeros(1, servo.LOAD_CELL)
    adc.setup_adc(cells[0]["adc"], rng.uniform(-100, 0), rng.uniform(1, 300), bits=int(rng.integers(8, 17)))
    cells[0]["fault"] = rng.choice([0.0, rng.uniform(-50, 50)])
    compiled, interpreted = _twins(cells)
    for _ in range(100):
        value = rng.uniform(-400, 400)
        if rng.random() < 0.5:
            _same(adc.adc_convert(compiled[0]["adc"], value), adc.adc_convert.py_func(interpreted[0].adc, value))
        else:
            _same(servo.read_load_cell(compiled[0], value), servo.read_load_cell.py_func(interpreted[0], value))
    _same(compiled, np.asarray(interpreted))


@pytest.mark.parametrize("seed", SEEDS)
def test_latch_setpoint_servo_tick_and_read_encoders(seed):
    from cnc_twin.dsp.compensation import MAX_POINTS, TABLE_ROWS, setup_comp

    rng = np.random.default_rng(seed)
    axes = _axes(rng)
    n = len(axes)
    tables = np.zeros((n, TABLE_ROWS, MAX_POINTS))
    for i in range(n):  # some axes with a pitch-error table and backlash (the leadscrew compensation)
        if rng.random() < 0.6:
            rows = int(rng.integers(2, MAX_POINTS + 1))
            setup_comp(axes[i]["comp"], tables[i], nominal=np.cumsum(rng.uniform(1.0, 1e4, rows)) - 5e5,
                       forward=rng.normal(0, 50, rows), reverse=rng.normal(0, 50, rows),
                       backlash=rng.uniform(0, 20), step=rng.uniform(0.5, 50))
    compiled, interpreted = _twins(axes)
    ticks = 4
    for _ in range(20):
        setpoint = rng.uniform(-1e6, 1e6, size=n)
        path = setpoint - rng.choice([0.0, 1.0], size=n) * rng.uniform(-100, 100, size=n)  # a force loop's push, or none
        servo.latch_setpoint(compiled, setpoint, path, 1000.0)
        servo.latch_setpoint.py_func(interpreted, setpoint, path, 1000.0)
        use_ticks = bool(rng.random() < 0.3)
        tick_commands = rng.uniform(-1e6, 1e6, size=(ticks, n))
        for j in range(ticks):
            positions = rng.uniform(-1, 1, size=n + 3)  # MuJoCo's qpos: the axes first
            outs_c = (np.zeros(n), np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros(n))
            outs_i = tuple(np.zeros_like(a) for a in outs_c)
            if rng.random() < 0.1:
                servo.fine_commands(compiled, (j + 1) / ticks, tick_commands[j], use_ticks, outs_c[0])
                servo.fine_commands.py_func(interpreted, (j + 1) / ticks, tick_commands[j], use_ticks, outs_i[0])
            elif rng.random() < 0.2:
                servo.read_encoders(compiled, positions, outs_c[1])
                servo.read_encoders.py_func(interpreted, positions, outs_i[1])
            else:
                servo.servo_tick(compiled, tables, (j + 1) / ticks, tick_commands[j], use_ticks, positions, *outs_c)
                servo.servo_tick.py_func(interpreted, tables, (j + 1) / ticks, tick_commands[j], use_ticks, positions,
                                         *outs_i)
            for a, b in zip(outs_c, outs_i):
                _same(a, b)
    _same(compiled, np.asarray(interpreted))


def test_the_differential_test_sees_a_difference():
    """The comparison is not vacuous: a record changed by one count differs."""
    axes = _axes(np.random.default_rng(0))
    other = axes.copy()
    other[3]["qep"]["position32"] += 1
    with pytest.raises(AssertionError):
        _same(axes, other)


@pytest.mark.parametrize("seed", SEEDS)
def test_force_update_through_every_state(seed):
    """The force loop's period from random records in each state (frozen too), with and without a
    profile: compiled and interpreted leave the same record and give the same depth."""
    from cnc_twin.dsp.force import FORCE, ForceState, force_update

    rng = np.random.default_rng(seed)
    loops = np.zeros(8, FORCE)
    for i in range(len(loops)):
        r = loops[i]
        for name, value in (("kp", rng.uniform(0, 1e-4)), ("ki", rng.uniform(0, 1e-2)), ("lo", -rng.uniform(1e-4, 3e-3)),
                            ("hi", rng.uniform(1e-4, 2e-3)), ("adapt_threshold", rng.choice([0.0, 0.3])),
                            ("adapt_feed", 0.5), ("adapt_hold", rng.uniform(0, 0.05)), ("setpoint", rng.uniform(5, 50)),
                            ("period", 1e-3), ("seek_speed", rng.uniform(1e-3, 1e-2)), ("retract_speed", 5e-3),
                            ("ramp_time", rng.choice([0.0, rng.uniform(0.01, 0.2)])), ("contact_threshold", 1.0),
                            ("integral", rng.uniform(-1e-3, 1e-3)), ("depth", rng.uniform(-2e-3, 1e-3)),
                            ("target", rng.uniform(0, 40)), ("feed_factor", rng.choice([0.5, 1.0])),
                            ("calm", rng.uniform(0, 0.05)), ("t", rng.uniform(0, 0.3)), ("ramp_from", rng.uniform(0, 30)),
                            ("contact_time", np.nan)):
            r[name] = value
        r["state"] = i % 6
        r["frozen"] = int(i == 7)
    profile = (np.array([0.0, 0.05, 0.2]), np.array([10.0, 30.0, 20.0])) if seed % 2 else (np.zeros(0), np.zeros(0))
    compiled, interpreted = _twins(loops)
    for _ in range(200):
        i = rng.integers(0, len(loops))
        measured, path_s = rng.uniform(-5, 60), rng.uniform(-0.1, 0.3)
        _same(force_update(compiled[i], *profile, measured, path_s),
              force_update.py_func(interpreted[i], *profile, measured, path_s))
    _same(compiled, np.asarray(interpreted))
    assert set(compiled["state"]) != {ForceState.OFF}  # the walk did not just end everything


@pytest.mark.parametrize("seed", SEEDS)
def test_supervise_and_the_switch_inputs(seed):
    """The supervisor's checks on random signals near each limit, and the plant's switch inputs
    from random sensor readings: compiled and interpreted agree, records included."""
    from cnc_twin.dsp.supervisor import LIMITS, SUPERVISOR, supervise
    from cnc_twin.machine.plant import switch_bits

    rng = np.random.default_rng(seed)
    n = 6
    limits = np.zeros(n, LIMITS)
    limits["ferr_limit"] = np.where(rng.random(n) < 0.7, rng.uniform(10, 1000, n), 0.0)
    limits["sat_seen"] = rng.integers(0, 50, n)
    limits["sat_run"] = rng.integers(0, 5, n)
    settings = np.zeros(1, SUPERVISOR)
    settings[0]["sat_limit"], settings[0]["ticks"] = rng.choice([0, 3, 6]), 4
    settings[0]["max_force"], settings[0]["check_switches"] = rng.choice([0.0, 60.0]), rng.integers(0, 2)
    compiled, interpreted = _twins(limits)
    saturations = limits["sat_seen"].copy()
    switches = np.array([(0, 1, 0, 1), (0, 2, 1, -1), (1, 4, 2, 1), (2, 2, 3, -1)], dtype=np.int64)
    for _ in range(100):
        command = rng.uniform(-1e4, 1e4, n)
        actual = command - rng.normal(0, 600, n).round()
        saturations += rng.choice([0, 4], n, p=[0.3, 0.7])
        sensordata = rng.uniform(-1, 1, 4)
        inputs_c, inputs_i = np.zeros(n, np.int64), np.zeros(n, np.int64)
        switch_bits(switches, sensordata, inputs_c)
        switch_bits.py_func(switches, sensordata, inputs_i)
        _same(inputs_c, inputs_i)
        force = rng.uniform(0, 80)
        _same(supervise(settings[0], compiled, command, actual, saturations, inputs_c, force),
              supervise.py_func(settings.view(np.recarray)[0], interpreted, command, actual, saturations, inputs_i,
                                force))
    _same(compiled, np.asarray(interpreted))


@pytest.mark.parametrize("seed", SEEDS)
def test_the_path_functions_the_batch_kernel_compiles(seed):
    """The card's feed, kinematics, tool axis and spindle functions, as the batch kernel compiles
    them (:mod:`cnc_twin.run.period_kernel`), against the plain functions the Python task runs."""
    import math

    from cnc_twin.geometry import kinematics, surface_path
    from cnc_twin.dsp import spindle
    from cnc_twin.motion import scurve, trapezoid
    from cnc_twin.run import period_kernel as pk

    rng = np.random.default_rng(seed)
    for _ in range(50):
        phase = rng.uniform(-1, 1, 6).tolist()
        assert pk._phase_state(*phase) == scurve.phase_state(*phase)
        t_acc, t_flat = rng.uniform(0, 0.5, 2)
        shape = (t_acc, 4.0 * rng.uniform(0.1, 2), t_flat, rng.uniform(0.1, 2), 2 * t_acc + t_flat)
        t = rng.uniform(-0.1, shape[-1] + 0.1)
        assert pk._trapezoid_state(*shape, t) == trapezoid.trapezoid_state(*shape, t)
        spin = (rng.uniform(-100, 100), rng.choice([0.0, rng.uniform(-100, 100)]), rng.uniform(0, 5), 1e-3)
        assert pk._spindle_turn(*spin) == spindle.spindle_turn(*spin)
        tip, axis, pivot, offset = (rng.uniform(-0.3, 0.3, 3) for _ in range(4))
        axis[2] = abs(axis[2]) + 0.1
        assert pk._pose_to_axes(tip, axis, pivot, offset) == kinematics.pose_to_axes(tip, axis, pivot, offset)
        su, sv, c1 = (rng.uniform(-1, 1, 3) for _ in range(3))
        lead, tilt = rng.uniform(-0.2, 0.2, 2)
        angles = (math.cos(lead), math.sin(lead), math.cos(tilt), math.sin(tilt))
        for leaned in (False, True):
            assert pk._tool_axis(su, sv, c1, *angles, leaned) == surface_path.tool_axis_leaned(su, sv, c1, *angles,
                                                                                                leaned)


def _amps(rng: np.random.Generator, n: int = 6) -> np.ndarray:
    """Amplifiers with random loops (some P only, some with notches) and state near their limits."""
    from cnc_twin.core.config import DriveConfig, Notch
    from cnc_twin.machine import amplifier, plant

    dt = 2.5e-4
    drives = [None if rng.random() < 0.2 else DriveConfig(
        speed_per_volt=rng.uniform(0.01, 0.5), kp=10 ** rng.uniform(1, 6), tn=rng.choice([0.0, rng.uniform(1e-3, 0.05)]),
        current_bandwidth=rng.uniform(300, 3000), force_limit=rng.uniform(10, 1e4),
        notches=tuple(Notch(rng.uniform(20, 900), rng.uniform(5, 200), rng.uniform(3, 40))
                      for _ in range(rng.integers(0, 3))),
        # the actual speed: exact, filtered, quantised, or both
        speed_filter=rng.choice([0.0, rng.uniform(100, 2000)]), feedback_counts=int(rng.choice([0, 10000, 2**20])))
        for _ in range(n)]
    taps = np.zeros(n, plant.ENCODER_TAP)
    taps["dof_adr"], taps["scale"] = rng.integers(0, 8, n), rng.uniform(1e-3, 1.0, n)
    taps["qpos_adr"] = rng.integers(0, 8, n)
    amps = amplifier.setup_amps(drives, taps, dt)
    amps["integral"] = rng.uniform(-1, 1, n) * amps["limit"]
    amps["notch_state"] = rng.uniform(-100, 100, amps["notch_state"].shape)
    return amps


@pytest.mark.parametrize("seed", SEEDS)
def test_amp_force_and_drive_amps(seed):
    from cnc_twin.machine import amplifier

    rng = np.random.default_rng(seed)
    amps = _amps(rng)
    _walk(amplifier.amp_force, amps[amps["modelled"]] if amps["modelled"].any() else amps, rng,
          lambda r: (r.uniform(-12, 12), r.uniform(-5, 5)), 50)
    _walk(amplifier.feedback_speed, amps[amps["modelled"]] if amps["modelled"].any() else amps, rng,
          lambda r: (r.uniform(-50, 50, 8), r.uniform(-50, 50, 8)), 50)
    compiled, interpreted = _twins(amps)
    qpos = rng.uniform(-50, 50, 8)
    for _ in range(20):
        volts, qvel = rng.uniform(-12, 12, 6), rng.uniform(-50, 50, 8)
        qpos += qvel * 2.5e-4
        ctrl_c, ctrl_i = np.zeros(6), np.zeros(6)
        amplifier.drive_amps(compiled, volts, qpos, qvel, ctrl_c)
        amplifier.drive_amps.py_func(interpreted, volts, qpos, qvel, ctrl_i)
        _same(ctrl_c, ctrl_i)
    _same(compiled, np.asarray(interpreted))
