"""Run one circle by NURBS, point-by-point and DDA interpolation, with analog and with pulse output.

    python examples/compare_interpolation.py

The passes of each run share the machine and the feed profile, so the table shows what the
interpolation and the output stage each add to the contour error.
"""

from cnc_twin import load_scenario, run_scenario
from cnc_twin.scenario.resources import scenarios_dir

print(f"{'output':8}{'method':16}{'contour max um':>16}{'rms um':>9}{'command dev max um':>20}")
for output in ("analog", "pulse"):
    scenario = load_scenario(scenarios_dir() / "circle_three_ways.yaml", overrides={"command_output": output})
    for p in run_scenario(scenario).metrics["contour"]["passes"]:
        err = p["contour_error_um"]
        print(f"{output:8}{p['method']:16}{err['max']:>16.2f}{err['rms']:>9.2f}{p['command_deviation_um']['max']:>20.3f}")
