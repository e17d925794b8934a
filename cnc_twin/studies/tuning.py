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
from cnc_twin.dsp.dac import CODE_MAX, CODE_MIN
from cnc_twin.geometry.kinematics import HeadGeometry
from cnc_twin.studies.linearize import (
    analyse, axis_plant, frequency_grid, frequency_response, margins_of, pid_controller,
)
from cnc_twin.scenario.load import load_scenario
from cnc_twin.run.twin import run_scenario

KI_RATIOS = (0.0, 0.05, 0.1, 0.2)
"""ki = ratio * kp^2 [1/s^2]: integral zero at ratio * kp"""


def gain_grid(kp_range: tuple[float, float]):
    """The position-loop search grid: ``(kp [1/s], ki [1/s^2])``, kp on 40 log-spaced values over
    ``kp_range``, each with ki = ratio kp^2 for the ratios ``KI_RATIOS``."""
    for kp in np.logspace(np.log10(kp_range[0]), np.log10(kp_range[1]), 40):
        for ratio in KI_RATIOS:
            yield float(kp), float(ratio * kp * kp)


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
    dt = scenario.timing.servo_period
    omega = frequency_grid(dt)
    plant = frequency_response(axis_plant(scenario, axis), omega, dt)  # once: only the PID changes
    out = []
    for kp, ki in gain_grid(kp_range):
        gm, pm, wc = margins_of(frequency_response(pid_controller(cfg, dt, kp=kp, ki=ki), omega, dt) * plant, omega)
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


SETTLE_MARGIN = 0.10
"""a candidate must settle at least this fraction sooner than the current gains to count as faster
(a step that saturates the DAC settles in nearly the same time whatever the gains: a few per cent
there shows nothing about the loop)"""
REFINE = 2
"""measured candidates: after the spread picks, this many on each side of the best are tried too"""
OVERSHOOT_MAX_PCT = 2.0
"""[%] the most overshoot of the tool a candidate judged on the twin alone may show"""
OVERSHOOT_SLACK_PCT = 0.5
"""[percentage points] overshoot a candidate may add over the current gains (the encoder's count
makes a small step's overshoot jump by about this much)"""


@dataclass(frozen=True)
class Verdict:
    """What the tuner found on the nonlinear twin.

    ``proposal`` is None when no candidate tried beat the current gains; ``reason`` then says
    why. ``before`` and ``best`` are twin step figures (:func:`twin_step`) of the current gains
    and of the chosen (or, when none is chosen, the fastest-settling) candidate."""

    proposal: Proposal | None
    before: dict[str, Any]
    best: dict[str, Any] | None
    best_candidate: Proposal | None
    tried: int
    reason: str


def beats(candidate: dict[str, Any], current: dict[str, Any]) -> bool:
    """Whether twin step figures ``candidate`` are better than ``current``: it settles (within
    the run), sooner by ``SETTLE_MARGIN``, with no more overshoot (within
    ``OVERSHOOT_SLACK_PCT``)."""
    settle, before = candidate["settling_time_s"], current["settling_time_s"]
    if not np.isfinite(settle):
        return False
    sooner = not np.isfinite(before) or settle < before * (1.0 - SETTLE_MARGIN)
    return sooner and candidate["overshoot_pct"] <= current["overshoot_pct"] + OVERSHOOT_SLACK_PCT


def check_margins(phase_margin: float, gain_margin: float) -> None:
    """ValueError (with the sentence) for margins no loop of this search can be asked for."""
    if not 0.0 < phase_margin < 90.0:
        raise ValueError(f"--phase-margin: expected more than 0 and less than 90 deg, got {phase_margin:g}")
    if not 0.0 < gain_margin <= 40.0:
        raise ValueError(f"--gain-margin: expected more than 0 and at most 40 dB, got {gain_margin:g}")


