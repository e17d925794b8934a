"""Run the same kind of curve with the tool axis held and tilting; compare contour and effort.

    python examples/compare_tool_axis.py
"""

from cnc_twin import load_scenario, run_scenario
from cnc_twin.scenario.resources import scenarios_dir

for name in ("nurbs_freeform.yaml", "nurbs_tilted.yaml"):
    result = run_scenario(load_scenario(scenarios_dir() / name))
    path = result.metrics["path"]
    peaks = path["axis_peaks"]
    axes = ", ".join(f"{a} {p['acceleration'] / p['acceleration_limit'] * 100:.0f} %" for a, p in peaks.items())
    print(f"{name:22} contour max {path['contour_error_um']['max']:7.1f} um, rms {path['contour_error_um']['rms']:6.1f} um,"
          f" feed fluctuation {path['feed_fluctuation']['max']:.1e}; peak acceleration of limit: {axes}")
