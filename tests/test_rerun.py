"""The rerun recording of a run: written into the run directory, readable, complete."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from rrd_read import entity_columns, rrd_contents, rrd_rows
from cnc_twin.scenario.load import scenario_from_dict
from cnc_twin.run.twin import run_scenario


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    scenario = scenario_from_dict({"name": "short", "program": {"type": "point_to_point", "settle": 0.05,
                                                                "moves": [{"X": 20, "A": 5}]}})
    result = run_scenario(scenario)
    return result, result.write(tmp_path_factory.mktemp("runs") / "run")


def test_run_directory_holds_a_readable_recording_with_every_entity(short_run):
    result, run_dir = short_run
    rows, static = rrd_rows(run_dir / "recording.rrd")
    periods = len(result.trace) // result.scenario.timing.ticks_per_period
    for axis in "XYZABC":
        assert rows[f"/axes/{axis}/position"] == periods, axis
    for name in ("/axes/ferr", "/axes/dac", "/axes/saturated", "/force/measured", "/whiteboard/counters"):
        assert rows[name] == periods, name
    poses = -(-periods // 4)  # 3D poses every 4 ms
    for body in ("x_carriage", "y_saddle", "z_ram", "a_yoke", "b_head", "c_spindle", "pad"):
        assert rows[f"/machine/{body}"] == poses, body
    assert static["/paths/commanded"] == 1 and static["/paths/actual"] == 1
    assert rows["/force/arrow"] == poses and rows["/feed"] == poses
    assert rows["/controller/events"] >= 2  # IDLE -> RUNNING -> ... -> FINISHED
    assert rows["/whiteboard/exchange_latency_us"] == result.metrics["whiteboard"]["exchanges"]
    assert any(k.startswith("/machine/pad/") for k in static)  # geometry logged
    contents = rrd_contents(run_dir / "recording.rrd")  # looked up by entity: column names are rerun's
    assert [(None, None, repr(list("XYZABC")))] in entity_columns(contents, "/axes/ferr", static=True)  # series names
    assert any(len(x) == periods and all(len(floats_of(r[2])) == 2 for r in x)  # command, actual
               for x in entity_columns(contents, "/axes/X/position", static=False))


def floats_of(text: str) -> list:
    """A repr'd list of floats back (the test's own output: no scenario content)."""
    return [float(v) for v in text.strip("[]").split(",")]


def test_no_rrd_flag_and_rrd_path(tmp_path, write_scenario):
    path = write_scenario({"name": "tiny", "program": {"type": "point_to_point", "settle": 0.0, "moves": [{"X": 1}]}})
    out, extra = tmp_path / "run", tmp_path / "extra.rrd"
    proc = subprocess.run([sys.executable, "-m", "cnc_twin", "run", str(path), "--out", str(out), "--no-rrd",
                           "--rrd", str(extra), "--quiet"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert not (out / "recording.rrd").exists() and extra.is_file()
    assert rrd_rows(extra)[0]["/axes/X/position"] > 0


def test_view_without_a_recording_is_a_clear_error(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "cnc_twin", "view", str(tmp_path)], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 2 and "no rerun recording" in proc.stderr


def test_view_without_a_display_says_what_to_do_and_web_serves_the_run(short_run, tmp_path):
    """No display: one sentence naming `--web`, exit 2. `--web` serves the recording over HTTP
    on 127.0.0.1 until Ctrl-C (exit 0); a port already taken is a one-line error, exit 2."""
    import os
    import signal
    import socket
    import time
    import urllib.parse
    import urllib.request

    _, run_dir = short_run
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["XDG_CONFIG_HOME"] = str(tmp_path / "config")
    proc = subprocess.run([sys.executable, "-m", "cnc_twin", "view", str(run_dir)], capture_output=True, text=True,
                          timeout=60, env=env)
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert "no display" in proc.stderr and "--web" in proc.stderr and "Listening" not in proc.stderr
    with socket.socket() as probe:  # a free port
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    server = subprocess.Popen([sys.executable, "-m", "cnc_twin", "view", str(run_dir), "--web", "--port", str(port)],
                              stderr=subprocess.PIPE, text=True, env=env)
    try:
        deadline, page = time.monotonic() + 30, None
        while page is None and time.monotonic() < deadline:
            try:
                page = urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=2).read()
            except OSError:
                time.sleep(0.2)
        assert page and b"<html" in page.lower()
        said = server.stderr.readline()  # printed once the viewer has held its port for 1 s
        assert f"http://127.0.0.1:{port}" in said and "Ctrl-C" in said, said
        # the printed address names where the page loads the recording from, and that is served
        # (else the browser opens rerun's Welcome page)
        query = urllib.parse.urlparse(said.split(" at ", 1)[1].split()[0]).query
        source = urllib.parse.urlparse(urllib.parse.parse_qs(query)["url"][0].removeprefix("rerun+"))
        assert (source.hostname, source.path) == ("127.0.0.1", "/proxy") and str(source.port) in said
        with socket.create_connection(("127.0.0.1", source.port), timeout=5):
            pass
        second = subprocess.run([sys.executable, "-m", "cnc_twin", "view", str(run_dir), "--web", "--port", str(port)],
                                capture_output=True, text=True, timeout=60, env=env)
        assert second.returncode == 2 and "did not start" in second.stderr and "in use" in second.stderr
    finally:
        server.send_signal(signal.SIGINT)
        _, err = server.communicate(timeout=30)
    assert server.returncode == 0 and "Traceback" not in err, err
    left = [pid for pid in os.listdir("/proc") if pid.isdigit() and _cmdline_has(pid, f"--web-viewer-port\0{port}\0")]
    assert not left, "a web viewer process outlived `cnc-twin view --web`"


def _cmdline_has(pid: str, text: str) -> bool:
    try:
        return text in open(f"/proc/{pid}/cmdline").read()
    except OSError:
        return False


def test_viewers_start_with_analytics_disabled_in_a_private_config(tmp_path, monkeypatch):
    import json
    import os

    from cnc_twin.view.viewer import viewer_config_home, viewer_environment

    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "user-config"))
    base = viewer_config_home()
    config = json.loads((base / "rerun" / "analytics.json").read_text())
    assert config["analytics_enabled"] is False
    assert base.is_relative_to(tmp_path / "user-config" / "cnc-twin")
    assert not (tmp_path / "user-config" / "rerun").exists()  # the user's own rerun settings untouched
    with viewer_environment() as env:
        assert env["XDG_CONFIG_HOME"] == str(base) == os.environ["XDG_CONFIG_HOME"]
    assert os.environ["XDG_CONFIG_HOME"] == str(tmp_path / "user-config")


def test_an_export_in_stretches_records_what_one_export_does(tmp_path):
    """However a run is cut into stretches (as a recording process receives it), the recording
    holds the same values: the pose grid, the feed across stretch edges, the events."""
    from cnc_twin.trace.trace import PeriodSamples
    from cnc_twin.view.rerun_export import RunExporter

    scenario = scenario_from_dict({"name": "stretches", "program": {"type": "point_to_point", "settle": 0.05,
                                                                    "moves": [{"X": 20}, {"Y": -10, "A": 3}]}})
    result = run_scenario(scenario)
    exporter = RunExporter(scenario, compiled=False)
    exporter.start(rrd=tmp_path / "stretches.rrd")
    n = result.trace.whole_periods
    assert n > 300
    edges = [0, 1, 7, n // 3, n // 3 + 1, n - 5, n]  # poses every 4th period: edges on and off the grid
    for first, stop in zip(edges, edges[1:]):
        exporter.send(PeriodSamples.take(result.trace, first, stop))
    with pytest.raises(ValueError, match="expected"):
        exporter.send(PeriodSamples.take(result.trace, 3, 5))  # not the next stretch
    exporter.finish(len(result.trace), result.metrics, result.exchange_latency)
    result.export_rerun(rrd=tmp_path / "whole.rrd")
    assert rrd_contents(tmp_path / "stretches.rrd") == rrd_contents(tmp_path / "whole.rrd")
