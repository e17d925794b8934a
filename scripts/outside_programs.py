"""Run NC programs nobody here wrote on the twin, in the air, and check each run from its trace.

    python scripts/outside_programs.py [FOLDER] [--in-air 10] [--only TEXT] [--timeout 1800]
                                       [--json OUT] [--keep RUNS_DIR]

FOLDER defaults to ../shared/data/outside-gcode/progs (real CAM programs from public
repositories; their sources and licences in SOURCES.tsv beside it). For each program:

1. **Read**: our reader with the bundled machine's tool table (T1-T99); with the LinuxCNC oracle
   unpacked (``scripts/fetch_linuxcnc_oracle.py``) rs274 reads it too, with the same table, and a
   program rs274 refuses is listed as such and not run (the corpus's must-show is about the
   programs LinuxCNC reads).
2. **Place**: where the program's tool tip goes (:func:`cnc_twin.gcode.extents.extents`, after its
   own offsets). A program that fits the machine's reach as written runs with every default
   (``cnc-twin run PROGRAM --in-air D``); one that does not is centred in X and Y on the
   workpiece by a one-line scenario, ``work_offsets: {G54: {X: .., Y: ..}}`` (its Z0 stays on the
   workpiece top, as CAM programs put it), printed in the table. A program that probes the work
   (G38.2 / G38.4 must touch) runs on the work, centred on it (``in_air: 0``): the pad probes
   the block's top, and the program goes on from what the card found.
3. **Run** ``cnc-twin run`` in its own process (lockstep, the compliant default machine), its
   wall time and peak memory measured (``os.wait4``), with ``--timeout`` seconds at most.
4. **Check from the trace** (``trace.parquet``), not from the run's own metrics: the commanded
   position of every axis at each interpolation period, differenced into velocity and
   acceleration over the whole run and X/Y/Z/A/B's jerk over the feed paths (rapids, moves run
   one by one and the spindle's speed changes are trapezoids, as LinuxCNC 2.9 plans them), against the parameter file's limits (1 %
   tolerance), and the final state FINISHED.

Verdicts: ``ran`` (finished, no axis over a limit), ``refused`` (exit 2 before any motion with
one line: the line is shown), ``over limit`` / ``fault`` / ``failed`` / ``timeout`` (each a
defect to look at), ``not read`` (rs274 refuses it too). The table and the counts are README's.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_FOLDER = next((path for path in (ROOT.parent / "shared", Path("/work/shared"))
                       if (path / "data" / "outside-gcode" / "progs").is_dir()), ROOT.parent / "shared") \
    / "data" / "outside-gcode" / "progs"
"""beside the checkout (as CI lays shared/ out), else the workplace's"""
LIMIT_TOLERANCE = 1.01
"""a commanded peak above this multiple of its limit is a violation (as the run's metrics use)"""
SUFFIXES = (".ngc", ".nc", ".gcode", ".tap", ".cnc", ".txt")
MAXRSS = "outside-programs-maxrss-kb:"
"""the line GNU time adds to a run's standard error"""


def machine_reach(in_air: float) -> tuple[np.ndarray, np.ndarray, object]:
    """The box [mm] the tool tip can reach with A = B = 0 (the soft limits through the head's
    kinematics, in the workpiece frame, less the raise ``in_air``), and the axes' configs."""
    from cnc_twin import load_scenario
    from cnc_twin.geometry.kinematics import HeadGeometry
    from cnc_twin.machine.model_file import load_model
    from cnc_twin.scenario.resources import models_dir, scenarios_dir

    scenario = load_scenario(scenarios_dir() / "jog_axes.yaml")  # the default machine
    head = HeadGeometry.from_model(load_model(models_dir() / scenario.machine["model"]))
    shift = np.asarray(head.pivot_home) + np.asarray(head.tool_offset) - np.asarray(head.workpiece_origin)
    soft = [a.allowed if a.allowed is not None else a.travel for a in scenario.axes[:3]]
    low = np.array([lo for lo, _ in soft]) + shift
    high = np.array([hi for _, hi in soft]) + shift
    low[2] -= in_air * 1e-3
    high[2] -= in_air * 1e-3
    return low * 1e3, high * 1e3, scenario.axes


