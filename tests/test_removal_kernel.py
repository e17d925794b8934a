"""The compiled removal update (cnc_twin/polishing/removal_kernel.py) against its numpy reference:
the same removal map, the same friction wrench, the same trace, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from cnc_twin import load_scenario
from cnc_twin.machine.workpiece import PAD_CONTACT_SLOTS
from cnc_twin.polishing import removal_kernel as rk
from cnc_twin.polishing.polish import FRICTION_SPEED, friction_wrench
from cnc_twin.polishing.removal import PrestonModel, RemovalGrid
from cnc_twin.run.twin import Twin
from cnc_twin.scenario.resources import scenarios_dir


def _bumpy_grid(rng) -> RemovalGrid:
    """A plate with a wavy top and tilted normals: candidates that touch and some that do not."""
    g = RemovalGrid.plate(center=(0.0, 0.0, 0.0), size_x=0.08, size_y=0.06, spacing=0.5e-3)
    pts = g.points.copy()
    pts[:, 2] = 2e-4 * np.sin(pts[:, 0] * 300.0) * np.cos(pts[:, 1] * 200.0) + 1e-5 * rng.standard_normal(len(pts))
    normals = g.normals + 0.05 * rng.standard_normal(g.normals.shape)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return RemovalGrid(pts, normals, g.areas * (1.0 + 0.1 * rng.random(len(pts))), g.shape, g.extent)


@pytest.mark.parametrize("seed", range(8))
def test_the_compiled_update_is_the_reference_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    grid = _bumpy_grid(rng)
    reference = PrestonModel(grid, preston_k=1e-13, pad_radius=0.02, pad_modulus=1e8)
    compiled = PrestonModel(grid, preston_k=1e-13, pad_radius=0.02, pad_modulus=1e8)
    wrench = np.zeros(6)
    for _ in range(20):
        tip = np.array([rng.uniform(-0.02, 0.02), rng.uniform(-0.015, 0.015), rng.uniform(-3e-4, 1e-4)])
        axis = np.array([rng.normal(0, 0.1), rng.normal(0, 0.1), 1.0]) * rng.uniform(0.5, 2.0)
        force = rng.choice([0.0, rng.uniform(1.0, 60.0)])
        v_tip, omega = rng.normal(0, 0.05, 3), np.array([0.0, 0.0, 125.0]) + rng.normal(0, 1.0, 3)
        centre = tip + np.array([0.0, 0.0, 0.03])
        dt, mu = 4e-3, 0.4
        patch = reference.patch(tip, axis, force, v_tip, omega)
        want = np.zeros(6)
        added = -1
        if patch is not None:
            added = reference.add(patch, dt)
            want = friction_wrench(patch, grid.areas, tip, centre, mu)
        got = compiled.step_compiled(tip, axis, force, v_tip, omega, dt, centre, mu, FRICTION_SPEED, wrench)
        assert got == added
        assert np.array_equal(wrench, want), (wrench, want)
        assert np.array_equal(compiled.depth, reference.depth)
    assert reference.depth.max() > 0  # the pad touched on the way


def test_a_polishing_run_gives_the_same_trace_and_map_compiled_or_not(tmp_path):
    """The flat plate (shortened) run with the compiled removal update and with the reference
    (``Twin(compiled=False)`` runs every reference path): the same trace bit for bit and the same
    removal map, and the compiled one costs less of the run's clock."""
    short = tmp_path / "plate.yaml"
    short.write_text((scenarios_dir() / "flat_plate_polish.yaml").read_text().replace("step_over: 4.0", "step_over: 30.0"))
    scenario = load_scenario(short)
    runs = {}
    for compiled in (True, False):
        twin = Twin(scenario, compiled=compiled)
        assert twin.removal.compiled == compiled
        runs[compiled] = (twin.run(), twin.removal.model_removal.depth.copy(), twin.removal.totals.copy())
    (fast, fast_depth, fast_totals), (ref, ref_depth, ref_totals) = runs[True], runs[False]
    for name in ("command", "actual", "dac", "pad_force"):
        assert np.array_equal(getattr(fast.trace, name), getattr(ref.trace, name)), name
    assert np.array_equal(fast_depth, ref_depth) and fast_depth.max() > 0
    # contact time, force integral, updates, most pad contacts: the same (the cost is not)
    keep = [rk.CONTACT_TIME, rk.FORCE_TIME, rk.CALLS, rk.MOST_CONTACTS]
    assert np.array_equal(fast_totals[keep], ref_totals[keep]) and fast_totals[rk.CONTACT_TIME] > 0
    assert 1 <= fast_totals[rk.MOST_CONTACTS] <= PAD_CONTACT_SLOTS
    assert fast.metrics["polish"]["removal"]["contact_time_s"] == fast_totals[rk.CONTACT_TIME]
