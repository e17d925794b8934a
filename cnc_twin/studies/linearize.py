"""One axis's servo loop as python-control systems: the MuJoCo plant linearised, the card's PID.

Plant, from the DAC voltage to encoder counts, discrete at the servo period ``Ts``::

    MuJoCo at the home keyframe, whole (every joint, tendon and actuator state), linearised by
    finite differences (mujoco.mjd_transitionFD) over one physics step, with what is not smooth
    left out: Coulomb friction (frictionloss), the joint limits, the harmonic drives' plasticity
    (an elastic copy: below the yield the element is a linear spring; mjd_transitionFD's A is
    wrong for a model with plastic state, MuJoCo 4.0.0) and the actuators' dead time (MuJoCo's
    actuator ``delay``, which mjd_transitionFD refuses: put back here as a shift register of
    whole physics steps between the control and the actuator). Every amplifier with loops of its own
    (cnc_twin.machine.amplifier: velocity PI on the motor's actual speed through the drive's
    speed filter, notch filters; the current loop is MuJoCo's actuator state; the feedback's
    quantisation left out) is closed around it at the physics rate, the others' inputs
    at 0 V; the axis's voltage held over the servo tick's ``n`` substeps (zero-order hold):
    Ad = M^n, Bd = sum_k M^k N; output y = counts_per_unit x the encoder's position (the motor's
    on a compliant machine, the axis joint's on a rigid one).

Controller, from following error [counts] to volts, as the card computes it each tick (the
encoder is read at the tick's start and the DAC written at once, so no extra delay)::

    C(z) = kp_c + ki_c Ts z / (z - 1) + kd_c / Ts (z - 1) / z,    gains in volts per count (pid.py)

The open loop is ``L = C P``; the closed loop from command to position is ``L / (1 + L)``. All
in state space (a transfer function of this order is numerically useless).
"""

from __future__ import annotations

from dataclasses import dataclass

import control
import mujoco
import numpy as np

from cnc_twin.core.axes import AXES
from cnc_twin.core.config import AxisConfig, Scenario
from cnc_twin.machine.model_file import load_model
from cnc_twin.machine.plant import Plant


def linear_plant(scenario: Scenario, *, at: dict[str, float] | None = None) -> Plant:
    """The scenario's machine as it is linearised: an elastic copy (no plastic state) without the
    actuators' dead time (:func:`actuator_delays` gives it back), with Coulomb friction and the
    joint limits off, at rest at the home keyframe, or with the axes ``at`` names (``{"Y": 0.2}``)
    moved there [m | rad] (:meth:`~cnc_twin.machine.plant.Plant.move_axis`: the screws' stiffness
    where their nuts are then)."""
    load_model(scenario.model_file)  # the file's checks, with their clear errors
    spec = mujoco.MjSpec.from_file(str(scenario.model_file))
    for tendon in spec.tendons:
        tendon.springyield = 0.0
    for actuator in spec.actuators:
        actuator.delay, actuator.nsample = 0.0, 0
    plant = Plant(spec.compile(), timestep=scenario.timing.physics_timestep, drives=scenario.drives,
                  encoder_mounts=scenario.encoder_mounts)
    plant.model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS | mujoco.mjtDisableBit.mjDSBL_LIMIT
    plant.reset()
    for axis, position in (at or {}).items():
        i = AXES.index(axis)
        plant.move_axis(i, position - scenario.home[i])
    return plant


def actuator_delays(scenario: Scenario) -> np.ndarray:
    """Each actuator's dead time in whole physics steps, shape ``(nu,)`` int: MuJoCo's actuator
    ``delay`` over the scenario's physics step (the machine's MJCF; 0 where it has none)."""
    model = load_model(scenario.model_file)
    steps = np.asarray(model.actuator_delay) / scenario.timing.physics_timestep
    whole = np.rint(steps).astype(int)
    if np.any(np.abs(steps - whole) > 1e-6):
        raise ValueError("the linear model takes actuator delays of whole physics steps only")
    return whole


def delay_ss(steps: int) -> control.StateSpace:
    """A dead time of ``steps`` >= 1 physics steps, discrete: a shift register, ``z^-steps``."""
    a = np.eye(steps, k=-1)
    b = np.zeros((steps, 1))
    b[0, 0] = 1.0
    c = np.zeros((1, steps))
    c[0, -1] = 1.0
    return control.ss(a, b, c, [[0.0]], True)


