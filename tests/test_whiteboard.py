"""The planner process and the whiteboard, end to end: streaming, faults, modes, cleanup."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from cnc_twin import load_scenario, run_scenario
from cnc_twin.trace.parquet import read_trace
from cnc_twin.scenario.resources import default_scenario
from cnc_twin.scenario.load import scenario_from_dict
from cnc_twin.whiteboard.block import leaked_segments, leftover_segments
from cnc_twin.whiteboard.status import DspState, FaultCode

JOG = load_scenario(default_scenario())


def jog_with(**changes) -> dict:
    """The default scenario as a mapping, with top-level keys replaced."""
    import yaml

    raw = yaml.safe_load(default_scenario().read_text())
    raw.update(changes)
    return raw


def steps_program(n: int = 6, step_mm: float = 10.0, settle: float = 0.1) -> dict:
    """Short X moves back to back: a program streamed move by move under a look-ahead."""
    return {"type": "point_to_point", "settle": settle,
            "moves": [{"X": step_mm * (i + 1)} for i in range(n)]}


def test_lockstep_run_is_bit_identical_on_repeat_and_with_planner_delays():
    clean = run_scenario(JOG).trace.columns()
    again = run_scenario(JOG).trace.columns()
    delayed = run_scenario(scenario_from_dict(jog_with(
        faults=[{"type": "planner_delay", "at": 0.5, "duration": 0.05, "delay": 2.0}]))).trace.columns()
    for name in clean:
        assert np.array_equal(clean[name], again[name]), name
        assert np.array_equal(clean[name], delayed[name]), name  # lockstep: late answers are waited for


def test_program_larger_than_the_fifo_is_streamed_in_chunks():
    """300 moves (14100 words) through a 2048-word RAM (992-word FIFO) in 512-byte chunks."""
    program = {"type": "point_to_point", "settle": 0.0,
               "moves": [{"C": 0.036 * ((i % 2) + 1)} for i in range(300)]}
    sc = scenario_from_dict({"name": "stream", "whiteboard": {"words": 2048, "chunk": 512}, "program": program})
    result = run_scenario(sc)
    wb = result.metrics["whiteboard"]
    assert result.status == "complete" and result.metrics["final_state"] == "FINISHED"
    assert wb["records_accepted"] == 301 and wb["records_rejected"] == 0
    fill = result.trace.period_signals["fifo_fill"]
    assert fill.max() <= 992
    executed = result.trace.period_signals["last_seq_executed"]
    assert executed[-1] == 301 and np.all(np.diff(executed) >= 0)


def test_bit_flip_is_rejected_never_executed_and_resent():
    base = jog_with(planner={"lookahead": 200.0})
    clean = run_scenario(scenario_from_dict(base))
    flipped = run_scenario(scenario_from_dict({**base, "faults": [{"type": "record_bitflip", "at": 1.0, "bit": 77}]}))
    wb = flipped.metrics["whiteboard"]
    assert wb["records_rejected"] == 1 and wb["records_retransmitted"] >= 1
    assert flipped.status == "complete"
    # The bad record was caught and resent long before it was due: the machine did exactly the same.
    for name, column in clean.trace.columns().items():
        if name != "records_rejected":
            assert np.array_equal(column, flipped.trace.columns()[name]), name
    assert flipped.trace.period_signals["records_rejected"][-1] == 1


def test_planner_killed_mid_move_stops_the_machine_within_limits():
    result = run_scenario(scenario_from_dict(jog_with(faults=[{"type": "planner_kill", "at": 1.0}])))
    assert result.status == "fault"
    assert result.metrics["fault"]["code"] == "PLANNER_LOST"
    assert 1.0 <= result.metrics["fault"]["time_s"] <= 1.01
    assert result.metrics["final_state"] == "FAULT"
    trace = result.trace
    state = trace.period_signals["state"]
    assert DspState.STOPPING in state and state[-1] == DspState.FAULT
    # Y was moving at 1.0 s; it decelerated to rest along its path within its acceleration limit.
    y = JOG.axis("Y")
    tpp = JOG.timing.ticks_per_period
    cmd = trace.command[tpp - 1::tpp, 1] / y.counts_per_unit
    v = np.diff(cmd) / JOG.timing.interpolation_period
    a = np.diff(v) / JOG.timing.interpolation_period
    k_fault = int(round(1.0 / JOG.timing.interpolation_period))
    assert abs(v[k_fault]) > 0.05                     # moving when the planner died
    assert abs(v[-1]) < 1e-9                          # at rest at the end
    assert np.max(np.abs(a[k_fault - 5:])) <= y.max_acceleration * 1.01
    assert trace.time[-1] < 1.5                       # stopped, not finished


def test_planner_heartbeat_stop_is_detected_in_lockstep():
    sc = scenario_from_dict(jog_with(planner={"heartbeat_timeout": 200.0},
                                     faults=[{"type": "planner_stall", "at": 0.5, "duration": 1500.0}]))
    result = run_scenario(sc)
    assert result.status == "fault"
    assert "heartbeat" in result.metrics["fault"]["message"]
    assert result.metrics["fault"]["time_s"] == pytest.approx(0.501, abs=0.002)


def test_realtime_stall_enters_feed_hold_and_finishes_the_program():
    sc = scenario_from_dict({
        "name": "rt_stall",
        "timing": {"mode": "realtime"},
        "planner": {"lookahead": 20.0},
        "faults": [{"type": "planner_stall", "at": 0.3, "duration": 50.0}],
        # 20 ms moves: the running move plus the one always sent behind it (40 ms) cannot cover a
        # 50 ms stall, so the card runs dry between moves
        "program": steps_program(n=40, step_mm=0.2),
    })
    result = run_scenario(sc)
    wb = result.metrics["whiteboard"]
    assert result.status == "complete" and result.metrics["final_state"] == "FINISHED"
    assert wb["missed_exchanges"] >= 20        # ~50 periods without an answer
    assert wb["underrun_periods"] > 0          # the card ran dry ...
    state = result.trace.period_signals["state"]
    assert DspState.FEED_HOLD in state         # ... held ...
    assert state[-1] == DspState.FINISHED      # ... and finished the program
    # X at 8 mm, within the stiction band: the axis stops where the Coulomb friction holds it, up to
    # friction / kp = 6.7 mV / 0.8 mV per count = 8 counts off (the integrator takes it in afterwards)
    assert result.trace.actual[-1, 0] == pytest.approx(8000, abs=8)


def test_cli_planner_kill_exits_3_with_complete_run_directory(tmp_path, write_scenario):
    path = write_scenario(jog_with(faults=[{"type": "planner_kill", "at": 0.5}]))
    out = tmp_path / "run"
    # only what this run made counts: a segment another process left on the machine (a killed
    # session's run, say) is not this run's leak
    segments_before = set(leftover_segments())
    proc = subprocess.run([sys.executable, "-m", "cnc_twin", "run", str(path), "--out", str(out)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 3, proc.stderr
    assert "PLANNER_LOST" in proc.stderr and "Traceback" not in proc.stderr
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == "fault" and metrics["fault"]["code"] == "PLANNER_LOST"
    trace = read_trace(out / "trace.parquet")
    assert trace["state"][-1] == DspState.FAULT and trace["fault"][-1] == FaultCode.PLANNER_LOST
    assert not leaked_segments(set(leftover_segments()) - segments_before)


def test_benchmark_paths_move_and_verify_every_record():
    """The speed benchmarks run the real ports; check they move what they claim (not their speed)."""
    from cnc_twin.studies.bench_whiteboard import exchange_round_trip, stream_throughput

    rt = exchange_round_trip(200)
    assert rt["exchanges"] == 200 and 0 < rt["min_us"] <= rt["median_us"] <= rt["p99_us"]
    block = stream_throughput(kind="block", count=50)
    assert block["records"] == 51 and block["bytes"] == 50 * 4096 + 12
    move = stream_throughput(kind="move", count=300)
    assert move["records"] == 301


@pytest.mark.parametrize("path", ["batched", "compiled-servo", "python-servo"])
def test_an_error_mid_run_still_reaps_the_planner_and_unlinks_the_segment(path, monkeypatch):
    from cnc_twin.run.period_batch import PeriodBatch
    from cnc_twin.run.twin import Twin

    twin = Twin(JOG, compiled=path != "python-servo", batch=path == "batched")
    calls = {"n": 0}
    # the servo loop's innermost call: a batch of periods, the compiled period, or the reference
    # path's physics step
    owner, name, at = {"batched": (PeriodBatch, "run", 30), "compiled-servo": (twin.kernel, "run_period", 500),
                       "python-servo": (twin.plant, "step", 500)}[path]
    real = getattr(owner, name)

    def failing(*args):
        calls["n"] += 1
        if calls["n"] == at:
            raise RuntimeError("simulated failure inside the servo loop")
        return real(*args)

    monkeypatch.setattr(owner, name, failing)
    segments_before = set(leftover_segments())
    with pytest.raises(RuntimeError, match="simulated failure"):
        twin.run()
    # the autouse fixture checks /dev/shm and child processes after this test too
    assert not leaked_segments(set(leftover_segments()) - segments_before)


def test_memory_map_in_the_docs_matches_the_layout():
    from pathlib import Path

    from cnc_twin.whiteboard.layout import Layout

    doc = (Path(__file__).resolve().parent.parent / "docs" / "whiteboard.md").read_text()
    for address, owner, contents in Layout().memory_map():
        assert f"| {address} | {owner} | {contents}" in doc, (address, owner, contents)


def test_card_goes_solo_once_the_program_is_streamed_and_still_notices_a_dead_planner():
    import os
    import signal

    from cnc_twin.run.twin import Twin

    result = run_scenario(JOG)
    wb = result.metrics["whiteboard"]
    assert wb["exchanges"] < 100 < wb["periods"]  # everything was sent early; no more exchanges

    twin = Twin(JOG)
    killed = []

    def kill_when_solo(t):
        if t.port.solo and not killed:
            os.kill(t.process.pid, signal.SIGKILL)
            killed.append(t.recorder.count)

    faulted = twin.run(observer=kill_when_solo)
    assert killed and faulted.status == "fault"
    assert faulted.metrics["fault"]["code"] == "PLANNER_LOST"
    assert faulted.metrics["final_state"] == "FAULT"


def test_the_fifo_interrupt_leaves_the_trace_as_an_exchange_every_period_does():
    """A program larger than the FIFO (two passes of the freeform raster): with the card's
    FIFO-threshold interrupt the planner is asked only when its next record fits, a handful of
    exchanges instead of thousands, and every record reaches the card in the same period, so the
    lockstep trace is the same bit for bit."""
    from cnc_twin.scenario.resources import scenarios_dir

    runs = {}
    for interrupt in (True, False):
        scenario = load_scenario(scenarios_dir() / "freeform_polish.yaml", overrides={
            "program.path.margin": 45.0, "whiteboard.fifo_interrupt": interrupt})
        runs[interrupt] = run_scenario(scenario)
    on, off = runs[True], runs[False]
    fill = on.trace.period_signals.per_period("fifo_fill")
    assert fill.max() > 0.9 * (8192 // 2 - 32)  # the FIFO was full: the planner had to wait for room
    cols_on, cols_off = on.trace.columns(), off.trace.columns()
    for key in cols_on:
        assert np.array_equal(cols_on[key], cols_off[key]), key
    assert on.metrics["whiteboard"]["exchanges"] < 20 < 1000 < off.metrics["whiteboard"]["exchanges"]
    assert on.metrics["whiteboard"]["records_accepted"] == off.metrics["whiteboard"]["records_accepted"]


def test_a_signal_while_the_segment_is_being_created_leaves_no_segment():
    """A SIGTERM whose handler raises, arriving between shm_open and ftruncate (seen in CI: a
    0-byte segment left in /dev/shm by a sweep worker ended by its pool): the run ends by the
    handler's exception, and the segment is unlinked all the same."""
    code = f"""
import os, signal, sys
from cnc_twin import load_scenario
from cnc_twin.run.twin import Twin

signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
twin = Twin(load_scenario({str(default_scenario())!r}))
truncate = os.ftruncate

def signalled_truncate(fd, size):
    os.kill(os.getpid(), signal.SIGTERM)  # its handler runs at the next bytecode
    truncate(fd, size)

os.ftruncate = signalled_truncate
print(os.getpid(), flush=True)
twin.run()
"""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    pid = proc.stdout.split()[0]
    assert proc.returncode == 143, proc.stderr
    assert [name for name in leftover_segments() if name.startswith(f"cnc_twin_{pid}_")] == []
