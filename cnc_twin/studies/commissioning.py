"""Drive commissioning on the nonlinear twin: an axis's mechanics measured as a drive's
commissioning software measures them, beside the linearised model's.

The measurement, on the machine with friction, plasticity and limits (the plant the twin runs)::

    the axis runs at a steady speed (out of stiction), every drive's velocity loop closed;
    a seeded pseudo-random binary sequence r [N | N m at the axis], held `hold` physics steps, is
    added to the axis's amplifier output; each physics step records the force command u that
    goes into the current loop and the motor's speed w (its encoder's rate);
    H(f) = S_rw(f) / S_ru(f)   (Welch cross spectra; r is independent of the loop's noise, so the
                                 estimate is unbiased under the feedback, unlike S_uw / S_uu)

H is from force command to motor speed [(m/s)/N | (rad/s)/(N m)], as
:func:`~cnc_twin.studies.linearize.mechanics` linearises it. A two-mass axis shows the motor-side
antiresonance (a dip) and the resonance (a peak) on the rigid body's mass line, 1 / (m 2 pi f):
:func:`resonances` takes that line out (|H| 2 pi f) and finds the pair.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from scipy import signal

from cnc_twin.core import units
from cnc_twin.core.axes import AXES, actuator_name, joint_name, motor_joint_name
from cnc_twin.core.config import Scenario
from cnc_twin.machine.amplifier import drive_amps
from cnc_twin.machine.model_file import load_model
from cnc_twin.machine.plant import Plant


@dataclass(frozen=True)
class FrequencyResponse:
    """A single-input single-output frequency response: ``frequency`` [Hz], ``response`` complex,
    ``coherence`` [0..1] (1 for a model's)."""

    frequency: np.ndarray
    response: np.ndarray
    coherence: np.ndarray


def measure_mechanics(scenario: Scenario, axis: str, *, seconds: float = 4.0, amplitude: float = 0.005,
                      speed: float = 0.05, hold: int = 2, seed: int = 0, segment: float = 2.0) -> FrequencyResponse:
    """The measured mechanics of ``axis`` (see the module docstring) on ``scenario``'s machine.

    Parameters
    ----------
    seconds : length of the excitation [s].
    amplitude : the PRBS's level, a fraction of the drive's force limit. Small, because the
        mechanics are not linear in it: a harmonic drive's elasto-plastic element yields past
        +-9.7 N m and its stiffness falls from K1 + Kp to K1 (A's resonance drops 5 % at 1 %,
        11 % at 2 % of the limit), as a real drive's measured resonance moves with the
        excitation level.
    speed : the steady speed, a fraction of the drive's full speed (10 V), away from the travel's
        end it starts at (it starts from whichever end leaves room).
    hold : physics steps each PRBS value is held (its spectrum is flat up to about 1 / (2 hold dt)).
    segment : Welch segment length [s] (the frequency resolution is its inverse).
    """
    i = AXES.index(axis)
    timestep = scenario.timing.physics_timestep
    plant = Plant(load_model(scenario.model_file), timestep=timestep, drives=scenario.drives)
    model, data = plant.model, plant.data
    amp = plant.amps[i]
    limit = amp["limit"] if amp["modelled"] else float(model.actuator_forcerange[plant.actuator_ids[i], 1])
    lead_in = int(round(0.3 / timestep))  # the drive reaches the steady speed first
    volts = np.zeros(len(AXES))
    travel = 10.0 * speed * scenario.axis(axis).speed_per_volt * (seconds + lead_in * timestep)
    volts[i] = 10.0 * speed * _direction(scenario, i, travel)
    n = int(round(seconds / timestep))
    rng = np.random.default_rng(seed)
    r = amplitude * limit * np.repeat(np.where(rng.random(n // hold + 1) < 0.5, -1.0, 1.0), hold)[:n]
    u, w = np.empty(n), np.empty(n)
    tap = plant.motor_taps[i]
    qvel, ctrl, act = data.qvel, data.ctrl, plant.actuator_ids[i]
    plant.apply_volts(volts)
    plant.step(lead_in)
    for k in range(n):
        drive_amps(plant.amps, plant.volts, data.qpos, qvel, ctrl)
        ctrl[act] += r[k]
        u[k] = ctrl[act]
        w[k] = qvel[tap["dof_adr"]] * tap["scale"]
        mujoco.mj_step(model, data)
    fs = 1.0 / timestep
    nperseg = int(round(segment * fs))
    f, s_rw = signal.csd(r, w, fs=fs, nperseg=nperseg)
    _, s_ru = signal.csd(r, u, fs=fs, nperseg=nperseg)
    _, coherence = signal.coherence(r, w, fs=fs, nperseg=nperseg)
    keep = f > 0
    return FrequencyResponse(f[keep], s_rw[keep] / s_ru[keep], coherence[keep])


def _direction(scenario: Scenario, i: int, distance: float) -> float:
    """+1 when the axis can travel ``distance`` [m | rad] up from home inside its soft limits (or
    travel), -1 when down (the tuner's :func:`~cnc_twin.studies.tuning.step_direction`); ValueError
    when neither."""
    from cnc_twin.studies.tuning import step_direction

    return step_direction(scenario, i, distance / units.position_factor(scenario.axes[i].rotary))


def model_mechanics(scenario: Scenario, axis: str, frequency: np.ndarray) -> FrequencyResponse:
    """The linearised mechanics (:func:`~cnc_twin.studies.linearize.mechanics`) at ``frequency`` [Hz]."""
    from cnc_twin.studies.linearize import frequency_response, mechanics

    system = mechanics(scenario, axis)
    response = frequency_response(system, 2.0 * np.pi * frequency, scenario.timing.physics_timestep)
    return FrequencyResponse(frequency, response, np.ones_like(frequency))


@dataclass(frozen=True)
class Resonance:
    """The largest resonance of a response and the deepest antiresonance below it [Hz]."""

    resonance_hz: float
    antiresonance_hz: float


def resonances(fr: FrequencyResponse, *, band: tuple[float, float] = (10.0, 500.0)) -> Resonance:
    """The resonance (the highest peak of |H| 2 pi f, the mass line taken out) within ``band``
    [Hz] and the antiresonance (the deepest dip of the same below it)."""
    keep = (fr.frequency >= band[0]) & (fr.frequency <= band[1])
    f = fr.frequency[keep]
    level = np.abs(fr.response[keep]) * 2.0 * np.pi * f
    peak = int(np.argmax(level))
    dip = int(np.argmin(level[:peak])) if peak > 0 else 0
    return Resonance(float(f[peak]), float(f[dip]))


@dataclass(frozen=True)
class RigidBody:
    """An axis's rigid-body parameters in axis units, fitted or entered: the inertia [kg | kg m^2]
    (table and everything it carries, plus the motor's reflected), viscous friction [N s/m |
    N m s/rad] and Coulomb friction [N | N m], motor side and guides together."""

    inertia: float
    viscous: float
    coulomb: float


def identify_rigid_body(scenario: Scenario, axis: str, *, seconds: float = 4.0, speed: float = 0.3,
                        frequencies: tuple[float, float] = (1.0, 2.7), threshold: float = 0.1) -> RigidBody:
    """Least-squares fit of ``u = m a + b v + c sign(v) + k x + d`` on a run of the nonlinear twin, as
    Erkorkmaz and Altintas identify a feed drive from its own signals.

    The axis follows a speed command of two sines (each ``speed / 2`` of the drive's full speed,
    at ``frequencies`` [Hz], well below the axis's first mode, so table and motor move as one;
    two, so that position and acceleration are not in antiphase and ``k`` and ``m`` part), on one
    side of home (the side the axis has room on), through its drive's loops. Each physics step
    records the force the drive applies (MuJoCo's actuator force, after the current loop), the
    motor's speed ``v`` after the step and so the step's acceleration ``a`` (the speed's backward
    difference), and its position ``x``. ``k x + d`` take the loads that depend on the position
    or on nothing (a counterbalance's spring, gravity on a tilting head). Samples slower than
    ``threshold`` of the full speed are left out of the fit: around a reversal MuJoCo's friction,
    a soft constraint, takes a few of its time constants to build up again.
    """
    i = AXES.index(axis)
    timestep = scenario.timing.physics_timestep
    plant = Plant(load_model(scenario.model_file), timestep=timestep, drives=scenario.drives)
    data = plant.data
    tap, act = plant.motor_taps[i], plant.actuator_ids[i]
    spv = scenario.axis(axis).speed_per_volt
    reach = sum(10.0 * speed / 2.0 * spv / (np.pi * f) for f in frequencies)  # the farthest it goes
    side = _direction(scenario, i, reach)
    n = int(round(seconds / timestep))
    t = np.arange(n) * timestep
    command = side * 10.0 * speed / 2.0 * sum(np.sin(2.0 * np.pi * f * t) for f in frequencies)
    volts = np.zeros(len(AXES))
    force, v, x = np.empty(n), np.empty(n), np.empty(n)
    for k in range(n):
        volts[i] = command[k]
        plant.apply_volts(volts)
        plant.step(1)
        force[k] = data.actuator_force[act]
        v[k] = data.qvel[tap["dof_adr"]] * tap["scale"]
        x[k] = data.qpos[tap["qpos_adr"]] * tap["scale"]
    a = np.diff(v, prepend=0.0) / timestep  # the force acts over the step that ends at v[k]
    settled = t > 1.0 / min(frequencies)  # the start's transient gone
    use = settled & (np.abs(v) > threshold * 10.0 * spv)
    basis = np.column_stack([a[use], v[use], np.sign(v[use]), x[use], np.ones(int(use.sum()))])
    (m, b, c, _, _), *_ = np.linalg.lstsq(basis, force[use], rcond=None)
    return RigidBody(float(m), float(b), float(c))


def entered_rigid_body(scenario: Scenario, axis: str) -> RigidBody:
    """The rigid-body parameters the MJCF enters for ``axis``: the mass (inertia) of the axis
    joint's subtree from MuJoCo's mass matrix plus the motor's armature reflected (1 / gear^2), and
    the joint's and the motor hinge's damping and frictionloss, the motor's reflected alike."""
    model = load_model(scenario.model_file)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    joint = model.joint(joint_name(axis))
    dof = int(joint.dofadr[0])
    inertia, viscous, coulomb = float(full[dof, dof]), float(model.dof_damping[dof]), float(model.dof_frictionloss[dof])
    motor = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, motor_joint_name(axis))
    if motor >= 0:
        mdof = int(model.jnt_dofadr[motor])
        gear = float(model.actuator(actuator_name(axis)).gear[0])
        inertia += float(full[mdof, mdof]) / gear ** 2
        viscous += float(model.dof_damping[mdof]) / gear ** 2
        coulomb += float(model.dof_frictionloss[mdof]) / gear
    return RigidBody(inertia, viscous, coulomb)


def format_mechanics(axis: str, measured: FrequencyResponse, model: FrequencyResponse) -> str:
    """One line: the resonance and antiresonance measured on the twin beside the model's."""
    got, expected = resonances(measured), resonances(model)
    return (f"axis {axis} mechanics (drive force -> motor speed), measured on the twin: resonance "
            f"{got.resonance_hz:.1f} Hz, antiresonance {got.antiresonance_hz:.1f} Hz; linear model: "
            f"{expected.resonance_hz:.1f} Hz, {expected.antiresonance_hz:.1f} Hz")


def save_mechanics_plot(axis: str, measured: FrequencyResponse, model: FrequencyResponse, out_dir):
    """The measured and the model's mechanics (|H| 2 pi f, the mass line taken out: the rigid
    body is a flat line, the antiresonance a dip, the resonance a peak), both marked, as PNG."""
    from pathlib import Path

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(7, 4))
    for name, fr, style in (("measured on the twin", measured, "-"), ("linear model", model, "--")):
        level = 20 * np.log10(np.abs(fr.response) * 2 * np.pi * fr.frequency)
        line, = ax.semilogx(fr.frequency, level, style, label=name)
        marks = resonances(fr)
        for f in (marks.resonance_hz, marks.antiresonance_hz):
            ax.axvline(f, color=line.get_color(), lw=0.6, ls=style)
    ax.set_xlim(5, measured.frequency[-1])
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("|H| 2 pi f [dB]  (1 / inertia)")
    ax.set_title(f"axis {axis}: force command -> motor speed (resonance, antiresonance marked)")
    ax.legend()
    path = out_dir / f"{axis}_mechanics.png"
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path
