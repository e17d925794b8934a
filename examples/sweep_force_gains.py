"""Sweep the grinding-force loop's gains on the flat-plate polishing scenario and print how well
each pair tracks the force setpoint.

    python examples/sweep_force_gains.py            # local processes
    python examples/sweep_force_gains.py tcp://host:8786   # a Dask scheduler (pip install '.[sweep]')

``force.kp`` [mm/N] and ``force.ki`` [mm/(N s)] stand for ``program.force.kp`` / ``.ki``. The
raster's step-over is widened to 40 mm so each run takes about 12 s simulated (a few seconds).
As with any Python process pool, the script's work sits under ``if __name__ == "__main__":``.
"""

import sys
import tempfile
from pathlib import Path

import yaml

from cnc_twin.scenario.resources import scenarios_dir
from cnc_twin.studies.sweep import cases, parse_param, run_dask, run_local


def main() -> None:
    raw = yaml.safe_load((scenarios_dir() / "flat_plate_polish.yaml").read_text())
    raw["program"]["path"]["step_over"] = 40.0  # fewer passes: a quicker sweep
    with tempfile.TemporaryDirectory() as folder:
        scenario = Path(folder) / "plate.yaml"
        scenario.write_text(yaml.safe_dump(raw))
        todo = cases([parse_param("force.kp=0.002,0.01,0.03"), parse_param("force.ki=1,3,6")])
        if len(sys.argv) > 1:
            rows = run_dask(str(scenario), todo, scheduler=sys.argv[1])
        else:
            rows = run_local(str(scenario), todo, workers=2)
    print("kp [mm/N]  ki [mm/(N s)]  force error rms [%]  max [%]  contact overshoot [%]  feed cut [s]")
    for row in sorted(rows, key=lambda r: r["force_rms_pct"]):
        print(f"{row['force.kp']:9.3f}  {row['force.ki']:13.1f}  {row['force_rms_pct']:19.2f}  "
              f"{row['force_max_pct']:7.1f}  {row['force_overshoot_pct']:21.1f}  {row['reduced_feed_s']:12.3f}")


if __name__ == "__main__":
    main()
