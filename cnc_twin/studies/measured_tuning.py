"""`cnc-twin tune` on an axis whose drive has loops of its own: its mechanics measured on the twin
near both ends of its travel and mid-way (:mod:`cnc_twin.studies.commissioning`: a screw's
resonance moves with its nut), the drive's velocity loop and then the position loop designed to
keep their margins at each (:mod:`cnc_twin.studies.drive_tuning`), the position gains verified on
the twin by where the tool went (:func:`~cnc_twin.studies.tuning.verified_proposal`)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import yaml

from cnc_twin.core.config import Scenario
from cnc_twin.studies import drive_tuning
from cnc_twin.studies.commissioning import commissioning_positions, format_mechanics, measure_mechanics, model_mechanics
from cnc_twin.studies.tuning import Proposal, format_verdict, verified_proposal
from cnc_twin.studies.tuning_plots import OpenLoop


def tune_on_measured(scenario_file: Path, scenario: Scenario, axis: str, *, phase_margin: float = 45.0,
                     gain_margin: float = 6.0, step: float = 1.0, overrides: dict | None = None) -> tuple:
    """An axis with drive loops: its mechanics measured on the twin; the drive's velocity loop and
    then the position loop designed on them, the position gains verified on the twin (the tool's
    step; proportional only: the drive's PI holds constant loads). Returns ``(responses, verdict,
    report text, open loops)``: the open loops (:class:`~cnc_twin.studies.tuning_plots.OpenLoop`,
    ``before`` and ``proposed`` / ``best tried``) are the position loops whose margins the report
    prints, at every place measured. ``overrides``: those ``scenario`` was loaded with, for the
    twin's steps. The responses are per commissioning position
    (:func:`~cnc_twin.studies.commissioning.commissioning_positions`): ``(position, measured, model)``."""
    cfg, timing = scenario.axis(axis), scenario.timing
    mechanics = []
    for position in commissioning_positions(scenario, axis):
        one = measure_mechanics(scenario, axis, at=position)
        model = model_mechanics(scenario, axis, one.frequency, at=position)
        mechanics.append((position, replace(one, reference=model.response), model))
    measured = [one for _, one, _ in mechanics]
    dt = timing.physics_timestep
    current, velocity = drive_tuning.choose_velocity_loop(measured, cfg.drive, dt, phase_margin=phase_margin,
                                                          gain_margin=gain_margin)
    found = drive_tuning.position_candidates(measured, velocity, cfg, timing.servo_period, dt,
                                             phase_margin=phase_margin, gain_margin=gain_margin)
    settings = drive_tuning.drive_settings(velocity, cfg.drive)
    misses = _current_misses(drive_tuning.position_margins(measured, velocity, cfg, timing.servo_period, dt),
                             velocity, phase_margin, gain_margin)
    extra = None if velocity is current else {f"axes.{axis}.drive.{key}": value for key, value in settings.items()}
    verdict = verified_proposal(scenario_file, scenario, axis, phase_margin=phase_margin,
                                gain_margin=gain_margin, step=step, extra=extra, overrides=overrides,
                                current_margins=misses,
                                measured=[Proposal(c.kp, c.ki, c.margins.phase_margin_deg, c.margins.gain_margin_db,
                                                   c.margins.first_crossover_hz) for c in found if c.ki == 0.0])

    def open_loop(kp, ki):
        gains = {"kp": kp, "ki": ki, "kd": cfg.kd}
        loops = drive_tuning.position_open_loops(measured, velocity, cfg, timing.servo_period, dt, **gains)
        return OpenLoop(measured[0].frequency, tuple(loop for loop, _ in loops),
                        tuple(drive_tuning.followed_phase(loop, reference) for loop, reference in loops),
                        drive_tuning.position_margins(measured, velocity, cfg, timing.servo_period, dt, **gains))

    loops = {"before": open_loop(cfg.kp, cfg.ki)}
    if verdict.best_candidate is not None:
        name = "proposed" if verdict.proposal is not None else "best tried"
        loops[name] = open_loop(verdict.best_candidate.kp, verdict.best_candidate.ki)
    margins = {name: (loop.margins.phase_margin_deg, loop.margins.gain_margin_db, loop.margins.first_crossover_hz)
               for name, loop in loops.items()}
    drive_use = "" if extra is None else ", drive: " + yaml.safe_dump(settings, default_flow_style=True,
                                                                      sort_keys=False, width=1 << 30).strip()
    report = "\n".join([format_mechanics(axis, mechanics, scenario.axis(axis)),
                        drive_tuning.format_velocity_loops(axis, current, velocity, cfg.drive),
                        format_verdict(verdict, scenario, axis, phase_margin=phase_margin, gain_margin=gain_margin,
                                       step=step, margins=margins, drive_use=drive_use)]
                       + ([] if extra is None else ["(every row's margins and step: on the proposed velocity loop)"]))
    return mechanics, verdict, report, loops


def _current_misses(now, velocity, phase_margin: float, gain_margin: float) -> str | None:
    """How the current position gains (their margins ``now`` on the measured response, on the
    ``velocity`` loop they will run on) miss what a candidate must meet, in words; None if not."""
    if not (now.phase_margin_deg >= phase_margin and now.gain_margin_db >= gain_margin):
        return f"miss the margins on the measured response ({now.phase_margin_deg:.1f} deg, {now.gain_margin_db:.1f} dB)"
    highest = drive_tuning.POSITION_LOOP_SHARE * velocity.margins.first_crossover_hz
    if now.first_crossover_hz > highest:
        return (f"cross over at {now.first_crossover_hz:.1f} Hz, above a quarter of the velocity loop's "
                f"{velocity.margins.first_crossover_hz:.1f} Hz")
    return None