def verified_proposal(scenario_file: Path, scenario: Scenario, axis: str, *, phase_margin: float = 45.0,
                      gain_margin: float = 6.0, step: float = 1.0, tries: int = 12,
                      measured: list[Proposal] | None = None, extra: dict[str, Any] | None = None,
                      overrides: dict[str, Any] | None = None, current_margins: str | None = None) -> Verdict:
    """Candidates meeting the margins on the linear loop (``tries`` of them, spread over the list
    from the highest crossover down) are each run on the nonlinear twin; of those that
    :func:`beats` the current gains' own twin step and overshoot within 10 points of their linear
    loop's prediction, the one that settles soonest is proposed. When none qualifies the current
    gains are kept: the tuner never recommends what it did not show to be better on the twin.

    ``measured``: candidates whose margins were read from the axis's measured response instead
    (:func:`~cnc_twin.studies.drive_tuning.position_candidates`, highest crossover first); the
    twin alone judges them then, with at most ``OVERSHOOT_MAX_PCT`` of the tool's overshoot; and
    where the current gains overshoot beyond that (plus the slack), a candidate that settles within
    it beats them however long it takes (a machine tool's position loop must not overshoot), and
    every candidate is tried, not ``tries`` of them; the same where ``current_margins`` says how
    the current gains miss the margins on the measured response (a sentence; None: they meet them).
    ``extra``: scenario overrides every twin step runs with, the current gains' too (a proposed
    velocity loop: the position loop is tuned on the velocity loop it will run on). ``overrides``: those ``scenario``
    was loaded with (e.g. a bundled machine): every twin step loads ``scenario_file`` with them."""
    check_margins(phase_margin, gain_margin)
    found = measured if measured is not None else candidates(scenario, axis, phase_margin=phase_margin,
                                                             gain_margin=gain_margin)
    if not found and measured is not None:
        raise ValueError(f"no gains on the search grid meet {phase_margin:g} deg / {gain_margin:g} dB on {axis}'s "
                         "measured response")
    if not found:
        best = max(candidates(scenario, axis, phase_margin=1e-9, gain_margin=1e-9), key=lambda p: p.phase_margin_deg)
        raise ValueError(f"no gains on the search grid meet {phase_margin:g} deg / {gain_margin:g} dB on {axis}; "
                         f"the most phase margin any reaches is {best.phase_margin_deg:.1f} deg (kp {best.kp:.3g})")
    before = twin_step(scenario_file, axis, step=step, extra=extra, base=overrides)
    if before["fault"] is not None:
        raise ValueError(f"the {abs(step):g} {units.position_unit(scenario.axis(axis).rotary)} step with the "
                         f"current gains ends in a fault on the twin ({before['fault']}); choose a smaller --step")
    plant = axis_plant(scenario, axis) if measured is None else None
    qualified, fastest, tried = [], None, {}
    overshooting = measured is not None and (before["overshoot_pct"] > OVERSHOOT_MAX_PCT + OVERSHOOT_SLACK_PCT
                                             or current_margins is not None)
    # gains that overshoot, or miss the margins, give no yardstick to stop at: every candidate is tried then
    picks = [int(i) for i in np.unique(np.linspace(0, len(found) - 1,
                                                   len(found) if overshooting else min(tries, len(found))).round())]

    def try_on_twin(index: int) -> None:
        nonlocal fastest
        cand = found[index]
        twin = tried[index] = twin_step(scenario_file, axis, step=step, kp=cand.kp, ki=cand.ki, extra=extra,
                                        base=overrides)
        # better than the current gains, and behaving as its linear loop predicts (drive force
        # limits and DAC saturation are not in the linear model); measured candidates: the twin
        # alone, with at most OVERSHOOT_MAX_PCT
        if measured is not None:
            behaves = twin["overshoot_pct"] <= OVERSHOOT_MAX_PCT
        else:
            behaves = twin["overshoot_pct"] <= analyse(scenario, axis, plant=plant, kp=cand.kp, ki=cand.ki)[0] \
                .overshoot_pct + 10.0
        # measured: current gains that overshoot the tool beyond the limit are no yardstick (a
        # machine tool's position loop must not overshoot): any candidate that settles within it beats them
        if behaves and (beats(twin, before) or (overshooting and np.isfinite(twin["settling_time_s"]))):
            qualified.append((index, twin))
        if fastest is None or _settle_key(twin) < _settle_key(fastest[1]):
            fastest = (cand, twin)

    for index in picks:
        try_on_twin(index)
    if qualified and measured is not None:  # the twin decides alone: look between the picks around the best
        best = min(qualified, key=lambda pair: _settle_key(pair[1]))[0]
        for index in range(max(0, best - REFINE), min(len(found), best + REFINE + 1)):
            if index not in tried:
                try_on_twin(index)
    if qualified:
        index, twin = min(qualified, key=lambda pair: _settle_key(pair[1]))
        if current_margins is not None:
            reason = (f"the current gains {current_margins}; these meet the margins and the rule, and settle within "
                      f"{OVERSHOOT_MAX_PCT:g} %")
        elif beats(twin, before):
            reason = "settles sooner with no more overshoot on the twin"
        else:
            reason = (f"the tool overshoots {before['overshoot_pct']:.1f} % with the current gains, beyond the "
                      f"{OVERSHOOT_MAX_PCT:g} % a position loop may; these settle within it on the twin")
        return Verdict(found[index], before, twin, found[index], len(tried), reason)
    return Verdict(None, before, fastest[1], fastest[0], len(tried),
                   f"none of the {len(tried)} candidates tried settled sooner than the current gains without "
                   "more overshoot on the twin")


