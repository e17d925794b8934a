"""The start-up benchmark's accounting (cnc_twin.studies.bench_startup): a command's phases, from
the marks it writes (cnc_twin.core.phases), add up to its whole wall time, each in its place."""

from __future__ import annotations

import pytest

from cnc_twin.scenario.resources import scenarios_dir
from cnc_twin.studies.bench_startup import _cnc_twin, phases, time_process


def test_phases_run_from_the_start_through_each_mark_to_the_end():
    got = phases(10.0, [(10.5, "entry"), (11.25, "imported"), (12.0, "loaded"), (12.5, "loaded")], 13.0)
    assert got == {"python start": 0.5, "imports": 0.75, "load": 1.25, "exit": 0.5}


def test_a_run_command_marks_each_phase_and_they_add_up_to_its_wall_time(tmp_path):
    out = tmp_path / "run"
    measured = time_process([*_cnc_twin(), "run", str(scenarios_dir() / "jog_axes.yaml"), "--quiet", "--no-rrd",
                             "--out", str(out)], marks=tmp_path / "marks")
    assert measured["code"] == 0
    names = list(measured["phases"])
    assert names == ["python start", "imports", "load", "twin built", "kernels", "planner ready", "run's clock",
                     "metrics", "other files", "recording.rrd", "trace.parquet", "metrics.json", "run directory",
                     "exit"]
    assert sum(measured["phases"].values()) == pytest.approx(measured["wall_s"], abs=1e-6)
    assert all(seconds >= 0.0 for seconds in measured["phases"].values())
    assert (out / "metrics.json").is_file()