def read(path: Path, tools: Path, oracle) -> tuple[str, str, tuple | None, bool]:
    """(our verdict, its message, the tool tip's box [mm], whether it probes the work (a G38.2 or
    G38.4, which must touch)): ``read`` or ``refused``."""
    from cnc_twin.gcode.extents import extents
    from cnc_twin.gcode.interpreter import ProgramError, read_program
    from cnc_twin.gcode.listing import read_tool_table
    from cnc_twin.gcode.source import Source
    from cnc_twin.gcode.toolpath import ToolpathError, operations

    try:
        calls = read_program(Source.read(path), read_tool_table(tools, "mm")).calls
    except ProgramError as exc:
        return "refused", f"{path.name}:{exc.line}: {exc.message}", None, False
    if oracle is not None:
        theirs = oracle(path.read_text(errors="replace"))
        if theirs:
            return "refused", f"rs274 refuses it too: {theirs}", None, False
    touches = any(c.name == "STRAIGHT_PROBE" and c.payload[0].kind in (2, 4) for c in calls)
    try:
        box = extents(operations(calls))
    except ToolpathError:
        box = None
    return "read", "", box, touches


def rs274(tools: Path):
    """A function: program text -> rs274's error line ('' when it reads the program whole), or
    None without the oracle."""
    sys.path.insert(0, str(ROOT / "tests"))
    import oracle

    if not oracle.available():
        return None
    table = tools.read_text()
    folder = Path(tempfile.mkdtemp(prefix="outside-rs274-"))

    def run(text: str) -> str:
        # rs274 reads tool lengths in inches: the table's lengths are 0, so the units do not matter
        oracle.TOOL_TABLE = table
        _, said = oracle.run(text, folder)
        return said[-2] if len(said) >= 2 else (said[-1] if said else "")

    return run


def placement(box, low, high, in_air: float, touches: bool = False) -> dict:
    """The one-line scenario that places the program (none when it fits as written and ``in_air``
    clears the work): centred in X and Y on the workpiece when it does not fit, and raised enough
    that its lowest point stays ``in_air`` above the workpiece top (Z0 in the workpiece frame) when
    it cuts deeper than that. A program that probes the work (``touches``) runs on it, not in
    the air (it must touch: the pad probes the block's top), centred on the workpiece."""
    if box is None:
        return {}
    lo, hi = box
    setup = {}
    if touches:
        centre = 0.5 * (lo + hi)
        return {"work_offsets": {"G54": {"X": round(-float(centre[0]), 3), "Y": round(-float(centre[1]), 3)}},
                "in_air": 0}
    if not (np.all(lo[:2] >= low[:2]) and np.all(hi[:2] <= high[:2])):
        centre = 0.5 * (lo + hi)
        setup["work_offsets"] = {"G54": {"X": round(-float(centre[0]), 3), "Y": round(-float(centre[1]), 3)}}
    if lo[2] < 0.0:
        setup["in_air"] = round(in_air - float(lo[2]), 3)
    return setup


