"""A PC program of your own that plans a jog by itself and streams it to the twin's card.

Plans each move as a synchronised, time-optimal trapezoid within every axis's velocity and
acceleration limit (and the feed along X Y Z, when one is given), stretched to whole interpolation
periods, and streams the moves, dwells and the end of the program through the card's whiteboard
with the client library in clients/python (nothing of the twin is imported).

    cnc-twin serve jog_axes --attach /tmp/jog &        # the card and the machine, waiting
    python examples/pc_jog.py /tmp/jog                 # this program: the PC side

The machine's limits, its home and the jog come from a JSON file (default: pc_jog.json beside
this file, the bundled machine's limits and jog_axes's moves): ``period`` [s], ``home`` (6 values,
m or rad), ``axes`` (name, max_velocity [m/s | rad/s], max_acceleration [m/s^2 | rad/s^2]),
``moves`` (``to``: 6 values or null to stay, ``feed`` [m/s] or null for rapid, ``dwell`` [s]),
``settle`` [s].
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "clients" / "python"))

import cnct_layout  # noqa: E402
from cnct_client import Card, Streamer, dwell, end_of_program, move  # noqa: E402

LINEAR = ("X", "Y", "Z")


def trapezoid(v_max: float, a_max: float, period: float) -> tuple[float, float, float, float, int]:
    """The fastest trapezoid over s: 0 -> 1 within ``v_max`` [1/s] and ``a_max`` [1/s^2], stretched
    to whole periods: ``(t_acc, t_flat, v_peak, accel, periods)``."""
    if v_max * v_max / a_max >= 1.0:  # never reaches v_max: a triangle
        t_acc = math.sqrt(1.0 / a_max)
        t_flat, v_peak = 0.0, a_max * t_acc
    else:
        t_acc = v_max / a_max
        t_flat, v_peak = 1.0 / v_max - t_acc, v_max
    duration = 2.0 * t_acc + t_flat
    periods = max(1, math.ceil(duration / period - 1e-9))
    k = periods * period / duration  # >= 1: slower, so every limit still holds
    return t_acc * k, t_flat * k, v_peak / k, a_max / k**2, periods


def plan(config: dict):
    """The jog's records and its length [periods]."""
    period, axes = config["period"], config["axes"]
    here, records, total = list(config["home"]), [], 0
    for step in config["moves"]:
        target = [here[i] if t is None else t for i, t in enumerate(step["to"])]
        v_s, a_s, xyz_sq = math.inf, math.inf, 0.0
        for axis, p0, p1 in zip(axes, here, target):
            d = abs(p1 - p0)
            if d == 0.0:
                continue
            v_s = min(v_s, axis["max_velocity"] / d)
            a_s = min(a_s, axis["max_acceleration"] / d)
            if axis["name"] in LINEAR:
                xyz_sq += d * d
        if not math.isinf(v_s):
            xyz = math.sqrt(xyz_sq)
            if step.get("feed") is not None and xyz > 0.0:
                v_s = min(v_s, step["feed"] / xyz)
            t_acc, t_flat, v_peak, accel, periods = trapezoid(v_s, a_s, period)
            records.append(move(target, t_acc, t_flat, v_peak, accel, periods))
            total += periods
        here = target
        if step.get("dwell", 0.0) > 0:
            n = max(1, math.ceil(step["dwell"] / period - 1e-9))
            records.append(dwell(n))
            total += n
    if config.get("settle", 0.0) > 0:
        n = max(1, math.ceil(config["settle"] / period - 1e-9))
        records.append(dwell(n))
        total += n
    records.append(end_of_program())
    return records, total


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("attach", type=Path, help="the attach folder cnc-twin serve printed")
    parser.add_argument("--config", type=Path, default=Path(__file__).with_name("pc_jog.json"))
    args = parser.parse_args()
    records, periods = plan(json.loads(args.config.read_text()))
    with Card(args.attach) as card:
        stream = Streamer(card)
        for record in records:
            stream.add(record)
        stream.complete = True
        card.attach(program_periods=periods)
        stream.run()
        ended = card.end_state()
    if ended is None:
        print("the card ended without a word (the twin's run was cut short)", file=sys.stderr)
        return 1
    state, fault = ended
    finished = state == cnct_layout.DSP_STATE_FINISHED
    print(f"card: {'finished' if finished else f'state {state}, fault {fault}'}; sent {stream.next_index} records, "
          f"{stream.retransmitted} again")
    return 0 if finished else 3


if __name__ == "__main__":
    sys.exit(main())
