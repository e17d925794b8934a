"""Run the same kind of curve with the tool axis held and tilting; compare contour and effort.

    python examples/compare_tool_axis.py [--out compare_tool_axis.png]

Left: the tool tip's path in the machine's X-Y plane [mm] while on the curve, with the tool axis
(tip to spindle, seen from above) drawn at a few points; right: each axis's peak acceleration as a
share of its limit [%]. Both from the trace and the metrics of two runs of about 5 s simulated
(about 8 s of CPU).
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
parser.add_argument("--out", type=Path, default=Path("compare_tool_axis.png"), help="the picture (PNG)")
out = parser.parse_args().out
AXES = ("X", "Y", "Z", "A", "B", "C")

fig, (ax_path, ax_peaks) = plt.subplots(1, 2, figsize=(10, 4))
for k, name in enumerate(("nurbs_freeform", "nurbs_tilted")):
    result = run_scenario(load_scenario(scenarios_dir() / f"{name}.yaml"))
    path = result.metrics["path"]
    peaks = path["axis_peaks"]
    axes = ", ".join(f"{a} {p['acceleration_ratio'] * 100:.0f} %" for a, p in peaks.items())
    print(f"{name:16} contour max {path['contour_error_um']['max']:7.1f} um, rms {path['contour_error_um']['rms']:6.1f} um,"
          f" feed fluctuation {path['feed_fluctuation']['max']:.1e}; peak acceleration of limit: {axes}")

    # the tool's true pose once per period [m]: tip, then the pivot on the tool axis above it;
    # path_u (the curve parameter) is negative off the curve (approach, retract)
    on_curve = result.trace.periods["path_u"] >= 0
    tip, pivot = result.trace.tool[on_curve, :3] * 1e3, result.trace.tool[on_curve, 3:] * 1e3
    label = f"{name}: contour error max {path['contour_error_um']['max']:.0f} µm"
    ax_path.plot(tip[:, 0], tip[:, 1], color=f"C{k}", label=label)
    every = slice(0, None, max(1, len(tip) // 10))
    axis = (pivot - tip) / np.linalg.norm(pivot - tip, axis=1, keepdims=True)
    ax_path.quiver(tip[every, 0], tip[every, 1], axis[every, 0], axis[every, 1], color=f"C{k}",
                   angles="xy", scale=4, width=0.004)
    # the metrics list only the axes that moved: a held axis is a bar of 0
    ratios = [peaks[a]["acceleration_ratio"] * 100 if a in peaks else 0.0 for a in AXES]
    ax_peaks.bar(np.arange(len(AXES)) + (k - 0.5) * 0.38, ratios, width=0.38, color=f"C{k}", label=name)

ax_path.set_xlabel("X [mm]")
ax_path.set_ylabel("Y [mm]")
ax_path.set_aspect("equal", adjustable="datalim")
ax_path.set_title("tool tip on the curve, tool axis arrows")
ax_path.legend(fontsize="small", loc="lower right")
ax_peaks.set_xticks(np.arange(len(AXES)), AXES)
ax_peaks.set_xlabel("axis")
ax_peaks.set_ylabel("peak acceleration [% of limit]")
ax_peaks.set_title("effort per axis")
ax_peaks.legend(fontsize="small")
fig.suptitle("tool axis held (freeform) and tilting ±20° (tilted)")
fig.tight_layout()
fig.savefig(out, dpi=100)
print(f"picture: {out.resolve()}")
