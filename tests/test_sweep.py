"""Sweeps: parameter parsing, local pool and Dask giving the same table, lost workers."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from cnc_twin.studies.sweep import WALL_CLOCK_COLUMNS, Param, best_row, cases, parse_param, run_case, run_local

SHORT = {"name": "sweep", "program": {"type": "point_to_point", "settle": 0.02, "moves": [{"X": 5}]}}


@pytest.fixture
def scenario_file(write_scenario):
    return str(write_scenario(SHORT))


def test_parse_param_forms_and_errors():
    assert parse_param("servo.X.kp=20:80:20") == Param("servo.X.kp", (20.0, 40.0, 60.0, 80.0))
    assert parse_param("servo.X.ki=0,400") == Param("servo.X.ki", (0, 400))
    assert parse_param("program.settle=0.5").values == (0.5,)
    for bad in ("servo.X.kp", "servo.X.kp=80:20:10", "a=1:2:0", "a=x:y:z", "=3"):
        with pytest.raises(ValueError):
            parse_param(bad)


def test_cases_grid_and_random():
    params = [parse_param("a=1,2"), parse_param("b=10:30:10")]
    assert cases(params) == [{"a": 1, "b": 10.0}, {"a": 1, "b": 20.0}, {"a": 1, "b": 30.0},
                             {"a": 2, "b": 10.0}, {"a": 2, "b": 20.0}, {"a": 2, "b": 30.0}]
    drawn = cases(params, random=5, seed=3)
    assert len(drawn) == 5 and drawn == cases(params, random=5, seed=3)
    assert all(1 <= c["a"] <= 2 and 10 <= c["b"] <= 30 for c in drawn)


def _deterministic(rows):
    return [{k: v for k, v in row.items() if k not in WALL_CLOCK_COLUMNS} for row in rows]


def test_local_pool_and_dask_cluster_give_identical_tables(scenario_file):
    import dask
    from distributed import LocalCluster

    from cnc_twin.studies.sweep import run_dask

    todo = cases([parse_param("servo.X.kp=30:50:20"), parse_param("servo.X.ki=0,400")])
    local = run_local(scenario_file, todo, workers=2)
    assert all(r["status"] == "complete" for r in local)
    assert len({r["ferr_max_X_mm"] for r in local}) == 4  # the gains really changed the runs
    with dask.config.set({"distributed.worker.daemon": False}):  # each run starts a planner process
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                          dashboard_address=None) as cluster:
            remote = run_dask(scenario_file, todo, scheduler=cluster.scheduler_address)
    assert _deterministic(remote) == _deterministic(local)
    best = best_row(local, "ferr_rms_xyz_mm")
    assert best["ferr_rms_xyz_mm"] == min(r["ferr_rms_xyz_mm"] for r in local)


def kill_or_run(scenario_file, overrides):
    """A case function for the lost-worker test: the 'die' case kills its worker process."""
    if overrides.get("program.settle") == 0.07:
        os._exit(13)
    return run_case(scenario_file, overrides)


def test_a_lost_worker_loses_only_its_case(scenario_file):
    todo = cases([parse_param("program.settle=0.05,0.06,0.07,0.08")])
    rows = run_local(scenario_file, todo, workers=2, case_fn=kill_or_run)
    status = {r["program.settle"]: r["status"] for r in rows}
    assert status == {0.05: "complete", 0.06: "complete", 0.07: "lost", 0.08: "complete"}


def test_cli_sweep_writes_the_table_and_prints_the_best_row(tmp_path, scenario_file):
    out = tmp_path / "sweep"
    proc = subprocess.run([sys.executable, "-m", "cnc_twin", "sweep", scenario_file, "--param", "servo.X.kp=30,60",
                           "--out", str(out)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "2 runs" in proc.stdout and "best by ferr_rms_xyz_mm" in proc.stdout
    import pyarrow.parquet as pq

    parquet = pq.read_table(out / "sweep.parquet")
    table = parquet.to_pylist()
    assert [r["servo.X.kp"] for r in table] == [30, 60] and (out / "sweep.csv").is_file()
    # one set of units: each figure's unit ends its name and is in the field's metadata; no sum
    # across unlike units
    units = {f.name: f.metadata[b"unit"].decode() for f in parquet.schema}
    assert units["ferr_max_X_mm"] == "mm" and units["ferr_rms_A_deg"] == "deg" and units["dac_sat_C_ticks"] == "ticks"
    assert not [name for name in units if name.startswith("ferr_") and units[name] == "1"]
    for r in table:
        assert r["ferr_rms_xyz_mm"] == pytest.approx(np.sqrt(sum(r[f"ferr_rms_{a}_mm"] ** 2 for a in "XYZ")))
    bad = subprocess.run([sys.executable, "-m", "cnc_twin", "sweep", scenario_file, "--param", "servo.X.kpp=1,2"],
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "servo.X.kpp" in bad.stderr and "Traceback" not in bad.stderr


def test_a_sweep_of_more_than_a_thousand_cases_asks_for_yes_and_a_huge_one_is_refused(tmp_path):
    import subprocess
    import sys

    from cnc_twin.scenario.resources import scenarios_dir

    base = [sys.executable, "-m", "cnc_twin", "sweep", str(scenarios_dir() / "jog_axes.yaml"), "--out", str(tmp_path)]
    asks = subprocess.run(base + ["--param", "servo.X.kp=1:100:1", "--param", "servo.X.ki=1:100:1"],
                          capture_output=True, text=True, timeout=120)
    assert asks.returncode == 2 and "10000 cases" in asks.stderr and "--yes" in asks.stderr, asks.stderr
    huge = subprocess.run(base + ["--param", "servo.X.kp=1:1e12:1", "--yes"], capture_output=True, text=True, timeout=120)
    assert huge.returncode == 2 and "at most 1000000 cases" in huge.stderr, huge.stderr
    assert list(tmp_path.iterdir()) == []
