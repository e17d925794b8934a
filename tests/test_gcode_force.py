"""The grinding-force loop from a G-code program (M100 P<newtons> / M101): the bundled program
polishes the workpiece top on the whole twin; contact, tracking, retract and removal checked from
the trace, the program's own lines and the scene's own geometry."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from cnc_twin import load_scenario, run_scenario
from cnc_twin.core.gcode_config import GcodeForce, GcodePath
from cnc_twin.dsp.force import ForceState
from cnc_twin.scenario.resources import scenarios_dir

FORCE_ON_LINE, FORCE_OFF_LINE = 14, 24
"""M100 and M101 in programs/polish_force.ngc"""


@pytest.fixture(scope="module")
def pressed():
    scenario = load_scenario(scenarios_dir() / "gcode_force.yaml")
    return scenario, run_scenario(scenario)


def test_the_program_reads_m100_and_m101_at_their_lines(pressed):
    scenario, _ = pressed
    program = scenario.program
    text = program.text.splitlines()
    assert text[FORCE_ON_LINE - 1].startswith("M100 P20") and text[FORCE_OFF_LINE - 1].startswith("M101")
    forces = [s for s in program.steps if isinstance(s, GcodeForce)]
    assert [(f.line, None if f.control is None else f.control.setpoint) for f in forces] == \
        [(FORCE_ON_LINE, 20.0), (FORCE_OFF_LINE, None)]
    on = program.steps.index(forces[0])
    assert isinstance(program.steps[on + 1], GcodePath)
    assert forces[0].control.standoff == pytest.approx(2e-3)


def test_the_force_program_presses_at_its_setpoint_and_polishes_by_prestons_law(pressed):
    _, result = pressed
    m = result.metrics
    assert m["final_state"] == "FINISHED"
    polish = m["polish"]
    tracking = polish["force"]["tracking"]
    assert polish["setpoints_n"] == [20.0]
    assert tracking["rms_error_pct"] <= 2.0 and abs(tracking["mean_force_n"] - 20.0) < 0.5
    assert polish["force"]["first_contact"]["overshoot_pct"] <= 20.0
    removal = polish["removal"]
    assert removal["volume_mm3"] > 0.0
    assert removal["volume_mm3"] == pytest.approx(removal["preston_by_hand_mm3"], rel=0.02)
    assert m["path"]["limit_violations"] == []
    assert m["path"]["chord_error_um"]["max"] <= m["path"]["chord_error_um"]["tolerance"]


def test_the_trace_presses_only_on_the_lines_between_m100_and_m101(pressed):
    _, result = pressed
    trace = result.trace
    state, mark = trace.period_signals["force_state"], trace.period_signals["mark"]
    active = state != ForceState.OFF
    assert np.any(state == ForceState.TRACK)
    assert set(np.unique(mark[active]).tolist()) <= set(range(FORCE_ON_LINE + 1, FORCE_OFF_LINE + 1))
    # before the seek the pad only touches the surface (G1 Z0: the nominal contact), under the
    # force that counts as contact
    first_seek = int(np.flatnonzero(state == ForceState.SEEK)[0])
    assert np.max(trace.pad_force[:first_seek]) < 2.0


def test_the_seek_starts_and_the_retract_ends_the_standoff_above_the_path(pressed):
    """No jump when the loop starts: the commanded Z moves by at most the seek speed per tick from
    the tick before the seek on (a regression: the first period of a seek used to command the
    nominal pose, a 2 mm step down and back); the seek starts and the retract ends at the same
    height over the flat path, the standoff above it."""
    scenario, result = pressed
    trace = result.trace
    state = trace.period_signals["force_state"]
    z_axis = 2
    cpu = trace.counts_per_unit[z_axis]
    z = trace.command[:, z_axis] / cpu + scenario.home[z_axis]  # [m]
    tick = float(trace.time[1] - trace.time[0])
    seek = np.flatnonzero(state == ForceState.SEEK)
    ramp = np.flatnonzero(state == ForceState.RAMP)
    window = slice(int(seek[0]) - 1, int(ramp[0]))
    force = [s for s in scenario.program.steps if isinstance(s, GcodeForce)][0].control
    assert np.max(np.abs(np.diff(z[window]))) <= force.seek_speed * tick * 1.01
    retract = np.flatnonzero(state == ForceState.RETRACT)
    after = int(retract[-1]) + scenario.timing.ticks_per_period  # the end of the first period off
    assert z[after] == pytest.approx(z[int(seek[0]) - 1], abs=1e-9)
    # the nominal path: the pad face on the surface, Z0 of the program = the workpiece top
    surface_z = scenario.program.workpiece.surface.control_net[0][0][2]
    tpp = scenario.timing.ticks_per_period
    ends = slice(tpp - 1, None, tpp)  # the last tick of each period: its setpoint
    track = state[ends] == ForceState.TRACK
    nominal = (z[ends] + trace.period_signals["force_depth"][ends])[track]  # the path's Z: the offset put back
    assert np.ptp(nominal) < 1e-9
    assert z[after] - nominal[0] == pytest.approx(force.standoff, abs=1e-9)
    assert surface_z == pytest.approx(0.06)


def test_without_a_workpiece_key_m100_presses_on_the_scenes_block_top(tmp_path):
    (tmp_path / "p.ngc").write_text("G21 G90\nG0 X0 Y0 Z5\nG1 Z0 F600\nM100 P15\nG1 X10 F1000\nM2\n")
    scenario = load_scenario(tmp_path / "p.ngc")
    program = scenario.program
    assert isinstance(program.steps[-1], GcodeForce) and program.steps[-1].control is None  # the end: off
    model = mujoco.MjModel.from_xml_path(str(scenario.model_file))
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    geom = model.geom("workpiece_collision")
    centre, half = data.geom_xpos[geom.id], model.geom_size[geom.id]
    net = np.asarray(program.workpiece.surface.control_net)
    assert net[..., 2] == pytest.approx(np.full((2, 2), centre[2] + half[2]))
    assert net[..., 0].min() == pytest.approx(centre[0] - half[0]) and net[..., 0].max() == pytest.approx(centre[0] + half[0])
    assert net[..., 1].min() == pytest.approx(centre[1] - half[1]) and net[..., 1].max() == pytest.approx(centre[1] + half[1])
