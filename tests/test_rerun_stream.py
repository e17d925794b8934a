"""The recording process: a run recorded while it runs is the recording an export after it makes,
and a recording that fails never costs the run."""

from __future__ import annotations

import os
import signal
import subprocess
import sys

import pytest
from rrd_read import entity_columns, rrd_contents, rrd_rows

from cnc_twin.trace.parquet import read_trace
from cnc_twin.view.rerun_stream import RecordingError, RecordingProcess
from cnc_twin.scenario.resources import scenarios_dir
from cnc_twin.scenario.load import load_scenario, scenario_from_dict
from cnc_twin.run.twin import Twin, run_scenario


def _ptp():
    return scenario_from_dict({"name": "streamed", "program": {"type": "point_to_point", "settle": 0.05,
                                                               "moves": [{"X": 20}, {"Y": -10, "A": 4}]}})


@pytest.mark.parametrize("name", ["nurbs_circle", "ptp"])
def test_a_run_recorded_while_it_runs_equals_the_export_after_it(tmp_path, name):
    """Every value of every entity, static and over time: the process's stretches, its Python
    kinematics and the planned path it is handed reproduce the in-process export exactly."""
    scenario = _ptp() if name == "ptp" else load_scenario(scenarios_dir() / f"{name}.yaml")
    with RecordingProcess(min_stretch=50) as recorder:
        recorder.open(scenario, rrd=tmp_path / "streamed.rrd")
        result = Twin(scenario).run(observer=recorder.observe)
        assert recorder.finish(result) == tmp_path / "streamed.rrd"
        assert recorder.stretches >= 3  # it really streamed, stretch by stretch
    result.export_rerun(rrd=tmp_path / "after.rrd")
    streamed, after = rrd_contents(tmp_path / "streamed.rrd"), rrd_contents(tmp_path / "after.rrd")
    assert streamed.keys() == after.keys()
    for key in after:
        assert streamed[key] == after[key], key
    if name == "nurbs_circle":  # the planned path, static (by entity: column names are rerun's)
        assert entity_columns(streamed, "/paths/planned", static=True)


def test_a_lost_recording_process_fails_the_recording_not_the_run(tmp_path):
    scenario = _ptp()
    with RecordingProcess() as recorder:
        recorder.open(scenario, rrd=tmp_path / "lost.rrd")

        def observe(twin):
            recorder.observe(twin)
            if recorder.stretches and recorder.popen.poll() is None:
                recorder.popen.kill()

        result = Twin(scenario).run(observer=observe)
        with pytest.raises(RecordingError) as failed:
            recorder.finish(result)
    assert result.status == "complete" and result.trace.whole_periods > 300
    message = str(failed.value)
    assert "\n" not in message and message.startswith("rerun recording process: ")


def test_a_recording_process_that_cannot_write_says_why(tmp_path):
    """The reason is the process's own (rerun's words, not quoted here: a release may reword
    them), passed on in one line, not one of the twin's fallbacks for a process that said nothing."""
    scenario = _ptp()
    (tmp_path / "a_file").write_text("")  # a file where the folder should be: no writer gets past that
    with RecordingProcess() as recorder:
        recorder.open(scenario, rrd=tmp_path / "a_file" / "x.rrd")
        result = Twin(scenario).run(observer=recorder.observe)
        with pytest.raises(RecordingError) as failed:
            recorder.finish(result)
    message = str(failed.value)
    assert "\n" not in message and message.startswith("rerun recording process: ")
    reason = message.removeprefix("rerun recording process: ")
    assert reason and not reason.startswith(("no answer within", "the recording process ended", "lost during the run"))