def run(path: Path, setup: dict, in_air: float, out: Path, timeout: float) -> dict:
    """``cnc-twin run`` in its own process: exit code, its last error line, wall time [s], peak
    memory [MB]."""
    source = path
    if setup:
        source = out.parent / f"{out.name}.yaml"
        source.write_text(yaml.safe_dump({"name": out.name, "program": {"type": "gcode", "file": str(path), **setup}}))
    air = [] if "in_air" in setup else ["--in-air", str(in_air)]
    # GNU time measures the run's own peak memory (a child forked from this process would count
    # this process's pages until it execs)
    command = [sys.executable, "-m", "cnc_twin", "run", str(source), *air, "--no-rrd", "--quiet", "--out", str(out)]
    if Path("/usr/bin/time").is_file():  # Debian's package 'time'; without it no memory figure
        command = ["/usr/bin/time", "-f", f"{MAXRSS} %M", *command]
    t0 = time.perf_counter()
    with tempfile.TemporaryFile("w+") as stderr:
        process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=stderr, text=True, start_new_session=True)
        timer = threading.Timer(timeout, os.killpg, (process.pid, 9))  # the run with the time around it
        timer.start()
        process.wait()
        timer.cancel()
        stderr.seek(0)
        err = stderr.read()
    wall = time.perf_counter() - t0
    rss = next((float(line.split()[1]) / 1024.0 for line in err.splitlines() if line.startswith(MAXRSS)), None)
    # GNU time's own lines: its figure, and how the run ended
    err = "\n".join(line for line in err.splitlines()
                    if not line.startswith((MAXRSS, "Command exited with", "Command terminated by")))
    if process.returncode != 0 and wall >= timeout:
        return {"code": None, "error": f"timeout after {timeout:g} s", "wall_s": wall, "rss_mb": rss}
    lines = [line for line in err.splitlines() if line.strip() and not line.startswith("note:")]
    return {"code": process.returncode, "error": lines[-1] if lines else "", "wall_s": wall, "rss_mb": rss,
            "notes": [line for line in err.splitlines() if line.startswith("note:")]}


