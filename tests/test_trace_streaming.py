"""A run longer than the recorder's window writes its trace to trace.parquet while it runs, and is
measured from the file a piece at a time: the same signals bit for bit, the same file, the same
figures as the run held whole; the window's memory does not grow with the run; what was written
is readable when the run dies; the CLI moves the file into the run directory."""

from __future__ import annotations

import filecmp
import json

import numpy as np
import pyarrow.parquet as pq
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnc_twin import load_scenario
from cnc_twin.run.curve_windows import curve_windows, run_bounds
from cnc_twin.run.gcode_metrics import gcode_run_metrics
from cnc_twin.run.twin import Twin
from cnc_twin.scenario.resources import scenarios_dir
from cnc_twin.trace.parquet import write_trace
from cnc_twin.trace.recorder import SPILL_GROUPS
from cnc_twin.trace.trace import SAMPLED
from cnc_twin.trace.trace_file import TraceFile
from conftest import run_cli

GROUP = 256
"""periods per row group in these runs: the recorder's window is SPILL_GROUPS of them (1024 periods)"""
CLOCKED = {"wall_time_s", "real_time_factor", "whiteboard", "planning", "interpolator_us_per_period", "memory_mb"}
"""metrics of the wall clock and the process's memory, different in every run"""


def _figures(metrics):
    if isinstance(metrics, dict):
        return {k: _figures(v) for k, v in metrics.items() if k not in CLOCKED}
    return [_figures(v) for v in metrics] if isinstance(metrics, list) else metrics


@pytest.fixture(scope="module")
def runs():
    """gcode_cam_raster held whole, and again written to its file every 1024 periods."""
    source = scenarios_dir() / "gcode_cam_raster.yaml"
    whole = Twin(load_scenario(source))
    held = whole.run()
    spilling = Twin(load_scenario(source))
    spilling.trace_group_periods = GROUP
    streamed = spilling.run()
    return held, streamed, spilling


def test_a_long_run_is_in_its_file_and_reads_back_bit_for_bit(runs):
    held, streamed, twin = runs
    assert isinstance(streamed.trace, TraceFile) and not isinstance(held.trace, TraceFile)
    # the window held at most SPILL_GROUPS row groups however long the run
    assert len(twin.recorder.periods) == SPILL_GROUPS * GROUP < held.trace.whole_periods // 10
    back = streamed.trace.load()
    for name in ("command", "actual", "dac", "pad_force", "periods", "tool"):
        a, b = getattr(held.trace, name), getattr(back, name)
        assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes(), name
    assert streamed.trace.command.tobytes() == held.trace.command.tobytes()  # a Trace's attributes, from the file
    # the twin's memory sampled when the clock started, each time the window moved on, at the end
    memory = streamed.metrics["memory_mb"]
    assert memory["samples"] == 2 + held.trace.whole_periods // (SPILL_GROUPS * GROUP)
    assert 0 < memory["at_start"] <= memory["run_max"]


