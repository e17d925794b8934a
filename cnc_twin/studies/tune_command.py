"""``cnc-twin tune``: propose an axis's gains, check them on the twin, print the verdict and
save the plots. An axis whose drive has loops of its own is tuned on its measured mechanics
(:mod:`~cnc_twin.studies.measured_tuning`); one with the MJCF's velocity-mode drive from its
linear loop (:mod:`~cnc_twin.studies.tuning`)."""

from __future__ import annotations

import sys
from pathlib import Path

from cnc_twin.core.config import Scenario
from cnc_twin.core.errors import ScenarioError


def tune_axis(scenario_file: Path, scenario: Scenario, axis: str, *, phase_margin: float, gain_margin: float,
              step: float, out: Path | None, overrides: dict | None = None) -> None:
    """Print the proposal and its check on the twin for ``axis`` (``step`` [mm | deg] the
    verification step; ``out`` a folder for the Bode and step plots, PNG). ``scenario`` is
    ``scenario_file`` loaded with ``overrides`` (e.g. a bundled machine), which the twin's steps
    load it with too. A design that cannot meet the margins is a ScenarioError naming ``scenario_file``."""
    from cnc_twin.studies.tuning import format_verdict, save_plots, verified_proposal

    cfg = scenario.axis(axis)
    mechanics = None
    if cfg.drive is not None:  # a drive with loops of its own: tuned on its mechanics, measured as commissioning does
        print(f"axis {axis}: measuring its mechanics on the twin, designing the drive's velocity loop and the "
              f"position loop on them (phase margin >= {phase_margin:g} deg, gain margin >= "
              f"{gain_margin:g} dB), each checked on the twin ...", file=sys.stderr, flush=True)
        try:
            from cnc_twin.studies.measured_tuning import tune_on_measured

            mechanics, verdict, report = tune_on_measured(scenario_file, scenario, axis, phase_margin=phase_margin,
                                                          gain_margin=gain_margin, step=step, overrides=overrides)
        except ValueError as exc:
            raise ScenarioError(scenario_file, "", str(exc)) from None
        print(report)
    else:
        print(f"axis {axis}: candidates with phase margin >= {phase_margin:g} deg, gain margin >= "
              f"{gain_margin:g} dB, each checked on the twin ...", file=sys.stderr, flush=True)
        try:
            verdict = verified_proposal(scenario_file, scenario, axis, phase_margin=phase_margin,
                                        gain_margin=gain_margin, step=step, overrides=overrides)
        except ValueError as exc:
            raise ScenarioError(scenario_file, "", str(exc)) from None
        print(format_verdict(verdict, scenario, axis, phase_margin=phase_margin, gain_margin=gain_margin, step=step))
    if out is not None:
        gains = {"before": {"kp": cfg.kp, "ki": cfg.ki}}
        if verdict.proposal is not None:
            gains["proposed"] = {"kp": verdict.proposal.kp, "ki": verdict.proposal.ki}
        paths = save_plots(scenario, axis, out, gains)
        if mechanics is not None:
            from cnc_twin.studies.commissioning import save_mechanics_plot

            paths.append(save_mechanics_plot(axis, mechanics, out, (cfg.display_unit, cfg.display_factor)))
        print("plots: " + ", ".join(str(p) for p in paths))
