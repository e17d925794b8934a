"""Programs of hours: what reading, validating and running a long CAM program costs, against its
length (``python benchmarks/bench_long_programs.py [--passes 25 250 2500] [--json OUT]``).

The program is a 3-axis CAM-style raster as CAM writes a finishing pass over a waved surface:
``passes`` passes of 200 mm along X, 0.5 mm apart in Y (250 passes cover 125 mm of the 200 x 150 mm
block; more go over it again, back and forth, as a polishing job repeats), a G1 line every 0.1 mm with Z following ``0.5 sin(x / 10) cos(y / 15)`` mm, four
decimals, under ``G64 P0.01`` at F3000, zig-zag (the step over is one more G1). 250 passes are
500 000 lines, about 50 m of path and 1100 s of machining; the same bytes every time.

For each length, each in its own process with its peak memory from GNU time (``%M``) and its
wall time: ``cnc-twin gcode --canon`` (to /dev/null) beside LinuxCNC's ``rs274 -g`` when the
oracle is unpacked (``scripts/fetch_linuxcnc_oracle.py``), ``cnc-twin validate``, and ``cnc-twin
run --in-air 10 --no-rrd`` (the raster 10 mm above where it is written: a dry run, so the pad
never touches), with the run's own clock and the twin's memory while it ran (when its clock
started, and the most it held from then to the end: ``memory_mb``) from its ``metrics.json``. A process killed (the
out-of-memory killer, or ``--timeout``) is reported as such. Speed and memory are measured and
printed, not asserted; a row per run goes to ``--json``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

LENGTH = 200.0
"""[mm] of each pass along X"""
STEP = 0.1
"""[mm] between programmed points along a pass"""
STEP_OVER = 0.5
"""[mm] between passes"""
FEED = 3000.0
"""[mm/min]"""
ROWS = 250
"""passes across the face (125 mm of the block's 150 mm); a longer program goes over it again,
back and forth, as a polishing job repeats its raster"""
CNC_TWIN = Path(sys.executable).parent / "cnc-twin"
MAXRSS = "bench-maxrss-kb:"


def raster_text(passes: int) -> str:
    """The program of ``passes`` passes (module docstring)."""
    points = int(round(LENGTH / STEP))
    xs = [-0.5 * LENGTH + STEP * k for k in range(points + 1)]
    y0 = -0.5 * STEP_OVER * (min(passes, ROWS) - 1)
    out = [f"(a {passes}-pass raster over a waved surface: benchmarks/bench_long_programs.py)",
           "G21 G90 G17 G94 G64 P0.01", "G0 Z5", f"G0 X{xs[0]:.4f} Y{y0:.4f}",
           f"G1 Z{0.5 * math.sin(xs[0] / 10.0) * math.cos(y0 / 15.0):.4f} F600", f"F{FEED:g}"]
    for k in range(passes):
        row = k % ROWS if (k // ROWS) % 2 == 0 else ROWS - 1 - k % ROWS  # back over the face every ROWS passes
        y = y0 + STEP_OVER * row
        row = xs if k % 2 == 0 else xs[::-1]
        cy = math.cos(y / 15.0)
        first = 0 if k else 1
        out += [f"G1 X{x:.4f} Y{y:.4f} Z{0.5 * math.sin(x / 10.0) * cy:.4f}" for x in row[first:]]
    out += ["G0 Z5", "M2"]
    return "\n".join(out) + "\n"


def timed(command: list[str], timeout: float, env=None) -> dict:
    """Run ``command`` (output to /dev/null): exit code (None when killed by the timeout), wall
    time [s], peak memory [MB] (GNU time), the last line of its standard error."""
    if Path("/usr/bin/time").is_file():
        command = ["/usr/bin/time", "-f", f"{MAXRSS} %M", *command]
    started = time.perf_counter()
    with tempfile.TemporaryFile("w+") as err:
        try:
            done = subprocess.run(command, stdout=subprocess.DEVNULL, stderr=err, timeout=timeout, env=env)
            code = done.returncode
        except subprocess.TimeoutExpired:
            code = None
        wall = time.perf_counter() - started
        err.seek(0)
        lines = err.read().splitlines()
    rss = next((float(line.split()[1]) / 1024.0 for line in lines if line.startswith(MAXRSS)), None)
    said = [line for line in lines if line.strip() and not line.startswith((MAXRSS, "Command "))]
    return {"code": code, "wall_s": round(wall, 3), "rss_mb": None if rss is None else round(rss, 1),
            "said": said[-1] if said else ""}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--passes", type=int, nargs="+", default=[25, 250, 2500])
    parser.add_argument("--timeout", type=float, default=7200.0, help="[s] each process at most")
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--keep", type=Path, default=None, help="keep the programs and runs here")
    args = parser.parse_args(argv)
    import oracle

    from cnc_twin.studies.bench_context import measurement_context

    folder = args.keep or Path(tempfile.mkdtemp(prefix="long-programs-"))
    folder.mkdir(parents=True, exist_ok=True)
    lib = oracle.ROOT / "usr" / "lib"
    rs274_env = dict(os.environ, LD_LIBRARY_PATH=f"{lib}:{lib / 'x86_64-linux-gnu'}")
    # each command in its own process: a warm server would run it in a fork of its own, whose
    # memory and time GNU time cannot see (it measures the small client)
    own_env = dict(os.environ, CNC_TWIN_SERVER="off")
    table = ROOT / "models" / "polisher.tbl"
    rows = []
    measured = measurement_context(["python", "benchmarks/bench_long_programs.py", *(argv or sys.argv[1:])])
    print(f"{'passes':>6} {'lines':>9} {'step':<10} {'code':>4} {'wall s':>8} {'peak MB':>8}  notes", flush=True)
    for passes in args.passes:
        program = folder / f"raster_{passes}.ngc"
        program.write_text(raster_text(passes))
        lines = sum(1 for _ in program.open())
        steps = [("gcode", [str(CNC_TWIN), "gcode", str(program), "--canon"], own_env)]
        if oracle.available():
            steps.append(("rs274", [str(oracle.RS274), "-t", str(table), "-g", str(program)], rs274_env))
        steps.append(("validate", [str(CNC_TWIN), "validate", str(program)], own_env))
        out = folder / f"run_{passes}"
        steps.append(("run", [str(CNC_TWIN), "run", str(program), "--in-air", "10", "--no-rrd", "--quiet",
                              "--out", str(out)], own_env))
        for name, command, env in steps:
            row = {"passes": passes, "lines": lines, "step": name, **timed(command, args.timeout, env)}
            if name == "run" and (out / "metrics.json").is_file():
                metrics = json.loads((out / "metrics.json").read_text())
                row["sim_s"] = metrics.get("sim_time_s")
                row["run_clock_s"] = metrics.get("wall_time_s")
                row["final_state"] = metrics.get("final_state")
                row["memory_mb"] = metrics.get("memory_mb")  # the twin's own, from the clock's start to its end
            rows.append(row)
            notes = row["said"][:90] if row["code"] not in (0,) else ""
            if name == "run" and "sim_s" in row:
                notes = f"{row['sim_s']:.0f} s simulated, the run's clock {row['run_clock_s']:.1f} s, {row['final_state']}"
                if row["memory_mb"]:
                    notes += f"; while running {row['memory_mb']['at_start']:.0f} -> {row['memory_mb']['run_max']:.0f} MB"
            print(f"{passes:>6} {lines:>9} {name:<10} {str(row['code']):>4} {row['wall_s']:>8.1f} "
                  f"{(row['rss_mb'] or 0):>8.0f}  {notes}", flush=True)
            if args.json:  # after each step: a benchmark stopped early keeps what it measured
                args.json.write_text(json.dumps({"measured": measured, "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
