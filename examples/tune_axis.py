"""Tune one axis: linear loop figures, a proposal that keeps the margins, checked on the twin.

    python examples/tune_axis.py [SCENARIO] [AXIS]
"""

import sys
from pathlib import Path

from cnc_twin import load_scenario
from cnc_twin.studies.linearize import analyse
from cnc_twin.scenario.resources import default_scenario
from cnc_twin.studies.tuning import verified_proposal

scenario_file = Path(sys.argv[1]) if len(sys.argv) > 1 else default_scenario()
axis = sys.argv[2] if len(sys.argv) > 2 else "Y"
scenario = load_scenario(scenario_file)

now, _, _ = analyse(scenario, axis)
print(f"{axis} now: PM {now.phase_margin_deg:.1f} deg, crossover {now.crossover_hz:.2f} Hz, "
      f"linear rise {now.rise_time_s * 1e3:.1f} ms, overshoot {now.overshoot_pct:.1f} %")

verdict = verified_proposal(scenario_file, scenario, axis, phase_margin=50.0)
before, best = verdict.before, verdict.best
if verdict.proposal is None:
    print(f"keeping the current gains: {verdict.reason}")
else:
    p = verdict.proposal
    print(f"proposal: kp {p.kp:.1f} 1/s, ki {p.ki:.1f} 1/s^2 -> PM {p.phase_margin_deg:.1f} deg, "
          f"crossover {p.crossover_hz:.2f} Hz ({verdict.tried} tried on the twin)")
print(f"twin 1 mm step, current -> {'proposed' if verdict.proposal else 'best tried'}: "
      f"rise {before['rise_time_s'] * 1e3:.1f} -> {best['rise_time_s'] * 1e3:.1f} ms, "
      f"settling {before['settling_time_s'] * 1e3:.0f} -> {best['settling_time_s'] * 1e3:.0f} ms, "
      f"overshoot {before['overshoot_pct']:.1f} -> {best['overshoot_pct']:.1f} %")
