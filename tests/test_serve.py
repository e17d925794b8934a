"""Your own PC program as the card's PC side (``cnc-twin serve``, clients/, examples/pc_jog.py and
examples/pc_curve.c): the served run of a program whose records are the twin's own planner's is
that planner's run bit for bit; every served run replays bit for bit from its run directory; a
program that sends a corrupted record, stops answering or dies gets what docs/pc-software.md says,
and nothing is left behind (segment, attach folder)."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest
import yaml

from cnc_twin.run.external_pc import STREAM_FILE
from cnc_twin.run.run_dir import METRICS_FILE, SCENARIO_FILE, TRACE_FILE
from cnc_twin.scenario.load import load_scenario
from cnc_twin.scenario.resources import scenarios_dir
from cnc_twin.whiteboard.block import NAME_PREFIX

REPO = Path(__file__).resolve().parent.parent
PC_PROGRAM = Path(__file__).with_name("pc_program.py")


def _cli(*words) -> list[str]:
    return [sys.executable, "-m", "cnc_twin", *map(str, words)]


def _segments_of(pid: int) -> list[str]:
    """Whiteboard segments process ``pid`` made that are still there (names carry the maker's pid)."""
    return [p.name for p in Path("/dev/shm").glob(f"{NAME_PREFIX}{pid}_*")]


class Served:
    """``cnc-twin serve`` as its own process, with the attach folder it printed."""

    def __init__(self, scenario, out: Path, *extra):
        self.out = out
        self.attach = out.parent / f"{out.name}-attach"
        self.proc = subprocess.Popen(_cli("serve", scenario, "--attach", self.attach, "--out", out, "--quiet",
                                          "--no-rrd", *extra), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True)

    def wait_for_attach(self) -> Path:
        line = self.proc.stdout.readline()
        assert line.startswith("attach: "), line + self.proc.stderr.read()
        assert Path(line.split(": ", 1)[1].strip()) == self.attach
        return self.attach

    def finish(self, timeout: float = 120) -> tuple[int, str, str]:
        out, err = self.proc.communicate(timeout=timeout)
        return self.proc.returncode, out, err


def _metrics(run: Path) -> dict:
    return json.loads((run / METRICS_FILE).read_text())


def _trace(run: Path):
    return pq.read_table(run / TRACE_FILE)


def _replay(run: Path, out: Path) -> None:
    done = subprocess.run(_cli("run", run / SCENARIO_FILE, "--out", out, "--quiet", "--no-rrd"), capture_output=True,
                          text=True, timeout=300)
    assert done.returncode in (0, 3), done.stderr


def _jog_config(scenario_path: Path, folder: Path) -> Path:
    """The JSON examples/pc_jog.py plans from, for ``scenario_path``'s machine and moves (SI)."""
    sc = load_scenario(scenario_path)
    config = {"period": sc.timing.interpolation_period, "home": list(sc.home),
              "axes": [{"name": a.name, "max_velocity": a.max_velocity, "max_acceleration": a.max_acceleration}
                       for a in sc.axes],
              "moves": [{"to": list(m.targets), "feed": m.feed, "dwell": m.dwell} for m in sc.program.moves],
              "settle": sc.program.settle}
    path = folder / "jog.json"
    path.write_text(json.dumps(config))
    return path


@pytest.fixture
def short_jog(tmp_path, write_scenario):
    """A two-move jog scenario (a heartbeat timeout of 0.5 s) and the PC program's JSON for it."""
    scenario = write_scenario({"name": "short_jog", "planner": {"heartbeat_timeout": 500},
                               "program": {"type": "point_to_point", "moves": [{"X": 60}, {"X": 0, "dwell": 0.2}],
                                           "settle": 0.2}})
    return scenario, _jog_config(scenario, tmp_path)


def test_the_bundled_jog_example_is_the_twins_own_jog_bit_for_bit_and_replays(tmp_path):
    """examples/pc_jog.py plans jog_axes's moves by itself (its own trapezoids, from pc_jog.json):
    its records are the twin's planner's, so the served trace is the twin's run's."""
    assert json.loads((REPO / "examples" / "pc_jog.json").read_text()) == \
        json.loads(_jog_config(scenarios_dir() / "jog_axes.yaml", tmp_path).read_text())  # the example says true
    served = Served("jog_axes", tmp_path / "served")
    client = subprocess.run([sys.executable, "-I", REPO / "examples" / "pc_jog.py", served.wait_for_attach()],
                            capture_output=True, text=True, timeout=120)
    code, out, err = served.finish()
    assert (code, client.returncode) == (0, 0), err + client.stderr
    assert out.splitlines()[-1] == f"run directory: {tmp_path / 'served'}"
    own = subprocess.run(_cli("run", "jog_axes", "--out", tmp_path / "own", "--quiet", "--no-rrd"), capture_output=True,
                         timeout=300)
    assert own.returncode == 0
    assert _trace(tmp_path / "served").equals(_trace(tmp_path / "own"))
    served_metrics = _metrics(tmp_path / "served")
    assert served_metrics["whiteboard"]["records_accepted"] == _metrics(tmp_path / "own")["whiteboard"]["records_accepted"]
    # the run directory runs again as it is: the twin's planner writes the program's stream again
    assert (tmp_path / "served" / STREAM_FILE).is_file()
    assert yaml.safe_load((tmp_path / "served" / SCENARIO_FILE).read_text())["planner"]["replay"] == STREAM_FILE
    _replay(tmp_path / "served", tmp_path / "replayed")
    assert _trace(tmp_path / "replayed").equals(_trace(tmp_path / "served"))
    assert not served.attach.exists() and _segments_of(served.proc.pid) == []


def _build_c(source: Path, program: Path) -> Path:
    """``source`` with the C client, built by the system's C compiler (warnings are errors)."""
    compiler = shutil.which("cc") or shutil.which("gcc")
    assert compiler is not None, "no C compiler (cc) on this machine: the C client cannot be tested"
    built = subprocess.run([compiler, "-O2", "-std=c11", "-Wall", "-Wextra", "-Werror", f"-I{REPO / 'clients' / 'c'}",
                            source, REPO / "clients" / "c" / "cnct_client.c", "-lm", "-o", program],
                           capture_output=True, text=True, timeout=120)
    assert built.returncode == 0, built.stderr
    return program


def test_the_c_example_streams_a_curve_that_replays_bit_for_bit(tmp_path):
    program = _build_c(REPO / "examples" / "pc_curve.c", tmp_path / "pc_curve")
    served = Served("nurbs_circle", tmp_path / "served")
    client = subprocess.run([program, served.wait_for_attach()], capture_output=True, text=True, timeout=120)
    code, _, err = served.finish()
    assert (code, client.returncode) == (0, 0), err + client.stderr + client.stdout
    metrics = _metrics(tmp_path / "served")
    assert metrics["status"] == "complete" and metrics["whiteboard"]["records_accepted"] == 8
    # the whole circle ran: its length as the card measured it, 2 pi 40 mm
    assert metrics["path"]["length_mm"] == pytest.approx(2 * 3.141592653589793 * 40.0, rel=1e-9)
    _replay(tmp_path / "served", tmp_path / "replayed")
    assert _trace(tmp_path / "replayed").equals(_trace(tmp_path / "served"))


def test_a_corrupted_record_is_rejected_and_resent_and_the_run_replays_with_its_reject(tmp_path, short_jog):
    scenario, config = short_jog
    served = Served(scenario, tmp_path / "served")
    client = subprocess.run([sys.executable, PC_PROGRAM, served.wait_for_attach(), config, "--corrupt", "2:100"],
                            capture_output=True, text=True, timeout=120)
    code, _, err = served.finish()
    assert (code, client.returncode) == (0, 0), err + client.stderr
    board = _metrics(tmp_path / "served")["whiteboard"]
    records = 5  # move, move, dwell, settle, end
    assert board["records_rejected"] == 1 and board["records_accepted"] == records
    assert board["records_retransmitted"] == records - 1  # go-back-N from the rejected one
    trace = _trace(tmp_path / "served")
    assert trace.column("records_rejected").to_pylist()[-1] == 1
    _replay(tmp_path / "served", tmp_path / "replayed")  # the same words again: the same reject
    assert _trace(tmp_path / "replayed").equals(trace)


def test_the_c_clients_go_back_n_resends_a_rejected_record(tmp_path, short_jog):
    program = _build_c(Path(__file__).with_name("pc_corrupt.c"), tmp_path / "pc_corrupt")
    served = Served(short_jog[0], tmp_path / "served")
    client = subprocess.run([program, served.wait_for_attach(), "2", "90"], capture_output=True, text=True,
                            timeout=120)
    code, _, err = served.finish()
    assert (code, client.returncode) == (0, 0), err + client.stdout
    assert client.stdout.split() == ["ended", "5", "0", "sent", "4", "again", "3"]  # FINISHED, no fault
    board = _metrics(tmp_path / "served")["whiteboard"]
    assert (board["records_rejected"], board["records_accepted"], board["records_retransmitted"]) == (1, 4, 3)


def test_a_program_that_stops_answering_is_lost_after_its_heartbeat_timeout(tmp_path, short_jog):
    scenario, config = short_jog
    served = Served(scenario, tmp_path / "served")
    client = subprocess.Popen([sys.executable, PC_PROGRAM, served.wait_for_attach(), config, "--every-period",
                               "--stop-after", "100"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        code, _, err = served.finish()
    finally:
        client.kill()
        client.communicate()
    assert code == 3, err
    fault = _metrics(tmp_path / "served")["fault"]
    assert fault["code"] == "PLANNER_LOST" and "heartbeat" in fault["message"]
    assert fault["time_s"] == pytest.approx(0.1, abs=0.002)  # the card waited at the period it was not answered
    assert not served.attach.exists()


def test_a_program_that_dies_is_lost_at_once(tmp_path, short_jog):
    scenario, config = short_jog
    served = Served(scenario, tmp_path / "served")
    started = time.monotonic()
    client = subprocess.run([sys.executable, PC_PROGRAM, served.wait_for_attach(), config, "--every-period",
                             "--die-after", "100"], capture_output=True, timeout=120)
    code, _, err = served.finish()
    waited = time.monotonic() - started
    assert client.returncode == -signal.SIGKILL and code == 3, err
    metrics = _metrics(tmp_path / "served")
    assert metrics["fault"]["code"] == "PLANNER_LOST" and "exited" in metrics["fault"]["message"]
    assert metrics["fault"]["stop"] == "controlled" and metrics["fault"]["at_rest_s"] is not None
    assert waited < 60  # not the heartbeat's timeout: its doorbell hung up
    assert not served.attach.exists() and _segments_of(served.proc.pid) == []


def test_a_program_that_never_attaches_is_a_planner_start_fault_and_leaves_nothing(tmp_path, short_jog):
    scenario, _ = short_jog
    served = Served(scenario, tmp_path / "served", "--wait", "0.5")
    served.wait_for_attach()
    code, _, err = served.finish()
    assert code == 3
    assert _metrics(tmp_path / "served")["fault"]["code"] == "PLANNER_START"
    assert not (tmp_path / "served" / STREAM_FILE).exists()  # nothing was streamed, nothing to replay
    assert not served.attach.exists()


def test_a_signal_while_serving_removes_the_attach_folder(tmp_path, short_jog):
    scenario, _ = short_jog
    served = Served(scenario, tmp_path / "served")
    served.wait_for_attach()
    served.proc.send_signal(signal.SIGINT)
    code, _, err = served.finish()
    assert code == 130, err
    assert not served.attach.exists()


@pytest.mark.parametrize("words, problem", [
    (("serve", "jog_axes", "--attach", "{here}"), "an attach folder that exists"),
    (("serve", "jog_axes", "--attach", "{here}/no/such/parent"), "an attach folder without its parent"),
    (("run", "jog_axes", "--replay", "{here}/missing.bin"), "no stream file"),
    (("run", "jog_axes", "--replay", "{here}/bad.bin"), "not a stream file"),
])
def test_bad_serve_and_replay_input_is_one_line_and_exit_2(tmp_path, words, problem):
    (tmp_path / "bad.bin").write_bytes(b"CNCTPCS1" + b"\x00" * 3)
    done = subprocess.run(_cli(*(w.format(here=tmp_path) for w in words), "--out", tmp_path / "run"),
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, problem
    assert len(done.stderr.strip().splitlines()) == 1 and "Traceback" not in done.stderr, problem
    assert not (tmp_path / "run").exists()


def test_the_client_libraries_layout_files_are_the_twins_and_import_nothing_of_it(tmp_path):
    check = subprocess.run([sys.executable, "-m", "cnc_twin.whiteboard.client_files", "--check"], capture_output=True,
                           text=True, cwd=REPO, timeout=60)
    assert check.returncode == 0, check.stderr
    stale = tmp_path / "root"
    shutil.copytree(REPO / "clients", stale / "clients")
    header = stale / "clients" / "c" / "cnct_whiteboard.h"
    header.write_text(header.read_text().replace("#define CNCT_PC_HOLD 8u", "#define CNCT_PC_HOLD 9u"))
    assert subprocess.run([sys.executable, "-m", "cnc_twin.whiteboard.client_files", "--check", stale],
                          capture_output=True, timeout=60).returncode == 1
    # the Python client, loaded in an interpreter that cannot see the twin, loads none of it
    code = ("import sys; sys.path.insert(0, sys.argv[1]); import cnct_client; "
            "print(sorted(m for m in sys.modules if m.startswith('cnc_twin')))")
    alone = subprocess.run([sys.executable, "-I", "-c", code, REPO / "clients" / "python"], capture_output=True,
                           text=True, timeout=60, cwd=tmp_path)
    assert alone.returncode == 0 and alone.stdout.strip() == "[]", alone.stderr
