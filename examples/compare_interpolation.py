"""Run one circle by NURBS, point-by-point and DDA interpolation, with analog and with pulse output.

    python examples/compare_interpolation.py [--out compare_interpolation.png]

The passes of each run share the machine and the feed profile (a 20 mm radius circle at 3 m/min),
so the table and the bar chart (contour error max and RMS [um] of each pass) show what the
interpolation and the output stage each add. Two runs of 11 s simulated each: about 15 s of CPU.
"""

import argparse
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from cnc_twin import load_scenario, run_scenario
from cnc_twin.scenario.resources import scenarios_dir

matplotlib.use("Agg")  # pictures to files only: no display needed

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--out", type=Path, default=Path("compare_interpolation.png"), help="the picture (PNG)")
out = parser.parse_args().out

outputs = ("analog", "pulse")
errors = {}  # (output, method) -> contour error {"max", "rms"} [um]
print(f"{'output':8}{'method':16}{'contour max um':>16}{'rms um':>9}{'command dev max um':>20}")
for output in outputs:
    scenario = load_scenario(scenarios_dir() / "circle_three_ways.yaml", overrides={"command_output": output})
    for p in run_scenario(scenario).metrics["contour"]["passes"]:
        err = errors[output, p["method"]] = p["contour_error_um"]
        print(f"{output:8}{p['method']:16}{err['max']:>16.2f}{err['rms']:>9.2f}{p['command_deviation_um']['max']:>20.3f}")

methods = list(dict.fromkeys(method for _, method in errors))
x = np.arange(len(methods))
fig, axes = plt.subplots(1, 2, figsize=(8, 3.6), sharey=True)
for ax, figure in zip(axes, ("max", "rms")):
    for k, output in enumerate(outputs):
        ax.bar(x + (k - 0.5) * 0.38, [errors[output, m][figure] for m in methods], width=0.38, label=f"{output} output")
    ax.set_xticks(x, methods)
    ax.set_title(f"contour error, {figure}")
    ax.set_xlabel("interpolation")
axes[0].set_ylabel("contour error [µm]")
axes[1].legend()  # the RMS panel has the room
fig.suptitle("circle R20 mm at 3 m/min: interpolation and output stage")
fig.tight_layout()
fig.savefig(out, dpi=100)
print(f"picture: {out.resolve()}")
