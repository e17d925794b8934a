"""A long run's trace worked through piece by piece (row groups, metrics) gives what the whole
trace gives: the file's columns bit for bit, the figures the whole arrays make."""

from __future__ import annotations

import numpy as np
import pyarrow.parquet as pq
import pytest

from cnc_twin import load_scenario, run_scenario
from cnc_twin.run.metrics import compute_metrics
from cnc_twin.scenario.resources import scenarios_dir
from cnc_twin.trace.parquet import read_trace, write_trace


@pytest.fixture(scope="module")
def result():
    return run_scenario(load_scenario(scenarios_dir() / "nurbs_circle.yaml"))


def test_pieces_join_into_the_whole_trace(result):
    trace = result.trace
    whole = trace.columns()
    pieces = list(trace.chunks(periods=777))
    assert len(pieces) == -(-len(trace.periods) // 777) > 3
    assert [p.first for p in pieces] == [k * 777 * trace.ticks_per_period for k in range(len(pieces))]
    joined = {name: np.concatenate([p.columns()[name] for p in pieces]) for name in whole}
    for name, values in whole.items():
        assert np.array_equal(joined[name], values), name


def test_the_file_in_row_groups_reads_back_as_the_trace(result, tmp_path):
    path = tmp_path / "trace.parquet"
    write_trace(result.trace, path, scenario_name="x", group_periods=500)
    groups = pq.ParquetFile(path).num_row_groups
    assert groups == -(-len(result.trace.periods) // 500) and groups > 3
    back, whole = read_trace(path), result.trace.columns()
    assert back.keys() == whole.keys()
    for name in whole:
        assert np.array_equal(back[name], whole[name]), name


def test_metrics_from_pieces_are_the_whole_arrays_figures(result):
    trace, sc = result.trace, result.scenario
    metrics = compute_metrics(trace, sc, wall_time=1.0, dac_saturations=[0] * 6, warnings={})
    e = trace.following_error
    for i, cfg in enumerate(sc.axes):
        m = metrics["following_error"][cfg.name]
        assert m["max_counts"] == float(np.max(np.abs(e[:, i])))
        assert m["rms_counts"] == pytest.approx(float(np.sqrt(np.mean(e[:, i] ** 2))), rel=1e-12)
        assert metrics["final_following_error"][cfg.name]["counts"] == float(e[-1, i])
    assert metrics["pad_force_max_n"] == float(np.max(trace.pad_force))


def test_a_per_period_signal_at_period_ends_is_the_per_tick_one_sampled(result):
    trace = result.trace
    tpp = trace.ticks_per_period
    for name in ("path_u", "path_ds", "mark", "state"):
        values = trace.at_period_ends(name)
        assert values.dtype == trace.period_signals[name].dtype
        assert np.array_equal(values, trace.period_signals[name][tpp - 1::tpp]), name
