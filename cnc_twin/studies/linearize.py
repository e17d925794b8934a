"""One axis's servo loop as python-control systems: the MuJoCo plant linearised, the card's PID.

Plant, from the DAC voltage to encoder counts, discrete at the servo period ``Ts``::

    MuJoCo at the home keyframe, Coulomb friction (frictionloss) removed (non-smooth), linearised
    by finite differences (mujoco.mjd_transitionFD) over one physics step; the axis's position
    and velocity and its drive's input picked out; ``n`` substeps per servo tick with the voltage
    held (zero-order hold): Ad = A^n, Bd = sum_k A^k B; output y = counts_per_unit * q.

Controller, from following error [counts] to volts, as the card computes it each tick (the
encoder is read at the tick's start and the DAC written at once, so no extra delay)::

    C(z) = kp_c + ki_c Ts z / (z - 1) + kd_c / Ts (z - 1) / z,    gains in volts per count (pid.py)

The open loop is ``L = C P``; the closed loop from command to position is ``L / (1 + L)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import control
import mujoco
import numpy as np

from cnc_twin.core.axes import AXES, actuator_name, joint_name
from cnc_twin.core.config import AxisConfig, Scenario
from cnc_twin.core.axes import HOME_KEYFRAME
from cnc_twin.machine.plant import load_model


def axis_plant(scenario: Scenario, axis: str) -> control.StateSpace:
    """The axis plant from DAC volts to encoder counts, discrete at the servo period."""
    timing = scenario.timing
    model = load_model(scenario.model_file)
    model.opt.timestep = timing.physics_timestep
    model.dof_frictionloss[:] = 0.0
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(HOME_KEYFRAME).id)
    mujoco.mj_forward(model, data)
    nv, na = model.nv, model.na
    A = np.zeros((2 * nv + na, 2 * nv + na))
    B = np.zeros((2 * nv + na, model.nu))
    mujoco.mjd_transitionFD(model, data, 1e-6, True, A, B, None, None)
    dof = model.joint(joint_name(axis)).dofadr[0]
    states = [dof, nv + dof]
    a = A[np.ix_(states, states)]
    b = B[states, model.actuator(actuator_name(axis)).id][:, None]
    ad, bd = np.eye(2), np.zeros((2, 1))
    for _ in range(timing.substeps_per_tick):  # voltage held over the servo tick
        bd = a @ bd + b
        ad = a @ ad
    cfg = scenario.axis(axis)
    return control.ss(ad, bd, [[cfg.counts_per_unit, 0.0]], [[0.0]], dt=timing.servo_period)


def pid_controller(cfg: AxisConfig, servo_period: float, **gains: float) -> control.TransferFunction:
    """The card's PID (feedback part) from error [counts] to volts; ``gains`` override kp/ki/kd."""
    g = 1.0 / (cfg.speed_per_volt * cfg.counts_per_unit)
    kp, ki, kd = (gains.get(name, getattr(cfg, name)) * g for name in ("kp", "ki", "kd"))
    z = control.tf([1.0, 0.0], [1.0], servo_period)
    return kp + ki * servo_period * z / (z - 1) + kd / servo_period * (z - 1) / z


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


def margins(loop: control.LTI, dt: float) -> tuple[float, float, float]:
    """(gain margin [dB], phase margin [deg], gain crossover [rad/s]) of a discrete open loop,
    from its frequency response on a dense grid up to Nyquist (phase unwrapped). The gain margin
    is inf when the phase never reaches -180 deg below Nyquist."""
    omega = np.logspace(-1, np.log10(np.pi / dt * 0.999), 20000)
    resp = loop(np.exp(1j * omega * dt))
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


def _bandwidth_hz(closed: control.LTI, dt: float) -> float:
    """First frequency where the closed loop falls 3 dB below its DC gain [Hz] (up to Nyquist)."""
    omega = np.logspace(-1, np.log10(np.pi / dt * 0.999), 4000)
    mag = np.abs(closed(np.exp(1j * omega * dt)))
    dc = abs(closed(1.0))
    below = np.flatnonzero(mag < dc / np.sqrt(2.0))
    return float(omega[below[0]] / (2 * np.pi)) if below.size else float(np.pi / dt / (2 * np.pi))


def analyse(scenario: Scenario, axis: str, **gains: float) -> tuple[LoopReport, control.LTI, control.LTI]:
    """Margins, bandwidth and step figures; returns (report, open loop, closed loop)."""
    if axis not in AXES:
        raise ValueError(f"axis must be one of {' '.join(AXES)}, got {axis!r}")
    cfg = scenario.axis(axis)
    plant = axis_plant(scenario, axis)
    loop = pid_controller(cfg, scenario.timing.servo_period, **gains) * plant
    closed = control.feedback(loop, 1)
    gm_db, pm, wc = margins(loop, scenario.timing.servo_period)
    info = control.step_info(closed)
    report = LoopReport(
        axis=axis,
        gain_margin_db=gm_db,
        phase_margin_deg=pm,
        crossover_hz=wc / (2 * np.pi),
        bandwidth_hz=_bandwidth_hz(closed, scenario.timing.servo_period),
        rise_time_s=float(info["RiseTime"]),
        overshoot_pct=float(info["Overshoot"]),
        settling_time_s=float(info["SettlingTime"]),
    )
    return report, loop, closed
