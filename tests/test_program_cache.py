"""A G-code program prepared once (cnc_twin.scenario.program_cache): the second load of the same
program is read from the cache and runs the same, bit for bit; a changed program, code or
damaged entry is prepared again; switched off, nothing is kept."""

from __future__ import annotations

import hashlib
import shutil

import numpy as np
import pytest

from cnc_twin.run.twin import run_scenario
from cnc_twin.core import disk_cache
from cnc_twin.scenario import gcode, program_cache
from cnc_twin.scenario.load import load_scenario
from cnc_twin.scenario.resources import programs_dir, scenarios_dir


@pytest.fixture
def cache(tmp_path, monkeypatch):
    folder = tmp_path / "cache"
    monkeypatch.setenv(program_cache.VARIABLE, str(folder))
    return folder / program_cache.KIND


def _trace_digest(result) -> str:
    digest = hashlib.sha256()
    for name, column in result.trace.columns().items():
        digest.update(name.encode())
        digest.update(np.ascontiguousarray(column).tobytes())
    return digest.hexdigest()


def _no_preparing(*_args, **_kwargs):
    raise AssertionError("prepared again instead of read from the cache")


def test_a_second_load_is_read_from_the_cache_and_runs_the_same(cache, monkeypatch):
    scenario = scenarios_dir() / "gcode_cam_raster.yaml"
    prepared = load_scenario(scenario, overrides={"max_time": 1.5})
    assert len(list(cache.glob("*.pickle"))) == 1
    monkeypatch.setattr(gcode, "_prepare", _no_preparing)
    kept = load_scenario(scenario, overrides={"max_time": 1.5})
    assert kept.program.steps == prepared.program.steps
    assert _trace_digest(run_scenario(kept)) == _trace_digest(run_scenario(prepared))


def _program_scenario(tmp_path, write_scenario):
    shutil.copy(programs_dir() / "cam_raster.ngc", tmp_path / "part.ngc")
    return write_scenario({"name": "part", "program": {"type": "gcode", "file": "part.ngc"}})


def test_a_changed_program_is_prepared_again(cache, tmp_path, write_scenario):
    scenario = _program_scenario(tmp_path, write_scenario)
    first = load_scenario(scenario)
    program = tmp_path / "part.ngc"
    program.write_text(program.read_text().replace("F3000", "F2000", 1))
    changed = load_scenario(scenario)
    assert len(list(cache.glob("*.pickle"))) == 2
    assert changed.program.steps != first.program.steps


def test_other_code_prepares_again(cache, tmp_path, write_scenario, monkeypatch):
    scenario = _program_scenario(tmp_path, write_scenario)
    load_scenario(scenario)
    monkeypatch.setattr(disk_cache, "_code_digest", "another version of the twin")
    load_scenario(scenario)
    assert len(list(cache.glob("*.pickle"))) == 2


def test_a_damaged_entry_is_prepared_again(cache, tmp_path, write_scenario):
    scenario = _program_scenario(tmp_path, write_scenario)
    first = load_scenario(scenario)
    (entry,) = cache.glob("*.pickle")
    entry.write_bytes(entry.read_bytes()[:1000])  # cut short
    again = load_scenario(scenario)
    assert again.program.steps == first.program.steps
    assert entry.stat().st_size > 1000  # made whole again


def test_switched_off_nothing_is_kept(tmp_path, write_scenario, monkeypatch):
    monkeypatch.setenv(program_cache.VARIABLE, "off")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    load_scenario(_program_scenario(tmp_path, write_scenario))
    assert not (tmp_path / "xdg").exists()
