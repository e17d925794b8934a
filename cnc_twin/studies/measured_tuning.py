"""`cnc-twin tune` on an axis whose drive has loops of its own: its mechanics measured on the twin
(:mod:`cnc_twin.studies.commissioning`), the drive's velocity loop and then the position loop
designed on them (:mod:`cnc_twin.studies.drive_tuning`), the position gains verified on the twin
by where the tool went (:func:`~cnc_twin.studies.tuning.verified_proposal`)."""

from __future__ import annotations

from pathlib import Path

import yaml

from cnc_twin.core.config import Scenario
from cnc_twin.studies import drive_tuning
from cnc_twin.studies.commissioning import format_mechanics, measure_mechanics, model_mechanics
from cnc_twin.studies.tuning import Proposal, format_verdict, verified_proposal


def tune_on_measured(scenario_file: Path, scenario: Scenario, axis: str, *, phase_margin: float = 45.0,
                     gain_margin: float = 6.0, step: float = 1.0, overrides: dict | None = None) -> tuple:
    """An axis with drive loops: its mechanics measured on the twin; the drive's velocity loop and
    then the position loop designed on them, the position gains verified on the twin (the tool's
    step; proportional only: the drive's PI holds constant loads). Returns ``((measured, model)
    responses, verdict, report text)``. ``overrides``: those ``scenario`` was loaded with, for the
    twin's steps."""
    cfg, timing = scenario.axis(axis), scenario.timing
    measured = measure_mechanics(scenario, axis)
    mechanics = (measured, model_mechanics(scenario, axis, measured.frequency))
    dt = timing.physics_timestep
    current, velocity = drive_tuning.choose_velocity_loop(measured, cfg.drive, dt, phase_margin=phase_margin,
                                                          gain_margin=gain_margin)
    found = drive_tuning.position_candidates(measured, velocity, cfg, timing.servo_period, dt,
                                             phase_margin=phase_margin, gain_margin=gain_margin)
    settings = drive_tuning.drive_settings(velocity, cfg.drive)
    extra = None if velocity is current else {f"axes.{axis}.drive.{key}": value for key, value in settings.items()}
    verdict = verified_proposal(scenario_file, scenario, axis, phase_margin=phase_margin,
                                gain_margin=gain_margin, step=step, extra=extra, overrides=overrides,
                                measured=[Proposal(c.kp, c.ki, c.margins.phase_margin_deg, c.margins.gain_margin_db,
                                                   c.margins.crossover_hz) for c in found if c.ki == 0.0])

    def on_measured(loop, kp, ki):
        response = drive_tuning.position_open_loop(measured, loop, cfg, timing.servo_period, dt, kp=kp, ki=ki, kd=cfg.kd)
        m = drive_tuning.loop_margins(response, measured.frequency, drive_tuning.valid_band(measured, dt))
        return m.phase_margin_deg, m.gain_margin_db, m.crossover_hz

    margins = {"before": on_measured(current, cfg.kp, cfg.ki)}
    if verdict.best_candidate is not None:
        name = "proposed" if verdict.proposal is not None else "best tried"
        margins[name] = on_measured(velocity, verdict.best_candidate.kp, verdict.best_candidate.ki)
    drive_use = "" if extra is None else ", drive: " + yaml.safe_dump(settings, default_flow_style=True,
                                                                      sort_keys=False, width=1 << 30).strip()
    report = "\n".join([format_mechanics(axis, *mechanics),
                        drive_tuning.format_velocity_loops(axis, current, velocity, cfg.drive),
                        format_verdict(verdict, scenario, axis, phase_margin=phase_margin, gain_margin=gain_margin,
                                       step=step, margins=margins, drive_use=drive_use)])
    return mechanics, verdict, report
