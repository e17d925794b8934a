"""A path's feed plan kept on disk (cnc_twin/planner/feed.py through cnc_twin/core/disk_cache.py):
the second run of the same program, in a new planner process, reads the sampled curve and the
plan its first run made, and runs the same bit for bit; other code plans again."""

from __future__ import annotations

import os

import numpy as np
import pytest

from cnc_twin.core import disk_cache
from cnc_twin.planner.feed import PLANS_KIND, SAMPLES_KIND
from cnc_twin.run.twin import run_scenario
from cnc_twin.scenario.load import load_scenario
from cnc_twin.scenario.resources import scenarios_dir


def _columns(result) -> dict[str, np.ndarray]:
    return {name: np.array(column, copy=True) for name, column in result.trace.columns().items()}


def _entries(folder) -> list:
    return sorted(folder.glob("*.pickle")) if folder.is_dir() else []


@pytest.mark.fresh_planner  # each run a new planner process: nothing kept in its memory
@pytest.mark.parametrize("name, kinds", [("nurbs_circle", (PLANS_KIND, SAMPLES_KIND)), ("gcode_3plus2", (PLANS_KIND,))])
def test_a_second_run_reads_the_plan_of_the_first_and_runs_the_same(tmp_path, monkeypatch, name, kinds):
    monkeypatch.setenv(disk_cache.VARIABLE, str(tmp_path))  # the planner process takes the environment
    scenario = scenarios_dir() / f"{name}.yaml"
    first = run_scenario(load_scenario(scenario))
    kept = {kind: _entries(tmp_path / kind) for kind in kinds}
    assert all(kept.values()), kept
    for entries in kept.values():
        for entry in entries:
            os.utime(entry, (0, 0))  # a read touches it: these times tell which were read
    second = run_scenario(load_scenario(scenario))
    for kind, entries in kept.items():
        assert _entries(tmp_path / kind) == entries  # nothing planned anew
        assert all(entry.stat().st_mtime > 0 for entry in entries), f"{kind}: not read from the cache"
    a, b = _columns(first), _columns(second)
    assert a.keys() == b.keys()
    for column in a:
        assert np.array_equal(a[column], b[column], equal_nan=True), column


def test_an_entry_is_named_by_the_code_as_well_as_the_inputs(monkeypatch):
    from cnc_twin.planner.feed import _disk_name, plan_key

    key = plan_key("the same", "inputs")
    monkeypatch.setattr(disk_cache, "_code_digest", "this version")
    this = _disk_name(key)
    monkeypatch.setattr(disk_cache, "_code_digest", "another version of the twin")
    assert _disk_name(key) != this and _disk_name(plan_key("other", "inputs")) != _disk_name(key)
