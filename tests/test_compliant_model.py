"""The compliant machine (models/polisher.xml) against outside references: the two-mass
formulas for its entered parameters, Hooke's law on a clamped table, the harmonic drive's
catalogue curve; and the card reading its encoders on the motors.

Reference values: the two-mass formulas (resonance f_r = sqrt(k (1/m_t + 1/m_m)) / 2 pi,
motor-side antiresonance f_a = sqrt(k / m_t) / 2 pi, m_m = J (2 pi / lead)^2) and the harmonic
drive's catalogue example (size 32: 60 N m -> 7.15e-4 rad) from the shared machine-dynamics
reference; the parameters (k, J, lead, masses) as the MJCF enters them.
"""

from __future__ import annotations

import math
import re

import mujoco
import numpy as np
import pytest

from cnc_twin.core.errors import ScenarioError
from cnc_twin.machine.model_file import load_model
from cnc_twin.machine.plant import Plant
from cnc_twin.machine.screw import screw_stiffness, setup_screws
from cnc_twin.scenario.resources import models_dir

MACHINE = models_dir() / "polisher.xml"
LOCK = 1e9
"""armature that holds a dof still [kg | kg m^2]"""
DT = 0.00025


def elastic_model() -> mujoco.MjModel:
    """The compliant machine without the harmonic drives' plastic state: mjd_transitionFD gives a
    wrong A for a model with plastic state (MuJoCo 4.0.0); below the yield the element is a linear
    spring, so the modes at rest are the same. Nor the drives' dead time (mjd_transitionFD
    refuses actuator delays; the mechanics' modes do not depend on it)."""
    text = re.sub(r' springyield="[^"]*"', "", MACHINE.read_text())
    return mujoco.MjModel.from_xml_string(re.sub(r' (delay|nsample)="[^"]*"', "", text))


def screw(model: mujoco.MjModel, axis: str, position: float = 0.0) -> tuple[float, float]:
    """``(k [N/m], lead / 2 pi [m/rad])`` of ``axis``'s screw as the MJCF enters it, with the table
    at ``position`` [m]: its chain (``<axis>_screw_chain``: k_rest, EA, a0, side) is the shaft
    between the fixed bearing and the nut, E A / a, in series with the rest, 1 / k = 1 / k_rest +
    a / (E A), a = a0 + side q (springs in series; the shaft a bar in tension)."""
    t = model.tendon(f"{axis}_screw").id
    adr, num = int(model.tendon_adr[t]), int(model.tendon_num[t])
    coefs = {model.joint(int(model.wrap_objid[w])).name: float(model.wrap_prm[w]) for w in range(adr, adr + num)}
    k_rest, ea, a0, side = model.numeric(f"{axis}_screw_chain").data
    return 1.0 / (1.0 / k_rest + (a0 + side * position) / ea), -coefs[f"{axis}_motor"]


