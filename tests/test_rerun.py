"""The rerun recording of a run: written into the run directory, readable, complete."""

from __future__ import annotations

import collections
import re
import subprocess
import sys
from pathlib import Path

import pytest

from cnc_twin.axes import AXES
from cnc_twin.scenario import scenario_from_dict
from cnc_twin.twin import run_scenario


def rrd_rows(path: Path) -> dict[str, int]:
    """Rows per entity path, read back with rerun's own CLI (``rerun rrd print``)."""
    from cnc_twin.viewer import rerun_command

    out = subprocess.run(rerun_command() + ["rrd", "print", str(path)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    rows: dict[str, int] = collections.Counter()
    for line in out.stdout.splitlines():
        m = re.match(r"Chunk\(\S+\) with (\d+) rows .* - (\S+) - data columns", line)
        if m:
            rows[m.group(2)] += int(m.group(1))
    return rows


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    scenario = scenario_from_dict({"name": "short", "program": {"type": "point_to_point", "settle": 0.05,
                                                                "moves": [{"X": 20, "A": 5}]}})
    result = run_scenario(scenario)
    return result, result.write(tmp_path_factory.mktemp("runs") / "run")


def test_run_directory_holds_a_readable_recording_with_every_entity(short_run):
    result, run_dir = short_run
    rows = rrd_rows(run_dir / "recording.rrd")
    periods = len(result.trace) // result.scenario.timing.ticks_per_period
    for axis in AXES:
        for signal in ("command", "actual", "ferr", "dac", "saturated"):
            assert rows[f"/axes/{axis}/{signal}"] == periods, (axis, signal)
    for name in ("/force/measured", "/whiteboard/fifo_fill", "/whiteboard/missed_exchanges"):
        assert rows[name] == periods, name
    poses = -(-periods // 4)  # 3D poses every 4 ms
    for body in ("x_carriage", "y_saddle", "z_ram", "a_yoke", "b_head", "c_spindle", "pad"):
        assert rows[f"/machine/{body}"] == poses, body
    assert rows["/paths/commanded"] == 1 and rows["/paths/actual"] == 1
    assert rows["/force/arrow"] == poses and rows["/feed/commanded"] == poses
    assert rows["/controller/events"] >= 2  # IDLE -> RUNNING -> ... -> FINISHED
    assert rows["/whiteboard/exchange_latency_us"] == result.metrics["whiteboard"]["exchanges"]
    assert any(k.startswith("/machine/pad/") for k in rows)  # geometry logged


def test_no_rrd_flag_and_rrd_path(tmp_path, write_scenario):
    path = write_scenario({"name": "tiny", "program": {"type": "point_to_point", "settle": 0.0, "moves": [{"X": 1}]}})
    out, extra = tmp_path / "run", tmp_path / "extra.rrd"
    proc = subprocess.run([sys.executable, "-m", "cnc_twin", "run", str(path), "--out", str(out), "--no-rrd",
                           "--rrd", str(extra), "--quiet"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert not (out / "recording.rrd").exists() and extra.is_file()
    assert rrd_rows(extra)["/axes/X/command"] > 0


def test_view_without_a_recording_is_a_clear_error(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "cnc_twin", "view", str(tmp_path)], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 2 and "no rerun recording" in proc.stderr


def test_viewers_start_with_analytics_disabled_in_a_private_config(tmp_path, monkeypatch):
    import json
    import os

    from cnc_twin.viewer import viewer_config_home, viewer_environment

    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "user-config"))
    base = viewer_config_home()
    config = json.loads((base / "rerun" / "analytics.json").read_text())
    assert config["analytics_enabled"] is False
    assert base.is_relative_to(tmp_path / "user-config" / "cnc-twin")
    assert not (tmp_path / "user-config" / "rerun").exists()  # the user's own rerun settings untouched
    with viewer_environment() as env:
        assert env["XDG_CONFIG_HOME"] == str(base) == os.environ["XDG_CONFIG_HOME"]
    assert os.environ["XDG_CONFIG_HOME"] == str(tmp_path / "user-config")


def test_streaming_during_the_run_records_what_a_post_run_export_does(tmp_path):
    """The live path (what --rerun feeds a viewer) sends the same rows, stretch by stretch."""
    from cnc_twin.rerun_export import RunExporter
    from cnc_twin.twin import Twin

    scenario = scenario_from_dict({"name": "live", "program": {"type": "point_to_point", "settle": 0.05,
                                                               "moves": [{"X": 20}, {"Y": -10}]}})
    twin = Twin(scenario)
    live = RunExporter(scenario, model=twin.plant.model)
    live.start(rrd=tmp_path / "live.rrd")
    stretches = []

    def observe(t):
        stretches.append(t.recorder.count)
        live.send(t.partial_trace(), t.recorder.count)

    result = twin.run(observer=observe)
    live.finish(result.trace, result.metrics, result.exchange_latency)
    result.export_rerun(rrd=tmp_path / "after.rrd")
    assert len(stretches) > 10  # it really streamed, in many stretches
    streamed, after = rrd_rows(tmp_path / "live.rrd"), rrd_rows(tmp_path / "after.rrd")
    for path, n in after.items():
        if not path.startswith(("/container", "/blueprint", "/view", "/__")):
            assert streamed[path] == n, path
