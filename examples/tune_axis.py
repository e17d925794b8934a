"""Tune one axis: linear loop figures, a proposal that keeps the margins, checked on the twin.

    python examples/tune_axis.py [SCENARIO] [AXIS]
"""

import sys
from pathlib import Path

from cnc_twin import load_scenario
from cnc_twin.studies.linearize import analyse
from cnc_twin.scenario.resources import default_scenario
from cnc_twin.studies.tuning import twin_step, verified_proposal

scenario_file = Path(sys.argv[1]) if len(sys.argv) > 1 else default_scenario()
axis = sys.argv[2] if len(sys.argv) > 2 else "Y"
scenario = load_scenario(scenario_file)

now, _, _ = analyse(scenario, axis)
print(f"{axis} now: PM {now.phase_margin_deg:.1f} deg, crossover {now.crossover_hz:.2f} Hz, "
      f"linear rise {now.rise_time_s * 1e3:.1f} ms, overshoot {now.overshoot_pct:.1f} %")

proposal, step, tried = verified_proposal(scenario_file, scenario, axis, phase_margin=50.0)
print(f"proposal: kp {proposal.kp:.1f} 1/s, ki {proposal.ki:.1f} 1/s^2 -> PM {proposal.phase_margin_deg:.1f} deg, "
      f"crossover {proposal.crossover_hz:.2f} Hz ({tried} tried on the twin)")
before = twin_step(scenario_file, axis)
print(f"twin 1 mm step: rise {before['rise_time_s'] * 1e3:.1f} -> {step['rise_time_s'] * 1e3:.1f} ms, "
      f"settling {before['settling_time_s'] * 1e3:.0f} -> {step['settling_time_s'] * 1e3:.0f} ms")