def two_mass(axis: str, *, motor_held: bool, timestep: float, position: float) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The machine with every dof but ``axis``'s table and motor held still (the motor too with
    ``motor_held``); no actuation, Coulomb friction or joint limits (not smooth: not linearisable),
    the table at ``position`` [m] with the screw relaxed."""
    m = elastic_model()
    m.opt.timestep = timestep
    m.opt.disableflags |= (mujoco.mjtDisableBit.mjDSBL_ACTUATION | mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS
                           | mujoco.mjtDisableBit.mjDSBL_LIMIT)
    free = {f"{axis}_joint"} | (set() if motor_held else {f"{axis}_motor"})
    for j in range(m.njnt):
        if m.joint(j).name not in free:
            m.dof_armature[m.jnt_dofadr[j]] = LOCK
    d = mujoco.MjData(m)
    mujoco.mj_setConst(m, d)
    _, r = screw(m, axis)
    d.qpos[m.joint(f"{axis}_joint").qposadr[0]] = position
    d.qpos[m.joint(f"{axis}_motor").qposadr[0]] = position / r
    screw_stiffness(setup_screws(m), d.qpos, m.tendon_stiffness)  # as before every physics step
    mujoco.mj_forward(m, d)
    return m, d


def highest_mode_hz(m: mujoco.MjModel, d: mujoco.MjData) -> float:
    """The highest undamped natural frequency [Hz] of the one-step transition matrix."""
    nx = 2 * m.nv + m.na
    A = np.zeros((nx, nx))
    mujoco.mjd_transitionFD(m, d, 1e-7, True, A, None, None, None)
    s = np.log(np.linalg.eigvals(A).astype(complex)) / m.opt.timestep
    oscillating = s[s.imag > 2 * np.pi]
    return float(np.abs(oscillating).max() / (2 * np.pi))


@pytest.mark.parametrize("axis", ["x", "y", "z"])
def test_two_mass_modes_match_the_formulas_at_both_ends_and_mid_travel(axis):
    model = load_model(MACHINE)
    m_t = float(model.body_subtreemass[model.joint(f"{axis}_joint").bodyid[0]])  # all the slide carries
    J = float(model.dof_armature[model.joint(f"{axis}_motor").dofadr[0]])
    lo, hi = model.joint(f"{axis}_joint").range
    for position in (lo + 0.002, 0.5 * (lo + hi), hi - 0.002):
        k, r = screw(model, axis, position)  # the screw's stiffness there
        m_m = J / r ** 2
        f_r = math.sqrt(k * (1 / m_t + 1 / m_m)) / (2 * math.pi)
        f_a = math.sqrt(k / m_t) / (2 * math.pi)
        got = {(held, dt): highest_mode_hz(*two_mass(axis, motor_held=held, timestep=dt, position=position))
               for held in (False, True) for dt in (DT, DT / 2)}
        assert got[False, DT] == pytest.approx(f_r, rel=0.03), (position, got)
        assert got[True, DT] == pytest.approx(f_a, rel=0.03), (position, got)
        for held in (False, True):  # halving the physics step moves them less than 1 %
            assert got[held, DT / 2] == pytest.approx(got[held, DT], rel=0.01), (position, held, got)


@pytest.mark.parametrize("axis", ["x", "y", "z"])
def test_a_force_on_the_clamped_table_deflects_it_f_over_k_where_the_nut_is(axis):
    """Hooke's law with the screw's stiffness where its nut is (the chain: springs in series, the
    shaft a bar E A / a), near both ends of the travel and mid-way, the stiffness written before
    every physics step as the twin does; the screw is stiffer near its fixed bearing."""
    model = load_model(MACHINE)
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_ACTUATION | mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS
    model.dof_armature[model.joint(f"{axis}_motor").dofadr[0]] = LOCK  # the motor held (its brake)
    mujoco.mj_setConst(model, mujoco.MjData(model))
    screws = setup_screws(model)
    joint = model.joint(f"{axis}_joint")
    lo, hi = joint.range
    stiffness = {}
    for position in (lo + 0.05, 0.5 * (lo + hi), hi - 0.05):  # away from the stops
        k, r = screw(model, axis, position)
        rest = {}
        for force in (0.0, 2000.0, -2000.0):
            d = mujoco.MjData(model)
            mujoco.mj_resetDataKeyframe(model, d, model.key("home").id)
            d.qpos[joint.qposadr[0]] += position
            d.qpos[model.joint(f"{axis}_motor").qposadr[0]] += position / r
            d.qfrc_applied[joint.dofadr[0]] = force
            for _ in range(6000):  # 1.5 s, many times the axial mode's decay time
                screw_stiffness(screws, d.qpos, model.tendon_stiffness)
                mujoco.mj_step(model, d)
            rest[force] = float(d.qpos[joint.qposadr[0]])
        deflection = 0.5 * (rest[2000.0] - rest[-2000.0])
        assert deflection == pytest.approx(2000.0 / k, rel=0.05), position
        stiffness[position] = 2000.0 / deflection
    ends = sorted(stiffness.values())
    assert ends[-1] > 1.25 * ends[0], stiffness  # the nut's position matters


def test_a_screw_whose_tendon_disagrees_with_its_chain_at_home_is_refused(tmp_path):
    """The MJCF's tendon stiffness is the chain's at home: a file where they differ is refused in
    one line naming the tendon."""
    bad = tmp_path / "polisher.xml"
    bad.write_text(MACHINE.read_text().replace('<fixed name="y_screw" stiffness="5e+07"',
                                               '<fixed name="y_screw" stiffness="6e+07"'))
    with pytest.raises(ScenarioError, match="y_screw"):
        load_model(bad)


def test_harmonic_drive_follows_the_catalogue_curve_with_a_hysteresis_loop():
    """Output torque ramped 0 -> +120 -> -120 -> +120 N m on A with its motor held: the loop's
    midline at 60 N m is the catalogue's 7.15e-4 rad within 5 %; the branches part at 0 N m (the
    hysteresis loss, about 1 arcmin entered)."""
    model = load_model(MACHINE)
    model.opt.disableflags |= (mujoco.mjtDisableBit.mjDSBL_ACTUATION | mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS
                               | mujoco.mjtDisableBit.mjDSBL_GRAVITY)
    model.dof_armature[model.joint("a_motor").dofadr[0]] = LOCK
    mujoco.mj_setConst(model, mujoco.MjData(model))
    d = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, d, model.key("home").id)
    out, motor, dof = model.joint("a_joint").qposadr[0], model.joint("a_motor").qposadr[0], model.joint("a_joint").dofadr[0]
    torques, angles = [], []
    for start, end in ((0.0, 120.0), (120.0, -120.0), (-120.0, 120.0)):
        n = int(abs(end - start) / 60.0 / model.opt.timestep)  # 60 N m/s: slow against the drive's mode
        for i in range(1, n + 1):
            d.qfrc_applied[dof] = start + (end - start) * i / n
            mujoco.mj_step(model, d)
            torques.append(d.qfrc_applied[dof])
            angles.append(d.qpos[out] - d.qpos[motor] / 100.0)
    torques, angles = np.array(torques), np.array(angles)
    first = int(np.argmax(torques >= 120.0))
    turn = first + int(np.argmax(torques[first:] <= -120.0))
    falling, rising = slice(first, turn), slice(turn, len(torques))

    def angle_at(branch, torque):
        order = np.argsort(torques[branch])
        return float(np.interp(torque, torques[branch][order], angles[branch][order]))

    midline = 0.5 * (angle_at(falling, 60.0) + angle_at(rising, 60.0))
    assert midline == pytest.approx(7.15e-4, rel=0.05)
    loss_arcmin = math.degrees(angle_at(falling, 0.0) - angle_at(rising, 0.0)) * 60.0
    assert 0.5 < loss_arcmin < 2.0  # the lost motion shows as a loop, about the 1 arcmin entered


def test_the_card_reads_the_encoders_on_the_motors_of_the_compliant_machine():
    """Each axis's encoder is its motor hinge times the drive's gear (a rotary encoder on the
    motor, semi-closed loop); under a steady force on the table, the motor reading and the
    table part by F/k: the card sees the motor, not the table."""
    plant = Plant(load_model(models_dir() / "scene.xml"), timestep=DT, drives=compliant_jog().drives)
    model, data = plant.model, plant.data
    for i, axis in enumerate("xyzab"):
        motor = model.joint(f"{axis}_motor")
        assert plant.encoder_taps[i]["qpos_adr"] == motor.qposadr[0]
        assert plant.encoder_taps[i]["scale"] == pytest.approx(model.actuator(f"{axis}_drive").gear[0])
    assert plant.encoder_taps[5]["qpos_adr"] == model.joint("c_joint").qposadr[0]  # C: no compliance modelled
    k, _ = screw(model, "y")
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS
    data.qfrc_applied[model.joint("y_joint").dofadr[0]] = 1000.0
    plant.apply_volts([0.0] * 6)  # the drives hold the motors still (their velocity loops)
    plant.step(8000)
    table = plant.axis_positions()[1]
    encoder = float(plant.encoder_positions()[1])
    assert table - encoder == pytest.approx(1000.0 / k, rel=0.05)


def test_a_rigid_machine_reads_its_encoders_on_the_axis_joints():
    plant = Plant(load_model(models_dir() / "scene_rigid.xml"), timestep=DT)
    assert list(plant.encoder_taps["qpos_adr"]) == list(plant.qpos_adr)
    assert list(plant.encoder_taps["scale"]) == [1.0] * 6
    assert plant.encoder_home == tuple(plant.axis_positions())


def test_a_notch_filter_attenuates_its_centre_by_its_depth_and_passes_the_rest():
    """The drive's notch (bilinear, prewarped at the centre) against its analog prototype:
    -depth dB at the centre, about -3 dB of the shallow prototype at the band's edges, 0 dB far away."""
    from cnc_twin.machine.amplifier import notch_coefficients

    dt, f0, width, depth = DT, 180.0, 60.0, 20.0
    b0, b1, b2, a1, a2 = notch_coefficients(f0, width, depth, dt)

    def gain_db(f):
        z = np.exp(-1j * 2 * np.pi * f * dt)
        return 20 * np.log10(abs((b0 + b1 * z + b2 * z * z) / (1 + a1 * z + a2 * z * z)))

    assert gain_db(f0) == pytest.approx(-depth, abs=0.01)
    assert abs(gain_db(1.0)) < 0.01 and abs(gain_db(1500.0)) < 0.5
    s = 2j * np.pi * np.array([f0 - width / 2, f0 + width / 2])
    w, zp = 2 * np.pi * f0, width / (2 * f0)
    zz = zp * 10 ** (-depth / 20)
    analog = 20 * np.log10(np.abs((s * s + 2 * zz * w * s + w * w) / (s * s + 2 * zp * w * s + w * w)))
    for f, expected in zip((f0 - width / 2, f0 + width / 2), analog):
        assert gain_db(f) == pytest.approx(expected, abs=0.5)


