"""The fair denominator for a run in contact: the run's own model stepped open loop with the drive
voltages the run recorded.

Bare stepping at rest (:func:`cnc_twin.studies.bench.time_bare_steps`) steps the machine's MJCF
out of contact: a polishing run's physics costs more than that, since MuJoCo resolves the pad's
contacts with the workpiece every step. Here the model the twin built for the run (with its
workpiece and obstacles) is reset to home and stepped ``substeps`` physics steps per servo tick,
each tick's six DAC codes from the trace put on the drives as the card's DAC outputs them
(``code * 10 / 2048`` V), with no controller, no planner, no recording: what the physics alone of
that run costs. Open loop the pad drifts from the run's path by the drives' own error, so the
mean contact count is reported beside the time (and the same for the machine at rest) for a
reader to see the contact load matched.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import mujoco
import numpy as np

from cnc_twin.core.config import Scenario
from cnc_twin.dsp.dac import CODE_MAX
from cnc_twin.machine.model_file import load_model
from cnc_twin.machine.plant import Plant

VOLTS_PER_CODE = 10.0 / (CODE_MAX + 1)
"""[V] the card's DAC step at its +/-10 V range (:mod:`cnc_twin.dsp.dac`)"""


def run_model(scenario: Scenario) -> mujoco.MjModel:
    """The model the twin builds for ``scenario`` (the program kind's plant: workpiece, obstacles)."""
    from cnc_twin.run.twin import Twin

    return Twin(scenario).plant.model


@dataclass(frozen=True)
class Replay:
    seconds: float
    """wall time of the stepping loop [s]"""
    contacts_mean: float
    """MuJoCo contacts per tick (after each tick's steps), mean"""
    final_encoders: np.ndarray
    """where the six encoders read after the last tick, counted from home [m | rad] (the motors'
    on the compliant machine's semi-closed axes; the axis joints' on the rigid one)"""


def time_replayed_steps(model: mujoco.MjModel, dac_codes: np.ndarray, *, timestep: float, substeps: int,
                        drives=None) -> Replay:
    """Step ``model`` from home, ``substeps`` physics steps of ``timestep`` per row of
    ``dac_codes`` ((ticks, 6) DAC codes), each row's voltages on the drives for its tick (through
    the amplifiers' loops where ``drives``, the scenario's, give them)."""
    plant = Plant(model, timestep=timestep, drives=drives)
    data = plant.data
    volts = np.asarray(dac_codes, dtype=np.float64) * VOLTS_PER_CODE
    contacts = 0
    start = time.perf_counter()
    if plant.per_step:  # the amplifiers and the screws run before every step
        apply_volts, step = plant.apply_volts, plant.step
        for row in volts:
            apply_volts(row)
            step(substeps)
            contacts += data.ncon
    else:
        ctrl = data.ctrl
        n = volts.shape[1]
        mj_step = mujoco.mj_step
        for row in volts:
            ctrl[:n] = row
            mj_step(model, data, nstep=substeps)
            contacts += data.ncon
    elapsed = time.perf_counter() - start
    final_encoders = plant.encoder_positions() - np.asarray(plant.encoder_home)
    return Replay(elapsed, contacts / max(len(volts), 1), final_encoders)


def contacts_at_rest(scenario: Scenario, *, steps: int = 200) -> float:
    """Mean contacts per step of the bare MJCF at home, drives at 0 V (the at-rest denominator)."""
    plant = Plant(load_model(scenario.model_file), timestep=scenario.timing.physics_timestep, drives=scenario.drives)
    total = 0
    for _ in range(steps):
        mujoco.mj_step(plant.model, plant.data)
        total += plant.data.ncon
    return total / steps
