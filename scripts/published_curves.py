"""Run every bundled published curve at 2400 and 6000 mm/min and interpolation periods of 1, 0.5
and 0.25 ms, and print README's table: each limit checked from the trace, not from the planner.

    python scripts/published_curves.py [--feeds 2400,6000] [--periods 1,0.5,0.25]
                                       [--machines rigid,compliant] [--json OUT]

Each curve runs on each machine named (BUNDLED_MACHINES: the rigid reference machine, and the compliant
one with its two-mass axes, bridge mode and drive loops, at the gains its parameter file holds),
so the table shows what the mechanics cost the same program.

Per run (lockstep, compiled twin):
- chord error [um] and feed fluctuation, from the trace (``metrics.path``);
- the largest commanded axis velocity / acceleration / jerk over its limit, computed here by
  finite differences of the commanded positions in the trace, period by period over the whole
  curve part of the run (``path_u >= 0``), feed holds and window joins included;
- contour error max / RMS [um]: where the tool really was (MuJoCo's tool site, period by period)
  against the curve;
- the real-time factor, and the card's longest wait for the planner's answer [ms] (the longest
  exchange latency: in lockstep the card waits for every answer);
- after the table, this machine's own floor for that wait: two bare processes ping-ponging a
  byte over pipes for 5 s (no twin, no Python work), the same sleep-and-wake the planner does.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from cnc_twin import load_scenario, run_scenario
from cnc_twin.scenario.resources import BUNDLED_MACHINES, bundled_machine_names, scenarios_dir


def trace_axis_ratios(result) -> tuple[float, float, float, str]:
    """(velocity, acceleration, jerk) peak / limit over X, Y, Z on the curve part, and where the
    worst is ("Y jerk at 3.217 s"), from the trace's commanded positions alone."""
    sc, trace = result.scenario, result.trace
    tpp, T = sc.timing.ticks_per_period, sc.timing.interpolation_period
    u = trace.periods["path_u"]
    on = np.flatnonzero(u >= 0.0)
    first, last = max(on[0] - 3, 0), min(on[-1] + 3, len(u) - 1)
    ticks = np.arange(first, last + 1) * tpp + (tpp - 1)
    position = trace.command[ticks, :3] / trace.counts_per_unit[:3]  # [m], period ends
    lim = sc.program.limits
    worst = (0.0, "")
    ratios = []
    for order, limits, name in ((1, lim.axis_velocity, "velocity"), (2, lim.axis_acceleration, "acceleration"),
                                (3, lim.axis_jerk, "jerk")):
        d = np.diff(position, n=order, axis=0) / T**order
        r = np.abs(d) / np.asarray(limits)[None, :]
        ratios.append(float(r.max()))
        k, axis = np.unravel_index(int(np.argmax(r)), r.shape)
        if r[k, axis] > worst[0]:
            worst = (float(r[k, axis]), f"{'XYZ'[axis]} {name} at {(first + k + order) * T:.3f} s")
    return ratios[0], ratios[1], ratios[2], worst[1]


def run_one(file: Path, feed: float, period_ms: float, machine: str = "rigid") -> dict:
    overrides = {"planner.feed": feed, "timing.interpolation_period": period_ms,
                 "timing.servo_period": min(0.25, period_ms), "timing.physics_timestep": min(0.25, period_ms),
                 **BUNDLED_MACHINES[machine]}
    result = run_scenario(load_scenario(file, overrides=overrides))
    m = result.metrics
    row = {"curve": file.stem, "machine": machine, "feed": feed, "period_ms": period_ms, "status": m["status"],
           "fault": (m.get("fault") or {}).get("message")}
    path = m.get("path")
    if path is not None and result.status == "complete":
        v, a, j, where = trace_axis_ratios(result)
        row.update({
            "chord_um": path["chord_error_um"]["max"], "chord_tolerance_um": path["chord_error_um"]["tolerance"],
            "feed_fluctuation": path["feed_fluctuation"]["max"],
            "velocity_ratio": v, "acceleration_ratio": a, "jerk_ratio": j, "worst": where,
            "contour_max_um": path["contour_error_um"]["max"], "contour_rms_um": path["contour_error_um"]["rms"],
            "real_time_factor": m["real_time_factor"],
            "longest_wait_ms": (m["whiteboard"]["exchange_latency_us"]["max"] or 0.0) / 1e3,
            "length_mm": path["length_mm"],
        })
    return row


