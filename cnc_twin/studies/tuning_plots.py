"""The tuner's plots, of the same responses its decision used: the tool's steps on the nonlinear
twin (the table's rise, overshoot and settling are read from them) and the open loops whose
margins the table prints, with each loop's crossover and margins marked.

``OpenLoop``: one gain set's open loop, ``frequency`` [Hz] and its complex ``responses`` (one per
place the axis was measured, or the linear model's one), with the
:class:`~cnc_twin.studies.drive_tuning.Margins` the table shows (the worst over the places; the
first crossover).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cnc_twin.studies.drive_tuning import Margins

SETTLED_SPAN = 2.5
"""the step plot's time axis runs to this many times the latest finite settling time shown"""


@dataclass(frozen=True)
class OpenLoop:
    """One gain set's open loop: ``responses`` (complex, each shape ``(n,)``) at ``frequency``
    [Hz], their ``phases`` [deg] as the margins follow them
    (:func:`~cnc_twin.studies.drive_tuning.followed_phase`), and its ``margins``."""

    frequency: np.ndarray
    responses: tuple[np.ndarray, ...]
    phases: tuple[np.ndarray, ...]
    margins: Margins


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def step_time_limit(steps: dict[str, dict[str, Any]]) -> float:
    """[s] where the step plot's time axis ends: ``SETTLED_SPAN`` times the latest settling
    time among ``steps`` (twin step figures), within the longest record; the whole record when one
    of them never settles (what it does instead is the point)."""
    record = max((float(t["time_s"][-1]) for t in steps.values() if len(t["time_s"])), default=0.5)
    settled = [t["settling_time_s"] for t in steps.values() if len(t["time_s"])]
    if not settled or not all(np.isfinite(settled)):
        return record
    return min(record, SETTLED_SPAN * max(settled))


def save_step_plot(axis: str, steps: dict[str, dict[str, Any]], step_label: str, out: Path) -> Path:
    """The tool's step on the nonlinear twin for each named gain set (``steps``: name -> the
    figures :func:`~cnc_twin.studies.tuning.twin_step` returned, with its ``time_s`` and
    ``response``), as a fraction of the step, with the 2 % band the settling time is read
    against; PNG at ``out``."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    limit = step_time_limit(steps)
    for name, twin in steps.items():
        if not len(twin["time_s"]):
            continue
        settle = twin["settling_time_s"]
        label = (f"{name}: overshoot {twin['overshoot_pct']:.1f} %, settles "
                 + (f"in {settle * 1e3:.0f} ms" if np.isfinite(settle) else "not within the record"))
        ax.plot(twin["time_s"] * 1e3, twin["response"], label=label)
    for level in (0.98, 1.02):
        ax.axhline(level, color="grey", lw=0.5, ls=":")
    ax.set_xlim(0.0, limit * 1e3)
    ax.set_xlabel("time [ms]")
    ax.set_ylabel("tool position / step")
    ax.set_title(f"axis {axis}: the tool's {step_label} step on the nonlinear twin (feed-forward off)")
    ax.legend(fontsize="small")
    fig.savefig(out, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return out


def save_bode_plot(axis: str, loops: dict[str, OpenLoop], title: str, out: Path) -> Path:
    """Each named open loop's magnitude and phase (every place's response, one colour per gain
    set), its first crossover marked by a vertical line and its margins in the legend; PNG at
    ``out``."""
    plt = _pyplot()
    fig, (ax_mag, ax_phase) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    for n, (name, loop) in enumerate(loops.items()):
        colour = f"C{n}"
        m = loop.margins
        label = (f"{name}: PM {m.phase_margin_deg:.1f} deg, GM {m.gain_margin_db:.1f} dB, "
                 f"crossover {m.first_crossover_hz:.1f} Hz")
        for k, (response, phase) in enumerate(zip(loop.responses, loop.phases)):
            ax_mag.semilogx(loop.frequency, 20 * np.log10(np.abs(response)), color=colour, lw=0.9,
                            label=label if k == 0 else None)
            ax_phase.semilogx(loop.frequency, phase, color=colour, lw=0.9)
        if np.isfinite(m.first_crossover_hz):
            for ax in (ax_mag, ax_phase):
                ax.axvline(m.first_crossover_hz, color=colour, lw=0.6, ls="--")
    ax_mag.axhline(0.0, color="grey", lw=0.5)
    ax_mag.set_ylabel("|L| [dB]")
    ax_phase.axhline(-180.0, color="grey", lw=0.5)
    ax_phase.set_ylabel("phase [deg]")
    ax_phase.set_xlabel("frequency [Hz]")
    ax_mag.legend(fontsize="small")
    fig.suptitle(f"axis {axis}: {title}")
    fig.savefig(out, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return out


def linear_open_loops(scenario, axis: str, gains: dict[str, dict[str, float]]) -> dict[str, OpenLoop]:
    """Each named gain set's open loop on the linear model (the card's PID times the linearised
    plant, :mod:`~cnc_twin.studies.linearize`), its margins as the linear tuner reads them."""
    from cnc_twin.studies.linearize import axis_plant, frequency_grid, frequency_response, margins_of, pid_controller

    cfg, dt = scenario.axis(axis), scenario.timing.servo_period
    omega = frequency_grid(dt, 2000)
    plant = frequency_response(axis_plant(scenario, axis), omega, dt)
    loops = {}
    for name, g in gains.items():
        response = frequency_response(pid_controller(cfg, dt, **g), omega, dt) * plant
        gm, pm, wc = margins_of(response, omega)
        loops[name] = OpenLoop(omega / (2 * np.pi), (response,), (np.degrees(np.unwrap(np.angle(response))),),
                               Margins(gm, pm, wc / (2 * np.pi), wc / (2 * np.pi)))
    return loops


__all__ = ["OpenLoop", "linear_open_loops", "save_bode_plot", "save_step_plot", "step_time_limit"]
