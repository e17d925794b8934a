"""Shared fixtures: paths and a helper that writes scenario files for a test."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture
def write_scenario(tmp_path):
    """Write a scenario mapping (or raw text) to a YAML file in tmp_path; returns its path."""

    def _write(content, name: str = "scenario.yaml") -> Path:
        path = tmp_path / name
        text = content if isinstance(content, str) else yaml.safe_dump(content, sort_keys=False)
        path.write_text(text, encoding="utf-8")
        return path

    return _write


def single_move(axis: str, target: float, *, settle: float = 0.5, **extra) -> dict:
    """A minimal scenario mapping: one point-to-point move of one axis."""
    return {"name": f"move_{axis}", "program": {"type": "point_to_point", "moves": [{axis: target}], "settle": settle},
            **extra}


@pytest.fixture(autouse=True)
def no_leftover_segments_or_processes():
    """Every test must leave no whiteboard segment in /dev/shm and no child process behind."""
    import multiprocessing

    from cnc_twin.whiteboard.block import leaked_segments, leftover_segments

    before = set(leftover_segments())
    yield
    # segments of other live processes (say a second test run on this machine) are not ours
    assert leaked_segments(set(leftover_segments()) - before) == set(), "shared-memory segment left behind"
    assert multiprocessing.active_children() == [], "child process left behind"
    assert _planner_children() == [], "planner process left behind"


def _planner_children() -> list[int]:
    """Live (not zombie) child processes of this one running the planner module."""
    import os
    from pathlib import Path

    me, out = os.getpid(), []
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        try:
            stat = (proc / "stat").read_text().rsplit(")", 1)[1].split()
            cmd = (proc / "cmdline").read_bytes()
        except OSError:
            continue
        if int(stat[1]) == me and stat[0] != "Z" and b"cnc_twin.planner.process" in cmd:
            out.append(int(proc.name))
    return out
