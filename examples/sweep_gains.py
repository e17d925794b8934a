"""Sweep two servo gains of one axis on the default scenario and print the table's best rows.

    python examples/sweep_gains.py            # local processes
    python examples/sweep_gains.py tcp://host:8786   # a Dask scheduler (pip install '.[sweep]')

A local sweep runs a process pool, so, as with any Python process pool, the script's work sits
under ``if __name__ == "__main__":`` (single runs need no guard).
"""

import sys

from cnc_twin.scenario.resources import default_scenario
from cnc_twin.studies.sweep import cases, parse_param, run_dask, run_local


def main() -> None:
    todo = cases([parse_param("servo.X.kp=30:90:30"), parse_param("servo.X.kvff=0.9,1.0")])
    if len(sys.argv) > 1:
        rows = run_dask(str(default_scenario()), todo, scheduler=sys.argv[1])
    else:
        rows = run_local(str(default_scenario()), todo, workers=2)
    for row in sorted(rows, key=lambda r: r["ferr_rms_X_mm"])[:3]:
        print(f"kp {row['servo.X.kp']:5.0f}  kvff {row['servo.X.kvff']:.1f}  "
              f"X following error rms {row['ferr_rms_X_mm'] * 1e3:6.2f} um, max {row['ferr_max_X_mm'] * 1e3:6.1f} um")


if __name__ == "__main__":
    main()
