"""A short soak (15 s simulated; ``python -m cnc_twin.studies.soak --minutes 10`` is the full one), run
as the command in a fresh process:
periodic planner delays in lockstep lose or tear no record, and memory beyond the trace stays flat."""

from __future__ import annotations

import json
import subprocess
import sys

from cnc_twin.studies.soak import soak_scenario


def test_soak_scenario_repeats_the_cycle_with_periodic_delays():
    raw = soak_scenario(1.0, every=2.0, delay_ms=3.0)
    assert len(raw["program"]["moves"]) % 5 == 0 and len(raw["program"]["moves"]) >= 75
    assert raw["faults"][0]["every"] == 2.0 and raw["faults"][0]["delay"] == 3.0


def test_short_soak_loses_nothing():
    # In a process of its own, as the command runs it: resident memory in this one depends on
    # what earlier tests allocated and freed (pages reused or returned), swinging +-10 MB.
    done = subprocess.run([sys.executable, "-m", "cnc_twin.studies.soak", "--minutes", "0.25", "--every", "2", "--delay", "2"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr + done.stdout
    figures = json.loads(done.stdout)
    assert figures["status"] == "complete" and figures["final_state"] == "FINISHED"
    assert figures["records_rejected"] == 0
    assert figures["records_accepted"] >= figures["records_expected_at_least"]
    assert figures["missed_exchanges"] == 0  # lockstep: late, never missed
    # 50 ms windows every 2 s in about 15 s: some 7 x 50 delayed answers
    assert figures["delayed_exchanges"] >= 100
    assert abs(figures["growth_beyond_trace_mb"]) < 10.0
