"""Propose an axis's PID gains from its linear loop, and check them on the nonlinear twin.

``propose_gains`` searches kp (log grid) and ki = c kp^2 (c in a few ratios, 0 included) for the
highest gain crossover whose loop keeps the phase and gain margins (:mod:`cnc_twin.studies.linearize`).
``twin_step`` runs the full twin on a small step of that axis (a one-period move, feed-forward
off, so the loop's own response shows) and returns the step figures.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import control
import numpy as np

from cnc_twin.core import units
from cnc_twin.core.config import Scenario
from cnc_twin.studies.linearize import analyse, margins, pid_controller, axis_plant
from cnc_twin.scenario.load import load_scenario
from cnc_twin.run.twin import run_scenario

KI_RATIOS = (0.0, 0.05, 0.1, 0.2)
"""ki = ratio * kp^2 [1/s^2]: integral zero at ratio * kp"""


@dataclass(frozen=True)
class Proposal:
    kp: float
    ki: float
    phase_margin_deg: float
    gain_margin_db: float
    crossover_hz: float


def candidates(scenario: Scenario, axis: str, *, phase_margin: float = 45.0, gain_margin: float = 6.0,
               kp_range: tuple[float, float] = (5.0, 400.0)) -> list[Proposal]:
    """Every (kp, ki) on the search grid meeting both margins, highest crossover first."""
    cfg = scenario.axis(axis)
    plant = axis_plant(scenario, axis)
    dt = scenario.timing.servo_period
    out = []
    for kp in np.logspace(np.log10(kp_range[0]), np.log10(kp_range[1]), 40):
        for ratio in KI_RATIOS:
            ki = ratio * kp * kp
            gm, pm, wc = margins(pid_controller(cfg, dt, kp=kp, ki=ki) * plant, dt)
            if pm >= phase_margin and gm >= gain_margin and np.isfinite(wc):
                out.append(Proposal(float(kp), float(ki), pm, gm, wc / (2 * np.pi)))
    return sorted(out, key=lambda p: -p.crossover_hz)


def propose_gains(scenario: Scenario, axis: str, *, phase_margin: float = 45.0, gain_margin: float = 6.0,
                  kp_range: tuple[float, float] = (5.0, 400.0)) -> Proposal:
    """The highest-crossover (kp, ki) meeting both margins (linear only); see :func:`verified_proposal`."""
    found = candidates(scenario, axis, phase_margin=phase_margin, gain_margin=gain_margin, kp_range=kp_range)
    if not found:
        raise ValueError(f"no kp in {kp_range} meets {phase_margin} deg / {gain_margin} dB on {axis}")
    return found[0]


def verified_proposal(scenario_file: Path, scenario: Scenario, axis: str, *, phase_margin: float = 45.0,
                      gain_margin: float = 6.0, step: float = 1.0, tries: int = 8):
    """The highest-crossover candidate whose nonlinear twin step settles with an overshoot within
    10 points of the linear loop's (drive force limits and DAC saturation are not in the linear
    model). Candidates are tried from the top, skipping down the list; returns
    (proposal, twin step figures, candidates tried)."""
    found = candidates(scenario, axis, phase_margin=phase_margin, gain_margin=gain_margin)
    if not found:
        raise ValueError(f"no gains meet {phase_margin} deg / {gain_margin} dB on {axis}")
    picks = [found[int(i)] for i in np.unique(np.linspace(0, len(found) - 1, min(tries, len(found))).round())]
    for tried, cand in enumerate(picks, start=1):
        twin = twin_step(scenario_file, axis, step=step, kp=cand.kp, ki=cand.ki)
        linear = analyse(scenario, axis, kp=cand.kp, ki=cand.ki)[0]
        if np.isfinite(twin["settling_time_s"]) and twin["overshoot_pct"] <= linear.overshoot_pct + 10.0:
            return cand, twin, tried
    raise ValueError(f"none of {len(picks)} candidates behaved on the nonlinear twin")


def step_direction(scenario: Scenario, axis_index: int, step: float) -> float:
    """+1 if the axis's home + ``step`` [mm | deg] is inside its soft limits (or it has none),
    -1 if only home - ``step`` is; ValueError if neither."""
    axis = scenario.axes[axis_index]
    allowed = axis.allowed
    if allowed is None:
        return 1.0
    home = scenario.home[axis_index]
    size = step * units.position_factor(axis.rotary)  # [m | rad]
    for sign in (1.0, -1.0):
        if allowed[0] <= home + sign * size <= allowed[1]:
            return sign
    raise ValueError(f"a step of {abs(step):g} {units.position_unit(axis.rotary)} either way from home leaves "
                     f"axis {axis.name}'s {axis.allowed_name}")


def twin_step(scenario_file: Path, axis: str, *, step: float = 1.0, kp: float | None = None,
              ki: float | None = None, settle: float = 0.5) -> dict[str, Any]:
    """Nonlinear twin response to a ``step`` (mm | deg) of ``axis`` from home; step figures.

    The step goes the other way when home + ``step`` is outside the axis's soft limits (Z's home
    is at the top of its travel); the figures are of its size either way."""
    i = "XYZABC".index(axis)
    step = step * step_direction(load_scenario(scenario_file), i, step)
    overrides: dict[str, Any] = {
        f"axes.{axis}.max_velocity": 1e9, f"axes.{axis}.max_acceleration": 1e9,
        f"servo.{axis}.kvff": 0.0, f"servo.{axis}.kaff": 0.0,
        "program": {"type": "point_to_point", "settle": settle, "moves": [{axis: step}]},
    }
    if kp is not None:
        overrides[f"servo.{axis}.kp"] = float(kp)
    if ki is not None:
        overrides[f"servo.{axis}.ki"] = float(ki)
    scenario = load_scenario(scenario_file, overrides=overrides)
    trace = run_scenario(scenario).trace
    sign = 1.0 if step > 0 else -1.0
    command, actual = sign * trace.command[:, i], sign * trace.actual[:, i]
    start = max(0, int(np.argmax(command != command[0])) - 1)
    final = float(command[-1])
    info = control.step_info(actual[start:] - actual[start], trace.time[start:] - trace.time[start],
                             yfinal=final - float(actual[start]))
    return {"rise_time_s": float(info["RiseTime"]), "overshoot_pct": float(info["Overshoot"]),
            "settling_time_s": float(info["SettlingTime"]),
            "final_error_counts": float(final - actual[-1]), "scenario": scenario}


def save_plots(scenario: Scenario, axis: str, out_dir: Path, gains: dict[str, dict[str, float]]) -> list[Path]:
    """Bode (open loop) and step (closed loop) plots of each named gain set, as PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    cfg = scenario.axis(axis)
    plant = axis_plant(scenario, axis)
    dt = scenario.timing.servo_period
    paths = []
    fig_bode, (ax_mag, ax_phase) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    fig_step, ax_step = plt.subplots(figsize=(7, 4))
    omega = np.logspace(-1, np.log10(np.pi / dt * 0.999), 2000)
    for name, g in gains.items():
        loop = pid_controller(cfg, dt, **g) * plant
        resp = loop(np.exp(1j * omega * dt))
        hz = omega / (2 * np.pi)
        ax_mag.semilogx(hz, 20 * np.log10(np.abs(resp)), label=name)
        ax_phase.semilogx(hz, np.degrees(np.unwrap(np.angle(resp))), label=name)
        t = np.arange(int(0.5 / dt)) * dt
        ax_step.plot(t, control.step_response(control.feedback(loop, 1), T=t).outputs, label=name)
    ax_mag.axhline(0, color="grey", lw=0.5)
    ax_mag.set_ylabel("|L| [dB]")
    ax_phase.axhline(-180, color="grey", lw=0.5)
    ax_phase.set_ylabel("phase [deg]")
    ax_phase.set_xlabel("frequency [Hz]")
    ax_mag.legend()
    fig_bode.suptitle(f"axis {axis}: open loop")
    ax_step.set_xlabel("time [s]")
    ax_step.set_ylabel("position / command")
    ax_step.legend()
    fig_step.suptitle(f"axis {axis}: closed-loop step (linear)")
    for fig, name in ((fig_bode, "bode"), (fig_step, "step")):
        path = out_dir / f"{axis}_{name}.png"
        fig.savefig(path, dpi=110, bbox_inches="tight")
        plt.close(fig)
        paths.append(path)
    return paths


__all__ = ["Proposal", "analyse", "propose_gains", "save_plots", "twin_step"]