def compliant_jog(**overrides):
    from cnc_twin import load_scenario
    from cnc_twin.scenario.resources import scenarios_dir

    return load_scenario(scenarios_dir() / "jog_axes.yaml", overrides={
        "machine.model": "scene.xml", "machine.parameters": "polisher.yaml", **overrides})


def test_the_compliant_machine_gives_one_trace_batched_compiled_and_in_python():
    """The amplifiers' loops are one implementation: the period batches, the compiled servo and
    the Python reference path give the same trace bit for bit on the compliant machine."""
    from cnc_twin.run.twin import Twin

    sc = compliant_jog(max_time=1.5)
    traces = [Twin(sc, compiled=compiled, batch=batch).run().trace for compiled, batch in
              ((True, True), (True, False), (False, False))]
    for other in traces[1:]:
        for name, column in traces[0].columns().items():
            assert np.asarray(column).tobytes() == np.asarray(other.columns()[name]).tobytes(), name


def test_the_drive_loops_are_required_on_a_current_mode_machine_and_refused_on_a_velocity_mode_one(write_scenario):
    """A parameter file that leaves out a current-mode drive's loops (or gives them to a
    velocity-mode drive) is refused at load, naming the key."""
    from cnc_twin.core.errors import ScenarioError
    from cnc_twin.scenario.load import load_scenario

    for model, parameters in (("scene.xml", "polisher_rigid.yaml"), ("scene_rigid.xml", "polisher.yaml")):
        path = write_scenario({"name": "mismatch", "machine": {"model": model, "parameters": parameters},
                               "program": {"type": "point_to_point", "moves": [{"X": 1.0}]}})
        with pytest.raises(ScenarioError) as caught:
            load_scenario(path)
        assert caught.value.key_path.startswith("axes.X.drive"), caught.value