def amplifier_ss(amp: np.void) -> control.StateSpace:
    """One amplifier's loops (:data:`~cnc_twin.machine.amplifier.AMP`) from speed error [axis units]
    to force command, discrete at the physics step: the PI (``u = kp e + I``, ``I += ki_dt e``),
    the torque filter and the notch biquads in series, as
    :func:`~cnc_twin.machine.amplifier.amp_force` runs them (its limit left out)."""
    out = control.ss([[1.0]], [[amp["ki_dt"]]], [[1.0]], [[amp["kp"]]], True)
    if amp["beta"] > 0.0:  # y = T + beta (u - T), T' = y: the same form as the speed filter
        out = control.series(out, speed_filter_ss(float(amp["beta"])))
    for n in range(int(amp["n_notches"])):
        b0, b1, b2, a1, a2 = amp["notch"][n]
        notch = control.ss([[-a1, 1.0], [-a2, 0.0]], [[b1 - a1 * b0], [b2 - a2 * b0]], [[1.0, 0.0]], [[b0]], True)
        out = control.series(out, notch)
    return out


def speed_filter_ss(alpha: float) -> control.StateSpace:
    """An amplifier's actual speed from the motor's speed [axis units], discrete at the physics
    step, as :func:`~cnc_twin.machine.amplifier.feedback_speed` measures it (its quantisation
    left out): the first-order low-pass ``w_act += alpha (w - w_act)`` (``alpha``: the
    :data:`~cnc_twin.machine.amplifier.AMP` field), or 1 without a filter (``alpha`` 0).
    (MuJoCo's step makes the position's difference over a step the step's speed exactly, so the
    differencing adds no lag.)"""
    if alpha == 0.0:
        return control.ss([], [], [], [[1.0]], True)
    return control.ss([[1.0 - alpha]], [[alpha]], [[1.0 - alpha]], [[alpha]], True)


