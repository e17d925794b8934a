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
    from cnc_twin.studies.tuning import check_margins, format_verdict, verified_proposal

    try:  # margins no loop can be asked for: refused before any measurement
        check_margins(phase_margin, gain_margin)
    except ValueError as exc:
        raise ScenarioError(scenario_file, "", str(exc)) from None
    cfg = scenario.axis(axis)
    mechanics = loops = None
    if cfg.drive is not None:  # a drive with loops of its own: tuned on its mechanics, measured as commissioning does
        print(f"axis {axis}: measuring its mechanics on the twin, designing the drive's velocity loop and the "
              f"position loop on them (phase margin >= {phase_margin:g} deg, gain margin >= "
              f"{gain_margin:g} dB), each checked on the twin ...", file=sys.stderr, flush=True)
        try:
            from cnc_twin.studies.measured_tuning import tune_on_measured

            mechanics, verdict, report, loops = tune_on_measured(scenario_file, scenario, axis, phase_margin=phase_margin,
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
        print("plots: " + ", ".join(str(p) for p in save_tuning_plots(scenario, axis, verdict, out, step=step,
                                                                      mechanics=mechanics, loops=loops)))


def save_tuning_plots(scenario: Scenario, axis: str, verdict, out: Path, *, step: float, mechanics=None,
                      loops=None) -> list[Path]:
    """The tuner's plots into ``out``: the tool's steps on the twin that the verdict read
    (``<axis>_step.png``), the open loops whose margins it printed (``<axis>_bode.png``: the
    measured position loops ``loops`` where the drive was tuned on its mechanics, else the linear
    model's), and the measured mechanics where there are some (``<axis>_mechanics.png``)."""
    from cnc_twin.studies.tuning_plots import linear_open_loops, save_bode_plot, save_step_plot

    cfg = scenario.axis(axis)
    out.mkdir(parents=True, exist_ok=True)
    best = "proposed" if verdict.proposal is not None else "best tried"
    steps = {"before": verdict.before} | ({} if verdict.best is None else {best: verdict.best})
    paths = [save_step_plot(axis, steps, f"{abs(step):g} {cfg.display_unit}", out / f"{axis}_step.png")]
    if loops is None:
        gains = {"before": {"kp": cfg.kp, "ki": cfg.ki}}
        if verdict.best_candidate is not None:
            gains[best] = {"kp": verdict.best_candidate.kp, "ki": verdict.best_candidate.ki}
        loops, title = linear_open_loops(scenario, axis, gains), "position open loop (linear model)"
    else:
        title = "position open loop on the measured responses (ends and mid travel)"
    paths.append(save_bode_plot(axis, loops, title, out / f"{axis}_bode.png"))
    if mechanics is not None:
        from cnc_twin.studies.commissioning import save_mechanics_plot

        paths.append(save_mechanics_plot(axis, mechanics, out, (cfg.display_unit, cfg.display_factor)))
    return paths
