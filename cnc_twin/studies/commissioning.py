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
:func:`resonances` takes that line out (``|H| 2 pi f``) and finds the pair.
"""

from __future__ import annotations

from collections.abc import Sequence
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
from cnc_twin.machine.screw import screw_stiffness


@dataclass(frozen=True)
class FrequencyResponse:
    """A single-input single-output frequency response: ``frequency`` [Hz], ``response`` complex,
    ``coherence`` [0..1] (1 for a model's), ``reference``."""

    frequency: np.ndarray
    response: np.ndarray
    coherence: np.ndarray
    reference: np.ndarray | None = None
    """the linear model's response at the same frequencies (a measured one's; None: none): it
    tells which turn a loop's phase through the measurement is on (a lag beyond -180 deg and a lead
    read the same, wrapped)"""


def measure_mechanics(scenario: Scenario, axis: str, *, seconds: float = 4.0, amplitude: float = 0.005,
                      speed: float = 0.05, hold: int = 2, seed: int = 0, segment: float = 2.0,
                      at: float | None = None) -> FrequencyResponse:
    """The measured mechanics of ``axis`` (see the module docstring) on ``scenario``'s machine.

    Parameters
    ----------
    seconds
        length of the excitation [s].
    amplitude
        the PRBS's level, a fraction of the drive's force limit. Small, because the
        mechanics are not linear in it: a harmonic drive's elasto-plastic element yields past
        +-9.7 N m and its stiffness falls from K1 + Kp to K1 (A's resonance drops 5 % at 1 %,
        11 % at 2 % of the limit), as a real drive's measured resonance moves with the
        excitation level.
    speed
        the steady speed, a fraction of the drive's full speed (10 V).
    hold
        physics steps each PRBS value is held (its spectrum is flat up to about 1 / (2 hold dt)).
    segment
        Welch segment length [s] (the frequency resolution is its inverse).
    at
        where the measurement is centred [m | rad, the axis's position]: the axis sweeps up through
        it at the steady speed, the excitation's middle there (a screw's stiffness depends on where
        its nut is). None: :func:`sweep_centre` of home.
    """
    i = AXES.index(axis)
    timestep = scenario.timing.physics_timestep
    plant = Plant(load_model(scenario.model_file), timestep=timestep, drives=scenario.drives)
    model, data = plant.model, plant.data
    amp = plant.amps[i]
    limit = amp["limit"] if amp["modelled"] else float(model.actuator_forcerange[plant.actuator_ids[i], 1])
    lead_in = int(round(0.3 / timestep))  # the drive reaches the steady speed first
    volts = np.zeros(len(AXES))
    rate = 10.0 * speed * scenario.axis(axis).speed_per_volt  # [m/s | rad/s]
    centre = sweep_centre(scenario, axis, scenario.home[i] if at is None else at, seconds=seconds, speed=speed)
    plant.move_axis(i, centre - rate * (lead_in * timestep + 0.5 * seconds) - scenario.home[i])
    volts[i] = 10.0 * speed
    n = int(round(seconds / timestep))
    rng = np.random.default_rng(seed)
    r = amplitude * limit * np.repeat(np.where(rng.random(n // hold + 1) < 0.5, -1.0, 1.0), hold)[:n]
    u, w = np.empty(n), np.empty(n)
    tap = plant.motor_taps[i]
    qpos, qvel, ctrl, act = data.qpos, data.qvel, data.ctrl, plant.actuator_ids[i]
    screws, stiffness = plant.screws, model.tendon_stiffness
    plant.apply_volts(volts)
    plant.step(lead_in)
    touched = 0
    for k in range(n):  # Plant.step's physics step, with the excitation added to the drive's output
        screw_stiffness(screws, qpos, stiffness)
        drive_amps(plant.amps, plant.volts, qpos, qvel, ctrl)
        ctrl[act] += r[k]
        u[k] = ctrl[act]
        w[k] = qvel[tap["dof_adr"]] * tap["scale"]
        mujoco.mj_step(model, data)
        touched += data.ncon > 0
    if touched:
        cfg = scenario.axis(axis)
        raise ValueError(f"axis {axis} touched something during its measurement about {centre * cfg.display_factor:.4g} "
                         f"{cfg.display_unit} ({touched} of {n} steps): measure it clear of the work")
    fs = 1.0 / timestep
    nperseg = int(round(segment * fs))
    f, s_rw = signal.csd(r, w, fs=fs, nperseg=nperseg, detrend="linear")
    _, s_ru = signal.csd(r, u, fs=fs, nperseg=nperseg, detrend="linear")
    _, coherence = signal.coherence(r, w, fs=fs, nperseg=nperseg, detrend="linear")
    keep = f > 0
    return FrequencyResponse(f[keep], s_rw[keep] / s_ru[keep], coherence[keep])


def _direction(scenario: Scenario, i: int, distance: float) -> float:
    """+1 when the axis can travel ``distance`` [m | rad] up from home inside its soft limits (or
    travel), -1 when down (the tuner's :func:`~cnc_twin.studies.tuning.step_direction`); ValueError
    when neither."""
    from cnc_twin.studies.tuning import step_direction

    return step_direction(scenario, i, distance / units.position_factor(scenario.axes[i].rotary))


SWEEP_MARGIN = 0.02
"""the measurement's sweep keeps this share of the axis's span from its limits"""


def sweep_centre(scenario: Scenario, axis: str, position: float, *, seconds: float = 4.0,
                 speed: float = 0.05, span: tuple[float, float] | None = None) -> float:
    """The centre [m | rad] nearest ``position`` for :func:`measure_mechanics`'s sweep (its
    lead-in and excitation at ``speed``, a fraction of full speed, for ``seconds``): the whole
    sweep inside ``span`` (default: the axis's soft limits, or travel), :data:`SWEEP_MARGIN` of it
    clear. ValueError when the sweep does not fit."""
    cfg = scenario.axis(axis)
    allowed = span if span is not None else cfg.allowed
    if allowed is None:
        return position
    rate = 10.0 * speed * cfg.speed_per_volt
    before, after = rate * (0.3 + 0.5 * seconds), rate * 0.5 * seconds
    lo, hi = allowed
    clear = SWEEP_MARGIN * (hi - lo)
    if hi - lo - 2.0 * clear < before + after:
        unit = units.position_unit(cfg.rotary)
        factor = units.position_factor(cfg.rotary)
        where = "the stretch clear of the work" if span is not None else cfg.allowed_name
        raise ValueError(f"axis {axis}'s {where} ({lo / factor:.4g} to {hi / factor:.4g} {unit}) is too short for "
                         f"the measurement's sweep of {(before + after) / factor:.4g} {unit}")
    return float(np.clip(position, lo + clear + before, hi - clear - after))


CLEAR_SAMPLES = 41
"""positions along the travel :func:`clear_span` checks for contacts"""


def clear_span(scenario: Scenario, axis: str) -> tuple[float, float] | None:
    """The stretch of ``axis``'s soft limits (or travel) [m | rad] around home where the machine,
    the other axes at home, touches nothing (no MuJoCo contact: the pad and head clear of the
    workpiece), sampled at :data:`CLEAR_SAMPLES` positions; None for an axis without limits.
    A measurement in contact measures the contact, not the drive's mechanics."""
    i = AXES.index(axis)
    allowed = scenario.axis(axis).allowed
    if allowed is None:
        return None
    plant = Plant(load_model(scenario.model_file), timestep=scenario.timing.physics_timestep, drives=scenario.drives)
    home = scenario.home[i]
    samples = np.linspace(allowed[0], allowed[1], CLEAR_SAMPLES)
    clear = []
    for q in samples:
        plant.reset()
        plant.move_axis(i, q - home)
        clear.append(plant.data.ncon == 0)
    start = int(np.argmin(np.abs(samples - home)))
    if not clear[start]:
        raise ValueError(f"axis {axis} touches something at home: its mechanics cannot be measured clear of it")
    lo = hi = start
    while lo > 0 and clear[lo - 1]:
        lo -= 1
    while hi < len(samples) - 1 and clear[hi + 1]:
        hi += 1
    # the last clear sample's neighbour touches: the stretch ends at the clear sample
    return float(samples[lo]), float(samples[hi])


def commissioning_positions(scenario: Scenario, axis: str) -> tuple[float, ...]:
    """Where commissioning measures ``axis`` [m | rad]: near both ends of its soft limits (or
    travel) and mid-way, within the stretch clear of the work (:func:`clear_span`;
    :func:`sweep_centre` of each), as its mechanics differ along the travel (a screw is stiffest
    with its nut near the motor); home alone for an axis without limits."""
    span = clear_span(scenario, axis)
    if span is None:
        return (scenario.home[AXES.index(axis)],)
    lo, hi = span
    return tuple(sweep_centre(scenario, axis, p, span=span) for p in (lo, 0.5 * (lo + hi), hi))


def model_mechanics(scenario: Scenario, axis: str, frequency: np.ndarray, *, at: float | None = None
                    ) -> FrequencyResponse:
    """The linearised mechanics (:func:`~cnc_twin.studies.linearize.mechanics`) at ``frequency``
    [Hz], the axis at ``at`` [m | rad] (None: :func:`sweep_centre` of home, where
    :func:`measure_mechanics` measures by default)."""
    from cnc_twin.studies.linearize import frequency_response, mechanics

    i = AXES.index(axis)
    centre = sweep_centre(scenario, axis, scenario.home[i] if at is None else at)
    system = mechanics(scenario, axis, at=centre)
    response = frequency_response(system, 2.0 * np.pi * frequency, scenario.timing.physics_timestep)
    return FrequencyResponse(frequency, response, np.ones_like(frequency))


@dataclass(frozen=True)
class Resonance:
    """The largest resonance of a response and the deepest antiresonance below it [Hz]."""

    resonance_hz: float
    antiresonance_hz: float


def resonances(fr: FrequencyResponse, *, band: tuple[float, float] = (10.0, 500.0)) -> Resonance:
    """The resonance (the highest peak of ``|H| 2 pi f``, the mass line taken out) within ``band``
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


def _home_mass_matrix(scenario: Scenario) -> tuple[mujoco.MjModel, np.ndarray]:
    """``scenario``'s model and its mass matrix at the home keyframe (shape ``(nv, nv)``)."""
    model = load_model(scenario.model_file)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    return model, full


def entered_coupling(scenario: Scenario, axes: Sequence[str]) -> dict[str, dict[str, float]]:
    """Per axis of ``axes``, the force on its joint per unit acceleration of each other's [N | N m
    per m/s^2 | rad/s^2] that the MJCF enters (as a CAD model gives it): their mass matrix entries
    at home."""
    model, full = _home_mass_matrix(scenario)
    dof = {axis: int(model.joint(joint_name(axis)).dofadr[0]) for axis in axes}
    return {axis: {other: float(full[dof[axis], dof[other]]) for other in axes if other != axis} for axis in axes}


def entered_rigid_body(scenario: Scenario, axis: str) -> RigidBody:
    """The rigid-body parameters the MJCF enters for ``axis``: the mass (inertia) of the axis
    joint's subtree from MuJoCo's mass matrix plus the motor's armature reflected (1 / gear^2), and
    the joint's and the motor hinge's damping and frictionloss, the motor's reflected alike."""
    model, full = _home_mass_matrix(scenario)
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


def format_mechanics(axis: str, mechanics, cfg) -> str:
    """One line per measured position: the resonance and antiresonance measured on the twin beside
    the model's. ``mechanics``: ``(position [m | rad], measured, model)`` each; ``cfg``: the
    axis's :class:`~cnc_twin.core.axis_config.AxisConfig` (its display unit)."""
    lines = [f"axis {axis} mechanics (drive force -> motor speed), measured on the twin and the linear model:"]
    for position, measured, model in mechanics:
        got, expected = resonances(measured), resonances(model)
        lines.append(f"  at {position * cfg.display_factor:8.1f} {cfg.display_unit}: resonance "
                     f"{got.resonance_hz:6.1f} Hz, antiresonance {got.antiresonance_hz:6.1f} Hz; linear model "
                     f"{expected.resonance_hz:6.1f} Hz, {expected.antiresonance_hz:6.1f} Hz")
    return "\n".join(lines)


def save_mechanics_plot(axis: str, mechanics, out_dir, unit: tuple[str, float] = ("m", 1.0)):
    """The measured and the model's mechanics at each measured position (``|H| 2 pi f``, the mass
    line taken out: the rigid body is a flat line, the antiresonance a dip, the resonance a peak),
    each marked, as PNG. ``mechanics``: ``(position, measured, model)`` each (see
    :func:`format_mechanics`); ``unit``: the position's display unit and factor."""
    from pathlib import Path

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(7, 4))
    for position, measured, model in mechanics:
        where = f"{position * unit[1]:.0f} {unit[0]}"
        for name, fr, style in ((f"measured at {where}", measured, "-"), (f"model at {where}", model, "--")):
            level = 20 * np.log10(np.abs(fr.response) * 2 * np.pi * fr.frequency)
            line, = ax.semilogx(fr.frequency, level, style, label=name)
            marks = resonances(fr)
            for f in (marks.resonance_hz, marks.antiresonance_hz):
                ax.axvline(f, color=line.get_color(), lw=0.6, ls=style)
    ax.set_xlim(5, mechanics[0][1].frequency[-1])
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("|H| 2 pi f [dB]  (1 / inertia)")
    ax.set_title(f"axis {axis}: force command -> motor speed (resonance, antiresonance marked)")
    ax.legend(fontsize="small")
    path = out_dir / f"{axis}_mechanics.png"
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path