def machine_loop(plant: Plant, axis: str, *, force_input: bool = False,
                 delays: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(M, N, speed)`` of the linearised machine over one physics step, ``x' = M x + N u``, with
    every amplifier's velocity loop closed (PI and notches as :func:`amplifier_ss`, on the speed
    its filter gives, :func:`speed_filter_ss`), the other
    axes' inputs at 0 V; ``u`` is ``axis``'s voltage [V], or with ``force_input`` its force
    command [N | N m at the axis] with that axis's own amplifier left open (what a drive's
    commissioning measures: the mechanics as its motor sees them). ``speed``: the row that reads
    the axis's motor speed [m/s | rad/s at the axis] from the state. ``plant``: :func:`linear_plant`;
    ``delays``: the actuators' dead times in physics steps (:func:`actuator_delays`; default none),
    between each control (an amplifier's, or ``u`` itself) and its actuator."""
    model, data = plant.model, plant.data
    nv, na = model.nv, model.na
    nx = 2 * nv + na
    A = np.zeros((nx, nx))
    B = np.zeros((nx, model.nu))
    mujoco.mjd_transitionFD(model, data, 1e-6, True, A, B, None, None)
    i_axis = AXES.index(axis)
    delays = np.zeros(model.nu, dtype=int) if delays is None else delays

    def delayed(i: int, loop: control.StateSpace) -> control.StateSpace:
        k = int(delays[plant.actuator_ids[i]])
        return control.series(loop, delay_ss(k)) if k else loop

    loops = [(i, speed_filter_ss(float(plant.amps[i]["alpha"])), delayed(i, amplifier_ss(plant.amps[i])))
             for i in range(len(AXES)) if plant.amps[i]["modelled"] and not (force_input and i == i_axis)]
    direct = force_input or not plant.amps[i_axis]["modelled"]  # u is the axis actuator's control itself
    lag = int(delays[plant.actuator_ids[i_axis]]) if direct else 0  # u's own dead time [steps]
    size = nx + sum(f.nstates + loop.nstates for _, f, loop in loops) + lag
    M, N = np.zeros((size, size)), np.zeros((size, 1))
    M[:nx, :nx] = A
    at = nx
    if direct:
        b = B[:, plant.actuator_ids[i_axis]]
        if lag:  # through the actuator's dead time
            shift, d = delay_ss(lag), slice(at, at + lag)
            M[d, d] = np.asarray(shift.A)
            N[d, 0] = np.asarray(shift.B)[:, 0]
            M[:nx, d] += np.outer(b, np.asarray(shift.C)[0])
            at += lag
        else:
            N[:nx, 0] = b
    for i, speed_filter, loop in loops:
        amp = plant.amps[i]
        # the actual speed as a row over the whole state: w_act = Cf s + Df (speed . x)
        f = slice(at, at + speed_filter.nstates)
        at += speed_filter.nstates
        Af, Bf, Cf, Df = (np.asarray(m) for m in (speed_filter.A, speed_filter.B, speed_filter.C, speed_filter.D))
        actual = np.zeros(size)
        actual[nv + amp["dof_adr"]] = amp["scale"] * Df[0, 0]  # the motor's speed [axis units] from the state
        if speed_filter.nstates:
            actual[f] = Cf[0]
            M[f, f] = Af
            M[f, nv + amp["dof_adr"]] = Bf[:, 0] * amp["scale"]
        Az, Bz, Cz, Dz = (np.asarray(m) for m in (loop.A, loop.B, loop.C, loop.D))
        k, b = slice(at, at + loop.nstates), B[:, plant.actuator_ids[i]]
        # u = Cz z + Dz e, e = spv V (this axis) - actual . X
        M[:nx, :] -= np.outer(b, actual) * Dz[0, 0]
        M[:nx, k] += np.outer(b, Cz[0])
        M[k, :] -= np.outer(Bz[:, 0], actual)
        M[k, k] += Az
        if i == i_axis:
            N[:nx, 0] += b * Dz[0, 0] * amp["speed_per_volt"]
            N[k, 0] += Bz[:, 0] * amp["speed_per_volt"]
        at += loop.nstates
    tap = plant.encoder_taps[i_axis]
    speed = np.zeros(size)
    speed[nv + tap["dof_adr"]] = tap["scale"]
    return M, N, speed


def axis_plant(scenario: Scenario, axis: str) -> control.StateSpace:
    """The axis plant from DAC volts to encoder counts, discrete at the servo period."""
    timing = scenario.timing
    plant = linear_plant(scenario)
    M, N, _ = machine_loop(plant, axis, delays=actuator_delays(scenario))
    ad, bd = np.eye(M.shape[0]), np.zeros((M.shape[0], 1))
    for _ in range(timing.substeps_per_tick):  # voltage held over the servo tick
        bd = M @ bd + N
        ad = M @ ad
    cfg = scenario.axis(axis)
    c = np.zeros((1, M.shape[0]))
    tap = plant.encoder_taps[AXES.index(axis)]
    c[0, tap["dof_adr"]] = cfg.counts_per_unit * tap["scale"]
    return control.ss(ad, bd, c, [[0.0]], dt=timing.servo_period)


def mechanics(scenario: Scenario, axis: str, *, at: float | None = None) -> control.StateSpace:
    """The axis's mechanics as its drive sees them: from the force command [N | N m at the axis]
    to the motor's speed [m/s | rad/s at the axis], discrete at the physics step, the other
    drives' loops closed (:func:`machine_loop` with ``force_input``); the axis at home, or at
    ``at`` [m | rad]."""
    M, N, speed = machine_loop(linear_plant(scenario, at=None if at is None else {axis: at}), axis, force_input=True, delays=actuator_delays(scenario))
    return control.ss(M, N, speed[None, :], [[0.0]], dt=scenario.timing.physics_timestep)


def pid_controller(cfg: AxisConfig, servo_period: float, **gains: float) -> control.TransferFunction:
    """The card's PID (feedback part) from error [counts] to volts; ``gains`` override kp/ki/kd."""
    g = 1.0 / (cfg.speed_per_volt * cfg.counts_per_unit)
    kp, ki, kd = (gains.get(name, getattr(cfg, name)) * g for name in ("kp", "ki", "kd"))
    z = control.tf([1.0, 0.0], [1.0], servo_period)
    return control.ss(kp + ki * servo_period * z / (z - 1) + kd / servo_period * (z - 1) / z)


@dataclass(frozen=True)
class LoopReport:
    """Figures of one axis's linear loop."""

    axis: str
    gain_margin_db: float
    phase_margin_deg: float
    crossover_hz: float
    bandwidth_hz: float
    rise_time_s: float
    overshoot_pct: float
    settling_time_s: float


def frequency_grid(dt: float, points: int = 20000) -> np.ndarray:
    """The analysis's frequencies [rad/s]: 0.1 rad/s to just below Nyquist, log-spaced."""
    return np.logspace(-1, np.log10(np.pi / dt * 0.999), points)


def frequency_response(system: control.StateSpace, omega: np.ndarray, dt: float) -> np.ndarray:
    """A discrete single-input single-output system's response at ``z = exp(j omega dt)``, by one
    eigendecomposition of its A (a solve per frequency costs 100 times more at 40 states); a
    direct evaluation where A's eigenvectors are too ill-conditioned for that."""
    z = np.exp(1j * omega * dt)
    A, B, C, D = (np.asarray(m, dtype=float) for m in (system.A, system.B, system.C, system.D))
    if A.shape[0] == 0:
        return np.full(z.shape, D[0, 0], dtype=complex)
    lam, V = np.linalg.eig(A)
    if np.linalg.cond(V) > 1e12:
        return np.asarray(system(z)).reshape(z.shape)
    weights = (C[0] @ V) * np.linalg.solve(V, B[:, 0])
    return weights @ (1.0 / (z[None, :] - lam[:, None])) + D[0, 0]


def margins_of(resp: np.ndarray, omega: np.ndarray) -> tuple[float, float, float]:
    """(gain margin [dB], phase margin [deg], gain crossover [rad/s]) of an open loop's frequency
    response ``resp`` at ``omega`` [rad/s] (phase unwrapped). The gain margin is inf when the
    phase never reaches -180 deg below Nyquist."""
    mag, phase = np.abs(resp), np.unwrap(np.angle(resp))
    cross = np.flatnonzero((mag[:-1] >= 1.0) & (mag[1:] < 1.0))
    if not cross.size:
        return float("inf"), float("inf"), float("nan")
    i = cross[0]
    wc = float(omega[i])
    pm = float(np.degrees(phase[i]) + 180.0)
    below = np.flatnonzero(np.degrees(phase) <= -180.0)
    gm_db = float(-20 * np.log10(mag[below[0]])) if below.size else float("inf")
    return gm_db, pm, wc


def _bandwidth_hz(loop_response: np.ndarray, omega: np.ndarray) -> float:
    """First frequency where the closed loop ``L / (1 + L)`` (from the open loop's response at
    ``omega`` [rad/s]) falls 3 dB below its DC gain [Hz]; the grid's end if it never does."""
    mag = np.abs(loop_response / (1.0 + loop_response))
    dc = 1.0  # the plant integrates (speed -> position): a closed position loop's DC gain is 1
    below = np.flatnonzero(mag < dc / np.sqrt(2.0))
    return float(omega[below[0] if below.size else -1] / (2 * np.pi))


def analyse(scenario: Scenario, axis: str, *, plant: control.StateSpace | None = None,
            **gains: float) -> tuple[LoopReport, control.LTI, control.LTI]:
    """Margins, bandwidth and step figures; returns (report, open loop, closed loop). ``plant``:
    the axis's :func:`~cnc_twin.studies.linearize.axis_plant`, when the caller has it already (it
    costs about 0.5 s)."""
    if axis not in AXES:
        raise ValueError(f"axis must be one of {' '.join(AXES)}, got {axis!r}")
    cfg = scenario.axis(axis)
    dt = scenario.timing.servo_period
    plant = axis_plant(scenario, axis) if plant is None else plant
    pid = pid_controller(cfg, dt, **gains)
    loop = control.series(pid, plant)
    closed = control.feedback(loop, 1)
    omega = frequency_grid(dt)
    response = frequency_response(pid, omega, dt) * frequency_response(plant, omega, dt)
    gm_db, pm, wc = margins_of(response, omega)
    info = control.step_info(closed, yfinal=1.0)  # type-1 loop (see _bandwidth_hz)
    report = LoopReport(
        axis=axis,
        gain_margin_db=gm_db,
        phase_margin_deg=pm,
        crossover_hz=wc / (2 * np.pi),
        bandwidth_hz=_bandwidth_hz(response, omega),
        rise_time_s=float(info["RiseTime"]),
        overshoot_pct=float(info["Overshoot"]),
        settling_time_s=float(info["SettlingTime"]),
    )
    return report, loop, closed
