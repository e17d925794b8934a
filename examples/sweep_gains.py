"""Sweep two servo gains of one axis on the default scenario; print the best rows, plot them all.

    python examples/sweep_gains.py [--out sweep_gains.png]            # local processes
    python examples/sweep_gains.py tcp://host:8786   # a Dask scheduler (pip install '.[sweep]')

X's position gain ``servo.X.kp`` [1/s] at 30, 60 and 90 with velocity feed-forward
``servo.X.kvff`` [1] at 0.9 and 1.0: six runs of the default jog (5.4 s simulated each), about
12 s of CPU on two workers. The picture: X's following error, RMS and max [um], against kp.
A local sweep runs a process pool, so, as with any Python process pool, the script's work sits
under ``if __name__ == "__main__":`` (single runs need no guard).
"""

import argparse
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt

from cnc_twin.scenario.resources import default_scenario
from cnc_twin.studies.sweep import cases, parse_param, run_dask, run_local


def main() -> None:
    matplotlib.use("Agg")  # pictures to files only: no display needed
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scheduler", nargs="?", help="a Dask scheduler's address (default: local processes)")
    parser.add_argument("--out", type=Path, default=Path("sweep_gains.png"), help="the picture (PNG)")
    args = parser.parse_args()

    todo = cases([parse_param("servo.X.kp=30:90:30"), parse_param("servo.X.kvff=0.9,1.0")])
    if args.scheduler:
        rows = run_dask(str(default_scenario()), todo, scheduler=args.scheduler)
    else:
        rows = run_local(str(default_scenario()), todo, workers=2)
    for row in sorted(rows, key=lambda r: r["ferr_rms_X_mm"])[:3]:
        print(f"kp {row['servo.X.kp']:5.0f}  kvff {row['servo.X.kvff']:.1f}  "
              f"X following error rms {row['ferr_rms_X_mm'] * 1e3:6.2f} um, max {row['ferr_max_X_mm'] * 1e3:6.1f} um")

    fig, ax = plt.subplots(figsize=(7.5, 4))
    for k, kvff in enumerate(sorted({row["servo.X.kvff"] for row in rows})):
        line = sorted((r for r in rows if r["servo.X.kvff"] == kvff), key=lambda r: r["servo.X.kp"])
        kp = [r["servo.X.kp"] for r in line]
        ax.plot(kp, [r["ferr_rms_X_mm"] * 1e3 for r in line], "o-", color=f"C{k}", label=f"kvff {kvff:.1f}: RMS")
        ax.plot(kp, [r["ferr_max_X_mm"] * 1e3 for r in line], "s--", color=f"C{k}", label=f"kvff {kvff:.1f}: max")
    ax.set_xlabel("servo.X.kp [1/s]")
    ax.set_ylabel("X following error [µm]")
    ax.set_yscale("log")
    ax.set_title("jog_axes: X's following error over a gain sweep")
    ax.legend(fontsize="small", loc="center left", bbox_to_anchor=(1.0, 0.5))  # beside: the lines fill the axes
    fig.tight_layout()
    fig.savefig(args.out, dpi=100)
    print(f"picture: {args.out.resolve()}")


if __name__ == "__main__":
    main()
