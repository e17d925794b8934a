"""Probing on the twin (G38.2 .. G38.5): the card's probe move, the program read on with the
card's answer, checked from the trace against the scene's geometry and the scenario's set-up."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
import pytest

from cnc_twin import load_scenario, run_scenario
from cnc_twin.core.gcode_config import GcodeProbe
from conftest import run_cli

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "gcode_probe.yaml"
PROBE_LINE, POLISH_LINE = 9, 16
"""programs/polish_probe.ngc: the G38.2 and the first polishing pass (G1 X40 at Z-0.2)"""
PRESS = 0.2e-3
"""[m] how far past the touch the program polishes"""


def _run(shift_mm: float):
    sc = load_scenario(SCENARIO, overrides={"machine.block_shift": [0.0, 0.0, shift_mm]})
    result = run_scenario(sc)
    assert result.metrics["final_state"] == "FINISHED", result.metrics.get("fault")
    return sc, result


def _block_top(sc) -> float:
    """[m] the real top of the scene's block, world frame: its geometry moved by the set-up's shift."""
    model = mujoco.MjModel.from_xml_path(str(sc.model_file))
    geom = model.geom("workpiece_collision")
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    return float(data.geom_xpos[geom.id][2] + model.geom_size[geom.id][2] + sc.block_shift[2])


def _probe_step(sc) -> GcodeProbe:
    return next(s for s in sc.program.steps if isinstance(s, GcodeProbe))


def _trip(trace, trip_force: float):
    """The first period of the probing line where the load cell read the trip force: its row."""
    rows = np.flatnonzero((trace["mark"] == PROBE_LINE) & (trace["pad_force"] >= trip_force))
    assert rows.size, "the probe never read its trip force"
    return int(rows[0])


@pytest.fixture(scope="module")
def runs():
    return {shift: _run(shift) for shift in (0.0, 1.5)}


def test_the_probe_finds_the_part_where_it_was_set_up(runs):
    """The part set up 1.5 mm higher than drawn: the pad trips 1.5 mm higher, within the load
    cell's resolution (an ADC step over the pad's stiffness: 0.049 N / 5 N/mm = 10 um), on the
    real top of the block (not the drawn one)."""
    found = {}
    for shift, (sc, result) in runs.items():
        tr = result.trace.columns()
        row = _trip(tr, _probe_step(sc).trip_force)
        cpu = sc.axes[2].counts_per_unit
        found[shift] = tr["actual_Z"][row] / cpu
        top = _block_top(sc)
        # the pad's face (undeflected) at the trip: on the real top, pressed less than 0.15 mm into it
        assert top - 0.15e-3 < tr["tip_z"][row] <= top + 2e-6, (shift, tr["tip_z"][row], top)
    lsb = (sc.force_sensor.range_max - sc.force_sensor.range_min) / 2 ** sc.force_sensor.bits
    model = mujoco.MjModel.from_xml_path(str(sc.model_file))
    stiffness = float(model.jnt_stiffness[model.joint("pad_joint").id])  # [N/m]
    assert abs((found[1.5] - found[0.0]) - 1.5e-3) <= lsb / stiffness + 1e-6


def test_the_program_polishes_at_its_depth_below_the_found_top(runs):
    """G10 L2 sets G54's Z at the trip (#5063), the pass runs 0.2 mm below it: commanded Z is the
    latched count less 0.2 mm, and the pass presses the part alike wherever it sits."""
    forces, heights = {}, {}
    for shift, (sc, result) in runs.items():
        tr = result.trace.columns()
        cpu = sc.axes[2].counts_per_unit
        row = _trip(tr, _probe_step(sc).trip_force)
        period_rows = round(sc.timing.interpolation_period / sc.timing.servo_period)
        latched = set(tr["actual_Z"][row - period_rows:row + period_rows + 1].tolist())
        polish = tr["mark"] == POLISH_LINE
        commanded = np.unique(np.round(tr["command_Z"][polish], 6))
        assert commanded.size == 1, commanded  # one depth all along the pass
        assert round(float(commanded[0]) + PRESS * cpu) in latched
        forces[shift] = float(np.mean(tr["pad_force"][polish]))
        heights[shift] = float(np.mean(tr["actual_Z"][polish])) / cpu
    lsb = (sc.force_sensor.range_max - sc.force_sensor.range_min) / 2 ** sc.force_sensor.bits
    assert forces[0.0] > 2.0 and abs(forces[1.5] - forces[0.0]) <= 2 * lsb, forces
    assert abs(heights[1.5] - heights[0.0] - 1.5e-3) <= 5e-6


def test_the_run_is_measured_against_the_program_as_it_ran(runs):
    """The metrics and the recording see the program read again with the card's answer: the
    polishing path's deviation is microns, not the 30 mm the load-time reading (rs274's
    standalone answer) would put it at."""
    sc, result = runs[1.5]
    probes = [s for s in result.scenario.program.steps if isinstance(s, GcodeProbe)]
    assert len(probes) == 1 and probes[0].line == PROBE_LINE
    assert result.metrics["program"]["deviation_um"]["max"] < 50.0
    assert result.scenario.program.paths[0].curve.control_points[0][2] != sc.program.paths[0].curve.control_points[0][2]


def test_lockstep_probing_runs_are_bit_identical(runs):
    sc, result = runs[1.5]
    first, again = result.trace.columns(), run_scenario(sc).trace.columns()
    assert first.keys() == again.keys()
    for name in first:
        assert np.array_equal(first[name], again[name]), name


PROGRAM = """G21 G90 G54
G0 X0 Y0 Z20
{probe}
o1 if [#5070 EQ 0]
  G0 X10
o1 else
  G0 X-10
o1 endif
G0 Z30
M2
"""


def _scenario(tmp_path: Path, probe: str, **program) -> Path:
    (tmp_path / "p.ngc").write_text(PROGRAM.format(probe=probe))
    lines = [f"  {k}: {v}" for k, v in program.items()]
    (tmp_path / "s.yaml").write_text("name: probe_case\nprogram:\n  type: gcode\n  file: p.ngc\n" + "\n".join(lines) + "\n")
    return tmp_path / "s.yaml"


def test_a_probe_that_must_trip_and_does_not_faults(tmp_path):
    """G38.2 ending on the block's top, where the pad barely touches: the card faults (PROBE) at
    the end of the move, as LinuxCNC's motion errs; G38.3 ending 10 mm above it accepts not
    tripping and the program reads #5070 = 0."""
    result = run_scenario(load_scenario(_scenario(tmp_path, "G38.2 Z0 F600")))
    assert result.metrics["fault"]["code"] == "PROBE"
    commanded_x = result.trace.columns()["command_X"]
    assert np.all(commanded_x == commanded_x[0])  # nothing after the probe ran
    (tmp_path / "b").mkdir()
    result = run_scenario(load_scenario(_scenario(tmp_path / "b", "G38.3 Z10 F600")))
    assert result.metrics["final_state"] == "FINISHED"
    sc = result.scenario
    commanded_x = result.trace.columns()["command_X"]
    x_end = commanded_x[-1] / sc.axes[0].counts_per_unit + sc.home[0]
    x_probe = commanded_x[0] / sc.axes[0].counts_per_unit + sc.home[0]
    assert x_end - x_probe == pytest.approx(10e-3, abs=1e-9)  # the not-tripped branch


@pytest.mark.parametrize("probe, extra", [
    ("G38.2 X10 Z-30 F60", {}),                       # across the tool axis
    ("G38.4 Z-30 F60", {}),                           # "until clear" moving down
    ("G38.2 Z-30 F60", {"in_air": 50}),               # must touch, in the air
    ("G38.2 Z10 F60", {}),                            # ends above the part
    ("G0 X130\nG38.2 Z-30 F60", {}),                  # beside the part (its top +-100 mm, the pad 25 mm)
])
def test_probes_the_pad_cannot_make_are_refused_at_load(tmp_path, probe, extra):
    path = _scenario(tmp_path, probe, **extra)
    for command in ("validate", "run"):
        code, out, err = run_cli(command, str(path), "--out", str(tmp_path / "run")) if command == "run" \
            else run_cli(command, str(path))
        assert code == 2, (command, out, err)
        assert len(err.strip().splitlines()) == 1 and f"p.ngc:{2 + probe.count(chr(10)) + 1}:" in err, err
        assert not (tmp_path / "run").exists()