def trace_check(out: Path, axes) -> dict:
    """From the run directory's trace: the final state, the simulated time and, per axis, the
    largest commanded velocity / acceleration / jerk over its limit (the worst named)."""
    from cnc_twin.trace.parquet import read_trace

    metrics = json.loads((out / "metrics.json").read_text())
    trace = read_trace(out / "trace.parquet")
    period = trace["period"]
    ends = np.flatnonzero(np.diff(period) != 0)  # the last tick of each period
    T = float(np.median(np.diff(trace["time"][ends]))) if len(ends) > 2 else 1e-3
    # jerk only where the card runs a feed path (path_u >= 0): its rapids and one-by-one moves
    # are trapezoids (as LinuxCNC 2.9's planner makes them), their jerk unlimited by design
    on_path = trace["path_u"][ends] >= 0.0
    worst, where = 0.0, ""
    for cfg in axes:
        q = trace[f"command_{cfg.name}"][ends] / cfg.counts_per_unit
        for order, limit, name in ((1, cfg.max_velocity, "velocity"), (2, cfg.max_acceleration, "acceleration"),
                                   (3, cfg.max_jerk, "jerk")):
            if len(q) <= order or limit <= 0:
                continue
            d = np.abs(np.diff(q, n=order)) / T ** order / limit
            if name == "jerk" and cfg.name == "C":  # the spindle's speed ramps are trapezoids too
                continue
            if name == "jerk":  # a difference counts where all the periods it spans are on a path
                d = d * np.all([on_path[i:len(on_path) - order + i] for i in range(order + 1)], axis=0)
            k = int(np.argmax(d))
            if d[k] > worst:
                worst, where = float(d[k]), f"{cfg.name} {name} at {(k + order) * T:.3f} s"
    return {"final_state": metrics.get("final_state"), "sim_s": metrics.get("sim_time_s"),
            "worst_ratio": worst, "worst": where, "fault": metrics.get("fault")}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("folder", nargs="?", type=Path, default=DEFAULT_FOLDER)
    parser.add_argument("--in-air", type=float, default=10.0, help="[mm] how far above where it is written (10)")
    parser.add_argument("--only", default=None, help="only programs whose name contains this")
    parser.add_argument("--timeout", type=float, default=1800.0, help="[s] a run's wall time at most")
    parser.add_argument("--json", type=Path, default=None, help="write every row here")
    parser.add_argument("--keep", type=Path, default=None, help="keep the run directories here")
    parser.add_argument("--markdown", type=Path, default=None, help="write the table as Markdown here")
    args = parser.parse_args(argv)

    from cnc_twin.scenario.resources import models_dir

    tools = models_dir() / "polisher.tbl"  # the bundled machine's (T1-T99), as a run uses
    programs = sorted(p for p in args.folder.iterdir() if p.suffix.lower() in SUFFIXES
                      and (args.only is None or args.only in p.name))
    low, high, axes = machine_reach(args.in_air)
    oracle = rs274(tools)
    print(f"{len(programs)} programs in {args.folder}; the tip reaches X {low[0]:.0f}..{high[0]:.0f} "
          f"Y {low[1]:.0f}..{high[1]:.0f} Z {low[2]:.0f}..{high[2]:.0f} mm (in the air by {args.in_air:g} mm); "
          f"rs274 {'checks each reading' if oracle else 'absent: our reader alone'}", flush=True)
    keep = args.keep or Path(tempfile.mkdtemp(prefix="outside-runs-"))
    keep.mkdir(parents=True, exist_ok=True)
    rows = []
    for number, path in enumerate(programs):
        row = {"program": path.name, "lines": sum(1 for _ in path.open(errors="replace"))}
        verdict, message, box, touches = read(path, tools, oracle)
        if verdict != "read":
            row.update(verdict="not read", detail=message)
        else:
            setup = placement(box, low, high, args.in_air, touches)
            row["setup"] = setup
            row["reach_mm"] = None if box is None else [[float(v) for v in box[0]], [float(v) for v in box[1]]]
            out = keep / f"{number:03d}_{path.stem[:56]}"  # numbered: long names share their first letters
            result = run(path, setup, args.in_air, out, args.timeout)
            row.update(result)
            if result["code"] == 0:
                row.update(trace_check(out, axes))
                bad = row["worst_ratio"] > LIMIT_TOLERANCE
                row["verdict"] = ("ran" if row["final_state"] == "FINISHED" and not bad else
                                  "over limit" if bad else "fault")
                row["detail"] = f"{row['final_state']}, worst {row['worst_ratio']:.2f} of its limit ({row['worst']})"
            elif result["code"] == 2:
                row.update(verdict="refused", detail=result["error"])
            else:
                row.update(verdict="timeout" if result["code"] is None else "failed", detail=result["error"])
        rows.append(row)
        print(f"{row['verdict']:10s} {path.name[:58]:58s} {row.get('wall_s', 0):7.1f} s "
              f"{(row.get('rss_mb') or 0):6.0f} MB  {row.get('detail', '')[:160]}"
              + (f"  [{json.dumps(row['setup'])}]" if row.get("setup") else ""), flush=True)
        if args.json:
            args.json.write_text(json.dumps(rows, indent=1))
    counts: dict[str, int] = {}
    for row in rows:
        counts[row["verdict"]] = counts.get(row["verdict"], 0) + 1
    print("counts: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    if args.markdown:
        args.markdown.write_text(markdown(rows, counts, args.in_air))
    return 0


def markdown(rows: list[dict], counts: dict[str, int], in_air: float) -> str:
    """The table, one row a program: verdict, what it took, the one-line set-up, the detail."""
    out = [f"Counts: {', '.join(f'{k} {v}' for k, v in sorted(counts.items()))} (in the air by at least "
           f"{in_air:g} mm above the workpiece top).", "",
           "| program | lines | verdict | simulated s | wall s | peak MB | set-up | detail |",
           "|---|---:|---|---:|---:|---:|---|---|"]
    for row in rows:
        setup = json.dumps(row["setup"]) if row.get("setup") else ""
        sim = f"{row['sim_s']:.1f}" if row.get("sim_s") else ""
        wall = f"{row['wall_s']:.1f}" if row.get("wall_s") else ""
        rss = f"{row['rss_mb']:.0f}" if row.get("rss_mb") else ""
        detail = str(row.get("detail", "")).replace("|", "/").replace(str(DEFAULT_FOLDER) + "/", "")
        out.append(f"| {row['program']} | {row['lines']} | {row['verdict']} | {sim} | {wall} | {rss} | {setup} | "
                   f"{detail[:200]} |")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    sys.exit(main())
