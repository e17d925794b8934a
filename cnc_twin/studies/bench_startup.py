"""The whole command, not only the run: ``cnc-twin run`` and ``cnc-twin validate`` of bundled
scenarios timed as whole processes, beside the floor (a Python process importing numpy, mujoco
and numba), with where the time outside the run's clock went.

Each command runs ``repeat`` times in a fresh process (alternating with the others, so all see
the same machine state); its wall time is taken from before the process starts to after it ends,
and its phases from the marks it writes (:mod:`cnc_twin.core.phases`: the interpreter's start,
the imports, the load, building the twin, loading the kernels, waiting for the planner, the
run's clock, the metrics, each file). A run writes its run directory with its default recording
(``recording.rrd``), as ``cnc-twin run SCENARIO`` does. The fastest of each command's repeats is
reported, with its first (a cold start: caches the command fills on its first run show there),
and the figures above the floor are those of the same benchmark run.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from cnc_twin.core import server_link
from cnc_twin.core.phases import VARIABLE, read_marks
from cnc_twin.core.server_control import start_in_a_new_process

SCENARIOS = ("jog_axes", "nurbs_circle", "gcode_cam_raster", "freeform_polish")
"""the scenarios measured by default: a jog, a NURBS curve, a CAM program of 4408 lines, a
polishing run in contact"""
FLOOR = ("-c", "import numpy, mujoco, numba")
"""what any run's process needs at least: the interpreter and the three native libraries"""
PHASE_NAMES = {
    "entry": "python start", "imported": "imports", "loaded": "load", "twin": "twin built",
    "kernels": "kernels", "planner": "planner ready", "clock": "run's clock", "result": "metrics",
    "trace": "trace.parquet", "files": "other files", "recording": "recording.rrd", "metrics": "metrics.json",
    "written": "run directory", "end": "exit", "forked": "to the server",
}
"""each mark's phase: the time from the mark before it (or the process's start) to it"""


def _cnc_twin() -> list[str]:
    """The command that starts ``cnc-twin`` with this interpreter (and this checkout)."""
    return [sys.executable, "-m", "cnc_twin"]


def time_process(command: list[str], *, marks: Path | None = None, timeout: float = 600.0,
                 env: dict[str, str] | None = None) -> dict[str, Any]:
    """Run ``command`` once: its wall time [s] from before the start to after the end, its exit
    code, and (``marks``: a file for :mod:`cnc_twin.core.phases`) each phase's seconds;
    ``env``: variables set for it."""
    env = {**os.environ, **(env or {})}
    if marks is not None:
        marks.unlink(missing_ok=True)
        env[VARIABLE] = str(marks)
    started = time.monotonic()
    done = subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env, timeout=timeout)
    ended = time.monotonic()
    out: dict[str, Any] = {"wall_s": ended - started, "code": done.returncode}
    if done.returncode != 0:
        out["said"] = done.stderr.decode(errors="replace").strip().splitlines()[-1:]
    if marks is not None and marks.exists():
        out["phases"] = phases(started, read_marks(marks), ended)
    return out


def phases(started: float, marks: list[tuple[float, str]], ended: float) -> dict[str, float]:
    """Seconds of each phase: from the process's start (or the mark before) to each mark, and
    from the last mark to the process's end (``exit``); a mark written twice (a validate of several
    files) adds up."""
    out: dict[str, float] = {}
    before = started
    for stamp, name in [*marks, (ended, "end")]:
        label = PHASE_NAMES.get(name, name)
        out[label] = out.get(label, 0.0) + (stamp - before)
        before = stamp
    return out


MODES = {"": {server_link.VARIABLE: "off"}, " (server)": {server_link.VARIABLE: "on"}}
"""each command measured twice: in a new interpreter of its own (the warm server off), and handed
to the warm server (started and ready before the measurements)"""


