"""The bundled dense 5-axis CAM raster (scripts/make_cam_raster.py): written again the same, and
run on the twin fitted (G64 P0.01) and segment by segment (G61.1), checked from the trace."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from cnc_twin import load_scenario, run_scenario
from cnc_twin.scenario.resources import BUNDLED_MACHINES, scenarios_dir

ROOT = Path(__file__).resolve().parents[1]


def test_the_script_writes_the_bundled_programs_again_byte_for_byte(tmp_path):
    subprocess.run([sys.executable, str(ROOT / "scripts" / "make_cam_raster.py"), "--out", str(tmp_path)], check=True,
                   capture_output=True)
    for name in ("cam_raster", "cam_raster_exact"):
        assert (tmp_path / "programs" / f"{name}.ngc").read_bytes() == (ROOT / "programs" / f"{name}.ngc").read_bytes()
        assert (tmp_path / "scenarios" / f"gcode_{name}.yaml").read_bytes() == \
            (scenarios_dir() / f"gcode_{name}.yaml").read_bytes()
    text = (ROOT / "programs" / "cam_raster.ngc").read_text()
    assert text.count("\nG1 ") > 4000 and " A" in text and " B" in text


@pytest.fixture(scope="module")
def raster_runs():
    """Both runs on the rigid machine: what is checked is the planner's fit and its timing (the
    commanded path), the same on either machine, and the rigid one steps 1.7x faster."""
    rigid = dict(BUNDLED_MACHINES["rigid"])
    return {name: run_scenario(load_scenario(scenarios_dir() / f"gcode_{name}.yaml", overrides=rigid)).metrics
            for name in ("cam_raster", "cam_raster_exact")}


def test_the_fitted_raster_stays_within_p_and_the_axis_tolerance_from_the_trace(raster_runs):
    m = raster_runs["cam_raster"]
    assert m["final_state"] == "FINISHED" and m["path"]["limit_violations"] == []
    program = m["program"]
    assert program["fits"]["runs"] >= 1 and program["fits"]["spans"] < 4408 / 5
    d = program["deviation_um"]
    assert d["tolerance_um"] == pytest.approx(10.0) and d["max"] <= 10.0 and d["vertices_max"] <= 10.0
    assert program["axis_deviation_deg"]["max"] <= 0.05
    assert m["whiteboard"]["underrun_periods"] == 0  # planning kept ahead of the card in lockstep
    for axis, peaks in m["path"]["axis_peaks"].items():  # X Y Z A B, from the trace
        for q in ("velocity", "acceleration", "jerk"):
            assert peaks[f"{q}_ratio"] <= 1.01, (axis, q)


def test_fitted_runs_the_raster_far_faster_than_segment_by_segment(raster_runs):
    fitted, exact = (raster_runs[n]["program"]["feed"] for n in ("cam_raster", "cam_raster_exact"))
    assert fitted["ideal_time_s"] == pytest.approx(exact["ideal_time_s"], rel=1e-3)  # the same program path
    assert exact["time_s"] >= 3.0 * fitted["time_s"]
    assert fitted["share_at_95pct"] >= 0.8 and exact["share_at_95pct"] <= 0.1
    assert fitted["time_s"] <= 1.10 * fitted["ideal_time_s"]  # the goal: within 10 % of the F-limited time
