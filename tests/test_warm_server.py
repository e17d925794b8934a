"""The warm server (cnc_twin/core/server_link.py, cnc_twin/server/): a command handed to it is the
command run in its own process: the same run directory and trace bit for bit, the same exit
codes and one-line errors, Ctrl-C and SIGTERM reaching it, a client that dies taking its command
with it (the run directory written, marked interrupted), servers per environment, outdated ones
replaced. The servers here live in a private folder (XDG_RUNTIME_DIR) and are stopped at the end."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from cnc_twin.core import helpers, server_link
from cnc_twin.run.run_dir import METRICS_FILE, RECORDING_FILE, TRACE_FILE
from cnc_twin.scenario.resources import scenarios_dir

CIRCLE = scenarios_dir() / "nurbs_circle.yaml"
LONG = scenarios_dir() / "freeform_polish.yaml"


def _cli(*words: str) -> list[str]:
    """The command, run by the installed package wherever it starts (``-P``: not a ``cnc_twin``
    folder in the working directory, as ``python -m`` would from a checkout beside a non-editable
    install: that is other code, with a server of its own)."""
    return [sys.executable, "-P", "-m", "cnc_twin", *words]


def _status(env: dict[str, str]) -> dict:
    """The state of the server for ``env`` (asked from a process with that environment)."""
    code = ("import json; from cnc_twin.core import server_link as s; "
            "print(json.dumps(s.server_status(s.socket_path(s.server_key()))))")
    out = subprocess.run([sys.executable, "-P", "-c", code], env=env, capture_output=True, text=True, timeout=60)
    return json.loads(out.stdout)


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    """A ready server in a private socket folder: the environment that reaches it."""
    runtime = tmp_path_factory.mktemp("rt")  # a short folder: a socket's path has room for 107 bytes
    env = {**os.environ, "XDG_RUNTIME_DIR": str(runtime), server_link.VARIABLE: "on"}
    started = subprocess.run(_cli("server", "--start"), env=env, capture_output=True, text=True, timeout=400)
    assert started.returncode == 0, started.stdout + started.stderr
    state = _status(env)
    yield env
    subprocess.run(_cli("server", "--stop"), env=env, capture_output=True, timeout=60)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and Path(f"/proc/{state['pid']}").exists():
        time.sleep(0.1)
    assert not Path(f"/proc/{state['pid']}").exists(), "the server outlived --stop"


def _server_processes(env: dict[str, str]) -> list[int]:
    """Live processes of the server for ``env``: it and its descendants (commands, their workers
    and planners, the spare recording process), by the process tree from its pid. (Not by its key
    on the command line: a user's own warm server of the same installation and environment, in
    their own socket folder, carries the same key.)"""
    root = int(_status(env)["pid"])
    parent: dict[int, int] = {}
    for proc in Path("/proc").iterdir():
        try:
            if proc.name.isdigit():
                fields = (proc / "stat").read_text().rsplit(")", 1)[1].split()
                if fields[0] != "Z":
                    parent[int(proc.name)] = int(fields[1])
        except (OSError, IndexError):
            continue
    found = []
    for pid in parent:
        ancestor = pid
        while ancestor not in (root, 0, 1) and ancestor in parent:
            ancestor = parent[ancestor]
        if ancestor == root:
            found.append(pid)
    return found


def test_a_run_handed_to_the_server_is_the_run_in_its_own_process(server, tmp_path):
    served = _status(server)["served"]
    warm = subprocess.run(_cli("run", str(CIRCLE), "--out", str(tmp_path / "warm")), env=server,
                          capture_output=True, text=True, timeout=300)
    cold = subprocess.run(_cli("run", str(CIRCLE), "--out", str(tmp_path / "cold")),
                          env={**server, server_link.VARIABLE: "off"}, capture_output=True, text=True, timeout=300)
    assert (warm.returncode, cold.returncode) == (0, 0), warm.stderr + cold.stderr
    assert _status(server)["served"] == served + 1  # the warm one ran in the server's fork
    assert warm.stdout.splitlines()[-1] == f"run directory: {tmp_path / 'warm'}"
    assert sorted(p.name for p in (tmp_path / "warm").iterdir()) == sorted(p.name for p in (tmp_path / "cold").iterdir())
    assert pq.read_table(tmp_path / "warm" / TRACE_FILE).equals(pq.read_table(tmp_path / "cold" / TRACE_FILE))
    metrics = [json.loads((tmp_path / side / METRICS_FILE).read_text()) for side in ("warm", "cold")]
    assert metrics[0]["status"] == metrics[1]["status"] == "complete"
    assert metrics[0]["sim_time_s"] == metrics[1]["sim_time_s"]
    assert (tmp_path / "warm" / RECORDING_FILE).stat().st_size > 0  # the spare recording process wrote it


def test_bad_input_through_the_server_is_one_line_and_exit_2(server, tmp_path):
    served = _status(server)["served"]
    missing = subprocess.run(_cli("run", str(tmp_path / "nowhere.yaml")), env=server, capture_output=True, text=True,
                             timeout=120)
    unknown = subprocess.run(_cli("validate", "--no-such-option"), env=server, capture_output=True, text=True,
                             timeout=120)
    assert _status(server)["served"] == served + 2
    for done in (missing, unknown):
        assert done.returncode == 2
        assert len(done.stderr.strip().splitlines()) == 1 and "Traceback" not in done.stderr


def test_the_command_takes_the_callers_directory_and_environment(server, tmp_path):
    (tmp_path / "here").mkdir()
    done = subprocess.run(_cli("run", str(CIRCLE), "--quiet", "--runs-dir", "mine"), cwd=tmp_path / "here",
                          env={**server, "CNC_TWIN_PHASES": str(tmp_path / "marks")}, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    runs = list((tmp_path / "here" / "mine").iterdir())  # relative to the caller's directory
    assert len(runs) == 1 and (runs[0] / RECORDING_FILE).stat().st_size > 0  # the spare's too
    names = [line.split()[1] for line in (tmp_path / "marks").read_text().splitlines()]
    assert names[:2] == ["entry", "forked"] and names[-1] == "written"  # the caller's variable reached the fork


def _start(scenario: Path, out: Path, env: dict[str, str]) -> subprocess.Popen:
    return subprocess.Popen(_cli("run", str(scenario), "--out", str(out)), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env, start_new_session=True)


def _wait_until_running(proc: subprocess.Popen) -> None:
    for line in proc.stderr:
        if ": running (" in line:
            return
    pytest.fail(f"the run never started (exit {proc.wait()})")


@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_to_the_caller_reaches_the_command(server, tmp_path, signum, code):
    proc = _start(LONG, tmp_path / "run", server)
    _wait_until_running(proc)
    proc.send_signal(signum)
    proc.communicate(timeout=120)
    assert proc.returncode == code
    metrics = json.loads((tmp_path / "run" / METRICS_FILE).read_text())
    assert metrics["status"] == "interrupted" and metrics["stop_reason"].startswith(signal.Signals(signum).name)
    assert (tmp_path / "run" / RECORDING_FILE).stat().st_size > 0


def test_a_killed_caller_takes_its_command_with_it(server, tmp_path):
    proc = _start(LONG, tmp_path / "run", server)
    _wait_until_running(proc)
    proc.kill()
    proc.wait(timeout=30)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and _status(server)["running"]:
        time.sleep(0.1)
    assert _status(server)["running"] == 0
    metrics = json.loads((tmp_path / "run" / METRICS_FILE).read_text())  # written whole, as on SIGTERM
    assert metrics["status"] == "interrupted" and metrics["stop_reason"].startswith("SIGTERM")
    assert len(_server_processes(server)) <= 2  # the server, and the spare recording process for the next


def test_another_environment_gets_a_server_of_its_own(server, tmp_path):
    other = {**server, "LC_TIME": "C"}  # read at import: another key
    first = _status(server)
    done = subprocess.run(_cli("list"), env=other, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0
    assert _status(server)["served"] == first["served"]  # not handed over: ran in its own process...
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and _status(other) is None:  # ...and started one for next time
        time.sleep(0.2)
    assert _status(other) is not None and _status(other)["pid"] != first["pid"]
    assert _status(server)["pid"] == first["pid"]  # the first stays: commands may alternate


def test_outdated_servers_are_those_of_other_code_in_the_same_environment(tmp_path):
    key = "aaaa-code2-env1"
    others = [tmp_path / f"{name}.sock" for name in ("aaaa-code1-env1", "aaaa-code1-env2", "bbbb-code1-env1",
                                                     "aaaa-code2-env1")]
    assert server_link.outdated(key, others) == [tmp_path / "aaaa-code1-env1.sock"]


def test_the_server_is_off_when_asked(tmp_path, monkeypatch):
    monkeypatch.setenv(server_link.VARIABLE, "off")
    assert server_link.delegate(["run"]) is None
    monkeypatch.setenv(server_link.VARIABLE, "on")
    assert server_link.delegate(["view"]) is None  # not a command it runs


def test_a_forked_helper_is_a_process_like_a_new_one():
    keep_read, keep_write = os.pipe()
    try:
        usage = helpers.ForkedHelper("cnc_twin.planner.process", ["--bad"])
        assert usage.wait(timeout=30) == 2  # its main's return value is its exit status
        usage.stdin.close()
        usage.stdout.close()
        waiting = helpers.ForkedHelper("cnc_twin.view.rerun_stream", [])
        os.close(keep_write)
        keep_write = -1
        assert os.read(keep_read, 1) == b""  # the helper holds none of this process's descriptors
        assert waiting.poll() is None
        with pytest.raises(subprocess.TimeoutExpired):
            waiting.wait(timeout=0.05)
        waiting.terminate()
        assert waiting.wait(timeout=30) == -signal.SIGTERM
        waiting.stdin.close()
        waiting.stdout.close()
    finally:
        os.close(keep_read)
        if keep_write >= 0:
            os.close(keep_write)


def test_helpers_are_forked_only_from_a_warm_process_running_no_other_thread(monkeypatch):
    import threading

    monkeypatch.setattr(helpers, "FORK", False)
    assert not helpers.can_fork()
    monkeypatch.setattr(helpers, "FORK", True)
    stop = threading.Event()
    other = threading.Thread(target=stop.wait)
    other.start()
    try:
        assert not helpers.can_fork()  # a thread holding a lock at the fork would hold it forever
        started = helpers.start_helper("cnc_twin.planner.process", ["--bad"])
        assert not isinstance(started, helpers.ForkedHelper)
        assert started.wait(timeout=60) == 2
        started.stdin.close()
        started.stdout.close()
    finally:
        stop.set()
        other.join()


def test_a_sweep_handed_to_the_server_forks_its_workers_and_gives_the_same_rows(server, tmp_path):
    scenario = tmp_path / "p2p.yaml"
    scenario.write_text("name: p2p\nprogram: {type: point_to_point, settle: 0.5, moves: [{X: 20}, {X: 0}]}\n")
    sweep = ("sweep", str(scenario), "--param", "servo.X.kp=20:50:10", "--workers", "2")
    served = _status(server)["served"]
    warm = subprocess.run(_cli(*sweep, "--out", str(tmp_path / "warm")), env=server, capture_output=True, text=True,
                          timeout=300)
    cold = subprocess.run(_cli(*sweep, "--out", str(tmp_path / "cold")), env={**server, server_link.VARIABLE: "off"},
                          capture_output=True, text=True, timeout=300)
    assert (warm.returncode, cold.returncode) == (0, 0), warm.stderr + cold.stderr
    assert _status(server)["served"] == served + 1
    rows = [pq.read_table(tmp_path / side / "sweep.parquet").to_pylist() for side in ("warm", "cold")]
    assert len(rows[0]) == 4 and all(row["status"] == "complete" for row in rows[0])
    figures = ("servo.X.kp", "ferr_rms_X_mm", "ferr_max_X_mm", "sim_time_s")
    assert [[row[k] for k in figures] for row in rows[0]] == [[row[k] for k in figures] for row in rows[1]]


def test_a_server_killed_under_a_command_leaves_it_to_finish_and_its_caller_waits(tmp_path, tmp_path_factory):
    runtime = tmp_path_factory.mktemp("rt")  # a short folder: a socket's path has room for 107 bytes
    env = {**os.environ, "XDG_RUNTIME_DIR": str(runtime), server_link.VARIABLE: "on"}
    assert subprocess.run(_cli("server", "--start"), env=env, capture_output=True, timeout=400).returncode == 0
    server = _status(env)["pid"]
    proc = _start(LONG, tmp_path / "run", env)
    _wait_until_running(proc)
    os.kill(server, signal.SIGKILL)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 1 and len(err.strip().splitlines()) == 1  # its status is lost with the server...
    metrics = json.loads((tmp_path / "run" / METRICS_FILE).read_text())
    assert metrics["status"] == "complete"  # ...but the run went on to its end, and the caller waited for it


def test_ctrl_c_stops_a_sweep_handed_to_the_server(server, tmp_path):
    """The terminal's Ctrl-C reaches the client's group only: the client passes it to the sweep,
    which passes it to its forked workers (as a sweep does on SIGTERM to its main process)."""
    import pty

    from test_sweep_interrupt import KP, PARAMS, SCENARIO, _PtyReader

    out = tmp_path / "sweep"
    master, slave = pty.openpty()
    with open(tmp_path / "stdout.txt", "wb") as stdout:
        proc = subprocess.Popen(_cli("sweep", str(SCENARIO), "--param", PARAMS[0], "--param", PARAMS[1], "--workers",
                                     "2", "--out", str(out)), stdout=stdout, stderr=slave, env=server,
                                start_new_session=True)
    os.close(slave)
    try:
        reader = _PtyReader(master)
        done = reader.wait_for_cases(2, deadline=time.monotonic() + 120.0)
        assert done >= 2, reader.text()
        os.killpg(proc.pid, signal.SIGINT)
        assert proc.wait(timeout=60) == 130, reader.text()
    finally:
        if proc.poll() is None:
            proc.kill()
        os.close(master)
    rows = pq.read_table(out / "sweep.parquet").to_pylist()
    assert [row["servo.X.kp"] for row in rows] == KP
    assert {row["status"] for row in rows} == {"complete", "interrupted"}
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and _status(server)["running"]:
        time.sleep(0.1)
    assert _status(server)["running"] == 0
    assert len(_server_processes(server)) <= 2  # workers and planners gone: the server and its spare
