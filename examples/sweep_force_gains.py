"""Sweep the grinding-force loop's gains on the flat-plate polishing scenario; print how well each
pair tracks the force setpoint and map it.

    python examples/sweep_force_gains.py [--out sweep_force_gains.png]       # local processes
    python examples/sweep_force_gains.py tcp://host:8786   # a Dask scheduler (pip install '.[sweep]')

``force.kp`` [mm/N] and ``force.ki`` [mm/(N s)] stand for ``program.force.kp`` / ``.ki``. To keep
it quick, every case also overrides the raster: 40 mm step-over and 45 mm margin (two 70 mm passes
instead of the plate's whole face) and a 12 m/min approach, so each run is about 8 s simulated and
the nine cases take about 25 s of CPU on two workers. The picture: the force error's RMS [% of the
setpoint] over the grid. As with any Python process pool, the script's work sits under
``if __name__ == "__main__":``.
"""

import argparse
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np

from cnc_twin.scenario.resources import scenarios_dir
from cnc_twin.studies.sweep import cases, parse_param, run_dask, run_local

KP = (0.002, 0.005, 0.01)  # [mm/N]
KI = (1, 3, 6)  # [mm/(N s)]
QUICK = ("program.path.step_over=40", "program.path.margin=45", "program.approach_feed=12000")
"""one value each: the same shorter raster in every case (mm, mm, mm/min)"""


def main() -> None:
    matplotlib.use("Agg")  # pictures to files only: no display needed
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scheduler", nargs="?", help="a Dask scheduler's address (default: local processes)")
    parser.add_argument("--out", type=Path, default=Path("sweep_force_gains.png"), help="the picture (PNG)")
    args = parser.parse_args()

    scenario = str(scenarios_dir() / "flat_plate_polish.yaml")
    params = [parse_param(f"force.kp={','.join(map(str, KP))}"), parse_param(f"force.ki={','.join(map(str, KI))}")]
    todo = cases(params + [parse_param(text) for text in QUICK])
    if args.scheduler:
        rows = run_dask(scenario, todo, scheduler=args.scheduler)
    else:
        rows = run_local(scenario, todo, workers=2)
    print("kp [mm/N]  ki [mm/(N s)]  force error rms [%]  max [%]  contact overshoot [%]  feed cut [s]")
    for row in sorted(rows, key=lambda r: r["force_rms_pct"]):
        print(f"{row['force.kp']:9.3f}  {row['force.ki']:13.1f}  {row['force_rms_pct']:19.2f}  "
              f"{row['force_max_pct']:7.1f}  {row['force_overshoot_pct']:21.1f}  {row['reduced_feed_s']:12.3f}")

    rms = np.array([[next(r["force_rms_pct"] for r in rows if r["force.kp"] == kp and r["force.ki"] == ki)
                     for kp in KP] for ki in KI])
    fig, ax = plt.subplots(figsize=(5.5, 4))
    image = ax.imshow(rms, origin="lower", cmap="viridis_r")
    for (i, j), value in np.ndenumerate(rms):
        ax.text(j, i, f"{value:.1f}", ha="center", va="center", color="w" if image.norm(value) > 0.5 else "k")
    ax.set_xticks(range(len(KP)), [f"{kp:g}" for kp in KP])
    ax.set_yticks(range(len(KI)), [f"{ki:g}" for ki in KI])
    ax.set_xlabel("force.kp [mm/N]")
    ax.set_ylabel("force.ki [mm/(N s)]")
    ax.set_title("flat plate at 20 N: force error RMS [%]")
    fig.colorbar(image, label="force error RMS [% of setpoint]")
    fig.tight_layout()
    fig.savefig(args.out, dpi=100)
    print(f"picture: {args.out.resolve()}")


if __name__ == "__main__":
    main()
