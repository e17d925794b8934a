"""A program set up on the machine as a machinist sets it up: it starts where the machine stands
(LinuxCNC's interpreter starts from the machine's position), its zero placed on the workpiece by
work offsets (a touch-off: the scenario's ``program.work_offsets``, as LinuxCNC's parameter file
holds them), and proved in the air (``program.in_air`` / ``run --in-air``: the whole program
raised, the pad never reaching the work). Checked from the trace the card wrote."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from conftest import run_cli
from cnc_twin.trace.parquet import read_trace

COUNTS_PER_MM = 1000.0
"""the bundled machine's X / Y / Z encoders: 1 um a count"""
MILL = "G21 G90\nG0 X10 Y10\nG0 Z2\nG1 Z-1 F300\nG1 X40 F1200\nG0 Z5\nM2\n"
"""a milling pass 1 mm into the bundled workpiece's top (Z0)"""


def _run(tmp_path, name: str, program: str, *extra: str, scenario: dict | None = None):
    (tmp_path / f"{name}.ngc").write_text(program)
    source = tmp_path / f"{name}.ngc"
    if scenario is not None:
        source = tmp_path / f"{name}.yaml"
        source.write_text(yaml.safe_dump({"name": name, "program": {"type": "gcode", "file": f"{name}.ngc",
                                                                    **scenario}}))
    code, out, err = run_cli("run", source, *extra, "--out", tmp_path / f"run_{name}", "--no-rrd", "--quiet")
    return code, err, (read_trace(tmp_path / f"run_{name}" / "trace.parquet") if code == 0 else None)


def test_the_first_move_starts_where_the_machine_stands(tmp_path):
    """G1 X5 as the first move moves X alone (read from 0, Z would have gone down to the workpiece
    top on the way); an arc as the first motion runs from there too, as LinuxCNC runs it."""
    code, err, trace = _run(tmp_path, "first_line", "G21 G90\nG1 X5 F600\nM2\n")
    assert code == 0, err
    for axis in "YZAB":
        assert np.all(trace[f"command_{axis}"] == 0)
    assert trace["command_X"][-1] == pytest.approx(5 * COUNTS_PER_MM)
    code, err, trace = _run(tmp_path, "first_arc", "G21 G90 G17\nG2 X2 Y2 R2 F600\nM2\n")
    assert code == 0, err
    assert np.all(trace["command_Z"] == 0)
    assert (trace["command_X"][-1], trace["command_Y"][-1]) == pytest.approx((2000.0, 2000.0), abs=1.0)


def test_work_offsets_put_the_program_zero_where_the_scenario_says(tmp_path):
    program = "G21 G90\nG0 X0 Y0 Z10\nG0 X5\nM2\n"
    code, err, plain = _run(tmp_path, "plain", program, scenario={})
    assert code == 0, err
    code, err, offset = _run(tmp_path, "offset", program,
                             scenario={"work_offsets": {"G54": {"X": 30.0, "Y": -20.0, "Z": 5.0}}})
    assert code == 0, err
    shift = [offset[f"command_{a}"][-1] - plain[f"command_{a}"][-1] for a in "XYZ"]
    assert shift == pytest.approx([30000.0, -20000.0, 5000.0], abs=1.0)


def test_a_program_proved_in_the_air_runs_raised_and_never_touches(tmp_path):
    code, err, cutting = _run(tmp_path, "cutting", MILL)
    assert code == 0, err
    code, err, air = _run(tmp_path, "air", MILL, "--in-air", "5")
    assert code == 0, err
    # the whole path 5 mm higher: its lowest commanded point, and the same moves in X
    assert air["command_Z"].min() - cutting["command_Z"].min() == pytest.approx(5 * COUNTS_PER_MM, abs=1.0)
    assert air["command_X"].max() == cutting["command_X"].max()
    # the pad's load cell: pressed into the work when cutting, only its own inertia in the air
    assert np.abs(cutting["pad_force"]).max() > 3.0
    assert np.abs(air["pad_force"]).max() < 1.5


def test_in_the_air_a_program_that_presses_is_refused_before_any_motion(tmp_path):
    code, err, _ = _run(tmp_path, "press", "G21 G90\nG0 X0 Y0 Z5\nM100 P20\nG1 X5 F100\nM101\nM2\n", "--in-air", "5")
    assert code == 2 and not (tmp_path / "run_press").exists()
    assert len(err.strip().splitlines()) == 1 and "program.in_air" in err


@pytest.mark.parametrize("program", [{"work_offsets": {"G60": {"X": 1}}}, {"work_offsets": {"G54": {"Q": 1}}},
                                     {"in_air": -3}])
def test_a_bad_set_up_is_one_line_at_its_key(program, tmp_path):
    code, err, _ = _run(tmp_path, "bad", "G21\nG0 X1\nM2\n", scenario=program)
    assert code == 2 and not (tmp_path / "run_bad").exists()
    assert len(err.strip().splitlines()) == 1 and "program." in err


def test_g28_and_g30_return_to_where_the_machine_stood_not_to_the_workpiece(tmp_path):
    """CAM programs end with ``G91 G28 Z0``: Z goes back up to the machine's home (the stored G28
    position is the home, as on a machine homed there), X and Y stay; G30 likewise."""
    for code in ("G28", "G30"):
        program = f"G21 G90\nG0 X10 Y10 Z5\nG1 X20 F600\nG91 {code} Z0\nG90\nM2\n"
        status, err, trace = _run(tmp_path, code.lower(), program)
        assert status == 0, err
        assert trace["command_Z"].min() < -280 * COUNTS_PER_MM  # it went down to Z5 first
        assert trace["command_Z"][-1] == 0 and trace["command_X"][-1] == pytest.approx(20 * COUNTS_PER_MM)


def test_a_program_beyond_the_travel_is_refused_with_where_it_goes_and_runs_once_placed(tmp_path):
    """A part programmed from its corner, 500 mm long: beyond X's soft limits as written (one line,
    naming the key that places it); with G54 half its length back it runs, X ending at +250 mm."""
    program = "G21 G90\nG0 X0 Y0 Z5\nG1 X500 F3000\nM2\n"
    code, err, _ = _run(tmp_path, "long", program, scenario={})
    assert code == 2 and not (tmp_path / "run_long").exists()
    assert len(err.strip().splitlines()) == 1 and "program.work_offsets" in err
    code, err, trace = _run(tmp_path, "placed", program, scenario={"work_offsets": {"G54": {"X": -250.0}}})
    assert code == 0, err
    assert trace["command_X"][-1] == pytest.approx(250 * COUNTS_PER_MM, abs=1.0)
