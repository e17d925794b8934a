"""The bench's replayed denominator (cnc_twin/studies/bench_replay.py): what it replays, not its speed."""

from __future__ import annotations

import numpy as np

from cnc_twin import load_scenario, run_scenario
from cnc_twin.scenario.resources import scenarios_dir
from cnc_twin.studies.bench_replay import contacts_at_rest, run_model, time_replayed_steps


def _replay(scenario, result):
    timing = scenario.timing
    return time_replayed_steps(run_model(scenario), result.trace.dac, timestep=timing.physics_timestep,
                               substeps=timing.substeps_per_tick, drives=scenario.drives)


def test_the_replay_retraces_a_run_that_only_drives_the_axes():
    """A curve run puts nothing on the model but the drive voltages: replayed open loop, the same
    codes from the same home take the encoders where the run's ended (within two counts: the trace's
    last reading is a whole count, taken before its tick's physics steps)."""
    scenario = load_scenario(scenarios_dir() / "nurbs_circle.yaml", overrides={"max_time": 1.0})
    result = run_scenario(scenario)
    replay = _replay(scenario, result)
    counts = result.trace.counts_per_unit
    ended = result.trace.actual[-1] / counts  # encoder counts are from home
    assert np.max(np.abs(result.trace.actual[-1])) > 1000  # the axes moved
    assert np.all(np.abs(replay.final_encoders - ended) <= 2.0 / counts)
    assert replay.seconds > 0


def test_a_polishing_replay_keeps_the_pad_in_contact_and_rest_has_none(tmp_path):
    """The polishing run replayed: the pad presses the workpiece (contacts every tick on average),
    where the machine at rest touches nothing: the contact load the bench reports on both sides."""
    short = tmp_path / "plate.yaml"
    short.write_text((scenarios_dir() / "flat_plate_polish.yaml").read_text().replace("step_over: 4.0", "step_over: 30.0"))
    scenario = load_scenario(short)
    replay = _replay(scenario, run_scenario(scenario))
    assert replay.contacts_mean >= 1.0, replay
    assert contacts_at_rest(scenario) == 0.0
