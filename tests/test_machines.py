"""The bundled machines by name: `cnc-twin run SCENARIO --machine rigid|compliant` runs the same
scenario on either (BUNDLED_MACHINES), and the run directory keeps which one it ran on."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import yaml

from cnc_twin.cli import build_parser
from cnc_twin.scenario.resources import BUNDLED_MACHINES, scenarios_dir
from cnc_twin.trace.parquet import read_trace

from conftest import run_cli


def _machine_choices(command: str) -> list[str]:
    option = next(a for a in build_parser()._subparsers._group_actions[0].choices[command]._actions
                  if a.dest == "machine")
    return list(option.choices)


def test_the_cli_offers_every_bundled_machine():
    assert _machine_choices("run") == _machine_choices("bench") == _machine_choices("tune") == list(BUNDLED_MACHINES)


def test_tune_tunes_the_machine_it_is_given():
    """`cnc-twin tune jog_axes --machine rigid` tunes the rigid variant: its velocity-mode drive has
    no velocity loop to design (no velocity-loop table), and its current gains are the rigid
    parameter file's (kp 400), where the default machine's Y is tuned on its measured mechanics."""
    import re

    code, out, err = run_cli("tune", scenarios_dir() / "jog_axes.yaml", "--axis", "Y", "--step", "0.1",
                             "--machine", "rigid")
    assert code == 0, err
    assert "velocity loop" not in out
    before = [line for line in out.splitlines() if line.startswith("before")]
    assert len(before) == 1 and float(re.findall(r"[-\d.]+", before[0])[0]) == 400.0, out


def test_bench_measures_the_machine_it_is_given(tmp_path):
    """`cnc-twin bench jog_axes --machine rigid` measures the rigid variant (its figures name the
    model the twin and the bare stepping ran)."""
    code, _, err = run_cli("bench", scenarios_dir() / "jog_axes.yaml", "--machine", "rigid", "--repeat", "1",
                           "--no-whiteboard", "--json", tmp_path / "bench.json")
    assert code == 0, err
    figures = json.loads((tmp_path / "bench.json").read_text())
    assert figures["model"] == "scene_rigid.xml"
    # what they were measured on, kept with them (the docs' performance page shows it)
    import mujoco

    measured = figures["measured"]
    assert measured["versions"]["mujoco"] == mujoco.__version__
    assert measured["command"].startswith("cnc-twin bench ") and "--machine rigid" in measured["command"]
    assert measured["machine"]["cores"] >= 1 and measured["date_utc"].endswith("+00:00")


def test_a_scenario_without_a_machine_runs_on_the_compliant_default(tmp_path):
    """A scenario that names no machine runs on the compliant machine (models/scene.xml,
    polisher.yaml), and its run directory's metrics say which machine it ran on."""
    code, _, err = run_cli("run", scenarios_dir() / "nurbs_circle.yaml", "--quiet", "--no-rrd",
                           "--out", tmp_path / "run")
    assert code == 0, err
    assert "machine" not in yaml.safe_load((tmp_path / "run" / "scenario.yaml").read_text())
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert metrics["machine"] == {"model": BUNDLED_MACHINES["compliant"]["machine.model"],
                                  "parameters": BUNDLED_MACHINES["compliant"]["machine.parameters"]}


def test_a_scenario_run_on_the_rigid_machine_is_that_machines_own_scenario(tmp_path):
    """jog_axes with --machine rigid gives, bit for bit, the trace of jog_axes whose machine section
    names the rigid variant's files (the same moves on its model and parameter file), and its run
    directory's scenario.yaml names that machine, so the run can be repeated from it."""
    code, _, err = run_cli("run", scenarios_dir() / "jog_axes.yaml", "--machine", "rigid", "--quiet",
                           "--no-rrd", "--out", tmp_path / "switched")
    assert code == 0, err
    raw = yaml.safe_load((scenarios_dir() / "jog_axes.yaml").read_text())
    raw["machine"] = {"model": "scene_rigid.xml", "parameters": "polisher_rigid.yaml"}
    (tmp_path / "own.yaml").write_text(yaml.safe_dump(raw))
    code, _, err = run_cli("run", tmp_path / "own.yaml", "--quiet", "--no-rrd", "--out", tmp_path / "own")
    assert code == 0, err
    switched = read_trace(tmp_path / "switched" / "trace.parquet")
    own = read_trace(tmp_path / "own" / "trace.parquet")
    assert switched.keys() == own.keys()
    for column in own:
        assert np.array_equal(switched[column], own[column]), column
    kept = yaml.safe_load((tmp_path / "switched" / "scenario.yaml").read_text())
    assert kept["machine"] == {"model": "scene_rigid.xml", "parameters": "polisher_rigid.yaml"}
    metrics = json.loads((tmp_path / "switched" / "metrics.json").read_text())
    assert metrics["status"] == "complete"
    assert metrics["machine"] == {"model": "scene_rigid.xml", "parameters": "polisher_rigid.yaml"}


def test_an_unknown_machine_is_refused_in_one_line(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "cnc_twin", "run", str(scenarios_dir() / "jog_axes.yaml"),
                           "--machine", "stiff", "--out", str(tmp_path / "run")], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2 and proc.stdout == "" and len(proc.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "run").exists()