def bench_startup(scenarios: tuple[str, ...] = SCENARIOS, *, repeat: int = 3,
                  progress=None) -> dict[str, Any]:
    """Time the floor, then ``cnc-twin run`` and ``cnc-twin validate`` of each of ``scenarios``
    (bundled names), ``repeat`` times each, alternating, in each of :data:`MODES`;
    ``progress(text)`` is told each step.

    Returns the figures: ``floor_s`` and, per command (``run jog_axes``, ``validate jog_axes``,
    ``run jog_axes (server)``...),
    ``wall_s`` (the fastest), ``first_s``, ``run_clock_s`` (the run's own clock, from its
    metrics), ``outside_s`` (wall less the clock), ``above_floor_s`` (outside less the floor) and
    ``phases`` (the fastest repeat's). What they were measured on is kept beside them by
    ``cnc-twin bench --json`` (:mod:`cnc_twin.studies.bench_context`)."""
    from cnc_twin.scenario.resources import scenarios_dir

    folder = Path(tempfile.mkdtemp(prefix="cnc-twin-startup-"))
    try:
        commands: dict[str, tuple[list[str], dict[str, str]]] = {"floor": ([sys.executable, *FLOOR], {})}
        for mode, env in MODES.items():
            for name in scenarios:
                path = str(scenarios_dir() / f"{name}.yaml")
                commands[f"run {name}{mode}"] = ([*_cnc_twin(), "run", path, "--quiet", "--out"], env)
                commands[f"validate {name}{mode}"] = ([*_cnc_twin(), "validate", path], env)
        if progress is not None:
            progress("starting the warm server")
        if not start_in_a_new_process():
            raise RuntimeError("the warm server did not come up")
        times: dict[str, list[dict[str, Any]]] = {key: [] for key in commands}
        for k in range(repeat):
            for key, (command, env) in commands.items():
                if progress is not None:
                    progress(f"{key} ({k + 1} of {repeat})")
                if key.startswith("run "):
                    out = folder / f"{key.replace(' ', '_')}_{k}"
                    measured = time_process([*command, str(out)], marks=folder / "marks", env=env)
                    metrics = out / "metrics.json"
                    if metrics.exists():
                        measured["run_clock_s"] = json.loads(metrics.read_text())["wall_time_s"]
                    shutil.rmtree(out, ignore_errors=True)
                else:
                    measured = time_process(command, marks=None if key == "floor" else folder / "marks", env=env)
                times[key].append(measured)
        return _figures(times)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _figures(times: dict[str, list[dict[str, Any]]]) -> dict[str, Any]:
    floor = min(t["wall_s"] for t in times.pop("floor"))
    figures: dict[str, Any] = {"floor_s": floor, "commands": {}}
    for key, runs in times.items():
        failed = [t for t in runs if t["code"] != 0]
        if failed:
            figures["commands"][key] = {"failed": failed[0].get("said"), "code": failed[0]["code"]}
            continue
        best = min(runs, key=lambda t: t["wall_s"])
        clock = best.get("run_clock_s", 0.0)
        figures["commands"][key] = {
            "wall_s": best["wall_s"], "first_s": runs[0]["wall_s"], "run_clock_s": clock,
            "outside_s": best["wall_s"] - clock, "above_floor_s": best["wall_s"] - clock - floor,
            "phases": best.get("phases", {}),
        }
    return figures



def format_startup(figures: dict[str, Any]) -> str:
    """The figures as a table: per command its whole wall time, the run's clock, what is outside
    it above the floor, then the phases that took 0.05 s or more."""
    lines = [f"floor (python -c \"import numpy, mujoco, numba\"): {figures['floor_s']:.2f} s",
             f"{'command':<28} {'whole s':>8} {'first s':>8} {'clock s':>8} {'outside-floor s':>16}  phases (s)"]
    for key, row in figures["commands"].items():
        if "failed" in row:
            lines.append(f"{key:<28} failed (exit {row['code']}): {' '.join(row['failed'] or [])}")
            continue
        shown = ", ".join(f"{name} {seconds:.2f}" for name, seconds in row["phases"].items() if seconds >= 0.05)
        lines.append(f"{key:<28} {row['wall_s']:>8.2f} {row['first_s']:>8.2f} {row['run_clock_s']:>8.2f} "
                     f"{row['above_floor_s']:>16.2f}  {shown}")
    return "\n".join(lines)
