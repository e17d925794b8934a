"""Run every bundled scenario on each bundled machine and print what each run did, as a Markdown table.

    python scripts/bundled_figures.py [SCENARIO.yaml ...] [--machines compliant,rigid] [--json OUT]

One row per scenario and machine (``BUNDLED_MACHINES``: the compliant default, the rigid
variant), from the run's own metrics (each computed from the trace): how the run ended, the
largest following error of the linear axes (X/Y/Z, um) and of the tilting axes (A/B, arcsec),
the tool tip's contour error against the path where the program has one (max / RMS, um), and
for polishing runs the force tracking (RMS, % of the setpoint) and the removed volume (mm3).
The README's table of the bundled scenarios on both machines comes from here.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from cnc_twin import load_scenario, run_scenario
from cnc_twin.scenario.resources import BUNDLED_MACHINES, bundled_machine_names, scenarios_dir

UM_PER_MM = 1e3
ARCSEC_PER_DEG = 3600.0


def figures(metrics: dict) -> dict:
    """The row's figures from a run's metrics (None where the run has no such figure)."""
    ferr = metrics["following_error"]
    path = metrics.get("path") or {}
    contour = path.get("contour_error_um")
    passes = (metrics.get("contour") or {}).get("passes") or []
    if contour is None and passes:  # a contour program: its passes' tool-tip contour errors
        contour = {"max": max(p["contour_error_um"]["max"] for p in passes),
                   "rms": max(p["contour_error_um"]["rms"] for p in passes)}
    force = ((metrics.get("polish") or {}).get("force") or {}).get("tracking") or {}
    removal = (metrics.get("polish") or {}).get("removal") or {}
    fault = metrics.get("fault") or {}
    return {
        "ended": metrics.get("final_state", metrics["status"]) + (f" ({fault['code']})" if fault.get("code") else ""),
        "sim_time_s": metrics["sim_time_s"],
        "ferr_xyz_um": max(ferr[a]["max"] for a in "XYZ") * UM_PER_MM,
        "ferr_ab_arcsec": max(ferr[a]["max"] for a in "AB") * ARCSEC_PER_DEG,
        "contour_max_um": contour["max"] if contour else None,
        "contour_rms_um": contour["rms"] if contour else None,
        "force_rms_pct": force.get("rms_error_pct"),
        "removed_mm3": removal.get("volume_mm3"),
    }


def _cell(value, digits: int) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenarios", nargs="*", type=Path)
    parser.add_argument("--machines", default="compliant,rigid", help=f"of {', '.join(BUNDLED_MACHINES)}")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)
    try:
        machines = bundled_machine_names(args.machines)
    except ValueError as exc:
        parser.error(f"--machines: {exc}")
    files = args.scenarios or sorted(scenarios_dir().glob("*.yaml"))
    print("| scenario | machine | ended | simulated [s] | ferr X/Y/Z max [um] | ferr A/B max [arcsec] "
          "| contour max / RMS [um] | force RMS [%] | removed [mm3] |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    rows = {}
    for file in files:
        for machine in machines:
            result = run_scenario(load_scenario(file, overrides=dict(BUNDLED_MACHINES[machine])))
            f = figures(result.metrics)
            rows[f"{file.stem}/{machine}"] = f
            contour = ("-" if f["contour_max_um"] is None
                       else f"{f['contour_max_um']:.1f} / {f['contour_rms_um']:.1f}")
            print(f"| {file.stem} | {machine} | {f['ended']} | {f['sim_time_s']:.2f} | {f['ferr_xyz_um']:.1f} "
                  f"| {f['ferr_ab_arcsec']:.1f} | {contour} | {_cell(f['force_rms_pct'], 2)} "
                  f"| {_cell(f['removed_mm3'], 4)} |", flush=True)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