def test_the_streamed_file_is_the_file_written_whole(runs, tmp_path):
    held, streamed, _ = runs
    write_trace(held.trace, tmp_path / "whole.parquet", scenario_name=held.scenario.name, group_periods=GROUP)
    assert filecmp.cmp(tmp_path / "whole.parquet", streamed.trace.path, shallow=False)
    assert pq.ParquetFile(streamed.trace.path).num_row_groups == -(-len(held.trace.periods) // GROUP)


def test_the_figures_from_the_file_are_the_whole_runs(runs):
    held, streamed, _ = runs
    assert _figures(streamed.metrics) == _figures(held.metrics)
    assert streamed.metrics["path"]["paths_run"] == held.metrics["path"]["feed_paths"] > 1


def test_the_file_pieces_are_cut_as_in_memory(runs):
    held, streamed, _ = runs
    for periods in (100, 1000, 3000):
        a, b = list(held.trace.chunks(periods)), list(streamed.trace.chunks(periods))
        assert [p.first for p in a] == [p.first for p in b] and len(a) > 3
        for p, q in zip(a, b):
            assert all(getattr(p, n).tobytes() == getattr(q, n).tobytes() for n in SAMPLED)


def test_curve_runs_and_their_windows_do_not_depend_on_the_pieces(runs):
    held, _, _ = runs
    whole = [run for _, found in curve_windows(held.trace, 1 << 30) for run in found]
    assert len(whole) == held.metrics["path"]["feed_paths"]
    for periods in (97, 1000):
        pieces = [run for _, found in curve_windows(held.trace, periods) for run in found]
        assert [(r.first, r.stop) for r in pieces] == [(r.first, r.stop) for r in whole]
        for r, s in zip(pieces, whole):
            assert r.window.first == s.window.first
            assert all(getattr(r.window, n).tobytes() == getattr(s.window, n).tobytes() for n in SAMPLED)
    # the path figures are the same; the check of the program's coordinated moves sums piece by piece
    path, program = gcode_run_metrics(held.trace, held.scenario, periods=97)
    assert _figures(path) == _figures(held.metrics["path"])
    assert program["deviation_um"] == held.metrics["program"]["deviation_um"]
    assert program["feed"] == pytest.approx(held.metrics["program"]["feed"], rel=1e-12)


def _runs_by_loop(u):
    """The curve runs of ``path_u`` as the definition says, a period at a time."""
    runs, start = [], None
    for k in range(len(u)):
        if u[k] >= 0 and (start is None or u[k] < u[k - 1]):
            if start is not None:
                runs.append((start, k))
            start = k
        elif u[k] < 0 and start is not None:
            runs.append((start, k))
            start = None
    return runs + ([(start, len(u))] if start is not None else [])


@settings(max_examples=200, deadline=None)
@given(st.lists(st.sampled_from([-1.0, 0.0, 0.3, 0.5, 1.0]), max_size=40), st.integers(0, 40))
def test_run_bounds_find_the_runs_the_definition_gives(u, cut):
    u = np.array(u)
    cut = min(cut, len(u))
    # in two pieces, the second knowing the first's last value
    s1, e1 = run_bounds(u[:cut])
    s2, e2 = run_bounds(u[cut:], u[cut - 1] if cut else -1.0, cut)
    starts, stops = np.concatenate([s1, s2]).tolist(), np.concatenate([e1, e2]).tolist()
    expected = _runs_by_loop(u)
    assert starts == [a for a, _ in expected]
    assert stops == [b for _, b in expected if b < len(u)]


def test_what_was_written_is_readable_when_the_run_dies():
    twin = Twin(load_scenario(scenarios_dir() / "gcode_cam_raster.yaml"))
    twin.trace_group_periods = GROUP

    def dies(t):
        if t.recorder.count > 20_000:
            raise RuntimeError("the run dies")

    with pytest.raises(RuntimeError):
        twin.run(observer=dies)
    written = pq.ParquetFile(twin.recorder.writer.path)  # closed, footer and all
    rows = written.metadata.num_rows
    assert rows >= 20_000 - SPILL_GROUPS * GROUP * 4
    assert np.array_equal(written.read(columns=["period"]).column(0).to_numpy()[::4], np.arange(rows // 4))


DWELL = """(a long dwell: a run of 70 s that takes a few seconds)
G21 G90 G17 G94
G0 Z5
G1 X1 F300
G4 P70
M2
"""


def test_the_cli_moves_a_long_runs_file_into_the_run_directory(tmp_path):
    program = tmp_path / "dwell.ngc"
    program.write_text(DWELL)
    out = tmp_path / "run"
    code, _, err = run_cli("run", str(program), "--in-air", "10", "--no-rrd", "--quiet", "--out", str(out))
    assert code == 0, err
    metrics = json.loads((out / "metrics.json").read_text())
    meta = pq.ParquetFile(out / "trace.parquet").metadata
    assert meta.num_rows == metrics["servo_ticks"] > 70 / 0.00025  # more than the window of 65 536 periods
    assert meta.num_row_groups > SPILL_GROUPS
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dwell.ngc", "run"]  # nothing staged left behind