def format_verdict(verdict: Verdict, scenario: Scenario, axis: str, *, phase_margin: float, gain_margin: float,
                   step: float, margins: dict[str, tuple[float, float, float]] | None = None,
                   drive_use: str = "") -> str:
    """The tuner's report: linear and twin figures of the current gains and of the proposed (or
    best tried) ones, a note when the step saturates the DAC, and the recommendation or the
    reason for keeping the current gains. ``margins``: per row (``before``, ``proposed`` /
    ``best tried``) its (PM [deg], GM [dB], crossover [Hz]) on the measured response, instead
    of the linear model's; ``drive_use``: the drive's part of the recommendation (``, drive:
    {...}``)."""
    cfg = scenario.axis(axis)
    rows = [("before", cfg.kp, cfg.ki, verdict.before)]
    if verdict.best_candidate is not None:
        name = "proposed" if verdict.proposal is not None else "best tried"
        rows.append((name, verdict.best_candidate.kp, verdict.best_candidate.ki, verdict.best))
    unit = cfg.display_unit
    lines = [f"axis {axis}: targets phase margin >= {phase_margin:g} deg, gain margin >= {gain_margin:g} dB",
             f"{'':18}{'kp [1/s]':>10}{'ki [1/s^2]':>12}{'PM [deg]':>10}{'GM [dB]':>9}{'fc [Hz]':>9}"
             f"{'rise [ms]':>11}{'overshoot':>11}{'settle [ms]':>13}"]
    plant = axis_plant(scenario, axis) if margins is None else None
    for name, kp, ki, twin in rows:
        if margins is None:
            lin = analyse(scenario, axis, plant=plant, kp=kp, ki=ki)[0]
            pm, gm, fc = lin.phase_margin_deg, lin.gain_margin_db, lin.crossover_hz
        else:
            pm, gm, fc = margins[name]
        lines.append(f"{name:<18}{kp:>10.1f}{ki:>12.1f}{pm:>10.1f}{gm:>9.1f}"
                     f"{fc:>9.2f}{twin['rise_time_s'] * 1e3:>11.2f}{twin['overshoot_pct']:>10.1f}%"
                     f"{twin['settling_time_s'] * 1e3:>13.1f}")
    where = "the measured response" if margins is not None else "the linear model"
    lines.append(f"(margins: {where}; step responses: the tool on the nonlinear twin, {abs(step):g} {unit} step, "
                 f"feed-forward off; {verdict.tried} candidate(s) tried on it)")
    saturated = verdict.before["saturated_ticks"] * scenario.timing.servo_period * 1e3
    if saturated > 0:
        lines.append(f"note: the {abs(step):g} {unit} step holds the DAC at full scale for {saturated:.2f} ms with "
                     "the current gains; the loop's own response shows on a smaller --step")
    if verdict.proposal is None and drive_use:
        lines.append(f"to use: axes: {{{axis}: {{{drive_use[2:]}}}}}  (the proposed velocity loop; keeping the "
                     f"current position gains: {verdict.reason})")
    elif verdict.proposal is None:
        lines.append(f"keeping the current gains: {verdict.reason}")
    else:
        lines.append(f"to use: axes: {{{axis}: {{servo: {{kp: {verdict.proposal.kp:.4g}, "
                     f"ki: {verdict.proposal.ki:.4g}}}{drive_use}}}}}  ({verdict.reason})")
    return "\n".join(lines)