def table(rows: list[dict]) -> str:
    head = ("| curve | machine | feed mm/min | period ms | status | chord um (tol 1) | feed fluct. | v / a / j over "
            "limit (worst) | contour max / rms um | RTF | longest wait ms |")
    out = [head, "|" + " --- |" * 11]
    for r in rows:
        start = f"| {r['curve']} | {r['machine']} | {r['feed']:g} | {r['period_ms']:g} |"
        if "chord_um" not in r:
            out.append(f"{start} {r['status']}: {r['fault']} |" + " |" * 6)
            continue
        out.append(f"{start} {r['status']} | {r['chord_um']:.3f} | "
                   f"{r['feed_fluctuation']:.1e} | {r['velocity_ratio']:.2f} / {r['acceleration_ratio']:.2f} / "
                   f"{r['jerk_ratio']:.2f} ({r['worst']}) | {r['contour_max_um']:.1f} / {r['contour_rms_um']:.1f} | "
                   f"{r['real_time_factor']:.1f} | {r['longest_wait_ms']:.1f} |")
    return "\n".join(out)


def wake_up_floor(seconds: float = 5.0, work: float = 60e-6) -> dict:
    """This machine's floor for the card's wait: two bare processes ping-ponging one byte over
    pipes (the side that answers sleeps in ``read``, as the planner sleeps on its doorbell), the
    asking side computing ``work`` seconds between exchanges, as the card simulates a period.
    Round-trip times [ms]: median, p99, max over ``seconds``."""
    import os
    import time

    ask_r, ask_w = os.pipe()
    answer_r, answer_w = os.pipe()
    pid = os.fork()
    if pid == 0:  # the answering side
        while os.read(ask_r, 1) == b"p":
            os.write(answer_w, b"a")
        os._exit(0)
    trips = []
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        busy = time.perf_counter()
        while time.perf_counter() - busy < work:
            pass
        t0 = time.perf_counter()
        os.write(ask_w, b"p")
        os.read(answer_r, 1)
        trips.append(time.perf_counter() - t0)
    os.write(ask_w, b"q")
    os.waitpid(pid, 0)
    trips.sort()
    return {"median_ms": trips[len(trips) // 2] * 1e3, "p99_ms": trips[int(len(trips) * 0.99)] * 1e3,
            "max_ms": trips[-1] * 1e3, "exchanges": len(trips)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenarios", nargs="*", type=Path)
    parser.add_argument("--feeds", default="2400,6000")
    parser.add_argument("--periods", default="1,0.5,0.25")
    parser.add_argument("--machines", default="rigid,compliant", help=f"of {', '.join(BUNDLED_MACHINES)}")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)
    try:
        machines = bundled_machine_names(args.machines)
    except ValueError as exc:
        parser.error(f"--machines: {exc}")
    files = args.scenarios or sorted((scenarios_dir() / "published").glob("*.yaml"))
    rows = []
    for file in files:
        for feed in (float(x) for x in args.feeds.split(",")):
            for period in (float(x) for x in args.periods.split(",")):
                for machine in machines:
                    rows.append(run_one(file, feed, period, machine))
                    print(table(rows[-1:]).splitlines()[-1], flush=True)
    print()
    print(table(rows))
    floor = wake_up_floor()
    print(f"\nthis machine's wake-up floor (bare pipe ping-pong, {floor['exchanges']} exchanges in 5 s): "
          f"median {floor['median_ms'] * 1e3:.0f} us, p99 {floor['p99_ms'] * 1e3:.0f} us, max {floor['max_ms']:.1f} ms")
    if args.json:
        args.json.write_text(json.dumps({"rows": rows, "wake_up_floor": floor}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
