"""Soak run: a long lockstep program with periodic planner delays; memory and records checked.

``python -m cnc_twin.studies.soak --minutes 10`` runs ten simulated minutes of point-to-point moves of
all five positioning axes, in lockstep, streamed with a 200 ms look-ahead, with the planner late by ``--delay`` ms on every answer
for 50 ms of every ``--every`` seconds (scenario fault ``planner_delay`` with ``every``). It
reports, as JSON:

- memory: the process's resident set sampled a few hundred times during the run, less the
  trace recorded so far (its raw bytes: the recorder's typed columns); its growth from the first
  sample to the last is what the run held beyond the trace (per-period bookkeeping such as the
  exchange latencies, 16 bytes a period, is included and reported);
- records: accepted, rejected (torn or corrupted: CRC or framing), retransmitted, and whether
  the card executed the last record of the program (none lost);
- the exchanges the planner answered late (at least ``--delay``): proof the delays happened;
- the run's status, simulated and wall time.

Exit code 0 when no record was rejected or lost and the run finished, 1 otherwise.

Run it in a process of its own (as the command does): in a process that has already allocated
and freed memory, freed pages are reused or returned unpredictably and the memory figures swing
by some 10 MB.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import Any

MOVES = ({"X": 120, "Y": 80, "Z": -60, "feed": 9000}, {"A": 20, "B": -15}, {"X": -100, "Y": -60, "feed": 12000},
         {"Z": -10, "A": 0, "B": 0}, {"X": 0, "Y": 0, "Z": 0})
"""one cycle of the soak program (3.88 s), repeated"""
CYCLE_S = 3.88
"""one cycle's time [s], to size the program"""


def soak_scenario(minutes: float, *, every: float = 5.0, delay_ms: float = 2.0) -> dict[str, Any]:
    """The soak scenario mapping: ``minutes`` of simulated moves, planner delays every ``every`` s."""
    cycles = max(1, math.ceil(minutes * 60.0 / CYCLE_S))
    return {
        "name": f"soak_{minutes:g}min",
        "description": "long lockstep run with periodic planner delays",
        "program": {"type": "point_to_point", "moves": [dict(m) for _ in range(cycles) for m in MOVES],
                    "settle": 0.2},
        # a short look-ahead: the planner streams records through the whole run, not all at once
        "planner": {"lookahead": 200.0},
        "faults": [{"type": "planner_delay", "at": 1.0, "duration": 0.05, "delay": delay_ms, "every": every}],
    }


def _rss_bytes() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096


def soak(minutes: float, *, every: float = 5.0, delay_ms: float = 2.0, progress=None) -> dict[str, Any]:
    """Run the soak; returns the figures (see the module docstring)."""
    from cnc_twin.trace.layout import PERIOD_DTYPE, TICK_BYTES, TOOL_BYTES
    from cnc_twin.scenario.load import scenario_from_dict
    from cnc_twin.run.twin import Twin

    raw = soak_scenario(minutes, every=every, delay_ms=delay_ms)
    twin = Twin(scenario_from_dict(raw))
    samples: list[tuple[float, int, int]] = []

    def observe(t: Twin) -> None:
        recorder = t.recorder
        periods = recorder.count // recorder.ticks_per_period
        samples.append((recorder.count * t.scenario.timing.servo_period, _rss_bytes(),
                        recorder.count * TICK_BYTES + periods * (PERIOD_DTYPE.itemsize + TOOL_BYTES)))

    result = twin.run(observer=observe, progress=progress)
    m, wb = result.metrics, result.metrics["whiteboard"]
    beyond = [rss - trace for _, rss, trace in samples]
    warm = len(beyond) // 10  # skip the start (imports, first allocations, page cache warm-up)
    growth = beyond[-1] - beyond[warm] if len(beyond) > warm + 1 else 0
    periods = wb["periods"]
    measured_periods = (samples[-1][0] - samples[warm][0]) / twin.scenario.timing.interpolation_period if samples else 0
    total_records = len(raw["program"]["moves"]) + 1  # a Move per move, the end
    return {
        "status": m["status"],
        "final_state": m["final_state"],
        "sim_time_s": m["sim_time_s"],
        "wall_time_s": m["wall_time_s"],
        "periods": periods,
        "records_accepted": wb["records_accepted"],
        "records_rejected": wb["records_rejected"],
        "records_retransmitted": wb["records_retransmitted"],
        "missed_exchanges": wb["missed_exchanges"],
        "delayed_exchanges": int((result.exchange_latency[1] >= delay_ms * 1e3).sum()),
        "records_expected_at_least": total_records,
        "trace_mb": samples[-1][2] / 1e6 if samples else 0.0,
        "rss_start_mb": samples[warm][1] / 1e6 if samples else 0.0,
        "rss_end_mb": samples[-1][1] / 1e6 if samples else 0.0,
        "growth_beyond_trace_mb": growth / 1e6,
        "growth_beyond_trace_bytes_per_period": growth / max(1.0, measured_periods),
        "samples": len(samples),
    }


def main(argv: list[str] | None = None) -> int:
    """``python -m cnc_twin.studies.soak``: the soak run, its figures printed as JSON; exit 1 if a
    record was rejected or the run did not finish with every record accepted."""
    from cnc_twin.run.progress import ProgressBar

    parser = argparse.ArgumentParser(prog="python -m cnc_twin.studies.soak", description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=10.0, help="simulated minutes (default 10)")
    parser.add_argument("--every", type=float, default=5.0, help="planner delay window every this many s")
    parser.add_argument("--delay", type=float, default=2.0, help="planner delay per answer in the window [ms]")
    args = parser.parse_args(argv)
    figures = soak(args.minutes, every=args.every, delay_ms=args.delay,
                   progress=ProgressBar("soak", period=1e-3))
    print(json.dumps(figures, indent=2))
    ok = (figures["records_rejected"] == 0 and figures["status"] == "complete"
          and figures["final_state"] == "FINISHED" and figures["records_accepted"] >= figures["records_expected_at_least"])
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