def _settle_key(twin: dict[str, Any]) -> tuple[float, float]:
    return (twin["settling_time_s"] if np.isfinite(twin["settling_time_s"]) else np.inf, twin["overshoot_pct"])


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
              ki: float | None = None, settle: float = 0.5, extra: dict[str, Any] | None = None,
              base: dict[str, Any] | None = None) -> dict[str, Any]:
    """Nonlinear twin response to a ``step`` (mm | deg) of ``axis`` from home; step figures of
    where the tool really went (X..B: the trace's tool pose through the head's inverse
    kinematics, per period; C: its encoder, per tick): on a compliant machine the table rings
    where the motor's encoder does not, and that is what the part gets. ``extra``: more scenario
    overrides (e.g. the drive's loops); ``base``: overrides the scenario was loaded with (a bundled
    machine), under the step's own.

    The step goes the other way when home + ``step`` is outside the axis's soft limits (Z's home
    is at the top of its travel); the figures are of its size either way. Besides the figures:
    ``time_s`` [s] from the step's start and ``response``, the tool's way there as a fraction of
    the step (shape ``(n,)`` each; empty when the step ended in a fault)."""
    i = "XYZABC".index(axis)
    step = step * step_direction(load_scenario(scenario_file, overrides=base), i, step)
    overrides: dict[str, Any] = {
        **(base or {}),
        f"axes.{axis}.max_velocity": 1e9, f"axes.{axis}.max_acceleration": 1e9,
        f"servo.{axis}.kvff": 0.0, f"servo.{axis}.kaff": 0.0,
        "program": {"type": "point_to_point", "settle": settle, "moves": [{axis: step}]},
    }
    if kp is not None:
        overrides[f"servo.{axis}.kp"] = float(kp)
    if ki is not None:
        overrides[f"servo.{axis}.ki"] = float(ki)
    scenario = load_scenario(scenario_file, overrides={**overrides, **(extra or {})})
    result = run_scenario(scenario)
    trace = result.trace
    if result.status != "complete":  # a step the supervisor stopped says nothing of the loop
        fault = result.metrics.get("fault") or {}
        return {"rise_time_s": np.inf, "overshoot_pct": np.nan, "settling_time_s": np.inf,
                "final_error_counts": np.nan, "saturated_ticks": 0, "scenario": scenario,
                "time_s": np.zeros(0), "response": np.zeros(0),
                "fault": f"{fault.get('code', result.status)}: {fault.get('message', '')}".rstrip(": ")}
    sign = 1.0 if step > 0 else -1.0
    command, actual, time = sign * trace.command[:, i], sign * trace.actual[:, i], trace.time
    if i < 5:  # where the tool went, at each period's last tick, in counts as the command
        tpp = trace.ticks_per_period
        head = HeadGeometry.from_model(result.model)
        tip, pivot = trace.tool[:, :3], trace.tool[:, 3:]
        true = head.axes_from_pose(tip, pivot - tip)[:, i]
        n = min(len(true), len(command) // tpp)
        command, time = command[tpp - 1::tpp][:n], time[tpp - 1::tpp][:n]
        actual = sign * (true[:n] - scenario.home[i]) * trace.counts_per_unit[i]
    start = max(0, int(np.argmax(command != command[0])) - 1)
    final = float(command[-1])
    response, elapsed = actual[start:] - actual[start], time[start:] - time[start]
    figures = step_figures(response, elapsed, final - float(actual[start]))
    dac = trace.dac[:, i]
    saturated = int(np.count_nonzero((dac >= CODE_MAX) | (dac <= CODE_MIN)))
    return {**figures, "final_error_counts": float(final - actual[-1]), "saturated_ticks": saturated,
            "scenario": scenario, "fault": None, "time_s": elapsed,
            "response": response / (final - float(actual[start]))}


def step_figures(response: np.ndarray, time: np.ndarray, final: float) -> dict[str, float]:
    """Rise time (10-90 %) [s], overshoot [%] and 2 % settling time [s] of a step ``response``
    (shape ``(n,)``, towards ``final``) sampled at ``time`` [s]; a response that does not rise or
    settle within the record gets ``inf`` there (python-control's step_info fails on it)."""
    try:
        info = control.step_info(response, time, yfinal=final)
        figures = {"rise_time_s": float(info["RiseTime"]), "overshoot_pct": float(info["Overshoot"]),
                   "settling_time_s": float(info["SettlingTime"])}
    except (IndexError, ValueError):
        figures = {"rise_time_s": np.inf, "overshoot_pct": max(0.0, float(np.max(response) / final - 1.0) * 100.0),
                   "settling_time_s": np.inf}
    # settled means inside 2 % from then to the end of the record; a step still outside at the
    # end has not settled, whatever step_info interpolates
    if abs(float(response[-1]) - final) > 0.02 * abs(final):
        figures["settling_time_s"] = np.inf
    return figures


__all__ = ["Proposal", "Verdict", "analyse", "beats", "candidates", "check_margins", "format_verdict", "gain_grid",
           "propose_gains", "step_direction", "step_figures", "twin_step", "verified_proposal"]