RIGID_ERA_X = {"axes.X.servo.kp": 400.0, "axes.X.servo.ki": 16000.0, "axes.X.drive.kp_speed": 1.14,
               "axes.X.drive.notch_filters": []}
"""X's loops before the compliant machine was tuned: the rigid machine's position gains, the drive's
velocity loop as first entered (kv of the rigid machine's velocity drive)"""


def test_todays_gains_ring_on_motor_encoders_and_go_unstable_on_linear_scales(write_scenario):
    """The gains tuned on the rigid machine (kp 400 1/s, ki 16000 1/s^2): on the compliant machine's
    motor encoders X keeps 12.6 deg of phase margin (it rings), on linear scales it is unstable;
    the supervisor then stops the machine on its following-error limit, drives off and at rest,
    where gains within the mechanics' limits (kp 30 1/s) run the same program through."""
    import yaml

    from cnc_twin import run_scenario
    from cnc_twin.scenario.load import load_scenario
    from cnc_twin.scenario.resources import scenarios_dir
    from cnc_twin.studies.linearize import analyse

    on_motor = compliant_jog(**RIGID_ERA_X)
    assert analyse(on_motor, "X")[0].phase_margin_deg < 20.0
    raw = yaml.safe_load((scenarios_dir() / "jog_axes.yaml").read_text())
    raw["program"] = {"type": "point_to_point", "moves": [{"X": 5.0, "feed": 600, "dwell": 0.5}], "settle": 0.3}
    outcome = {}
    for kp, ki in ((400.0, 16000.0), (30.0, 0.0)):
        raw["axes"] = {"X": {"encoder": {"mount": "table"}, "following_error_limit": 0.1, "servo": {"kp": kp, "ki": ki},
                             "drive": {"kp_speed": 1.14, "notch_filters": []}}}
        scenario = load_scenario(write_scenario(raw, name=f"scales_{kp:g}.yaml"))
        report = analyse(scenario, "X")[0]
        result = run_scenario(scenario)
        outcome[kp] = (report, result)
    report, result = outcome[400.0]
    assert report.gain_margin_db < 0.0  # unstable on the linear model too
    assert result.status == "fault" and result.metrics["fault"]["code"] == "FOLLOWING_ERROR"
    assert result.metrics["fault"]["stop"] == "disable" and result.metrics["fault"]["at_rest_s"] < 1.0
    report, result = outcome[30.0]
    assert report.gain_margin_db >= 6.0 and report.phase_margin_deg >= 40.0
    assert result.status == "complete" and result.metrics["final_state"] == "FINISHED"
