"""The machine failing around a run (docs/faults.md, "When the computer fails"): a disk too small
for the run or filling up under it, the same run directory taken twice, a damaged recording. Each
case is provoked for real: a small tmpfs of its own (tests/small_disk.py, in a user and mount
namespace: no root needed), two processes, a file of garbage."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from cnc_twin.scenario.resources import scenarios_dir

SMALL_DISK = Path(__file__).with_name("small_disk.py")


def _cli(*words) -> list[str]:
    return [sys.executable, "-m", "cnc_twin", *map(str, words)]


def _on_small_disk(tmp_path: Path, size_kb: int, *words, fill_leaving_kb: int | None = None,
                   read_only: bool = False) -> dict:
    """``cnc-twin WORDS`` with a tmpfs of ``size_kb`` mounted on ``tmp_path/disk`` (the run's
    folder); what happened, as tests/small_disk.py reports it."""
    fill = [] if fill_leaving_kb is None else ["--fill-when-running", str(fill_leaving_kb)]
    fill += ["--read-only-when-running"] if read_only else []
    done = subprocess.run(["unshare", "--user", "--map-root-user", "--mount", sys.executable, SMALL_DISK,
                           tmp_path / "disk", str(size_kb), *fill, "--", *_cli(*words)],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, f"a small disk could not be mounted here (unshare: user namespaces?): {done.stderr}"
    return json.loads(done.stdout)


def test_a_run_whose_files_cannot_fit_is_refused_before_its_clock_starts(tmp_path):
    seen = _on_small_disk(tmp_path, 2048, "run", "nurbs_circle", "--out", tmp_path / "disk" / "run")
    assert seen["code"] == 4, seen["stderr"]
    assert len(seen["stderr"].strip().splitlines()) == 1 and "Traceback" not in seen["stderr"]
    assert ": running (" not in seen["stderr"]  # refused before any motion
    assert seen["files"] == []  # the claimed run directory and the staged recording: gone


def test_a_write_that_fails_keeps_metrics_with_the_runs_status_and_why(tmp_path):
    seen = _on_small_disk(tmp_path, 8192, "run", "nurbs_circle", "--out", tmp_path / "disk" / "run", "--no-rrd",
                          fill_leaving_kb=64)
    assert seen["filled"] and seen["code"] == 4, seen["stderr"]
    lines = [line for line in seen["stderr"].strip().splitlines() if ": running (" not in line]
    assert len(lines) == 1 and "trace.parquet" in lines[0], seen["stderr"]
    assert seen["files"] == ["run", "run/metrics.json"]  # no partial trace, no temporary folder
    kept = json.loads(seen["metrics"]["run/metrics.json"])
    assert kept["status"] == "complete" and kept["written"] is False and "trace.parquet" in kept["write_error"]


def test_a_disk_that_fills_under_a_recorded_run_makes_room_for_metrics_first(tmp_path):
    """The recording process writes its file during the run: the disk fills with it; the partial
    recording goes first, and metrics.json fits in its room."""
    seen = _on_small_disk(tmp_path, 16384, "run", "nurbs_circle", "--out", tmp_path / "disk" / "run",
                          fill_leaving_kb=64)
    assert seen["filled"] and seen["code"] == 4, seen["stderr"]
    assert seen["files"] == ["run", "run/metrics.json"], seen["files"]


def test_a_disk_turned_read_only_under_the_run_is_one_line(tmp_path):
    seen = _on_small_disk(tmp_path, 16384, "run", "nurbs_circle", "--out", tmp_path / "disk" / "run", "--no-rrd",
                          read_only=True)
    assert seen["filled"] and seen["code"] == 4, seen["stderr"]
    assert [line for line in seen["stderr"].strip().splitlines() if ": running (" not in line][0].endswith(
        "nothing could be kept")
    assert "Traceback" not in seen["stderr"]


def test_a_write_that_cannot_even_keep_metrics_leaves_nothing(tmp_path):
    seen = _on_small_disk(tmp_path, 8192, "run", "nurbs_circle", "--out", tmp_path / "disk" / "run", "--no-rrd",
                          fill_leaving_kb=0)
    assert seen["filled"] and seen["code"] == 4, seen["stderr"]
    assert seen["files"] == []


def test_a_run_directory_taken_by_a_running_run_is_refused_at_once(tmp_path):
    out = tmp_path / "same"
    first = subprocess.Popen(_cli("run", "nurbs_circle", "--out", out, "--no-rrd"), stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        for line in first.stderr:
            if ": running (" in line:
                break
        started = time.monotonic()
        second = subprocess.run(_cli("run", "nurbs_circle", "--out", out, "--no-rrd"), capture_output=True,
                                text=True, timeout=300)
        refused_after = time.monotonic() - started
        assert first.poll() is None, "the first run ended before the second was refused: the test proves nothing"
    finally:
        first.communicate(timeout=300)
    assert second.returncode == 2 and len(second.stderr.strip().splitlines()) == 1, second.stderr
    assert "running (" not in second.stderr  # refused before its run, not after simulating it
    assert first.returncode == 0
    assert json.loads((out / "metrics.json").read_text())["status"] == "complete"  # the first is whole
    assert refused_after < 60


def test_view_refuses_a_damaged_recording_in_one_line(tmp_path):
    from cnc_twin.run.twin import run_scenario
    from cnc_twin.scenario.load import load_scenario
    from cnc_twin.scenario.resources import scenarios_dir

    run = run_scenario(load_scenario(scenarios_dir() / "jog_axes.yaml", overrides={"program.settle": 0.0})).write(
        tmp_path / "run")
    from cnc_twin.view.recording_check import check_recording

    check_recording(run / "recording.rrd")  # a whole one passes
    whole = (run / "recording.rrd").read_bytes()
    cases = {"garbage": bytes(range(256)) * 40, "cut": whole[: len(whole) // 2], "empty": b""}
    import socket

    with socket.socket() as probe:  # a port free now: without the check the viewer would serve (and time out)
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    for name, data in cases.items():
        (run / "recording.rrd").write_bytes(data)
        done = subprocess.run(_cli("view", run, "--web", "--port", port), capture_output=True, text=True, timeout=60)
        assert done.returncode == 2, (name, done.stderr)
        assert len(done.stderr.strip().splitlines()) == 1 and "Traceback" not in done.stderr, (name, done.stderr)


def test_no_room_in_shared_memory_is_one_line_before_any_motion(tmp_path):
    """/dev/shm too small for the whiteboard (a container's default is 64 MB, and other programs
    fill it): before, the zeroing of the segment ended the run with SIGBUS."""
    command = " ".join(f"'{w}'" for w in _cli("run", "jog_axes", "--out", tmp_path / "run", "--no-rrd"))
    done = subprocess.run(["unshare", "--user", "--map-root-user", "--mount", "sh", "-c",
                           f"mount -t tmpfs -o size=8k tmpfs /dev/shm && exec {command}"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 4, done.stderr
    assert len(done.stderr.strip().splitlines()) == 1 and "/dev/shm" in done.stderr, done.stderr
    assert not (tmp_path / "run").exists() and list(tmp_path.glob(".run*")) == []


def test_a_run_directory_left_empty_by_a_killed_run_is_taken_over_and_one_in_use_is_not(tmp_path):
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (tmp_path / "left").mkdir()  # what a run killed (SIGKILL) after its claim leaves
    (tmp_path / f".left.claim-{dead.pid}").touch()
    done = subprocess.run(_cli("run", "jog_axes", "--out", tmp_path / "left", "--no-rrd", "--quiet"),
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "left" / "metrics.json").is_file() and list(tmp_path.glob(".left.claim-*")) == []
    (tmp_path / "mine").mkdir()  # a folder of the user's (no claim), or a live run's: refused
    (tmp_path / "live").mkdir()
    (tmp_path / f".live.claim-{__import__('os').getpid()}").touch()
    for name in ("mine", "live"):
        refused = subprocess.run(_cli("run", "jog_axes", "--out", tmp_path / name, "--no-rrd"), capture_output=True,
                                 text=True, timeout=300)
        assert refused.returncode == 2 and len(refused.stderr.strip().splitlines()) == 1, refused.stderr


def _helpers_of(pid: int, module: str) -> list[int]:
    """Live children of ``pid`` running ``module`` (the planner, the recording process)."""
    found = []
    for proc in Path("/proc").iterdir():
        try:
            if not proc.name.isdigit():
                continue
            stat = (proc / "stat").read_text().rsplit(")", 1)[1].split()
            if int(stat[1]) == pid and stat[0] != "Z" and module.encode() in (proc / "cmdline").read_bytes():
                found.append(int(proc.name))
        except (OSError, IndexError):
            continue
    return found


def _marked_processes(mark: str) -> list[int]:
    """Live processes whose environment carries ``mark`` (a command and every process it started)."""
    found = []
    for proc in Path("/proc").iterdir():
        try:
            if proc.name.isdigit() and mark.encode() in (proc / "environ").read_bytes() and \
                    (proc / "stat").read_text().rsplit(")", 1)[1].split()[0] != "Z":
                found.append(int(proc.name))
        except OSError:
            continue
    return found


@pytest.mark.parametrize("module, seed", [("cnc_twin.planner.process", 1), ("cnc_twin.planner.process", 2),
                                          ("cnc_twin.view.rerun_stream", 1), ("cnc_twin.view.rerun_stream", 2)])
def test_a_helper_killed_at_a_random_moment_ends_the_run_as_documented(tmp_path, module, seed):
    """SIGKILL to the planner: the card's PLANNER_LOST (a controlled stop, exit 3), or a complete
    run when it came after the program was all on the card; to the recording process: the run
    goes on and its recording is exported after it. Either way a whole run directory, no orphan,
    no segment."""
    import os
    import random
    import signal
    import uuid

    from cnc_twin.view.recording_check import check_recording

    mark = uuid.uuid4().hex
    env = {**os.environ, "CNC_TWIN_TEST_MARK": mark}
    # paced to the wall clock (4.5 s), so that the helper lives through the moment chosen: in
    # lockstep the twin runs the circle in a fraction of a second and the kill came after it
    raw = yaml.safe_load((scenarios_dir() / "nurbs_circle.yaml").read_text())
    raw["timing"] = {**raw.get("timing", {}), "mode": "realtime"}
    (tmp_path / "circle.yaml").write_text(yaml.safe_dump(raw))
    run = subprocess.Popen(_cli("run", tmp_path / "circle.yaml", "--out", tmp_path / "run"), stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True, env=env)
    for line in run.stderr:
        if ": running (" in line:
            break
    time.sleep(random.Random(seed).uniform(0.0, 2.0))  # within the run
    victims = _helpers_of(run.pid, module)
    for pid in victims:
        os.kill(pid, signal.SIGKILL)
    out, err = run.communicate(timeout=300)
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert len(victims) == 1, "no helper to kill: the test proves nothing"
    if module.endswith("process"):
        assert (run.returncode, metrics["status"]) in ((3, "fault"), (0, "complete")), err
        if run.returncode == 3:
            assert metrics["fault"]["code"] == "PLANNER_LOST" and metrics["fault"]["at_rest_s"] is not None
    else:
        assert run.returncode == 0 and metrics["status"] == "complete", err
        check_recording(tmp_path / "run" / "recording.rrd")  # exported after the run, whole
    assert "Traceback" not in err
    time.sleep(0.5)
    assert _marked_processes(mark) == [], "a process of the run outlived it"
    assert not list(Path("/dev/shm").glob(f"cnc_twin_{run.pid}_*"))


@pytest.mark.parametrize("words", [("tune", "jog_axes", "--axis", "X"), ("bench", "nurbs_circle", "--repeat", "1")])
@pytest.mark.parametrize("signum, code", [("SIGINT", 130), ("SIGTERM", 143)])
def test_tune_and_bench_end_on_a_signal_leaving_nothing_behind(tmp_path, words, signum, code):
    import os
    import signal
    import uuid

    mark = uuid.uuid4().hex
    proc = subprocess.Popen(_cli(*words), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "CNC_TWIN_TEST_MARK": mark}, cwd=tmp_path)
    time.sleep(5.0)  # into their runs: planners started, whiteboards made
    assert proc.poll() is None, "it ended before the signal: the test proves nothing"
    proc.send_signal(getattr(signal, signum))
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == code, err
    assert "Traceback" not in err and err.strip().splitlines()[-1] in ("interrupted", "terminated (SIGTERM)")
    time.sleep(0.5)
    assert _marked_processes(mark) == [], "a planner or helper outlived the command"
    assert not list(Path("/dev/shm").glob(f"cnc_twin_{proc.pid}_*"))
