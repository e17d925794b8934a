"""The start-up benchmark's accounting (cnc_twin.studies.bench_startup): a command's phases, from
the marks it writes (cnc_twin.core.phases), each in its place, inside the process's wall time as
the parent measured it, and the run's own phase as long as the run's clock says (metrics.json,
timed inside the run by other calls, nested in it)."""

from __future__ import annotations

import json


from cnc_twin.scenario.resources import scenarios_dir
from cnc_twin.studies.bench_startup import _cnc_twin, phases, time_process


def test_phases_run_from_the_start_through_each_mark_to_the_end():
    got = phases(10.0, [(10.5, "entry"), (11.25, "imported"), (12.0, "loaded"), (12.5, "loaded")], 13.0)
    assert got == {"python start": 0.5, "imports": 0.75, "load": 1.25, "exit": 0.5}


def test_a_run_command_marks_each_phase_in_its_place_around_the_run_s_own_clock(tmp_path):
    out = tmp_path / "run"
    measured = time_process([*_cnc_twin(), "run", str(scenarios_dir() / "jog_axes.yaml"), "--quiet", "--no-rrd",
                             "--out", str(out)], marks=tmp_path / "marks")
    assert measured["code"] == 0
    names = list(measured["phases"])
    assert names == ["python start", "imports", "load", "twin built", "kernels", "planner ready", "run's clock",
                     "metrics", "other files", "recording.rrd", "trace.parquet", "metrics.json", "run directory",
                     "exit"]
    # every mark the child wrote falls, in order, between the parent's start and end (a mark's
    # clock other than the parent's, or a phase out of place, shows as a negative phase)
    assert all(seconds >= 0.0 for seconds in measured["phases"].values())
    # the run's phase against the run's own clock (its metrics, timed by the run itself around its
    # loop): the phase holds it, and the clock's set-up before it (buffers), well under a second
    clock = json.loads((out / "metrics.json").read_text())["wall_time_s"]
    assert 0.0 < clock <= measured["phases"]["run's clock"] <= clock + 1.0