def test_the_twin_process_gone_keeps_what_was_sent(tmp_path):
    """EOF before ``finish`` (the twin's process died): the recording is closed with the stretches
    it received, readable."""
    scenario = _ptp()
    result = run_scenario(scenario)
    recorder = RecordingProcess()
    recorder.open(scenario, rrd=tmp_path / "cut.rrd")
    recorder._send_periods(result.trace, 200)
    recorder.popen.stdin.close()
    assert recorder.popen.wait(timeout=60) == 1
    recorder.close()
    rows, _ = rrd_rows(tmp_path / "cut.rrd")
    assert rows["/axes/X/position"] == 200 and rows["/machine/x_carriage"] == 50


def test_cli_records_during_the_run_and_leaves_nothing_beside_the_run(tmp_path, write_scenario):
    path = write_scenario({"name": "tiny", "program": {"type": "point_to_point", "settle": 0.0, "moves": [{"X": 2}]}})
    out, extra = tmp_path / "runs" / "one", tmp_path / "copy.rrd"
    proc = subprocess.run([sys.executable, "-m", "cnc_twin", "run", str(path), "--out", str(out), "--rrd", str(extra),
                           "--quiet"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert not [line for line in proc.stderr.splitlines() if line.startswith("warning:")], proc.stderr  # ours
    assert sorted(os.listdir(out.parent)) == ["one"]  # the staged recording was moved in
    assert rrd_contents(out / "recording.rrd") == rrd_contents(extra)
    assert rrd_rows(out / "recording.rrd")[0]["/axes/X/position"] > 0


def test_cli_exports_after_the_run_when_the_recording_process_is_lost(tmp_path, monkeypatch, capsys):
    from cnc_twin import cli

    observe = RecordingProcess.observe

    def observe_then_kill(self, twin):
        observe(self, twin)
        if self.stretches and self.popen.poll() is None:
            self.popen.send_signal(signal.SIGKILL)

    monkeypatch.setattr(RecordingProcess, "observe", observe_then_kill)
    out = tmp_path / "run"
    assert cli.main(["run", "--out", str(out), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "warning: rerun recording process:" in err and "exporting the recording after the run" in err
    periods = len(read_trace(out / "trace.parquet")["time"]) // 4
    assert rrd_rows(out / "recording.rrd")[0]["/axes/X/position"] == periods
    assert sorted(os.listdir(tmp_path)) == ["run"]


def test_cli_rrd_into_a_missing_folder_is_a_one_line_error(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "cnc_twin", "run", "--out", str(tmp_path / "run"),
                           "--rrd", str(tmp_path / "nope" / "x.rrd")], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    assert proc.stderr.strip().count("\n") == 0 and "does not exist" in proc.stderr
    assert not (tmp_path / "run").exists()


def test_bench_measures_the_recording_after_the_run(write_scenario):
    """The figures, not their speed: a tail was measured and both clocks are the run's."""
    from cnc_twin.studies.bench import time_streamed_recording

    path = write_scenario({"name": "bench", "program": {"type": "point_to_point", "settle": 0.0, "moves": [{"X": 3}]}})
    figures = time_streamed_recording(path, repeat=1)
    assert 0 < figures["rerun_streamed_tail_s"] < 60
    assert 0 < figures["rerun_streamed_run_s"] and 0 < figures["rerun_streamed_run_alone_s"]
    assert figures["rerun_streamed_run_slowdown"] == pytest.approx(
        figures["rerun_streamed_run_s"] / figures["rerun_streamed_run_alone_s"] - 1.0)


def test_cli_rerun_without_a_display_says_so_and_keeps_the_recording(tmp_path, write_scenario):
    path = write_scenario({"name": "tiny", "program": {"type": "point_to_point", "settle": 0.0, "moves": [{"X": 1}]}})
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    proc = subprocess.run([sys.executable, "-m", "cnc_twin", "run", str(path), "--out", str(tmp_path / "run"), "--rerun",
                           "--quiet"], capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 0, proc.stderr
    assert "--rerun: no display" in proc.stderr and "cnc-twin view" in proc.stderr
    assert rrd_rows(tmp_path / "run" / "recording.rrd")[0]["/axes/X/position"] > 0
