"""Outside CAM programs run on the twin in the air, checked from the trace against the program's
own text and the parameter file's limits (the whole corpus: ``scripts/outside_programs.py``,
docs/outside_programs.md). Here the short ones that exercise what real CAM output brings: a
pcb2gcode drill file (G81 canned cycles, an M0 tool change stop, T words) and a pcb2gcode
board outline (arcs, plunges)."""

from __future__ import annotations

import re

import numpy as np
import pytest

import shared_data
from conftest import run_cli
from cnc_twin.scenario.load import load_scenario
from cnc_twin.trace.parquet import read_trace

IN_AIR = 15.0
"""[mm] above where the programs put the tool: the drill file goes 1.75 mm, the outline 3.3 mm below the
workpiece top, so the pad never reaches it"""
HOME_TIP_Z = 290.0
"""[mm] the bundled machine's pad tip above the workpiece top at the home pose (Z axis 0)"""
TOLERANCE = 1.01
"""a commanded peak may exceed its limit by 1 %"""


def _run(name: str, tmp_path):
    path = shared_data.require(shared_data.OUTSIDE_GCODE) / name
    out = tmp_path / "run"
    code, _, err = run_cli("run", path, "--in-air", IN_AIR, "--out", out, "--no-rrd", "--quiet")
    assert code == 0, err
    return path, read_trace(out / "trace.parquet"), load_scenario(out / "scenario.yaml")


def _within_limits(trace, scenario) -> None:
    """Every axis's commanded velocity and acceleration, period by period, within its limits."""
    ends = np.flatnonzero(np.diff(trace["period"]) != 0)
    T = scenario.timing.interpolation_period
    for cfg in scenario.axes:
        q = trace[f"command_{cfg.name}"][ends] / cfg.counts_per_unit
        assert np.abs(np.diff(q)).max() / T <= cfg.max_velocity * TOLERANCE, cfg.name
        assert np.abs(np.diff(q, n=2)).max() / T**2 <= cfg.max_acceleration * TOLERANCE, cfg.name


def test_a_drill_file_drills_every_hole_of_its_text_at_its_depth_in_the_air(tmp_path):
    path, trace, scenario = _run("pcb2gcode__testing_gerbv_example_milldrilldiatest_units_expected_drill.ngc",
                                 tmp_path)
    text = path.read_text()
    holes, bottoms, cycle = 0, set(), False
    for line in text.splitlines():
        words = line.split("(")[0]
        if "G81" in words:
            cycle = True
            bottoms.add(float(re.search(r"Z(-?[\d.]+)", words).group(1)))
        if "G80" in words:
            cycle = False
        holes += cycle and bool(re.search(r"X-?[\d.]+", words))
    assert holes == 5 and bottoms == {-1.75}
    z = trace["command_Z"] / 1000.0  # mm (1 um a count), the Z axis from home
    bottom = -1.75 + IN_AIR - HOME_TIP_Z
    assert z.min() == pytest.approx(bottom, abs=1e-3)
    at_bottom = np.abs(z - bottom) < 1e-3
    assert np.count_nonzero(np.diff(at_bottom.astype(int)) == 1) == holes  # one plunge a hole
    assert np.abs(trace["pad_force"]).max() < 1.5  # in the air: only the pad's own inertia
    _within_limits(trace, scenario)


def test_a_board_outline_with_arcs_runs_to_the_end_within_every_limit(tmp_path):
    _, trace, scenario = _run("pcb2gcode__extras_example_board_outline.ngc", tmp_path)
    assert np.abs(trace["pad_force"]).max() < 1.5
    _within_limits(trace, scenario)
