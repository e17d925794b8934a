"""Tune one axis: linear loop figures, a proposal that keeps the margins, checked on the twin.

    python examples/tune_axis.py [SCENARIO] [AXIS] [--out tune_axis.png]

Defaults: the default scenario's Y axis, a 50 deg phase margin. Six candidate gain pairs (of the
ones meeting the margins on the linear loop) are each run on the nonlinear twin as a 1 mm step
(``cnc-twin tune`` tries twelve), about 10 s of CPU in all. The picture: the tool's step response with
the current gains and with the proposed (or best tried) ones [fraction of the step against ms],
with the 2 % band the settling time is read against.
"""

import argparse
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt

from cnc_twin import load_scenario
from cnc_twin.scenario.resources import default_scenario
from cnc_twin.studies.linearize import analyse
from cnc_twin.studies.tuning import verified_proposal

matplotlib.use("Agg")  # pictures to files only: no display needed

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("scenario", nargs="?", type=Path, default=default_scenario())
parser.add_argument("axis", nargs="?", default="Y")
parser.add_argument("--out", type=Path, default=Path("tune_axis.png"), help="the picture (PNG)")
args = parser.parse_args()
scenario, axis = load_scenario(args.scenario), args.axis

now, _, _ = analyse(scenario, axis)
print(f"{axis} now: PM {now.phase_margin_deg:.1f} deg, crossover {now.crossover_hz:.2f} Hz, "
      f"linear rise {now.rise_time_s * 1e3:.1f} ms, overshoot {now.overshoot_pct:.1f} %")

verdict = verified_proposal(args.scenario, scenario, axis, phase_margin=50.0, tries=6)
before, best = verdict.before, verdict.best
if verdict.proposal is None:
    print(f"keeping the current gains: {verdict.reason}")
else:
    p = verdict.proposal
    print(f"proposal: kp {p.kp:.1f} 1/s, ki {p.ki:.1f} 1/s^2 -> PM {p.phase_margin_deg:.1f} deg, "
          f"crossover {p.crossover_hz:.2f} Hz ({verdict.tried} tried on the twin)")
name = "proposed" if verdict.proposal else "best tried"
print(f"twin 1 mm step, current -> {name}: "
      f"rise {before['rise_time_s'] * 1e3:.1f} -> {best['rise_time_s'] * 1e3:.1f} ms, "
      f"settling {before['settling_time_s'] * 1e3:.0f} -> {best['settling_time_s'] * 1e3:.0f} ms, "
      f"overshoot {before['overshoot_pct']:.1f} -> {best['overshoot_pct']:.1f} %")

fig, ax = plt.subplots(figsize=(7, 4))
cfg, tried = scenario.axis(axis), verdict.best_candidate
for label, kp, ki, step in (("current", cfg.kp, cfg.ki, before), (name, tried.kp, tried.ki, best)):
    # time_s [s] from the step's start, response: where the tool went as a fraction of the step
    ax.plot(step["time_s"] * 1e3, step["response"],
            label=f"{label}: kp {kp:.0f} 1/s, ki {ki:.0f} 1/s², overshoot {step['overshoot_pct']:.1f} %")
for level in (0.98, 1.02):
    ax.axhline(level, color="grey", lw=0.5, ls=":")
ax.set_xlabel("time after the step [ms]")
ax.set_ylabel("tool position / step [1]")
ax.set_title(f"axis {axis}: 1 mm step on the nonlinear twin (feed-forward off)")
ax.legend(fontsize="small", loc="lower right")
fig.tight_layout()
fig.savefig(args.out, dpi=100)
print(f"picture: {args.out.resolve()}")
